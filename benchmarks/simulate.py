"""Cost and outcome of the report's collapse in every contact mode and rule.

Scenario: zero torque from the drive pose, zero initial velocity, 5 s simulated, the wrist,
camera and gripper joints locked (the report's model had them as solid parts). Runs
``contact_mode="joint_clamp"`` with (reset_rule, clamp_rule) in {zero, momentum} x
{velocity, jacobian}, and ``contact_mode="none"``. Prints one table row per case (wall time:
median of REPEATS runs; the other columns come from the last run, which is deterministic), then
a cProfile of the default rule (zero + velocity), top 15 functions by cumulative time.

Run: python benchmarks/simulate.py [--repeats N] [--duration S]
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
    ("zero/velocity", {"reset_rule": "zero", "clamp_rule": "velocity"}),
    ("zero/jacobian", {"reset_rule": "zero", "clamp_rule": "jacobian"}),
    ("momentum/velocity", {"reset_rule": "momentum", "clamp_rule": "velocity"}),
    ("momentum/jacobian", {"reset_rule": "momentum", "clamp_rule": "jacobian"}),
    ("none", {"contact_mode": "none"}),
)


def run(robot: packbot.Robot, cfg: packbot.SimConfig, duration: float) -> packbot.SimResult:
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs per case (median wall time)")
    ap.add_argument("--duration", type=float, default=5.0, help="simulated time [s]")
    args = ap.parse_args()
    robot = packbot.load_robot()
    run(robot, packbot.SimConfig(locked_joints=LOCKED), 0.2)  # warm-up (imports, caches)
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

    cfg = packbot.SimConfig(locked_joints=LOCKED)
    prof = cProfile.Profile()
    prof.enable()
    run(robot, cfg, args.duration)
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(15)
    print("\ncProfile, zero/velocity (the default rule), top 15 by cumulative time:")
    print(buf.getvalue())


if __name__ == "__main__":
    main()
