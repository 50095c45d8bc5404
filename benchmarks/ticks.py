"""Controlled runs: a step at every controller tick versus the held ticks of packbot.ticks.

Runs ``reconfig_elbow1`` (1 ms ticks, elbow1 frozen at 1 s, the arm at rest from about 4.5 s)
for 60 s of simulated time, interleaved: the current loop, and the same code with every tick
ending a step and restarting the stepper (``Ticks.same`` patched to say that every command
changed: the loop before the held ticks). Prints the median wall time, the real-time factor, the
steps, right-hand-side calls and restarts of each, and the largest difference of the sampled
joint angles between the two.

Run: python benchmarks/ticks.py [--duration 60] [--repeats 3] [--scenario reconfig_elbow1]
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np

from packbot.model import load_robot
from packbot.scenario import load_scenario, run_scenario
from packbot.ticks import Ticks


def run(name: str, duration: float, every_tick: bool) -> tuple[float, Any]:
    """Wall time [s] and result of one run."""
    same = Ticks.same
    if every_tick:
        Ticks.same = lambda self, tau: False  # type: ignore[method-assign]
    try:
        robot = load_robot()
        scenario = load_scenario(name)
        t0 = time.perf_counter()
        res = run_scenario(scenario, robot, duration=duration)
        return time.perf_counter() - t0, res
    finally:
        Ticks.same = same  # type: ignore[method-assign]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="reconfig_elbow1")
    ap.add_argument("--duration", type=float, default=60.0, help="simulated time [s]")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    walls: dict[bool, list[float]] = {False: [], True: []}
    results: dict[bool, Any] = {}
    for _ in range(args.repeats):
        for every in (True, False):
            wall, res = run(args.scenario, args.duration, every)
            walls[every].append(wall)
            results[every] = res
    print(f"{args.scenario}, {args.duration:g} s simulated, median of {args.repeats} interleaved")
    print("| loop | wall [s] | real-time factor | steps | rhs calls | restarts | ticks |")
    print("|---|---|---|---|---|---|---|")
    for every, label in ((True, "a step at every tick"), (False, "held ticks (packbot.ticks)")):
        w = statistics.median(walls[every])
        d = results[every].diagnostics
        print(
            f"| {label} | {w:.2f} | {args.duration / w:.1f} | {d.steps:,} | {d.rhs_calls:,} | "
            f"{d.restarts} | {results[every].control_ticks:,} |"
        )
    a, b = results[True], results[False]
    if a.q.shape == b.q.shape:
        print(f"largest |q difference| over the samples: {np.abs(a.q - b.q).max():.2e} rad")


if __name__ == "__main__":
    main()
