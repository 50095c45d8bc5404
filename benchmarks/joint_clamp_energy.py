"""Energy the report's law gains at impacts, from random wrist-locked starts.

The collapse (zero torque, zero initial velocity, 3 s) under the report's law
(``contact_mode="joint_clamp"``, the default ``reset_rule="zero"``, ``clamp_rule="velocity"``,
e = 0) from N random starts: run i's start is ``start_poses(robot, 1, seed + i, ...)`` of
``benchmarks/robustness.py`` (every joint uniform within its limits, a start within
``2 * contact_tolerance`` of a contact drawn again), the wrist, camera and gripper joints
locked at their drawn angles. A run's gain is :func:`packbot.impact_gain.impact_gain`'s: the
positive ``energy_after - energy_before`` of its ``impact`` events, summed (the total that
warns above ``IMPACT_GAIN_WARN_J``). Prints a markdown table: runs, errors, runs that gain at
some impact, runs whose impacts gain more than ``IMPACT_GAIN_WARN_J`` in total, the largest
single-impact gain [J] with its run's seed, time and pair, the median total gain over all runs
(a run that gains nothing counts as 0) and over the runs that gain, the largest total gain [J],
and the wall time [s].

    python benchmarks/joint_clamp_energy.py               # 100 starts, seeds 2026..2125
    python benchmarks/joint_clamp_energy.py --starts 20 --workers 2
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing as mp
import os
import statistics
import time
from dataclasses import dataclass

import numpy as np
from robustness import start_poses  # (benchmarks/: the script's folder, first on sys.path)

import packbot
from packbot.impact_gain import IMPACT_GAIN_WARN_J, ImpactGain, impact_gain
from packbot.mujoco_model import WRIST_JOINTS

_ROBOT: packbot.Robot | None = None


def _robot() -> packbot.Robot:
    global _ROBOT
    if _ROBOT is None:
        _ROBOT = packbot.load_robot()
    return _ROBOT


@dataclass
class Outcome:
    """One run's figures."""

    seed: int
    gain: ImpactGain
    error: str = ""


def one_run(job: tuple[int, float]) -> Outcome:
    """Draw the start of ``seed`` and simulate it under the report's law (in a worker)."""
    seed, duration = job
    logging.getLogger("packbot").setLevel(logging.ERROR)  # (the run's own warning: counted)
    robot = _robot()
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST_JOINTS)
    (q0,) = start_poses(robot, 1, seed, 2 * cfg.contact_tolerance)
    try:
        res = packbot.simulate(robot, q0, np.zeros(robot.nq), duration, config=cfg)
    except packbot.SimulationError as exc:
        events = exc.result.events if exc.result is not None else []
        return Outcome(seed, impact_gain(events), f"{type(exc).__name__}: {exc}")
    return Outcome(seed, impact_gain(res.events))


def main(argv: list[str] | None = None) -> None:
    """Print the table (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=100, help="random starts")
    ap.add_argument("--seed", type=int, default=2026, help="run i's seed is seed + i")
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time per run [s]")
    ap.add_argument("--workers", type=int, default=1, help="worker processes")
    args = ap.parse_args(argv)
    jobs = [(args.seed + i, args.duration) for i in range(args.starts)]
    wall = time.perf_counter()
    if args.workers > 1:
        with mp.get_context("spawn").Pool(args.workers) as pool:
            outs = pool.map(one_run, jobs, chunksize=1)
    else:
        outs = [one_run(job) for job in jobs]
    wall = time.perf_counter() - wall
    totals = [o.gain.total for o in outs]
    gained = [o.gain.total for o in outs if o.gain.count]
    top = max(outs, key=lambda o: o.gain.largest)
    largest = (
        f"+{top.gain.largest:.3f} (seed {top.seed}, t = {top.gain.t:.4f} s, {top.gain.pair})"
        if top.gain.count
        else "0"
    )
    print(
        f"the report's law (joint_clamp, zero reset, e = 0), wrist locked: {args.starts} random "
        f"starts (seeds {args.seed}..{args.seed + args.starts - 1}), {args.duration:g} s each, "
        f"{args.workers} worker(s), load {os.getloadavg()[0]:.2f}"
    )
    print(
        "| runs | errors | runs that gain at some impact | "
        f"runs gaining > {IMPACT_GAIN_WARN_J:g} J in total | largest single-impact gain [J] | "
        "median total gain [J] | median total gain of the runs that gain [J] | "
        "max total gain [J] | wall time [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    print(
        f"| {len(outs)} | {sum(bool(o.error) for o in outs)} | "
        f"{sum(o.gain.count > 0 for o in outs)} | "
        f"{sum(t > IMPACT_GAIN_WARN_J for t in totals)} | {largest} | "
        f"{statistics.median(totals):.3f} | {statistics.median(gained or [0.0]):.3f} | "
        f"{max(totals):.3f} | {wall:.1f} |"
    )
    for o in outs:
        if o.error:
            print(f"    seed {o.seed}: {o.error[:150]}")


if __name__ == "__main__":
    main()
