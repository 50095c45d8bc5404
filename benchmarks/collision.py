"""Cost of the collision sweep (smallest signed distance and its pair) at the named poses.

For each pose, microseconds per call (median over many short batches, so that batches slowed
by other processes on this shared machine are filtered out):

- ``sweep``: :meth:`CollisionWorld.sweep` -- forward kinematics, the piece boxes and the box
  test in numpy, one ``pin.computeDistances`` over the candidate pairs (which also returns the
  closest), and one read per candidate: what the simulator calls at every step;
- ``unpruned``: the same answer without pruning, one C++ call over every tested pair
  (``pin.computeDistances(model, data, gmodel, gdata, q)``, FK included, min only);
- ``all_distances``: the unpruned sweep with every pair's distance read back into numpy;
- ``C++ same pairs``: one ``pin.computeDistances`` call (FK included) with exactly the sweep's
  candidate pairs active: the floor for any sweep that runs the narrowphase in C++;
- ``coal.distance loop``: ``coal.distance`` called from Python on the same candidate pairs
  (transforms prebuilt, requests and results reused): the floor for a Python narrowphase;
- ``tests``: primitive (narrowphase) tests the sweep ran, of the pairs considered.

The targets: the sweep at the drive pose under 30 us, and within 2x of ``C++ same pairs``.
A breakdown of the sweep at the drive pose follows the table.

Run: python benchmarks/collision.py [--margin 0.05]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import coal
import numpy as np
import pinocchio as pin

from packbot import CollisionWorld, load_robot

POSES = ("drive", "stow", "stand", "high", "low")
TARGET_US = 30.0
TARGET_RATIO = 2.0


def timeit_us(fn: Callable[[], object], repeat: int = 41, batch_s: float = 2e-3) -> float:
    """Median time per call [us] over ``repeat`` batches of about ``batch_s`` each."""
    for _ in range(200):
        fn()
    k, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < batch_s:
        fn()
        k += 1
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(k):
            fn()
        times.append((time.perf_counter() - t0) / k * 1e6)
    return float(np.median(times))


def activate(world: CollisionWorld, pairs: np.ndarray) -> None:
    active = np.zeros((world.geom_model.ngeoms,) * 2, dtype=bool)
    for k in pairs:
        p = world.pairs[int(k)]
        active[min(p.geom1, p.geom2), max(p.geom1, p.geom2)] = True
    world.geom_data.setActiveCollisionPairs(world.geom_model, active)


def coal_loop(world: CollisionWorld, q: np.ndarray, pairs: np.ndarray) -> Callable[[], float]:
    """coal.distance on ``pairs`` from Python, everything else prepared."""
    world.update(q)
    gos, oMg = world.geom_model.geometryObjects, world.geom_data.oMg
    jobs = []
    for k in pairs:
        p = world.pairs[int(k)]
        M1, M2 = oMg[p.geom1], oMg[p.geom2]
        jobs.append(
            (
                gos[p.geom1].geometry,
                coal.Transform3s(M1.rotation, M1.translation),
                gos[p.geom2].geometry,
                coal.Transform3s(M2.rotation, M2.translation),
            )
        )
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    dist = coal.distance

    def run() -> float:
        best = np.inf
        for s1, T1, s2, T2 in jobs:
            res.clear()
            d = dist(s1, T1, s2, T2, req, res)
            best = min(best, d)
        return best

    return run


def measure(world: CollisionWorld, q: np.ndarray, margin: float) -> dict[str, float]:
    model, data = world.robot.model, world._data
    gm, gd = world.geom_model, world.geom_data
    sw = world.sweep(q, margin)
    cand = sw.pairs
    row: dict[str, float] = {
        "pairs": float(len(world.pairs)),
        "tests": float(sw.counts.tests),
        "min": sw.min_distance,
    }
    row["sweep"] = timeit_us(lambda: world.sweep(q, margin))
    activate(world, world._all_pairs)
    row["unpruned"] = timeit_us(lambda: pin.computeDistances(model, data, gm, gd, q))
    row["all_distances"] = timeit_us(lambda: world.all_distances(q))
    activate(world, cand)
    row["cpp_same"] = timeit_us(lambda: pin.computeDistances(model, data, gm, gd, q))
    k = pin.computeDistances(model, data, gm, gd, q)
    assert len(cand) == 0 or abs(gd.distanceResults[k].min_distance - sw.min_distance) < 1e-9
    row["coal_loop"] = timeit_us(coal_loop(world, q, cand))
    return row


def breakdown(world: CollisionWorld, q: np.ndarray, margin: float) -> list[tuple[str, float]]:
    """Cost of each stage of the sweep at q [us] (each stage timed alone)."""
    model, data = world.robot.model, world._data
    gm, gd = world.geom_model, world.geom_data
    world.sweep(q, margin)
    F, idx = world._F, world._I

    def box_test() -> np.ndarray:
        t = F.take(idx)
        gap = t[:6]
        gap += t[6:]
        return (np.maximum.reduce(gap, axis=0) <= margin).nonzero()[0]

    cand = box_test()
    ok = np.zeros(len(world.pairs), dtype=bool)
    ok[cand] = True
    res = world._results

    def activation() -> None:
        world._active.put(world._pair_flat, ok)
        gd.setActiveCollisionPairs(gm, world._active)

    activation()

    def place() -> None:
        pin.updateGeometryPlacements(model, data, gm, gd, q)

    def read() -> list[float]:
        return [res[p].min_distance for p in cand.tolist()]

    return [
        ("forward kinematics + placements (C++)", timeit_us(place)),
        ("world boxes of the moving pieces (numpy)", timeit_us(world._update_boxes)),
        ("box test of every pair (numpy)", timeit_us(box_test)),
        ("pair activation", timeit_us(activation)),
        ("narrowphase on the candidates (C++)", timeit_us(lambda: pin.computeDistances(gm, gd))),
        ("read the candidates' distances", timeit_us(read)),
        ("whole sweep", timeit_us(lambda: world.sweep(q, margin))),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--margin", type=float, default=None, help="query margin [m]")
    args = parser.parse_args()
    robot = load_robot()
    world = CollisionWorld(robot)
    margin = world.margin if args.margin is None else args.margin
    print(
        f"{len(world.pairs)} tested pairs ({robot.collision_model.ngeoms} robot pieces + floor), "
        f"margin {margin} m; times in us, median of 41 batches of ~2 ms\n"
    )
    head = (
        "| pose | tests / pairs | min distance [m] | sweep (pruned) | unpruned (1 C++ call) "
        "| all_distances | C++ same pairs | coal.distance loop | sweep / C++ same pairs |"
    )
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    rows = {}
    for name in POSES:
        r = measure(world, robot.pose(name), margin)
        rows[name] = r
        print(
            f"| {name} | {int(r['tests'])} / {int(r['pairs'])} | {r['min']:.4f} | "
            f"{r['sweep']:.1f} | {r['unpruned']:.1f} | {r['all_distances']:.1f} | "
            f"{r['cpp_same']:.1f} | {r['coal_loop']:.1f} | {r['sweep'] / r['cpp_same']:.2f} |"
        )
    drive = rows["drive"]
    ratio = drive["sweep"] / drive["cpp_same"]
    print(
        f"\ndrive pose: sweep {drive['sweep']:.1f} us (target < {TARGET_US:.0f}: "
        f"{'met' if drive['sweep'] < TARGET_US else 'NOT met'}); {ratio:.2f}x one C++ call on the "
        f"same pairs (target < {TARGET_RATIO:.0f}x: {'met' if ratio < TARGET_RATIO else 'NOT met'})"
    )
    print("\nBreakdown of the sweep at the drive pose (each stage timed alone):\n")
    print("| stage | us |\n|---|---|")
    for stage, us in breakdown(world, robot.pose("drive"), margin):
        print(f"| {stage} | {us:.1f} |")


if __name__ == "__main__":
    main()
