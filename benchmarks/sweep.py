"""Cost of the compiled collision sweep against one Pinocchio call on the same candidate pairs.

Configurations: the five named poses; states along the contact-normal collapse (drive pose,
zero torque, mu 0.5, wrist, camera and gripper locked, 3 s; every k-th kept sample); uniform
random poses within the joint limits. Margin: the world's (0.05 m).

Per configuration, microseconds per call, medians over interleaved batches of about 1 ms (each
variant timed in turn, ``--repeat`` times, so that load from other processes hits them alike):

- ``sweep``: :meth:`CollisionWorld.sweep` (forward kinematics, the broadphase boxes, their
  overlaps and Coal's distances on the candidates, in one native call);
- ``C++ same pairs``: one ``pin.computeDistances(model, data, gmodel, gdata, q)`` (forward
  kinematics included) with exactly the sweep's candidate pairs active: the floor for a sweep
  whose narrowphase is one C++ call;
- ``unpruned``: that call with every pair active (the answer without pruning).

Both answers are checked to agree on the candidates (to 1e-6 m, the GJK tolerance of
Pinocchio's default distance requests; the sweep's is 1e-10 m). Then the sweep among 0 to 200
box obstacles.

Run: python benchmarks/sweep.py [--repeat N] [--collapse K] [--random K] [--seed S]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

import packbot
from packbot import CollisionWorld, load_robot

Array = NDArray[np.float64]
POSES = ("drive", "stow", "stand", "high", "low")
LOCKED = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]


def interleaved(fns: dict[str, Callable[[], object]], repeat: int) -> dict[str, float]:
    """Median time per call [us] of each function, their ~1 ms batches interleaved."""
    counts = {}
    for name, fn in fns.items():
        for _ in range(20):
            fn()
        k, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < 1e-3:
            fn()
            k += 1
        counts[name] = max(k, 1)
    times: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            n = counts[name]
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            times[name].append((time.perf_counter() - t0) / n * 1e6)
    return {name: statistics.median(ts) for name, ts in times.items()}


def configurations(robot: packbot.Robot, k_collapse: int, k_random: int, seed: int) -> dict:
    """The three groups of configurations (name -> list of q)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)
    step = max(len(res.t) // k_collapse, 1)
    rng = np.random.default_rng(seed)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    return {
        "named poses": [robot.pose(p) for p in POSES],
        "along the collapse": [res.q[i] for i in range(0, len(res.t), step)][:k_collapse],
        "random poses": [rng.uniform(lo, hi) for _ in range(k_random)],
    }


def row(world: CollisionWorld, qs: list[Array], repeat: int) -> tuple[int, float, float, float]:
    """(tests, sweep us, C++ same pairs us, unpruned us) medians over the configurations."""
    model, gm = world.robot.model, world.geom_model
    data, gd = model.createData(), gm.createData()
    tests, t_sweep, t_same, t_all = [], [], [], []
    for q in qs:
        res = world.sweep(q)
        pairs = [int(p) for p in res.pairs]
        for i in range(len(gm.collisionPairs)):
            gd.activateCollisionPair(i) if i in pairs else gd.deactivateCollisionPair(i)
        pin.computeDistances(model, data, gm, gd, q)
        for p, d in zip(pairs, res.distances, strict=True):
            other = gd.distanceResults[p].min_distance
            assert abs(other - d) <= 1e-6, (p, other, d)  # Pinocchio's default GJK tolerance
        same = interleaved(
            {
                "sweep": lambda q=q: world.sweep(q),
                "same": lambda q=q: pin.computeDistances(model, data, gm, gd, q),
            },
            repeat,
        )
        for i in range(len(gm.collisionPairs)):
            gd.activateCollisionPair(i)
        unpruned = interleaved({"all": lambda q=q: pin.computeDistances(model, data, gm, gd, q)}, 3)
        tests.append(len(pairs))
        t_sweep.append(same["sweep"])
        t_same.append(same["same"])
        t_all.append(unpruned["all"])
    med = statistics.median
    return round(med(tests)), med(t_sweep), med(t_same), med(t_all)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15, help="interleaved batches per variant")
    ap.add_argument("--collapse", type=int, default=12, help="states along the collapse")
    ap.add_argument("--random", type=int, default=8, help="random poses")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    robot = load_robot()
    world = CollisionWorld(robot)
    groups = configurations(robot, args.collapse, args.random, args.seed)
    print(
        "| group | configurations | tests | sweep [us] | C++ same pairs [us] | sweep / C++ "
        "| unpruned C++ [us] |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, qs in groups.items():
        tests, ts, tc, ta = row(world, qs, args.repeat)
        print(f"| {name} | {len(qs)} | {tests} | {ts:.1f} | {tc:.1f} | {ts / tc:.2f} | {ta:.0f} |")
    print()
    print("| box obstacles | pairs | sweep, named poses [us] |")
    print("|---|---|---|")
    rng = np.random.default_rng(args.seed)
    for n in (0, 50, 200):
        boxes = [
            packbot.Obstacle(
                name=f"box{i}",
                kind="box",
                size=(0.1, 0.1, 0.1),
                xyz=tuple(float(x) for x in rng.uniform((-2.0, -2.0, 0.05), (2.0, 2.0, 1.0))),
            )
            for i in range(n)
        ]
        env = packbot.Environment(obstacles=(packbot.FLOOR, *boxes))
        w = CollisionWorld(robot, env) if n else world
        fns = {f"q{i}": (lambda q=q, w=w: w.sweep(q)) for i, q in enumerate(groups["named poses"])}
        t = interleaved(fns, args.repeat)
        print(f"| {n} | {len(w.geom_model.collisionPairs)} | {statistics.median(t.values()):.1f} |")


if __name__ == "__main__":
    main()
