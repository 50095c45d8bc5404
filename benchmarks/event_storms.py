"""Event storms of the contact-normal mode at two installs side by side: random starts, collapse.

The runs where events and re-patches dominate: the random starts of ``robustness.py`` with the
wrist free (8 starts, seed 2026, 3 s each, zero torque, restitution 0; mu 0 and mu 0.5) and
the collapse (mu 0.5, wrist locked, 5 s from "drive"). Each round runs the "before" Python
(another environment with packbot installed, e.g. the main checkout's: ``--before
/path/to/venv/bin/python``) and this one, alternately, each in a fresh process that first
runs a 0.3 s start (a warm-up). Printed per case: the events and steps (the last
round's: a run is deterministic), the median over rounds of the CPU time (the process's,
which other jobs on a shared machine disturb less) of all 8 starts, of the median start, and
of the collapse, before and after, and their ratio.

    python benchmarks/event_storms.py --before /work/venv/bin/python [--rounds 5] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

CHILD = r"""
import json, logging, sys, time
from pathlib import Path
import numpy as np
import packbot
sys.path.insert(0, sys.argv[1])
import robustness as rb

logging.getLogger("packbot").setLevel(logging.ERROR)
robot = rb._robot()
poses = rb.start_poses(robot, 8, 2026, 2 * packbot.SimConfig().contact_tolerance)
out = {}
for mu in (0.0, 0.5):
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0)
    packbot.simulate(robot, poses[0], np.zeros(8), 0.3, config=cfg)
    cpu, events, steps = [], 0, 0
    for q0 in poses:
        c0 = time.process_time()
        r = packbot.simulate(robot, q0, np.zeros(8), 3.0, config=cfg)
        cpu.append(time.process_time() - c0)
        events += len(r.events)
        steps += r.diagnostics.steps
    out[f"starts_mu{mu:g}"] = {"cpu": sum(cpu), "median": float(np.median(cpu)),
                              "events": events, "steps": steps}
arm = packbot.load_robot()
wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=wrist)
packbot.simulate(arm, arm.pose("drive"), np.zeros(8), 1.0, config=cfg)
c0 = time.process_time()
r = packbot.simulate(arm, arm.pose("drive"), np.zeros(8), 5.0, config=cfg)
out["collapse"] = {"cpu": time.process_time() - c0, "median": 0.0, "events": len(r.events),
                   "steps": r.diagnostics.steps}
print(json.dumps(out))
"""


def _one(python: str) -> dict[str, Any]:
    here = str(Path(__file__).resolve().parent)
    res = subprocess.run(
        [python, "-c", CHILD, here], capture_output=True, text=True, check=True, cwd="/"
    )
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="the Python of the 'before' install")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    runs: dict[str, list[dict[str, Any]]] = {"before": [], "after": []}
    for k in range(args.rounds):
        for side, py in (("before", args.before), ("after", sys.executable)):
            runs[side].append(_one(py))
        print(f"round {k + 1}/{args.rounds} done", file=sys.stderr)
    print(
        "| case | events before / after | steps before / after | CPU before [s] | "
        "CPU after [s] | after / before | median start before / after [s] |"
    )
    print("|---|---|---|---|---|---|---|")
    for case in runs["before"][0]:
        b = [r[case] for r in runs["before"]]
        a = [r[case] for r in runs["after"]]
        cb = statistics.median(x["cpu"] for x in b)
        ca = statistics.median(x["cpu"] for x in a)
        mb = statistics.median(x["median"] for x in b)
        ma = statistics.median(x["median"] for x in a)
        med = f"{mb:.3f} / {ma:.3f}" if mb else "-"
        print(
            f"| {case} | {b[-1]['events']} / {a[-1]['events']} | {b[-1]['steps']} / "
            f"{a[-1]['steps']} | {cb:.3f} | {ca:.3f} | {ca / cb:.3f} | {med} |"
        )
    if args.json is not None:
        args.json.write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
