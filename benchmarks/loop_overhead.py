"""The event loop's own Python at two installs side by side: CPU time, interleaved.

Two Python interpreters, each with its own packbot installed (a virtual environment of the
revision before a change and one of the revision after), run the same cases in turn, each in a
fresh process, ``--rounds`` times (before, after, before, after, ...): the collapse (wrist
locked, 5 s from "drive", zero torque) in the contact-normal mode (mu 0.5) and under the report's
law (``joint_clamp``), each timed ``--repeats`` times after a warm run (median kept), and the
controlled scenario ``reconfig_elbow1`` for ``--duration`` simulated seconds (one run after a
warm 1 s run). Printed: the medians of the rounds' CPU times, after over before, and each case's
steps, restarts and events (the last round's: before and after agree where a change is bit for
bit).

    python benchmarks/loop_overhead.py --before /path/to/venv-before/bin/python [--rounds 5]
    python benchmarks/loop_overhead.py --before "$(which python)" --before-tree /tmp/old

``--before-tree``: the before side is an older revision's source tree (``git archive REV |
tar -x -C /tmp/old``: its data files too, the installed ``packbot/_native*.so`` copied into
``/tmp/old/packbot/``) run by the ``--before`` interpreter with its editable import hook
removed: for a change in Python alone, the same compiled extensions on both sides. Run it
outside a source tree (``cd /tmp``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

CHILD = r"""
import json, logging, sys, time
tree = sys.argv[3]
if tree:  # an older revision's source tree run by this interpreter (its editable hook removed)
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
    sys.path.insert(0, tree)
import numpy as np
import packbot
if tree:
    assert packbot.__file__.startswith(tree), packbot.__file__
from packbot.scenario import load_scenario
logging.getLogger("packbot").setLevel(logging.ERROR)
WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
robot = packbot.load_robot()
case, arg = sys.argv[1], sys.argv[2]
if case in ("normal", "joint_clamp"):
    extra = {"mu": 0.5} if case == "normal" else {}
    cfg = packbot.SimConfig(contact_mode=case, locked_joints=WRIST, **extra)
    q0 = robot.pose("drive")
    def run(duration):
        return packbot.simulate(robot, q0, np.zeros(robot.nq), duration, config=cfg)
    n, duration = int(arg), 5.0
else:
    sc = load_scenario("reconfig_elbow1")
    def run(duration):
        q, v = sc.initial_state(robot)
        return packbot.simulate(
            robot, q, v, duration, controller=sc.build_controller(robot),
            environment=sc.environment, config=sc.config, failures=list(sc.failures),
            inform_controller=sc.inform_controller,
        )
    n, duration = 1, float(arg)
run(1.0)
cpus = []
for _ in range(n):
    c0 = time.process_time()
    r = run(duration)
    cpus.append(time.process_time() - c0)
d = r.diagnostics
out = {"cpu": float(np.median(cpus)), "steps": d.steps, "restarts": d.restarts,
       "events": len(r.events)}
print(json.dumps(out))
"""


def _run(python: str, case: str, arg: str, tree: str = "") -> dict[str, float]:
    cmd = [python, "-c", CHILD, case, arg, tree]
    done = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd="/")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="the Python of the install before")
    ap.add_argument(
        "--before-tree",
        default="",
        help="run the before side from this source tree (an older revision's checkout with the "
        "installed packbot/_native*.so copied into its packbot/) with the --before Python",
    )
    ap.add_argument("--after", default=sys.executable, help="the Python of the install after")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3, help="collapse runs per process")
    ap.add_argument("--duration", type=float, default=20.0, help="reconfig_elbow1 [s]")
    args = ap.parse_args(argv)
    cases = {
        "collapse, normal (mu 0.5, 5 s)": ("normal", str(args.repeats)),
        "collapse, joint_clamp (5 s)": ("joint_clamp", str(args.repeats)),
        f"reconfig_elbow1 ({args.duration:g} s)": ("reconfig", str(args.duration)),
    }
    got: dict[str, dict[str, list[dict[str, float]]]] = {
        c: {"before": [], "after": []} for c in cases
    }
    for _ in range(args.rounds):
        for label, (case, arg) in cases.items():
            for side, python in (("before", args.before), ("after", args.after)):
                tree = args.before_tree if side == "before" else ""
                got[label][side].append(_run(python, case, arg, tree))
    print(f"CPU time [s], medians of {args.rounds} interleaved rounds")
    print(
        f"{'case':32s} {'before':>8s} {'after':>8s} {'after/before':>12s}  steps, restarts, events"
    )
    for label, sides in got.items():
        b = statistics.median(r["cpu"] for r in sides["before"])
        a = statistics.median(r["cpu"] for r in sides["after"])
        lb, la = sides["before"][-1], sides["after"][-1]
        keys = ("steps", "restarts", "events")
        same = "same" if all(lb[k] == la[k] for k in keys) else "DIFFER"
        counts = ", ".join(f"{la[k]:.0f}" for k in keys)
        print(f"{label:32s} {b:8.3f} {a:8.3f} {a / b:12.3f}  {counts} ({same} before)")


if __name__ == "__main__":
    main()
