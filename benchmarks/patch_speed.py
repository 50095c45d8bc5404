"""The contact set's patches, per call and in whole runs, for two installs side by side.

Measures, in one process per round and interpreter:

- ``add_pair`` and ``refresh`` per call at states of the contact-normal collapse (mu 0.5,
  wrist locked; the states with at least two pairs within the contact tolerance): each pair
  re-added at its state, then the whole set refreshed there, many times, the median call
  kept (CPU time);
- the collapse (5 s from "drive", zero torque) CPU time, after a warm-up run;
- the CPU time of 8 random wrist-free frictionless starts of 3 s (``robustness.py``'s start
  poses, seed 2026, mu 0, no restitution), summed.

``--python`` names the interpreters to compare (each imports the packbot installed in its own
environment, e.g. the venv of a checkout of the revision before and this one's); ``--before``
adds the source tree of an older revision run by this interpreter (its editable import hook
removed, the tree first on ``sys.path``: copy the installed ``packbot/_native*.so`` into the
tree's ``packbot/``, as for ``normal_before_after.py``). The rounds run them in turn
(interleaved), and the table prints the medians over the rounds and the ratios of the medians
(the last column over the first). Run it outside a source tree (``cd /tmp``), so that each
interpreter imports its installed packbot with its compiled modules::

    python benchmarks/patch_speed.py --python /venv-before/bin/python /venv-after/bin/python
    git archive REV | tar -x -C /tmp/before && cp $SITE/packbot/_native*.so /tmp/before/packbot/
    python benchmarks/patch_speed.py --before /tmp/before --rounds 5
    python benchmarks/patch_speed.py --one          # one round in this interpreter (JSON)
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
HERE = Path(__file__).resolve().parent


def _per_call(robot, cfg) -> dict[str, float]:
    """add_pair and refresh per call [us] at the collapse's contact states (medians)."""
    import packbot
    from packbot.collision import CollisionWorld
    from packbot.contact.normal_set import ContactSet

    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 5.0, config=cfg)
    world = CollisionWorld(robot)
    model = robot.model
    cs = ContactSet(
        model,
        model.createData(),
        world,
        mu=0.5,
        restitution=0.0,
        zeno_speed=cfg.zeno_speed,
        contact_tolerance=cfg.contact_tolerance,
    )
    qs = np.asarray(res.q)
    add, refresh, npairs = [], [], []
    for q in qs[:: max(1, len(qs) // 40)]:
        q = np.array(q, dtype=float)
        near = [c.pair.index for c in world.contacts(q, cfg.contact_tolerance)]
        for k in list(cs.pairs):
            cs.remove_pair(k)
        ks = [k for k in near if cs.add_pair(q, k)]
        if len(ks) < 2:
            continue
        npairs.append(len(ks))
        for _ in range(20):
            for k in ks:
                t = time.process_time_ns()
                cs.add_pair(q, k)
                add.append(time.process_time_ns() - t)
            t = time.process_time_ns()
            cs.refresh(q)
            refresh.append(time.process_time_ns() - t)
    return {
        "add_pair_us": statistics.median(add) / 1e3,
        "refresh_us": statistics.median(refresh) / 1e3,
        "pairs_per_refresh": float(statistics.median(npairs)),
    }


def one(tree: str | None = None) -> dict[str, float]:
    """One round in this interpreter (of the packbot in ``tree`` if given)."""
    if tree:
        sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
        sys.path.insert(0, tree)
    sys.path.insert(0, str(HERE))
    import robustness as rb

    import packbot

    if tree:
        assert packbot.__file__.startswith(tree), packbot.__file__
    logging.getLogger("packbot").setLevel(logging.ERROR)
    robot = packbot.load_robot()
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    q0 = robot.pose("drive")
    packbot.simulate(robot, q0, np.zeros(8), 1.0, config=cfg)  # warm-up
    out = _per_call(robot, cfg)
    t = time.process_time()
    packbot.simulate(robot, q0, np.zeros(8), 5.0, config=cfg)
    out["collapse_cpu_s"] = time.process_time() - t
    rrobot = rb._robot()
    tol = packbot.SimConfig().contact_tolerance
    poses = rb.start_poses(rrobot, 8, 2026, 2 * tol)
    wf = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    packbot.simulate(rrobot, poses[0], np.zeros(8), 0.3, config=wf)
    t = time.process_time()
    for p in poses:
        packbot.simulate(rrobot, p, np.zeros(8), 3.0, config=wf)
    out["wrist_free_8_cpu_s"] = time.process_time() - t
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", nargs="+", default=[sys.executable], help="interpreters")
    ap.add_argument("--before", help="an older revision's source tree, run first")
    ap.add_argument("--tree", help=argparse.SUPPRESS)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--one", action="store_true", help="one round here, printed as JSON")
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.tree)))
        return
    commands = {p: [p, __file__, "--one"] for p in args.python}
    if args.before:
        tree = str(Path(args.before).resolve())
        commands = {tree: [sys.executable, __file__, "--one", "--tree", tree], **commands}
    runs: dict[str, list[dict[str, float]]] = {p: [] for p in commands}
    for r in range(args.rounds):
        for p, cmd in commands.items():
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd="/tmp")
            if proc.returncode:
                sys.exit(f"{cmd} failed:\n{proc.stderr}")
            runs[p].append(json.loads(proc.stdout.strip().splitlines()[-1]))
            print(f"round {r + 1} {p}: {runs[p][-1]}", file=sys.stderr)
    names = list(commands)
    keys = list(runs[names[0]][0])
    med = {p: {k: statistics.median(x[k] for x in runs[p]) for k in keys} for p in names}
    print(f"medians of {args.rounds} interleaved rounds (CPU times)")
    print(f"| quantity | {' | '.join(names)} | ratio |")
    print("|---" * (len(names) + 2) + "|")
    for k in keys:
        vals = [med[p][k] for p in names]
        ratio = vals[-1] / vals[0] if vals[0] else float("nan")
        print(f"| {k} | {' | '.join(f'{v:.4g}' for v in vals)} | {ratio:.3f} |")


if __name__ == "__main__":
    main()
