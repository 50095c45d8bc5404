"""The contact-normal mode's native right-hand side against the Python path.

Two tables (docs/performance.md, "Where the time goes", quotes the first):

1. Per right-hand-side call [us], at states of a collapse (every 50th call with engaged rows,
   mu 0.5, timed inside the run): the Python path (``pin.aba`` then ``NormalLaw.accel``:
   Pinocchio's Python calls and the extension's rows and accelerations) against the native
   call with its Python wrapper (``NativeRhs.load`` + ``accel``) and the bare extension call;
   medians over the states of the best of 3 timings each.
2. The collapse (contact-normal, mu 0.5, wrist locked, 5 s): CPU time of the run in a warm
   process on the Python path, with the native right-hand side (the stepper's stages in
   Python around it: ``native.STEP_ENABLED = False``) and with the native Dormand-Prince step
   (``NormalLaw.step_kernel``: one call per attempt, and the step end's mode conditions from
   its last stage), interleaved, medians.

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
    """Time both paths at every ``every``-th engaged rhs call of a 1 s collapse, in the run."""
    py_t: list[float] = []
    nat_t: list[float] = []
    raw_t: list[float] = []
    worst = [0.0]
    count = [0]
    orig = NormalLaw.torque_accel

    def spy(law: NormalLaw, q: Any, v: Any, tau: Any) -> Any:
        nc, rhs = law.normal, law._native
        if rhs is not None and nc.engaged and not nc.resting and not law.locks.any_locked:
            count[0] += 1
            if count[0] % every == 0:
                out = np.zeros(len(q))

                def python_path() -> Any:
                    nc._kin_cache.clear()  # a new state at every call, as in a run
                    return law.accel(q, v, law.sys.aba(q, v, tau))

                def native_path() -> Any:
                    rhs.load(nc, nc._plan())
                    return rhs.accel(q, v, tau, True)

                def bare() -> Any:
                    return rhs._rhs.accel(q, v, tau, True, out)

                a_py, a_nat = python_path(), native_path()
                if a_nat is not None:
                    err = float(np.abs(a_py - a_nat).max() / max(1.0, np.abs(a_py).max()))
                    worst[0] = max(worst[0], err)
                n = 100
                py_t.append(min(timeit.repeat(python_path, number=n, repeat=3)) / n * 1e6)
                nat_t.append(min(timeit.repeat(native_path, number=n, repeat=3)) / n * 1e6)
                raw_t.append(min(timeit.repeat(bare, number=n, repeat=3)) / n * 1e6)
        return orig(law, q, v, tau)

    NormalLaw.torque_accel = spy  # type: ignore[method-assign]
    native.STEP_ENABLED = False  # every stage through torque_accel
    try:
        cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
        packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    finally:
        NormalLaw.torque_accel = orig  # type: ignore[method-assign]
        native.STEP_ENABLED = True
    print(f"\nPer right-hand-side call, {len(py_t)} collapse states (us, medians of best-of-3):")
    print("| Python path | native (wrapper) | native (bare call) | ratio |")
    print("|---|---|---|---|")
    p, w, b = statistics.median(py_t), statistics.median(nat_t), statistics.median(raw_t)
    print(f"| {p:.1f} | {w:.1f} | {b:.1f} | {p / w:.1f}x |")
    print(f"largest relative difference of the accelerations: {worst[0]:.1e}")


def collapse(robot: packbot.Robot, repeats: int, duration: float) -> None:
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    q0, tau = robot.pose("drive"), np.zeros(8)
    ways = {"Python path": (False, False), "native rhs": (True, False), "native step": (True, True)}
    for on, step in ways.values():  # warm: imports
        native.ENABLED, native.STEP_ENABLED = on, step
        packbot.simulate(robot, q0, tau, 0.3, config=cfg)
    cpu: dict[str, list[float]] = {k: [] for k in ways}
    runs: dict[str, Any] = {}
    for _ in range(repeats):
        for k, (on, step) in ways.items():
            native.ENABLED, native.STEP_ENABLED = on, step
            t0 = time.process_time()
            runs[k] = packbot.simulate(robot, q0, tau, duration, config=cfg)
            cpu[k].append(time.process_time() - t0)
    native.ENABLED = native.STEP_ENABLED = True
    print(f"\nCollapse, contact-normal mu 0.5, {duration:g} s, CPU [s], {repeats} interleaved:")
    print("| | " + " | ".join(ways) + " |")
    print("|---" * (len(ways) + 1) + "|")
    print("| median | " + " | ".join(f"{statistics.median(cpu[k]):.3f}" for k in ways) + " |")
    print("| runs | " + " | ".join(" / ".join(f"{c:.2f}" for c in cpu[k]) for k in ways) + " |")
    for k in ways:
        r = runs[k]
        d, deep = r.diagnostics, max(0.0, -r.diagnostics.min_distance)
        print(f"{k}: samples / events / steps / rhs calls {len(r.t)} / {len(r.events)} / "
              f"{d.steps} / {d.rhs_calls}, deepest penetration {deep:.2e} m")  # fmt: skip
    ref = runs["Python path"]
    for k in list(ways)[1:]:
        r = runs[k]
        same = r.q.shape == ref.q.shape and float(np.abs(r.q - ref.q).max())
        rest = float(np.abs(r.q[-1] - ref.q[-1]).max())
        print(f"{k} against the Python path: largest joint-angle difference {same!r} rad, "
              f"at the end {rest:.1e} rad")  # fmt: skip


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
