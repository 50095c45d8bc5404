"""The contact-normal collapse at two revisions side by side, with MuJoCo Euler 1 ms bare.

The collapse of ``benchmarks/peers.py`` (contact-normal mode, mu 0.5, wrist locked, 5 s from
"drive", zero torque; with ``--mode joint_clamp`` the report's law's collapse of the same table)
run by the installed packbot ("after") and by the packbot of another source tree ("before": a
checkout of an older revision, e.g. ``git archive REV | tar -x -C DIR``), and MuJoCo Euler 1 ms
stepped bare (``peers.py``'s case: one ``mj_step(..., nstep=n)`` call). Each round runs the three,
in that order, each in a fresh process; a packbot process first runs a 1 s collapse (a warm-up) and
then times the 5 s one (``--repeats``: that many times, the median kept; MuJoCo's run as often).
Printed: steps, right-hand-side calls, events and restarts (the last round's: a run is
deterministic), the medians of the CPU and wall times, both over MuJoCo's (ratios of the medians;
for the wall time also the median of the rounds' own ratios, steadier under a changing load; on a
machine shared with other jobs the CPU times compare best), the deepest penetration, the largest
energy gain at an event and the rest pose.

The before tree is imported in place of the installed packbot: with packbot installed in
editable mode, its import hook is removed from the child's ``sys.meta_path`` and the tree put
first on ``sys.path`` (copy the installed compiled extension, ``packbot/_native*.so``, into
the tree's ``packbot/`` for a revision that has one; it only gained methods since).

    python benchmarks/normal_before_after.py --before DIR [--rounds N] [--json PATH]
    python benchmarks/normal_before_after.py --before DIR --mode joint_clamp --repeats 7
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

CHILD = r"""
import json, os, sys, time
tree = os.environ.get("PACKBOT_TREE")
if tree:
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
    sys.path.insert(0, tree)
import numpy as np
import packbot
if tree:
    assert packbot.__file__.startswith(tree), packbot.__file__
robot = packbot.load_robot()
mode, repeats = os.environ["PACKBOT_MODE"], int(os.environ["PACKBOT_REPEATS"])

def timed(f):
    walls, cpus = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = f()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return out, float(np.median(walls)), float(np.median(cpus))

if sys.argv[1] == "mujoco":
    sys.path.insert(0, os.environ["PEERS_DIR"])
    import peers
    from packbot.mujoco_model import build_mujoco_model
    arm = build_mujoco_model(robot, mu=0.5, timestep=1e-3, integrator="euler")
    once = peers._mujoco_case(robot, peers.Row("MuJoCo Euler 1 ms", 5.0), arm)
    once()
    _, wall, cpu = timed(once)
    print(json.dumps({"wall": wall, "cpu": cpu}))
else:
    wrist = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]
    cfg = packbot.SimConfig(contact_mode=mode, mu=0.5, locked_joints=wrist)
    q0, v0 = robot.pose("drive"), np.zeros(robot.nq)
    packbot.simulate(robot, q0, v0, 1.0, config=cfg)
    res, wall, cpu = timed(lambda: packbot.simulate(robot, q0, v0, 5.0, config=cfg))
    d = res.diagnostics
    names = list(robot.joint_names)
    print(json.dumps({
        "wall": wall, "cpu": cpu, "steps": d.steps, "rhs": d.rhs_calls,
        "events": len(res.events), "restarts": d.restarts,
        "pen": max(0.0, -d.min_distance),
        "gain": max([e.energy_after - e.energy_before for e in res.events] + [0.0]),
        "rest": [float(res.q[-1][names.index(j)]) for j in ("shoulder", "elbow1", "elbow2")],
    }))
"""


def _child(what: str, tree: str | None, mode: str, repeats: int) -> dict[str, Any]:
    env = dict(
        os.environ,
        PEERS_DIR=str(Path(__file__).resolve().parent),
        PACKBOT_MODE=mode,
        PACKBOT_REPEATS=str(repeats),
    )
    env.pop("PACKBOT_TREE", None)
    if tree is not None:
        env["PACKBOT_TREE"] = str(Path(tree).resolve())
    # (run outside any source tree: ``python -c`` puts the working directory first on
    # sys.path, and a checkout's packbot/ there, without its compiled extension, would be the
    # one imported)
    out = subprocess.run(
        [sys.executable, "-c", CHILD, what],
        env=env,
        check=True,
        capture_output=True,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="source tree of the older revision")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds")
    ap.add_argument("--json", help="write every round's numbers here")
    ap.add_argument(
        "--mode", choices=("normal", "joint_clamp"), default="normal", help="the contact law"
    )
    ap.add_argument("--repeats", type=int, default=1, help="timed runs per process (median)")
    args = ap.parse_args()
    rows: dict[str, list[dict[str, Any]]] = {"before": [], "after": [], "mujoco": []}
    for _ in range(args.rounds):
        rows["before"].append(_child("packbot", args.before, args.mode, args.repeats))
        rows["after"].append(_child("packbot", None, args.mode, args.repeats))
        rows["mujoco"].append(_child("mujoco", None, args.mode, args.repeats))

    def med(k: str, f: str) -> float:
        return statistics.median(r[f] for r in rows[k])

    mj, mj_cpu = med("mujoco", "wall"), med("mujoco", "cpu")
    law = "contact-normal collapse, mu 0.5" if args.mode == "normal" else "joint_clamp collapse"
    print(f"{law}, 5 s; medians of {args.rounds} interleaved rounds")
    print(
        "| | steps | rhs calls | events | restarts | CPU [s] | wall [s] | CPU / MuJoCo's "
        "| wall / MuJoCo's | penetration [m] | largest event gain [J] "
        "| rest pose: shoulder, elbow1, elbow2 [rad] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for k in ("before", "after"):
        x = rows[k][-1]
        rounds = statistics.median(
            p["wall"] / m["wall"] for p, m in zip(rows[k], rows["mujoco"], strict=True)
        )
        rest = ", ".join(f"{r:.4f}" for r in x["rest"])
        print(
            f"| {k} | {x['steps']} | {x['rhs']} | {x['events']} | {x['restarts']} "
            f"| {med(k, 'cpu'):.4f} | {med(k, 'wall'):.4f} | {med(k, 'cpu') / mj_cpu:.2f}x "
            f"| {med(k, 'wall') / mj:.2f}x "
            f"(rounds {rounds:.2f}x) | {x['pen']:.2e} | {x['gain']:.1e} | {rest} |"
        )
    print(f"| MuJoCo Euler 1 ms | | | | | {mj_cpu:.4f} | {mj:.4f} | 1 | 1 | | | |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
