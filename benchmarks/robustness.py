"""Robustness of a contact law from random starts: errors, energy gained at events, penetration.

The collapse (zero torque) from random start poses: every free joint uniform inside its limits,
the start at least ``2 * contact_tolerance`` from any contact, zero velocity; the same poses
(seeded) for every setting. For each setting of friction mu, restitution e and the wrist (and
camera) joints locked or free, it prints: runs, errors (a ``SimulationError``: step-size
underflow, the ``max_events`` guard, ...), runs that reached ``max_events``, runs stopped by the
wall-time guard, the largest energy gained at one event [J] (``energy_after - energy_before``,
over every event of every run), the largest energy gained over a whole run [J] (final minus
initial energy), the deepest penetration [m] (``-min_distance``, 0 if none), the runs at rest at
the end, the runs that used time-stepping windows and the most energy a run's windows removed
(``Diagnostics.window_energy_removed``, docs/contact.md), and the median and worst wall time
and CPU time (the worker process's, which other jobs on a shared machine disturb less) per
run [s]; below a setting's row, the runs whose largest gain at one event exceeds 1e-6 J and
1 J, with the largest (start, time, pair). Each worker loads the compiled kernels before its
first timed run. ``--per-run`` also lists every run.

The independent checks (``benchmarks/robustness_checks.py``) read every sample of each run
(``--sample-dt``, 1 ms by default, and the states before and after every event) with code that
does not go through the engine. A second table prints, per setting: the largest rise of the
total energy (recomputed from q and v with Pinocchio) above its running minimum [J] and the
runs rising by more than 1e-2 J; the same largest rise over the raw samples (a time-stepping
window's interpolated samples dip across an impulse with restitution, and the first figure
does not let such a dip lower the minimum: ``robustness_checks.energy_rise``); the deepest
penetration by a separate Coal query of every tested pair [m] and the runs below -1.1e-5 m;
the largest overrun of a joint's position limit [rad] and the runs beyond 1e-5 rad (issue 38's
bounds); the largest difference between the recomputed energy and ``result.energy`` [J]; the
checks' median time per run [s] and the setting's wall time [s]. Then every run beyond a bound,
with its start index, the setting and the time, worst first.

    python benchmarks/robustness.py                      # the contact-normal mode, full grid
    python benchmarks/robustness.py --starts 100 --mu 0 0.5 1.2 --wrist free  # issue 38's grid
    python benchmarks/robustness.py --law joint_clamp --mu 0 --e 0 0.3
    python benchmarks/robustness.py --starts 20 --mu 0.5 --wrist locked --workers 2
    python benchmarks/robustness.py --law joint_clamp --handoff --joint-friction \
        --reset-rule momentum --mu 0.5 --starts 40     # the hand-off with joint friction

The full grid (200 starts x 5 mu x 2 e x 2 wrist settings = 4,000 runs of 3 s) takes hours on 2
cores; ``--starts`` and the filters pick a slice. Issue 16's goal: 0 errors, 0 energy gained at
any event (beyond 1e-6 J), penetration within ``PENETRATION_TOL``, in every setting. Issue 38's
(with the second command): in every run, no energy rise beyond 1e-2 J, no pair below
-1.1e-5 m at any sample, no joint beyond its limit by more than 1e-5 rad, and no error.
"""

from __future__ import annotations

import argparse
import itertools
import logging
import multiprocessing as mp
import os
import statistics
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import robustness_checks as rc

import packbot
from packbot.collision import CollisionWorld
from packbot.mujoco_model import WRIST_JOINTS

MU = (0.0, 0.2, 0.5, 0.8, 1.2)
RESTITUTION = (0.0, 0.3)
WRIST = ("locked", "free")
#: Energy gained at one event beyond this is counted as a gain [J].
GAIN_TOL = 1e-6
#: Sampling interval of the runs [s]: the samples the independent checks read (fine enough to
#: see the motion between events; the samples do not change the integration).
SAMPLE_DT = 1e-3


@dataclass
class Outcome:
    """One run's figures."""

    error: str = ""
    max_events: bool = False
    timeout: bool = False
    event_gain: float = 0.0
    event_gain_at: str = ""
    run_gain: float = 0.0
    penetration: float = 0.0
    at_rest: bool = False
    wall: float = 0.0
    cpu: float = 0.0
    windows: int = 0
    removed: float = 0.0
    handoffs: int = 0
    window_steps: int = 0
    steps: int = 0
    events: int = 0
    start: int = -1
    checks: rc.Checks | None = None
    check_wall: float = 0.0


class _Timeout(Exception):
    pass


def start_poses(robot: packbot.Robot, n: int, seed: int, clearance: float) -> list[np.ndarray]:
    """``n`` random start poses, each at least ``clearance`` [m] from any contact."""
    rng = np.random.default_rng(seed)
    world = CollisionWorld(robot)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    out: list[np.ndarray] = []
    while len(out) < n:
        q = rng.uniform(lo, hi)
        if not world.in_collision(q, tol=clearance):
            out.append(q)
    return out


def one_run(args: tuple[int, np.ndarray, dict[str, Any], float, float]) -> Outcome:
    """Simulate one start with one setting (in a worker process), then check its samples."""
    start, q0, cfg_kw, duration, timeout = args
    logging.getLogger("packbot").setLevel(logging.ERROR)
    robot = _robot()
    cfg = packbot.SimConfig(**cfg_kw)
    q = q0.copy()
    t0 = time.perf_counter()
    c0 = time.process_time()

    def guard(t: float) -> None:
        if time.perf_counter() - t0 > timeout:
            raise _Timeout(t)

    out = Outcome(start=start)
    res = None
    try:
        res = packbot.simulate(robot, q, np.zeros(robot.nq), duration, config=cfg, progress=guard)
    except packbot.SimulationError as exc:
        out.error = str(exc)
        out.max_events = "max_events=" in str(exc)
        res = exc.result
    except _Timeout:
        out.timeout = True
    out.wall = time.perf_counter() - t0
    out.cpu = time.process_time() - c0
    if res is not None and len(res.t):
        gains = [(e.energy_after - e.energy_before, e) for e in res.events]
        finite = [(g, e) for g, e in gains if np.isfinite(g) and g > 0.0]
        if finite:
            g, e = max(finite, key=lambda ge: ge[0])
            out.event_gain = g
            out.event_gain_at = (
                f"{e.kind} at t {e.t:.4f} s, {e.link1}/{e.piece1} - {e.link2}/{e.piece2}"
            )
        out.run_gain = float(res.energy[-1] - res.energy[0])
        out.penetration = max(0.0, -float(res.diagnostics.min_distance))
        out.at_rest = res.rest_time is not None and not out.error
        out.windows = res.diagnostics.windows
        out.removed = res.diagnostics.window_energy_removed
        out.handoffs = len(res.events_of("handoff"))
        out.window_steps = res.diagnostics.window_steps
        out.steps = res.diagnostics.steps
        out.events = len(res.events)
        t1 = time.perf_counter()
        out.checks = rc.check_result(res, robot.model, _query(robot, res.environment))
        out.check_wall = time.perf_counter() - t1
    return out


_QUERIES: dict[object, rc.PenetrationQuery] = {}


def _query(robot: packbot.Robot, environment: packbot.Environment | None) -> rc.PenetrationQuery:
    """The independent penetration query of a world (the collision world's model, built once)."""
    env = packbot.Environment() if environment is None else environment
    query = _QUERIES.get(env)
    if query is None:
        query = _QUERIES[env] = rc.PenetrationQuery(
            robot.model, CollisionWorld(robot, env).geom_model
        )
    return query


_ROBOT: packbot.Robot | None = None


def _warm() -> None:
    """A worker's first contact-normal run before its timed runs (its one-time imports)."""
    logging.getLogger("packbot").setLevel(logging.ERROR)
    robot = _robot()
    try:
        from packbot.contact import conic
    except ImportError:  # a checkout before the compiled window solver (before/after tables)
        pass
    else:
        conic.solve_conic(np.eye(3), np.zeros(3), np.ones(1), np.zeros(0), np.zeros(3), 1e-9, 1)
    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST_JOINTS)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.2, config=cfg)


def _robot() -> packbot.Robot:
    global _ROBOT
    if _ROBOT is None:
        _ROBOT = packbot.load_robot()
    return _ROBOT


def main(argv: list[str] | None = None) -> None:
    """Print the tables (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--law", default="normal", help="contact_mode (default: normal)")
    ap.add_argument("--starts", type=int, default=200, help="random starts per setting")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--mu", type=float, nargs="*", default=list(MU))
    ap.add_argument("--e", type=float, nargs="*", default=list(RESTITUTION))
    ap.add_argument("--wrist", nargs="*", default=list(WRIST), choices=WRIST)
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time per run [s]")
    ap.add_argument("--timeout", type=float, default=120.0, help="wall limit per run [s]")
    ap.add_argument(
        "--sample-dt",
        type=float,
        default=SAMPLE_DT,
        help="SimConfig.sample_dt [s]: the samples the independent checks read",
    )
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--handoff", action="store_true", help="SimConfig.handoff (joint_clamp)")
    ap.add_argument("--joint-friction", action="store_true", help="SimConfig.joint_friction")
    ap.add_argument("--reset-rule", default=None, help="SimConfig.reset_rule (joint_clamp)")
    ap.add_argument(
        "--per-run",
        action="store_true",
        help="also print every run: start, wall [s], steps, window steps, windows, events, "
        "energy removed by the windows [J], the independent checks",
    )
    args = ap.parse_args(argv)
    robot = _robot()
    tol = packbot.SimConfig().contact_tolerance
    poses = start_poses(robot, args.starts, args.seed, 2 * tol)
    extra: dict[str, Any] = {}
    if args.handoff:
        extra["handoff"] = True
    if args.joint_friction:
        extra["joint_friction"] = True
    if args.reset_rule is not None:
        extra["reset_rule"] = args.reset_rule
    print(
        f"{args.law} {extra or ''}: collapse from {args.starts} random starts (seed {args.seed}), "
        f"{args.duration:g} s each, sample_dt {args.sample_dt:g} s, {args.workers} workers, "
        f"load {os.getloadavg()[0]:.2f}",
        flush=True,
    )
    engine_rows: list[str] = []
    check_rows: list[str] = []
    offenders: list[str] = []
    t_grid = time.perf_counter()
    ctx = mp.get_context("spawn")
    with ctx.Pool(args.workers, initializer=_warm) as pool:
        for mu, e, wrist in itertools.product(args.mu, args.e, args.wrist):
            kw: dict[str, Any] = {
                "contact_mode": args.law,
                "restitution": e,
                "sample_dt": args.sample_dt,
                **extra,
            }
            if args.law == "normal" or args.handoff:  # the handed-off pairs' friction
                kw["mu"] = mu
            if wrist == "locked":
                kw["locked_joints"] = WRIST_JOINTS
            jobs = [(k, q, kw, args.duration, args.timeout) for k, q in enumerate(poses)]
            t_setting = time.perf_counter()
            outs = pool.map(one_run, jobs, chunksize=1)
            setting_wall = time.perf_counter() - t_setting
            setting = f"mu {mu:g}, e {e:g}, wrist {wrist}"
            row = _engine_row(mu, e, wrist, outs)
            checks = _check_row(mu, e, wrist, outs, setting_wall)
            engine_rows.append(row)
            check_rows.append(checks)
            print(f"{row}\n{checks}", flush=True)
            if args.handoff:
                print(f"    runs with a hand-off: {sum(o.handoffs > 0 for o in outs)}")
            gaining = [o for o in outs if o.event_gain > GAIN_TOL]
            if gaining:
                worst = max(gaining, key=lambda o: o.event_gain)
                print(
                    f"    runs gaining at an event: {len(gaining)} (> 1 J: "
                    f"{sum(o.event_gain > 1.0 for o in gaining)}); the largest "
                    f"+{worst.event_gain:.4g} J, start {worst.start}, {worst.event_gain_at}"
                )
            for o in [o for o in outs if o.error][:3]:
                print(f"    error (start {o.start}): {o.error[:150]}")
            offenders += _offenders(setting, outs)
            if args.per_run:
                for o in outs:
                    print(_per_run(o), flush=True)
    grid_wall = time.perf_counter() - t_grid
    print()
    print(
        "| mu | e | wrist | runs | errors | max_events | timeouts | max gain at an event [J] | "
        "max gain over a run [J] | deepest penetration [m] | at rest | runs with windows | "
        "max removed by windows [J] | median wall [s] | worst wall [s] | median CPU [s] | "
        "worst CPU [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(engine_rows))
    print()
    print(
        f"| mu | e | wrist | runs checked | max energy rise [J] | runs > {rc.RISE_BOUND:g} J | "
        "max rise, raw samples [J] | "
        f"deepest by the query [m] | runs < {rc.DEPTH_BOUND:g} m | max limit overrun [rad] | "
        f"runs > {rc.OVERRUN_BOUND:g} rad | max energy mismatch [J] | median check [s] | "
        "setting wall [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(check_rows))
    print()
    print(f"grid: {grid_wall:.0f} s wall ({grid_wall / 60:.1f} min)")
    if offenders:
        print(f"runs beyond a bound (seed {args.seed}; start: index in start_poses):")
        print("\n".join(offenders))


def _engine_row(mu: float, e: float, wrist: str, outs: list[Outcome]) -> str:
    walls = [o.wall for o in outs]
    cpus = [o.cpu for o in outs]
    return (
        f"| {mu:g} | {e:g} | {wrist} | {len(outs)} | {sum(bool(o.error) for o in outs)} | "
        f"{sum(o.max_events for o in outs)} | {sum(o.timeout for o in outs)} | "
        f"{max(o.event_gain for o in outs):.2g} | {max(o.run_gain for o in outs):.3g} | "
        f"{max(o.penetration for o in outs):.2g} | {sum(o.at_rest for o in outs)} | "
        f"{sum(o.windows > 0 for o in outs)} | {max(o.removed for o in outs):.2g} | "
        f"{statistics.median(walls):.2f} | {max(walls):.2f} | "
        f"{statistics.median(cpus):.2f} | {max(cpus):.2f} |"
    )


def _check_row(mu: float, e: float, wrist: str, outs: list[Outcome], wall: float) -> str:
    cs = [o.checks for o in outs if o.checks is not None]
    if not cs:
        return f"| {mu:g} | {e:g} | {wrist} | 0 | | | | | | | | | | {wall:.0f} |"
    rises = [c.energy.rise for c in cs]
    depths = [c.depth.distance for c in cs]
    overruns = [c.overrun.overrun for c in cs]
    return (
        f"| {mu:g} | {e:g} | {wrist} | {len(cs)} | {max(rises):.3g} | "
        f"{sum(r > rc.RISE_BOUND for r in rises)} | "
        f"{max(c.energy_raw.rise for c in cs):.3g} | {min(depths):.3g} | "
        f"{sum(d < rc.DEPTH_BOUND for d in depths)} | {max(overruns):.3g} | "
        f"{sum(x > rc.OVERRUN_BOUND for x in overruns)} | "
        f"{max(c.energy_mismatch for c in cs):.1g} | "
        f"{statistics.median(o.check_wall for o in outs if o.checks is not None):.2f} | "
        f"{wall:.0f} |"
    )


def _offenders(setting: str, outs: list[Outcome]) -> list[str]:
    """Every run beyond one of the bounds, worst first, one line each."""
    rows: list[tuple[int, float, str]] = []
    for o in outs:
        c = o.checks
        if c is None:
            continue
        if c.energy.rise > rc.RISE_BOUND:
            r = c.energy
            rows.append(
                (
                    0,
                    -r.rise,
                    f"  energy +{r.rise:.3g} J from t {r.t_from:.3f} to {r.t_to:.3f} s "
                    f"(largest in one interval +{r.step:.3g} J at {r.t_step:.3f} s): "
                    f"start {o.start}, {setting}",
                )
            )
        if c.depth.distance < rc.DEPTH_BOUND:
            d = c.depth
            rows.append(
                (
                    1,
                    d.distance,
                    f"  depth {d.distance:.3g} m at t {d.t:.3f} s, {d.pair} "
                    f"({d.samples_below} samples below): start {o.start}, {setting}",
                )
            )
        if c.overrun.overrun > rc.OVERRUN_BOUND:
            x = c.overrun
            rows.append(
                (
                    2,
                    -x.overrun,
                    f"  overrun {x.overrun:.3g} rad at t {x.t:.3f} s, {x.joint} "
                    f"({x.side}): start {o.start}, {setting}",
                )
            )
    rows.sort()
    return [r[2] for r in rows]


def _per_run(o: Outcome) -> str:
    text = (
        f"    start {o.start}: wall {o.wall:.3f} s, CPU {o.cpu:.3f} s, {o.steps} steps "
        f"({o.window_steps} in {o.windows} windows), {o.events} events, "
        f"removed {o.removed:.2g} J"
    )
    c = o.checks
    if c is not None:
        text += (
            f", rise {c.energy.rise:.2g} J, depth {c.depth.distance:.2g} m, "
            f"overrun {c.overrun.overrun:.2g} rad"
        )
    return text + (f", {o.error[:60]}" if o.error else "")


if __name__ == "__main__":
    main()
