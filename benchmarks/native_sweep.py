"""Whole runs with the native collision sweep against its Python path.

The collapse (drive pose, zero torque, the wrist locked, 5 s) in the contact-normal mode
(mu 0.5, the native right-hand side and step as shipped) and in the joint_clamp mode: CPU time
of the run in a warm process with ``packbot.native_sweep.ENABLED`` on and off, interleaved,
medians; the sweeps' calls and their share of the run (timed around every sweep call in a
separate, instrumented run); and the results of the two: events, samples and the largest
joint-angle difference.

    python benchmarks/native_sweep.py [--repeats 7] [--duration 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np

import packbot
from packbot import native_sweep
from packbot.collision import CollisionWorld

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
MODES = {
    "normal": packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST),
    "joint_clamp": packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST),
}


def run(robot: packbot.Robot, cfg: packbot.SimConfig, duration: float) -> packbot.SimResult:
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)


def sweep_share(robot: packbot.Robot, cfg: packbot.SimConfig, duration: float) -> tuple[int, float]:
    """(sweep calls, their total time [s]) in one run, each call timed (perf_counter)."""
    original = CollisionWorld.sweep
    acc = [0, 0.0]

    def timed(self: CollisionWorld, *args: Any, **kw: Any) -> Any:
        t0 = time.perf_counter()
        out = original(self, *args, **kw)
        acc[0] += 1
        acc[1] += time.perf_counter() - t0
        return out

    CollisionWorld.sweep = timed  # type: ignore[method-assign]
    try:
        run(robot, cfg, duration)
    finally:
        CollisionWorld.sweep = original  # type: ignore[method-assign]
    return int(acc[0]), float(acc[1])


def compare(robot: packbot.Robot, mode: str, repeats: int, duration: float) -> None:
    cfg = MODES[mode]
    ways = {"Python sweep": False, "native sweep": True}
    for on in ways.values():  # warm: imports
        native_sweep.ENABLED = on
        run(robot, cfg, 0.3)
    cpu: dict[str, list[float]] = {k: [] for k in ways}
    runs: dict[str, packbot.SimResult] = {}
    for _ in range(repeats):
        for k, on in ways.items():
            native_sweep.ENABLED = on
            t0 = time.process_time()
            runs[k] = run(robot, cfg, duration)
            cpu[k].append(time.process_time() - t0)
    shares: dict[str, list[tuple[int, float]]] = {k: [] for k in ways}
    for _ in range(3):  # instrumented runs, interleaved; the median total
        for k, on in ways.items():
            native_sweep.ENABLED = on
            shares[k].append(sweep_share(robot, cfg, duration))
    share = {k: (v[0][0], statistics.median(t for _, t in v)) for k, v in shares.items()}
    native_sweep.ENABLED = True
    print(f"\nCollapse, {mode}, {duration:g} s, CPU [s], {repeats} interleaved runs:\n")
    print("| | " + " | ".join(ways) + " | ratio |")
    print("|---" * (len(ways) + 2) + "|")
    med = {k: statistics.median(cpu[k]) for k in ways}
    a, b = list(ways)
    print("| median | " + " | ".join(f"{med[k]:.3f}" for k in ways) + f" | {med[b] / med[a]:.2f} |")
    print("| runs | " + " | ".join(" / ".join(f"{c:.3f}" for c in cpu[k]) for k in ways) + " | |")
    calls = " | ".join(f"{share[k][0]}" for k in ways)
    print(f"| sweep calls | {calls} | |")
    tot = " | ".join(f"{share[k][1] * 1e3:.1f}" for k in ways)
    print(f"| sweep total [ms] (median of 3 instrumented runs) | {tot} | |")
    per = " | ".join(f"{share[k][1] / max(share[k][0], 1) * 1e6:.1f}" for k in ways)
    print(f"| per call [us] | {per} | |")
    frac = " | ".join(f"{100 * share[k][1] / med[k]:.1f} %" for k in ways)
    print(f"| share of the median run | {frac} | |")
    ra, rb = runs[a], runs[b]
    ev_a = [(e.t, e.kind) for e in ra.events]
    ev_b = [(e.t, e.kind) for e in rb.events]
    same_shape = ra.q.shape == rb.q.shape
    diff = float(np.abs(ra.q - rb.q).max()) if same_shape else float("nan")
    print(
        f"\nresults: events {len(ev_a)} / {len(ev_b)} (identical: {ev_a == ev_b}), samples "
        f"{len(ra.t)} / {len(rb.t)}, largest joint-angle difference {diff:.1e} rad, "
        f"min_distance {ra.diagnostics.min_distance:.6e} / {rb.diagnostics.min_distance:.6e} m"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--duration", type=float, default=5.0)
    args = ap.parse_args(argv)
    if not native_sweep.available():
        raise SystemExit("packbot._native_coal is not available (pip install .)")
    robot = packbot.load_robot()
    for mode in MODES:
        compare(robot, mode, args.repeats, args.duration)


if __name__ == "__main__":
    main()
