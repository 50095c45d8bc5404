"""Where the random-start robustness runs spend their time: a cProfile split by phase.

Runs ``robustness.py``'s collapse (zero torque, the same seeded random start poses) for one
setting of friction mu and the wrist, in this process, with cProfile on, after a warm-up run
(the compiled kernels loaded). It prints each run's CPU time (under the profiler, so larger
than without) and its counts, then a table of the phases' cumulative times under the
profiler: the event location, the event handling and its parts, the steps' after-step work
(re-patch and projection), the time-stepping windows and their parts, the RK45 steps, the
step-end watch, and three costs that several phases share (the drift projection, the
contact set's re-patches, the native sweep). The rows overlap (a row's time includes its
callees'; the shared rows are counted inside the phases too): they say what dominates, not
a partition. The shares are of the profiler's total time. The profiler inflates Python-heavy
parts more than compiled ones; ``--no-profile`` prints the CPU times alone.

    python benchmarks/robustness_profile.py --mu 0 --wrist locked          # 24 starts
    python benchmarks/robustness_profile.py --mu 1.2 --wrist free --starts 8
    python benchmarks/robustness_profile.py --mu 0 --wrist locked --dump /tmp/lk.prof

Run it outside a source tree (``cd /tmp``) so that the installed packbot with its compiled
modules is imported.
"""

from __future__ import annotations

import argparse
import cProfile
import logging
import os
import pstats
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import robustness

import packbot
from packbot.mujoco_model import WRIST_JOINTS

#: (label, file name ending, function name): the rows of the split, in print order
PHASES = (
    ("event location (Brent on the event functions)", "integrator.py", "locate"),
    ("event handling", "normal_law.py", "_handle"),
    ("  restart (modes, impulse, projection, re-patch)", "normal_contacts.py", "restart"),
    ("  impact impulse (normal_steps.impulse)", "normal_steps.py", "impulse"),
    ("  mode selection (normal_modes.select_modes)", "normal_modes.py", "select_modes"),
    ("after a step (normal_law.after_step)", "normal_law.py", "after_step"),
    ("  re-patch and projection (patch_events._repatch)", "patch_events.py", "_repatch"),
    ("windows (Moreau-Jean steps)", "timestep.py", "step"),
    ("  contact set update (_update_set)", "timestep.py", "_update_set"),
    ("  step problem solve (_solve)", "window_impulses.py", "_solve"),
    ("RK45 steps (ode step)", "ode.py", "step"),
    ("step-end watch (normal_law.watch)", "normal_law.py", "watch"),
    ("shared: drift projection (normal_steps.project)", "normal_steps.py", "project"),
    ("shared: re-patches (ContactSet.add_pairs)", "normal_set.py", "add_pairs"),
    ("shared: native sweep (NativeDispatch.sweep)", "native_sweep.py", "sweep"),
)


def _phase_times(stats: pstats.Stats) -> list[tuple[str, int, float]]:
    """Each phase's (label, calls, cumulative seconds) from profile statistics."""
    table = stats.stats  # type: ignore[attr-defined]
    out = []
    for label, tail, name in PHASES:
        calls, cum = 0, 0.0
        for (path, _line, func), (_cc, nc, _tt, ct, _callers) in table.items():
            if func == name and path.endswith(os.sep + tail):
                calls += nc
                cum += ct
        out.append((label, calls, cum))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=24, help="random starts (default 24)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--mu", type=float, default=0.0, help="friction coefficient")
    ap.add_argument("--e", type=float, default=0.0, help="restitution")
    ap.add_argument("--wrist", choices=("locked", "free"), default="locked")
    ap.add_argument("--duration", type=float, default=3.0, help="per run [s]")
    ap.add_argument("--no-profile", action="store_true", help="CPU times only")
    ap.add_argument("--dump", default="", help="write the profile to this file")
    args = ap.parse_args(argv)
    logging.getLogger("packbot").setLevel(logging.ERROR)
    robot = robustness._robot()
    tol = packbot.SimConfig().contact_tolerance
    poses = robustness.start_poses(robot, args.starts, args.seed, 2 * tol)
    kw: dict[str, object] = {"contact_mode": "normal", "mu": args.mu, "restitution": args.e}
    if args.wrist == "locked":
        kw["locked_joints"] = WRIST_JOINTS
    cfg = packbot.SimConfig(**kw)  # type: ignore[arg-type]
    zero = np.zeros(robot.nq)
    packbot.simulate(robot, poses[0], zero, 0.3, config=cfg)  # warm-up (compiled kernels)
    prof = None if args.no_profile else cProfile.Profile()
    cpus = []
    print(
        f"mu {args.mu:g}, e {args.e:g}, wrist {args.wrist}: {args.starts} starts "
        f"(seed {args.seed}), {args.duration:g} s each, load {os.getloadavg()[0]:.2f}"
    )
    for i, q in enumerate(poses):
        c = time.process_time()
        if prof is not None:
            prof.enable()
        res = packbot.simulate(robot, q, zero, args.duration, config=cfg)
        if prof is not None:
            prof.disable()
        cpus.append(time.process_time() - c)
        d = res.diagnostics
        print(
            f"    start {i}: CPU {cpus[-1]:.3f} s, {d.steps} steps ({d.window_steps} in "
            f"{d.windows} windows), {len(res.events)} events",
            flush=True,
        )
    label = "under the profiler" if prof is not None else "without the profiler"
    print(f"CPU {label}: total {sum(cpus):.2f} s, median {statistics.median(cpus):.3f} s a run")
    if prof is None:
        return
    if args.dump:
        prof.dump_stats(args.dump)
    stats = pstats.Stats(prof)
    total = stats.total_tt  # type: ignore[attr-defined]
    print(f"profiled time {total:.2f} s (the profiler's clock; the shares are of it)")
    print("| phase (cumulative, overlapping) | calls | time [s] | share |")
    print("|---|---|---|---|")
    for lab, calls, cum in _phase_times(stats):
        print(f"| {lab} | {calls} | {cum:.2f} | {cum / total:.0%} |")


if __name__ == "__main__":
    main()
