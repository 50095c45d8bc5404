"""Cost of the collision sweep against one C++ call on the same candidate pairs.

Configurations: the five named poses; states along the contact-normal collapse (drive pose,
zero torque, mu 0.5, wrist, camera and gripper locked, 3 s; every k-th kept sample); uniform
random poses within the joint limits. Margin: the world's (0.05 m).

For each configuration, microseconds per call: medians over interleaved batches (every
variant timed in turn, ``--repeat`` times, so that load from other processes on this shared
machine hits them alike):

- ``native``: :meth:`CollisionWorld.sweep` with the compiled sweep (``packbot._native_coal``,
  :mod:`packbot.native_sweep`): forward kinematics, the broadphase boxes, their overlaps and
  Coal's distances on the candidates in one native call (the default when it is built);
- ``sweep``: the sweep's Python path -- forward kinematics; the broadphase in C++
  (Pinocchio's ``BroadPhaseManager`` over Coal's ``SSaPCollisionManager``: the pieces' world
  boxes inflated by half the margin, their overlaps, the pairs collected by
  ``pin.CollisionCallBackCollect``); the candidates read back; one ``pin.computeDistances``
  over them (which also returns the closest); one read per candidate;
- ``before``: the sweep this replaced, kept here as a reference (:class:`NumpyBoxSweep`):
  the same forward kinematics and narrowphase, with the world boxes and the box test in numpy
  (it tests the same pairs);
- ``C++ same pairs``: one ``pin.computeDistances(model, data, gmodel, gdata, q)`` call
  (forward kinematics included) with exactly the sweep's candidate pairs active: the floor for
  any sweep whose narrowphase is one C++ call, and the target's yardstick ("the event sweep
  within 2x of one C++ call on the same candidate pairs");
- ``unpruned``: that call with every pair active (the answer without pruning);
- the same sweep with each of Pinocchio's broadphase manager types, and with the broadphase's
  candidates sent one by one to ``pin.computeDistance`` (no activation, a Python loop);
- the sweep among 0 to 200 box obstacles with three manager types;
- the sweeps of one collapse, timed in the run (:func:`in_run`);
- building a world (:func:`build_time`: ``CollisionWorld(robot)``, its fixed parts shared).

Every variant is checked to test the same pairs and return the same distances as ``sweep``.
A breakdown of the sweep, each stage timed alone, follows the tables.

Run: python benchmarks/collision.py [--repeat N] [--collapse K] [--random K] [--seed S]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

import packbot
from packbot import CollisionWorld, load_robot, native_sweep
from packbot.collision import BOX_PAD, GJK_TOLERANCE, SweepCounts, SweepResult

Array = NDArray[np.float64]
POSES = ("drive", "stow", "stand", "high", "low")
LOCKED = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]
TARGET_RATIO = 2.0
_SWEEP = CollisionWorld.sweep  # (in_run replaces it while it runs)
MANAGERS = (
    "SSaPCollisionManager",
    "NaiveCollisionManager",
    "DynamicAABBTreeCollisionManager",
    "IntervalTreeCollisionManager",
)  # not DynamicAABBTreeArrayCollisionManager: wrong pairs with these boxes (Coal 3.0.3)


# ------------------------------------------------------------------------------ timing
def interleaved(
    fns: dict[str, Callable[[], object]], repeat: int, batch_s: float = 1e-3
) -> dict[str, float]:
    """Median time per call [us] of each function, their batches of ~batch_s interleaved."""
    counts = {}
    for name, fn in fns.items():
        for _ in range(20):
            fn()
        k, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < batch_s:
            fn()
            k += 1
        counts[name] = max(k, 1)
    times: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            k = counts[name]
            t0 = time.perf_counter()
            for _ in range(k):
                fn()
            times[name].append((time.perf_counter() - t0) / k * 1e6)
    return {name: statistics.median(v) for name, v in times.items()}


def distance_data(world: CollisionWorld) -> pin.GeometryData:
    """A fresh GeometryData of the world's model with the world's distance requests."""
    gd = world.geom_model.createData()
    for dreq in gd.distanceRequests:
        dreq.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
        dreq.gjk_tolerance = GJK_TOLERANCE
        dreq.epa_tolerance = GJK_TOLERANCE
    return gd


def activate(world: CollisionWorld, gd: pin.GeometryData, pairs: NDArray[np.intp]) -> None:
    G = world.geom_model.ngeoms
    active = np.zeros((G, G), dtype=bool)
    for k in pairs.tolist():
        p = world.pairs[k]
        active[min(p.geom1, p.geom2), max(p.geom1, p.geom2)] = True
    gd.setActiveCollisionPairs(world.geom_model, active)


# ------------------------------------------------------------------------------ before
class NumpyBoxSweep:
    """The sweep before this change: world boxes and the box test in numpy (reference).

    Each piece has a box in its joint frame padded by ``BOX_PAD``; per query one batched
    matrix product gives the moving pieces' world boxes, one gather of a (12, P) array, a sum
    and a maximum give every pair's box gap, and the pairs whose gap is at most the margin
    go to one ``pin.computeDistances``. Runs on its own Data and GeometryData.
    """

    def __init__(self, world: CollisionWorld) -> None:
        self.world = world
        self.model = world.robot.model
        self.data = self.model.createData()
        self.gm = world.geom_model
        self.gd = distance_data(world)
        self.results = list(self.gd.distanceResults)
        oMi = list(self.data.oMi)
        gm, G = self.gm, self.gm.ngeoms
        bodies = world._body_of_geom
        lo_all, hi_all = np.zeros((G, 3)), np.zeros((G, 3))
        for g, go in enumerate(gm.geometryObjects):
            b = int(bodies[g])
            if b >= 0:
                M = go.placement
                pts = np.asarray(go.geometry.points(), dtype=float) @ M.rotation.T + M.translation
                lo, hi = pts.min(axis=0), pts.max(axis=0)
            else:
                lo, hi = world.environment.obstacles[-1 - b].world_aabb()
            lo, hi = lo - BOX_PAD, hi + BOX_PAD
            lo_all[g], hi_all[g] = np.clip(lo, -1e9, 1e9), np.clip(hi, -1e9, 1e9)
        moving = sorted({int(b) for b in bodies if b > 0})
        groups = [np.flatnonzero(bodies == j) for j in moving]
        J, n = len(groups), max((len(gr) for gr in groups), default=1)
        A = np.zeros((max(J, 1), 8, 2 * n))
        base = max(J, 1) * 4 * 2 * n
        F = np.zeros(base + 6 * G)
        lo_idx = np.zeros((G, 3), dtype=np.intp)
        nhi_idx = np.zeros((G, 3), dtype=np.intp)
        axes = np.arange(3)
        for g in range(G):
            lo_idx[g] = base + 6 * g + axes
            nhi_idx[g] = base + 6 * g + 3 + axes
            F[lo_idx[g]], F[nhi_idx[g]] = lo_all[g], -hi_all[g]
        for i, gr in enumerate(groups):
            for s, g in enumerate(gr.tolist()):
                c, h = (lo_all[g] + hi_all[g]) / 2, (hi_all[g] - lo_all[g]) / 2
                A[i, :3, s], A[i, 3, s], A[i, 4:7, s] = c, 1.0, -h
                A[i, :3, n + s], A[i, 3, n + s], A[i, 4:7, n + s] = -c, -1.0, -h
                lo_idx[g] = i * 8 * n + axes * 2 * n + s
                nhi_idx[g] = i * 8 * n + axes * 2 * n + n + s
        self.A, self.F = A, F
        self.F_moving = F[:base].reshape(max(J, 1), 4, 2 * n)
        self.oMi_moving = [oMi[j] for j in moving]
        g1 = np.array([p.geom1 for p in world.pairs], dtype=np.intp)
        g2 = np.array([p.geom2 for p in world.pairs], dtype=np.intp)
        self.I = np.vstack([lo_idx[g1].T, lo_idx[g2].T, nhi_idx[g2].T, nhi_idx[g1].T])
        self.active = np.zeros((G, G), dtype=bool)
        self.pair_flat = np.minimum(g1, g2) * G + np.maximum(g1, g2)

    def update_boxes(self) -> None:
        H = np.array([M.homogeneous for M in self.oMi_moving])
        np.matmul(np.concatenate((H, np.abs(H)), axis=2), self.A, out=self.F_moving)

    def box_test(self, m: float) -> NDArray[np.bool_]:
        t = self.F.take(self.I)
        gap = t[:6]
        gap += t[6:]
        ok: NDArray[np.bool_] = np.maximum.reduce(gap, axis=0) <= m
        return ok

    def sweep(self, q: Array, m: float) -> tuple[float, int, NDArray[np.intp], Array]:
        pin.updateGeometryPlacements(self.model, self.data, self.gm, self.gd, q)
        self.update_boxes()
        ok = self.box_test(m)
        cand = ok.nonzero()[0]
        if len(cand) == 0:
            return np.inf, -1, cand, np.zeros(0)
        self.active.put(self.pair_flat, ok)
        self.gd.setActiveCollisionPairs(self.gm, self.active)
        k = pin.computeDistances(self.gm, self.gd)
        res = self.results
        d = np.array([res[p].min_distance for p in cand.tolist()])
        return res[k].min_distance, k, cand, d


def loop_sweep(world: CollisionWorld) -> Callable[[Array, float], tuple[NDArray[np.intp], Array]]:
    """The world's broadphase, then ``pin.computeDistance`` pair by pair (no activation)."""
    gm, gd = world.geom_model, world.geom_data
    dist = pin.computeDistance

    def run(q: Array, m: float) -> tuple[NDArray[np.intp], Array]:
        world._fk(q)
        cand = world._collect(m)
        d = np.array([dist(gm, gd, p).min_distance for p in cand.tolist()])
        return cand, d

    return run


def python_world(
    robot: packbot.Robot, environment: packbot.Environment | None = None
) -> CollisionWorld:
    """A collision world whose sweep takes its Python path (Pinocchio's SSaP manager)."""
    world = CollisionWorld(robot, environment)
    world._native = None
    return world


def world_with(
    robot: packbot.Robot, manager: str, environment: packbot.Environment | None = None
) -> CollisionWorld:
    """A collision world whose sweep prunes with the given one of Pinocchio's manager types.

    On the sweep's Python path (with the SSaP manager, the world would take the native sweep).
    """
    kind = getattr(pin, f"BroadPhaseManager_{manager}")
    cls = type(f"World{manager}", (CollisionWorld,), {"_broadphase_type": kind})
    world: CollisionWorld = cls(robot, environment)
    world._native = None
    return world


def clutter(n: int, seed: int) -> packbot.Environment:
    """The floor and n boxes of 20 cm on the ground, 0.8 to 3 m from the robot."""
    rng = np.random.default_rng(seed)
    boxes = []
    for i in range(n):
        a, r = rng.uniform(0.0, 2 * np.pi), rng.uniform(0.8, 3.0)
        xyz = (r * np.cos(a), r * np.sin(a), 0.1)
        boxes.append(packbot.Obstacle(name=f"box{i}", kind="box", size=(0.2,) * 3, xyz=xyz))
    return packbot.Environment().with_obstacles(*boxes)


def clutter_table(robot: packbot.Robot, q: Array, repeat: int, seed: int) -> None:
    """The sweep's cost with 0 to 200 box obstacles, for three manager types."""
    kinds = ("SSaPCollisionManager", "NaiveCollisionManager", "DynamicAABBTreeCollisionManager")
    cols = ("native", *kinds)
    print("| obstacles | pieces | pairs | tests | " + " | ".join(k[:-16] or k for k in cols) + " |")
    print("|---|---|---|---|" + "---|" * len(cols))
    for n in (0, 25, 50, 100, 150, 200):
        env = clutter(n, seed)
        worlds = {"native": CollisionWorld(robot, env)}
        worlds.update({k: world_with(robot, k, env) for k in kinds})
        w0 = worlds["native"]
        tests = len(w0.sweep(q).pairs)
        for w in worlds.values():
            assert np.array_equal(w.sweep(q).pairs, w0.sweep(q).pairs)
        t = interleaved({k: (lambda w=w: w.sweep(q)) for k, w in worlds.items()}, repeat)
        row = " | ".join(f"{t[k]:.1f}" for k in cols)
        print(f"| {n} | {w0.geom_model.ngeoms} | {len(w0.pairs)} | {tests} | {row} |")


# ------------------------------------------------------------------------------ configurations
def configurations(
    robot: packbot.Robot, n_collapse: int, n_random: int, seed: int
) -> list[tuple[str, str, Array]]:
    """(group, label, q): the named poses, states along the collapse, random poses."""
    out = [("named", name, robot.pose(name)) for name in POSES]
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)
    idx = np.linspace(0, len(res.t) - 1, n_collapse).round().astype(int)
    out += [("collapse", f"collapse t={res.t[i]:.2f} s", res.q[i].copy()) for i in idx]
    rng = np.random.default_rng(seed)
    lo, hi = robot.params.lower, robot.params.upper
    out += [("random", f"random {i}", rng.uniform(lo, hi)) for i in range(n_random)]
    return out


def measure(
    native: CollisionWorld,
    world: CollisionWorld,
    before: NumpyBoxSweep,
    variants: dict[str, CollisionWorld],
    q: Array,
    repeat: int,
) -> dict[str, float]:
    """Times of every variant at q [us], after checking that they agree."""
    m = world.margin
    model = world.robot.model
    data = model.createData()
    gm = world.geom_model
    sw = world.sweep(q)
    cand = sw.pairs
    d0 = dict(zip(cand.tolist(), sw.distances.tolist(), strict=True))
    s_nat = native.sweep(q)
    assert np.array_equal(s_nat.pairs, cand), "the native sweep's candidates differ"
    assert np.allclose(s_nat.distances, sw.distances, rtol=0.0, atol=1e-12)
    assert s_nat.min_pair == sw.min_pair
    # every variant tests the same pairs and finds the same distances (GJK warm starts: 1e-9 m)
    _, _, cand_b, d_b = before.sweep(q, m)
    assert np.array_equal(cand_b, cand), "the numpy boxes and the broadphase disagree"
    assert np.allclose(d_b, sw.distances, rtol=0.0, atol=1e-9)
    for name, w in variants.items():
        s = w.sweep(q)
        assert np.array_equal(s.pairs, cand), name
        assert np.allclose(s.distances, sw.distances, rtol=0.0, atol=1e-9), name
    loop = loop_sweep(world)
    cand_l, d_l = loop(q, m)
    assert np.array_equal(cand_l, cand) and np.allclose(d_l, sw.distances, rtol=0, atol=1e-9)
    gd_same = distance_data(world)
    activate(world, gd_same, cand)
    gd_all = distance_data(world)
    fns: dict[str, Callable[[], object]] = {
        "native": lambda: native.sweep(q),
        "sweep": lambda: world.sweep(q),
        "before": lambda: before.sweep(q, m),
        "cpp_same": lambda: pin.computeDistances(model, data, gm, gd_same, q),
        "unpruned": lambda: pin.computeDistances(model, data, gm, gd_all, q),
        "loop": lambda: loop(q, m),
    }
    for name, w in variants.items():
        fns[name] = lambda w=w: w.sweep(q)  # type: ignore[misc]
    row = interleaved(fns, repeat)
    if len(cand):  # the C++ call agrees on the closest pair
        k = pin.computeDistances(model, data, gm, gd_same, q)
        assert abs(gd_same.distanceResults[k].min_distance - sw.min_distance) < 1e-9
    row["tests"] = float(len(cand))
    row["within"] = float(sum(1 for v in d0.values() if v <= m))
    row["min"] = float(sw.min_distance)
    return row


def breakdown(
    native: CollisionWorld, world: CollisionWorld, q: Array, repeat: int
) -> list[tuple[str, float]]:
    """Cost of each stage of the Python sweep at q [us], each stage timed alone (interleaved)."""
    m = world.margin
    model, data = world.robot.model, world.robot.model.createData()
    gd_same = distance_data(world)
    activate(world, gd_same, world.sweep(q).pairs)

    def cpp() -> object:
        return pin.computeDistances(model, data, world.geom_model, gd_same, q)

    gm, gd = world.geom_model, world.geom_data
    world.sweep(q)
    bp = world._bp  # (started on first use)
    cb, pairs = world._bp_callback, world._bp_pairs
    cand = world._collect(m)
    res = world._results

    def read_pairs() -> NDArray[np.intp]:
        out = np.fromiter(pairs, np.intp, len(pairs))
        out.sort()
        return out

    lst = cand.tolist()
    stages: dict[str, Callable[[], object]] = {
        "forward kinematics + placements (C++)": lambda: world._fk(q),
        "broadphase: placements, margin, boxes (C++ update)": lambda: world._place_broadphase(m),
        "broadphase: overlapping pairs (C++ collide)": lambda: bp.collide(cb),
        "read the candidates' indices": read_pairs,
        "pair activation (only when the candidates change)": lambda: world._activate(cand),
        "narrowphase on the candidates (C++)": lambda: pin.computeDistances(gm, gd),
        "read the candidates' distances": lambda: [res[p].min_distance for p in lst],
        "whole sweep (Python path)": lambda: world.sweep(q),
        "whole sweep (native, for comparison)": lambda: native.sweep(q),
        "one C++ computeDistances, same pairs (for comparison)": lambda: cpp(),
    }
    times = interleaved(stages, repeat)
    world._active_list = lst  # the activation stage left exactly the candidates active
    return list(times.items())


def numpy_sweep() -> Callable[..., SweepResult]:
    """A drop-in for :meth:`CollisionWorld.sweep` that prunes like before (numpy boxes)."""
    refs: dict[int, NumpyBoxSweep] = {}

    def sweep(
        self: CollisionWorld, q: Array, margin: float | None = None, reuse: bool = False
    ) -> SweepResult:
        ref = refs.get(id(self))
        if ref is None:
            ref = refs[id(self)] = NumpyBoxSweep(self)
        self._fk(q)  # the world's own placements, as its sweep leaves them
        d_min, k, cand, d = ref.sweep(q, self.margin if margin is None else margin)
        n, n_all = len(cand), len(self.pairs)
        return SweepResult(d_min, k, cand, d, SweepCounts(n_all, n_all - n, n))

    return sweep


def in_run(robot: packbot.Robot, inner: Callable[..., SweepResult]) -> Array:
    """The sweeps of one contact-normal collapse (3 s), timed where the simulator calls them.

    Every call of the sweep (``inner`` in place of :meth:`CollisionWorld.sweep`) during the
    run is timed, and so is one ``pin.computeDistances`` (forward kinematics included) on its
    candidates, on a separate Data and GeometryData; the two alternate in order from call to
    call (whichever runs second finds warmer caches). Caches are colder than in the loops
    above: everything costs more. Returns (sweep [us], C++ call [us], candidates) per call.
    """
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    original = CollisionWorld.sweep
    rows: list[tuple[float, float, int]] = []
    extra: dict[int, tuple[pin.Data, pin.GeometryData, list[int]]] = {}

    def timed(
        self: CollisionWorld, q: Array, margin: float | None = None, reuse: bool = False
    ) -> SweepResult:
        if id(self) not in extra:
            extra[id(self)] = (self.robot.model.createData(), distance_data(self), [])
        data, gd, active = extra[id(self)]

        def cpp(pairs: NDArray[np.intp]) -> float:
            if pairs.tolist() != active:
                activate(self, gd, pairs)
                active[:] = pairs.tolist()
            t0 = time.perf_counter()
            pin.computeDistances(self.robot.model, data, self.geom_model, gd, q)
            return time.perf_counter() - t0

        first = len(rows) % 2 == 0 and active  # the C++ call first, on the last candidates
        t_cpp = cpp(np.array(active, dtype=np.intp)) if first else 0.0
        t0 = time.perf_counter()
        sw = inner(self, q, margin, reuse=reuse)
        t_sweep = time.perf_counter() - t0
        if not first or sw.pairs.tolist() != active:
            t_cpp = cpp(sw.pairs)
        rows.append((t_sweep * 1e6, t_cpp * 1e6, len(sw.pairs)))
        return sw

    CollisionWorld.sweep = timed  # type: ignore[method-assign]
    try:
        packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)
    finally:
        CollisionWorld.sweep = original  # type: ignore[method-assign]
    return np.array(rows)


def python_sweep(
    self: CollisionWorld, q: Array, margin: float | None = None, reuse: bool = False
) -> SweepResult:
    """:meth:`CollisionWorld.sweep` on its Python path."""
    native_sweep.ENABLED = False
    try:
        return _SWEEP(self, q, margin, reuse=reuse)
    finally:
        native_sweep.ENABLED = True


def in_run_table(robot: packbot.Robot) -> None:
    """The in-run timings of the sweep and of the numpy sweep before it."""
    runs = {
        "native": in_run(robot, CollisionWorld.sweep),
        "Python path (broadphase)": in_run(robot, python_sweep),
        "before (numpy boxes)": in_run(robot, numpy_sweep()),
    }
    print("\nIn the run (contact-normal collapse, mu 0.5, 3 s; medians per call in us):\n")
    print(
        "| sweep | calls | candidates (mean) | median | C++ same pairs (median) | ratio "
        "| total [ms] | C++ total [ms] | ratio |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, a in runs.items():
        med_s, med_c = float(np.median(a[:, 0])), float(np.median(a[:, 1]))
        tot_s, tot_c = a[:, 0].sum() / 1e3, a[:, 1].sum() / 1e3
        print(
            f"| {name} | {len(a)} | {a[:, 2].mean():.1f} | {med_s:.1f} | {med_c:.1f} | "
            f"{med_s / med_c:.2f} | {tot_s:.1f} | {tot_c:.1f} | {tot_s / tot_c:.2f} |"
        )


def build_time(robot: packbot.Robot, n: int = 51) -> float:
    """Median time [ms] of ``CollisionWorld(robot)`` after a first one (the fixed parts, the
    pristine data and the native sweep's prototype built): what each simulation pays."""
    CollisionWorld(robot)
    walls = []
    for _ in range(n):
        t0 = time.perf_counter()
        CollisionWorld(robot)
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=21, help="interleaved batches per variant")
    parser.add_argument("--collapse", type=int, default=12, help="states along the collapse")
    parser.add_argument("--random", type=int, default=8, help="random poses")
    parser.add_argument("--seed", type=int, default=1, help="seed of the random poses")
    parser.add_argument("--no-extras", action="store_true", help="the main tables only")
    args = parser.parse_args()
    robot = load_robot()
    native = CollisionWorld(robot)
    if native._native is None:
        raise SystemExit("packbot._native_coal is not available: nothing to compare")
    world = python_world(robot)
    before = NumpyBoxSweep(world)
    variants = {name: world_with(robot, name) for name in MANAGERS[1:]}
    configs = configurations(robot, args.collapse, args.random, args.seed)
    load = os.getloadavg()[0]
    print(
        f"{len(world.pairs)} tested pairs ({robot.collision_model.ngeoms} robot pieces + floor), "
        f"margin {world.margin} m; times in us, medians of {args.repeat} interleaved batches of "
        f"~1 ms; load average {load:.2f} at the start; building a world "
        f"{build_time(robot):.2f} ms (median of 51)\n"
    )
    head = (
        "| configuration | tests / within margin | native | Python path | before (numpy boxes) "
        "| C++ same pairs | native / C++ | Python / C++ | before / C++ | unpruned |"
    )
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    rows: list[tuple[str, str, dict[str, float]]] = []
    for group, label, q in configs:
        r = measure(native, world, before, variants, q, args.repeat)
        rows.append((group, label, r))
        c = r["cpp_same"]
        print(
            f"| {label} | {int(r['tests'])} / {int(r['within'])} | {r['native']:.1f} | "
            f"{r['sweep']:.1f} | {r['before']:.1f} | {c:.1f} | {r['native'] / c:.2f} | "
            f"{r['sweep'] / c:.2f} | {r['before'] / c:.2f} | {r['unpruned']:.1f} |"
        )

    def med(group: str, f: Callable[[dict[str, float]], float]) -> float:
        return statistics.median(f(r) for g, _, r in rows if g == group or group == "all")

    print("\nMedians per group:\n")
    print(
        "| group | configurations | tests | native | Python path | before | C++ same pairs "
        "| native / C++ | Python / C++ | before / C++ | target native / C++ <= 2 |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for group in ("named", "collapse", "random", "all"):
        n = sum(1 for g, _, _ in rows if g == group or group == "all")
        ratio = med(group, lambda r: r["native"] / r["cpp_same"])
        print(
            f"| {group} | {n} | {med(group, lambda r: r['tests']):.0f} | "
            f"{med(group, lambda r: r['native']):.1f} | {med(group, lambda r: r['sweep']):.1f} | "
            f"{med(group, lambda r: r['before']):.1f} | "
            f"{med(group, lambda r: r['cpp_same']):.1f} | {ratio:.2f} | "
            f"{med(group, lambda r: r['sweep'] / r['cpp_same']):.2f} | "
            f"{med(group, lambda r: r['before'] / r['cpp_same']):.2f} | "
            f"{'met' if ratio <= TARGET_RATIO else 'not met'} |"
        )
    worst = max(r["native"] / r["cpp_same"] for _, _, r in rows)
    print(f"\nWorst native / C++ over the {len(rows)} configurations: {worst:.2f}")

    print("\nThe Python path's variants (medians per group, us; every one tests the same pairs):\n")
    cols = ["native", "sweep", *MANAGERS[1:], "loop"]
    names = {
        "native": "native",
        "sweep": "SSaP (Python path)",
        "loop": "SSaP + pin.computeDistance per pair",
        **{m: m.removesuffix("CollisionManager") for m in MANAGERS[1:]},
    }
    print("| group | " + " | ".join(names[c] for c in cols) + " |")
    print("|---|" + "---|" * len(cols))
    for group in ("named", "collapse", "random"):
        vals = " | ".join(f"{med(group, lambda r, c=c: r[c]):.1f}" for c in cols)
        print(f"| {group} | {vals} |")
    if args.no_extras:
        return

    in_run_table(robot)
    collapse = [(label, q) for g, label, q in configs if g == "collapse"]
    label, q_mid = collapse[len(collapse) // 2]
    print(f"\nThe sweep among 20 cm box obstacles on the ground at {label} (us):\n")
    clutter_table(robot, q_mid, args.repeat, args.seed)
    for label, q in [("the drive pose", robot.pose("drive")), *collapse[len(collapse) // 2 :][:1]]:
        print(f"\nBreakdown of the Python sweep at {label} (each stage timed alone):\n")
        print("| stage | us |\n|---|---|")
        for stage, us in breakdown(native, world, q, args.repeat):
            print(f"| {stage} | {us:.1f} |")


if __name__ == "__main__":
    main()
