"""The contact-normal mode's native right-hand side: one call, and the collapse.

Two tables (docs/performance.md, "Where the time goes", quotes the first):

1. Per right-hand-side call [us], at states of a collapse (every 50th call with engaged rows,
   mu 0.5, timed inside the run; a zero torque function, so that the stepper's stages call the
   law's right-hand side): the native call with its Python wrapper (``NativeRhs.load`` +
   ``accel``) and the bare extension call; medians over the states of the best of 3 timings
   each.
2. The collapse (contact-normal, mu 0.5, wrist locked, 5 s): CPU time of the run in a warm
   process (the native Dormand-Prince step and the compiled stretch), medians.

    python benchmarks/native_rhs.py [--repeats 5] [--duration 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
import timeit
from typing import Any

import numpy as np

import packbot
from packbot.contact import native
from packbot.contact.normal import NormalLaw

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def per_call(robot: packbot.Robot, every: int = 50) -> None:
    """Time the native call at every ``every``-th engaged rhs call of a 1 s collapse."""
    nat_t: list[float] = []
    raw_t: list[float] = []
    count = [0]
    orig = NormalLaw.torque_accel

    def spy(law: NormalLaw, q: Any, v: Any, tau: Any) -> Any:
        nc, rhs = law.normal, law._native
        if nc.engaged and not nc.resting and not law.locks.any_locked:
            count[0] += 1
            if count[0] % every == 0:
                out = np.zeros(len(q))

                def native_path() -> Any:
                    rhs.load(nc, nc._plan())
                    return rhs.accel(q, v, tau, True)

                def bare() -> Any:
                    return rhs._rhs.accel(q, v, tau, True, out)

                native_path()
                n = 100
                nat_t.append(min(timeit.repeat(native_path, number=n, repeat=3)) / n * 1e6)
                raw_t.append(min(timeit.repeat(bare, number=n, repeat=3)) / n * 1e6)
        return orig(law, q, v, tau)

    NormalLaw.torque_accel = spy  # type: ignore[method-assign]
    try:
        cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
        zero = lambda t, q, v: np.zeros(8)  # noqa: E731
        packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg, controller=zero)
    finally:
        NormalLaw.torque_accel = orig  # type: ignore[method-assign]
    print(f"\nPer right-hand-side call, {len(nat_t)} collapse states (us, medians of best-of-3):")
    print("| native (wrapper) | native (bare call) |")
    print("|---|---|")
    print(f"| {statistics.median(nat_t):.1f} | {statistics.median(raw_t):.1f} |")


def collapse(robot: packbot.Robot, repeats: int, duration: float) -> None:
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    q0, tau = robot.pose("drive"), np.zeros(8)
    packbot.simulate(robot, q0, tau, 0.3, config=cfg)  # warm: imports
    cpu: list[float] = []
    for _ in range(repeats):
        t0 = time.process_time()
        r = packbot.simulate(robot, q0, tau, duration, config=cfg)
        cpu.append(time.process_time() - t0)
    print(f"\nCollapse, contact-normal mu 0.5, {duration:g} s, CPU [s], {repeats} runs:")
    print(f"median {statistics.median(cpu):.3f}; runs " + " / ".join(f"{c:.2f}" for c in cpu))
    d, deep = r.diagnostics, max(0.0, -r.diagnostics.min_distance)
    print(f"samples / events / steps / rhs calls {len(r.t)} / {len(r.events)} / "
          f"{d.steps} / {d.rhs_calls}, deepest penetration {deep:.2e} m")  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=5.0)
    args = ap.parse_args(argv)
    if not native.available():
        raise SystemExit("packbot._native is not built (pip install .)")
    robot = packbot.load_robot()
    per_call(robot)
    collapse(robot, args.repeats, args.duration)


if __name__ == "__main__":
    main()
