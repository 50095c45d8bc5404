"""Per-step Python overhead of packbot.ode.RK45Stepper versus scipy.integrate.RK45.

Problem: n/2 uncoupled harmonic oscillators (q_i'' = -w_i^2 q_i, w_i = 1..n/2), state
y = [q, v] of dimension n, integrated over [0, 10] with rtol=1e-6, atol=1e-9. The right-hand
side is one small matrix-vector product, whose cost is measured separately and subtracted:
"overhead/step" = (wall time - rhs calls * rhs cost) / accepted steps.

Run: python benchmarks/ode.py
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import RK45

from packbot.ode import RK45Stepper, locate_root

T_END = 10.0
RTOL = 1e-6
ATOL = 1e-9
REPEATS = 7


def make_problem(n: int) -> tuple[Callable[[float, np.ndarray], np.ndarray], np.ndarray]:
    m = n // 2
    w = np.arange(1.0, m + 1.0)
    M = np.zeros((n, n))
    M[:m, m:] = np.eye(m)
    M[m:, :m] = -np.diag(w * w)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return M @ y

    y0 = np.concatenate((np.ones(m), np.zeros(m)))
    return rhs, y0


def best_time(fn: Callable[[], object], repeats: int = REPEATS) -> float:
    """Best wall time of fn() over repeats [s]."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def rhs_cost(rhs: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray) -> float:
    """Cost of one rhs call [s]."""
    n_calls = 20000

    def loop() -> None:
        for _ in range(n_calls):
            rhs(0.5, y0)

    return best_time(loop) / n_calls


def run_packbot(rhs: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray) -> RK45Stepper:
    s = RK45Stepper(rhs, rtol=RTOL, atol=ATOL)
    s.reset(0.0, y0)
    while s.t < T_END:
        s.step(T_END)
    return s


def run_scipy(rhs: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray) -> RK45:
    r = RK45(rhs, 0.0, y0, T_END, rtol=RTOL, atol=ATOL)
    while r.status == "running":
        r.step()
    return r


def main() -> None:
    us = 1e6
    print(
        f"# {sys.version.split()[0]}, numpy {np.__version__}; problem: harmonic oscillators on "
        f"[0, {T_END}], rtol={RTOL:g}, atol={ATOL:g}; best of {REPEATS}"
    )
    print()
    print(
        f"| {'n':>3} | {'solver':<19} | {'steps':>5} | {'rejected':>8} | {'nfev':>5} | "
        f"{'rhs us':>6} | {'us/step':>7} | {'overhead us/step':>16} | {'max error':>9} |"
    )
    widths = (5, 21, 7, 10, 7, 8, 9, 18, 11)
    print("|" + "|".join("-" * k for k in widths) + "|")
    for n in (2, 16, 64):
        rhs, y0 = make_problem(n)
        m = n // 2
        w = np.arange(1.0, m + 1.0)
        exact = np.concatenate((np.cos(w * T_END), -w * np.sin(w * T_END)))
        c = rhs_cost(rhs, y0)

        s = run_packbot(rhs, y0)
        t_pb = best_time(lambda rhs=rhs, y0=y0: run_packbot(rhs, y0))
        r = run_scipy(rhs, y0)
        t_sp = best_time(lambda rhs=rhs, y0=y0: run_scipy(rhs, y0))
        n_scipy_steps = 0
        r2 = RK45(rhs, 0.0, y0, T_END, rtol=RTOL, atol=ATOL)
        while r2.status == "running":
            r2.step()
            n_scipy_steps += 1
        rows = [
            ("packbot RK45Stepper", s.n_steps, s.n_rejected, s.n_rhs, t_pb, s.y),
            # scipy: 2 rhs calls at construction, 6 per attempted step.
            ("scipy RK45", n_scipy_steps, (r.nfev - 2) // 6 - n_scipy_steps, r.nfev, t_sp, r.y),
        ]
        for name, steps, rej, nfev, wall, y in rows:
            per_step = wall / steps * us
            overhead = (wall - nfev * c) / steps * us
            err = float(np.abs(y - exact).max())
            print(
                f"| {n:>3} | {name:<19} | {steps:>5} | {rej:>8} | {nfev:>5} | {c * us:>6.2f} | "
                f"{per_step:>7.1f} | {overhead:>16.1f} | {err:>9.2e} |"
            )

    # Restart costs and dense output, n = 16.
    n = 16
    rhs, y0 = make_problem(n)
    c = rhs_cost(rhs, y0)
    s = RK45Stepper(rhs, rtol=RTOL, atol=ATOL)
    s.reset(0.0, y0)
    k = 2000

    def resets(h: float | None) -> None:
        for i in range(k):
            s.reset(0.001 * i, y0, h)

    t_reset = best_time(lambda: resets(None)) / k
    t_reset_h = best_time(lambda: resets(0.01)) / k

    def restricts() -> None:
        for i in range(k):
            s.restrict(0.001 * i, y0)

    t_restrict = best_time(restricts) / k

    def constructs() -> None:
        for _ in range(200):
            RK45(rhs, 0.0, y0, T_END, rtol=RTOL, atol=ATOL)

    t_scipy_new = best_time(constructs) / 200

    s.reset(0.0, y0)
    seg = s.step(T_END)
    tm = 0.5 * (seg.t0 + seg.t1)

    def evals() -> None:
        for _ in range(k):
            seg(tm)

    t_eval = best_time(evals) / k

    def g(t: float) -> float:
        return float(seg(t)[0]) - float(seg(tm)[0])  # crosses 0 at tm

    g0, g1 = g(seg.t0), g(seg.t1)
    if not g0 > 0 >= g1:
        g0, g1 = -g0, -g1

        def g(t: float) -> float:
            return float(seg(tm)[0]) - float(seg(t)[0])

    t_root = best_time(lambda: [locate_root(g, seg.t0, seg.t1, g0, g1) for _ in range(100)]) / 100

    print()
    print(f"Restart and dense-output costs, n = {n} (rhs {c * us:.2f} us/call):")
    print()
    print(f"| {'operation':<44} | {'us':>6} | {'us minus rhs':>12} |")
    print(f"|{'-' * 46}|{'-' * 8}|{'-' * 14}|")
    for name, tt, calls in (
        ("RK45Stepper.reset(t, y) (2 rhs calls)", t_reset, 2),
        ("RK45Stepper.reset(t, y, h) (1 rhs call)", t_reset_h, 1),
        ("RK45Stepper.restrict(t, y) (1 rhs call)", t_restrict, 1),
        ("scipy RK45(...) construction (2 rhs calls)", t_scipy_new, 2),
        ("DenseSegment(t)", t_eval, 0),
        ("locate_root on a segment, xtol=1e-10", t_root, 0),
    ):
        print(f"| {name:<44} | {tt * us:>6.1f} | {(tt - calls * c) * us:>12.1f} |")


if __name__ == "__main__":
    main()
