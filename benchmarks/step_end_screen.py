"""The contact-normal mode's step ends at two installs side by side: CPU time, interleaved.

Two Python interpreters, each with its own packbot installed (e.g. a virtual environment of the
revision before a change and one of the revision after), run the same cases in turn, each in a
fresh process, ``--rounds`` times (before, after, before, after, ...): the collapse of
``benchmarks/peers.py`` (contact-normal mode, mu 0.5, wrist locked, 5 s from "drive", zero
torque; timed ``--repeats`` times after a warm run, the median kept) and the 8 wrist-free
random starts of ``benchmarks/robustness.py`` (seed 2026, every joint free, mu ``--mu``,
restitution 0, 3 s each; the CPU time of all 8 after a warm 0.3 s run). Printed: the medians of
the rounds' CPU times and after over before, and the steps and events of each case (the last
round's: a run is deterministic; before and after should agree where the change is bit for
bit). CPU time: on a machine shared with other jobs it compares better than the wall time.

    python benchmarks/step_end_screen.py --before /path/to/venv-before/bin/python [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, logging, sys, time
import numpy as np
import packbot
sys.path.insert(0, sys.argv[2])
import robustness as rb
logging.getLogger("packbot").setLevel(logging.ERROR)
WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
robot = rb._robot()
out = {}
if sys.argv[1] == "collapse":
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    q0 = robot.pose("drive")
    packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg)
    cpus = []
    for _ in range(int(sys.argv[3])):
        c0 = time.process_time()
        r = packbot.simulate(robot, q0, np.zeros(robot.nq), 5.0, config=cfg)
        cpus.append(time.process_time() - c0)
    out = {"cpu": float(np.median(cpus)), "steps": r.diagnostics.steps, "events": len(r.events)}
else:
    cfg = packbot.SimConfig(contact_mode="normal", mu=float(sys.argv[3]), restitution=0.0)
    poses = rb.start_poses(robot, 8, 2026, 2 * cfg.contact_tolerance)
    packbot.simulate(robot, poses[0], np.zeros(robot.nq), 0.3, config=cfg)
    steps = events = 0
    c0 = time.process_time()
    for q in poses:
        r = packbot.simulate(robot, q, np.zeros(robot.nq), 3.0, config=cfg)
        steps += r.diagnostics.steps
        events += len(r.events)
    out = {"cpu": time.process_time() - c0, "steps": steps, "events": events}
print(json.dumps(out))
"""


def _run(python: str, case: str, arg: str) -> dict[str, float]:
    here = str(Path(__file__).resolve().parent)
    cmd = [python, "-c", CHILD, case, here, arg]
    done = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd="/")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="the Python of the install before")
    ap.add_argument("--after", default=sys.executable, help="the Python of the install after")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3, help="collapse runs per process")
    ap.add_argument("--mu", type=float, default=0.0, help="friction of the wrist-free starts")
    args = ap.parse_args(argv)
    cases = {
        "collapse (mu 0.5, 5 s)": ("collapse", str(args.repeats)),
        f"8 wrist-free starts (mu {args.mu:g}, 3 s each)": ("starts", str(args.mu)),
    }
    got: dict[str, dict[str, list[dict[str, float]]]] = {
        c: {"before": [], "after": []} for c in cases
    }
    for _ in range(args.rounds):
        for label, (case, arg) in cases.items():
            for side, python in (("before", args.before), ("after", args.after)):
                got[label][side].append(_run(python, case, arg))
    print(f"CPU time [s], medians of {args.rounds} interleaved rounds")
    print(f"{'case':38s} {'before':>8s} {'after':>8s} {'after/before':>12s}  steps, events")
    for label, sides in got.items():
        b = statistics.median(r["cpu"] for r in sides["before"])
        a = statistics.median(r["cpu"] for r in sides["after"])
        lb, la = sides["before"][-1], sides["after"][-1]
        same = "same" if (lb["steps"], lb["events"]) == (la["steps"], la["events"]) else "DIFFER"
        print(
            f"{label:38s} {b:8.3f} {a:8.3f} {a / b:12.3f}  "
            f"{la['steps']:.0f}, {la['events']:.0f} ({same} before)"
        )


if __name__ == "__main__":
    main()
