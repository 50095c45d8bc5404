"""Cost and outcome of the report's collapse in every contact mode and rule.

Scenario: zero torque from the drive pose, zero initial velocity, 5 s simulated, the wrist,
camera and gripper joints locked (the report's model had them as solid parts). Runs
``contact_mode="joint_clamp"`` with (reset_rule, clamp_rule) in {zero, momentum} x
{velocity, jacobian}, and ``contact_mode="none"``. Prints one table row per case (wall time:
median of REPEATS runs; the other columns come from the last run, which is deterministic), then
a cProfile of the default rule (zero + velocity), top 15 functions by cumulative time.

Then the collapse side by side: ``joint_clamp`` (zero and momentum reset) and
``contact_mode="normal"`` with mu = 0 and mu = 0.5 (one run each, stopped after
``--normal-timeout`` wall seconds; ``--normal-duration`` shortens them): wall time, real-time
factor, rest time, rest pose and deepest penetration (max(0, -min signed distance)).
Skipped with ``--no-compare``.

MuJoCo is not timed here: benchmarks/peers.py times it stepped bare (``mj_step`` with no
Python between the steps) next to packbot, interleaved, as docs/performance.md quotes;
benchmarks/mujoco_reference.py compares MuJoCo settings as references of the rest pose.

Run: python benchmarks/simulate.py [--repeats N] [--duration S] [--normal-duration S]
    [--normal-timeout S] [--no-compare] [--no-profile]
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import platform
import pstats
import statistics
import time

import numpy as np

import packbot

LOCKED = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
CASES: tuple[tuple[str, dict[str, str]], ...] = (
    (
        "zero/velocity",
        {"contact_mode": "joint_clamp", "reset_rule": "zero", "clamp_rule": "velocity"},
    ),
    (
        "zero/jacobian",
        {"contact_mode": "joint_clamp", "reset_rule": "zero", "clamp_rule": "jacobian"},
    ),
    (
        "momentum/velocity",
        {"contact_mode": "joint_clamp", "reset_rule": "momentum", "clamp_rule": "velocity"},
    ),
    (
        "momentum/jacobian",
        {"contact_mode": "joint_clamp", "reset_rule": "momentum", "clamp_rule": "jacobian"},
    ),
    ("none", {"contact_mode": "none"}),
)


def run(robot: packbot.Robot, cfg: packbot.SimConfig, duration: float) -> packbot.SimResult:
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs per case (median wall time)")
    ap.add_argument("--duration", type=float, default=5.0, help="simulated time [s]")
    ap.add_argument(
        "--normal-duration", type=float, default=None, help="simulated time of normal rows [s]"
    )
    ap.add_argument(
        "--normal-timeout", type=float, default=300.0, help="wall limit per normal row [s]"
    )
    ap.add_argument("--no-compare", action="store_true", help="skip the side-by-side table")
    ap.add_argument("--no-profile", action="store_true", help="skip the cProfile")
    args = ap.parse_args()
    robot = packbot.load_robot()
    warm = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=LOCKED)
    run(robot, warm, 0.2)  # warm-up (imports, caches)
    print(
        f"packbot collapse, {args.duration:g} s simulated, median of {args.repeats} runs; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}, load average {os.getloadavg()[0]:.2f}"
    )
    head = (
        f"{'case':<18}{'wall[s]':>8}{'RTF':>6}{'steps':>7}{'rej':>5}{'rhs':>7}{'sweeps':>7}"
        f"{'events':>7}{'restarts':>9}{'min d[m]':>11}{'rest[s]':>8}{'shoulder':>9}{'elbow1':>8}"
        f"{'elbow2':>8}{'dE[J]':>8}"
    )
    print(head)
    print("-" * len(head))
    for label, kw in CASES:
        cfg = packbot.SimConfig(locked_joints=LOCKED, **kw)
        walls = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = run(robot, cfg, args.duration)
            walls.append(time.perf_counter() - t0)
        wall = statistics.median(walls)
        d = res.diagnostics
        q = res.q[-1]
        rest = "-" if res.rest_time is None else f"{res.rest_time:.3f}"
        mind = f"{d.min_distance:.3e}" if np.isfinite(d.min_distance) else "n/a"
        print(
            f"{label:<18}{wall:8.3f}{args.duration / wall:6.0f}{d.steps:7d}{d.rejected_steps:5d}"
            f"{d.rhs_calls:7d}{d.sweeps:7d}{len(res.events):7d}{d.restarts:9d}{mind:>11}"
            f"{rest:>8}{q[res.joint('shoulder')]:9.4f}{q[res.joint('elbow1')]:8.4f}"
            f"{q[res.joint('elbow2')]:8.4f}{res.energy[-1] - res.energy[0]:8.2f}"
        )
    print(
        "\nRTF: real-time factor (simulated / wall time); min d: smallest signed distance over "
        "the kept states\n(diagnostics.min_distance; n/a without a collision world); dE: energy "
        "at the end minus at the start."
    )

    if not args.no_compare:
        compare(robot, args)
    if args.no_profile:
        return
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=LOCKED)
    prof = cProfile.Profile()
    prof.enable()
    run(robot, cfg, args.duration)
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(15)
    print("\ncProfile, joint_clamp zero/velocity (the report's rules), top 15 by cumulative time:")
    print(buf.getvalue())


class _Timeout(Exception):
    """Raised from the progress callback when a row exceeds its wall-time budget."""


def _ours(
    robot: packbot.Robot, cfg: packbot.SimConfig, duration: float, repeats: int, timeout: float
) -> tuple[str, float, packbot.SimResult | None, float]:
    """Run one of our rows; returns (status, wall [s], result or None, simulated time [s])."""
    walls = []
    res = None
    reached = [0.0]
    for _ in range(repeats):
        t0 = time.perf_counter()

        def progress(t: float, t0: float = t0) -> None:
            reached[0] = t
            if time.perf_counter() - t0 > timeout:
                raise _Timeout

        try:
            res = packbot.simulate(
                robot,
                robot.pose("drive"),
                np.zeros(robot.nq),
                duration,
                config=cfg,
                progress=progress,
            )
        except _Timeout:
            return "timeout", time.perf_counter() - t0, None, reached[0]
        except packbot.SimulationError as exc:
            print(f"  ({exc})")
            return "error", time.perf_counter() - t0, None, reached[0]
        walls.append(time.perf_counter() - t0)
    return "ok", statistics.median(walls), res, duration


def compare(robot: packbot.Robot, args: argparse.Namespace) -> None:
    """The collapse side by side: joint_clamp and normal (see the module docstring)."""
    dur = args.duration
    ndur = dur if args.normal_duration is None else args.normal_duration
    head = (
        f"{'case':<26}{'sim[s]':>7}{'wall[s]':>9}{'RTF':>7}{'rest[s]':>8}{'shoulder':>9}"
        f"{'elbow1':>8}{'elbow2':>8}{'pen[m]':>10}"
    )
    print(f"\ncollapse side by side (drive pose, wrist locked, load {os.getloadavg()[0]:.2f})")
    print(head)
    print("-" * len(head))
    i_s, i_e1, i_e2 = (robot.joint_names.index(n) for n in ("shoulder", "elbow1", "elbow2"))

    def row(label: str, sim: float, wall: float, rest: float | None, q: np.ndarray, pen: float):
        r = "-" if rest is None else f"{rest:.3f}"
        print(
            f"{label:<26}{sim:7.2f}{wall:9.3f}{sim / wall:7.1f}{r:>8}{q[i_s]:9.4f}{q[i_e1]:8.4f}"
            f"{q[i_e2]:8.4f}{pen:10.2e}"
        )

    ours = (
        (
            "joint_clamp zero",
            {"contact_mode": "joint_clamp", "reset_rule": "zero"},
            dur,
            args.repeats,
        ),
        (
            "joint_clamp momentum",
            {"contact_mode": "joint_clamp", "reset_rule": "momentum"},
            dur,
            args.repeats,
        ),
        ("normal mu=0", {"contact_mode": "normal", "mu": 0.0}, ndur, 1),
        ("normal mu=0.5", {"contact_mode": "normal", "mu": 0.5}, ndur, 1),
    )
    for label, kw, d, reps in ours:
        cfg = packbot.SimConfig(locked_joints=LOCKED, **kw)  # type: ignore[arg-type]
        status, wall, res, reached = _ours(robot, cfg, d, reps, args.normal_timeout)
        if res is None:
            print(f"{label:<26}{status} after {wall:.1f} s wall at t = {reached:.3f} s simulated")
            continue
        pen = max(0.0, -res.diagnostics.min_distance)
        row(label, d, wall, res.rest_time, res.q[-1], pen)
    print(
        "\npen: deepest penetration over the run [m] (max(0, -diagnostics.min_distance)); "
        "rest: every joint speed below 1e-3 rad/s from then on.\nMuJoCo, stepped bare: "
        "benchmarks/peers.py."
    )


if __name__ == "__main__":
    main()
