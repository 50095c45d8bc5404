"""The contact-normal mode's stretch of quiet steps, off and on: CPU, interleaved.

:mod:`packbot.contact.stretch` takes the steps with nothing at their end for the law in one
native call (``packbot.contact.stretch.ENABLED``). The same install runs each case with the
switch off and on, each in a fresh process, ``--rounds`` times in turn (off, on, off, on, ...):
the collapse of ``benchmarks/peers.py`` (mu 0.5, wrist locked, 5 s from "drive", zero torque;
timed ``--repeats`` times after a warm run, the median kept) and the 8 wrist-free random starts
of ``benchmarks/robustness.py`` (seed 2026, mu ``--mu``, restitution 0, 3 s each; all 8 after a
warm 0.3 s run). Printed: the medians of the rounds' CPU times, on over off, the steps, of them
those taken in stretches and those handed back pending, and the events. CPU time: on a machine
shared with other jobs it compares better than the wall time.

    python benchmarks/stretch.py [--rounds 5] [--repeats 3] [--mu 0.5]
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
from packbot.contact import stretch
sys.path.insert(0, sys.argv[2])
import robustness as rb
logging.getLogger("packbot").setLevel(logging.ERROR)
stretch.ENABLED = sys.argv[4] == "on"
count = {"stretched": 0, "pending": 0}
run = stretch.QuietStretch.run
def counted(self, *args):
    done, out = run(self, *args)
    count["stretched"] += done.steps
    count["pending"] += done.pending is not None
    return done, out
stretch.QuietStretch.run = counted
WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
robot = rb._robot()
if sys.argv[1] == "collapse":
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    q0 = robot.pose("drive")
    packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg)
    cpus = []
    for _ in range(int(sys.argv[3])):
        count.update(stretched=0, pending=0)
        c0 = time.process_time()
        r = packbot.simulate(robot, q0, np.zeros(robot.nq), 5.0, config=cfg)
        cpus.append(time.process_time() - c0)
    out = {"cpu": float(np.median(cpus)), "steps": r.diagnostics.steps, "events": len(r.events)}
else:
    cfg = packbot.SimConfig(contact_mode="normal", mu=float(sys.argv[3]), restitution=0.0)
    poses = rb.start_poses(robot, 8, 2026, 2 * cfg.contact_tolerance)
    packbot.simulate(robot, poses[0], np.zeros(robot.nq), 0.3, config=cfg)
    count.update(stretched=0, pending=0)
    steps = events = 0
    c0 = time.process_time()
    for q in poses:
        r = packbot.simulate(robot, q, np.zeros(robot.nq), 3.0, config=cfg)
        steps += r.diagnostics.steps
        events += len(r.events)
    out = {"cpu": time.process_time() - c0, "steps": steps, "events": events}
out.update(count)
print(json.dumps(out))
"""


def _run(case: str, arg: str, side: str) -> dict:
    here = str(Path(__file__).resolve().parent)
    cmd = [sys.executable, "-c", CHILD, case, here, arg, side]
    done = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd="/")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3, help="collapse runs per process")
    ap.add_argument("--mu", type=float, default=0.5, help="friction of the wrist-free starts")
    ap.add_argument("--no-starts", action="store_true", help="the collapse only")
    args = ap.parse_args(argv)
    cases = {"collapse (mu 0.5, 5 s)": ("collapse", str(args.repeats))}
    if not args.no_starts:
        cases[f"8 wrist-free starts (mu {args.mu:g}, 3 s)"] = ("starts", str(args.mu))
    got: dict[str, dict[str, list[dict]]] = {c: {"off": [], "on": []} for c in cases}
    for _ in range(args.rounds):
        for label, (case, arg) in cases.items():
            for side in ("off", "on"):
                got[label][side].append(_run(case, arg, side))
    print(f"CPU time [s], medians of {args.rounds} interleaved rounds")
    print(
        f"{'case':34s} {'switch':>6s} {'CPU':>7s} {'on/off':>7s} {'steps':>6s} "
        f"{'stretched':>9s} {'pending':>7s} {'events':>6s}"
    )
    for label, sides in got.items():
        off = statistics.median(r["cpu"] for r in sides["off"])
        for side in ("off", "on"):
            cpu = statistics.median(r["cpu"] for r in sides[side])
            last = sides[side][-1]
            ratio = f"{cpu / off:7.3f}" if side == "on" else " " * 7
            print(
                f"{label:34s} {side:>6s} {cpu:7.3f} {ratio} {last['steps']:6d} "
                f"{last['stretched']:9d} {last['pending']:7d} {last['events']:6d}"
            )


if __name__ == "__main__":
    main()
