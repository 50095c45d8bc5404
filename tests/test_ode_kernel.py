"""The stepper's step kernel (a compiled attempt): its results, its failures and rejections.

A kernel written in numpy with the stepper's own arithmetic (its stages by ``rhs``) must give
the steps of the stepper without a kernel, bit for bit: the step-size control around it is the
same code. A kernel that fails (-1) falls back to the stages by ``rhs`` for that attempt.
"""

from __future__ import annotations

import math

import numpy as np

from packbot.ode import RK45Stepper

W = np.arange(1.0, 9.0)  # angular frequencies [rad/s]


def oscillators(t: float, y: np.ndarray) -> np.ndarray:
    """8 uncoupled oscillators q_i'' = -w_i^2 q_i (autonomous), y = [q, v]."""
    return np.concatenate((y[8:], -W * W * y[:8]))


Y0 = np.concatenate((np.linspace(0.5, 1.0, 8), np.zeros(8)))


class NumpyKernel:
    """A step kernel that runs the stepper's stages by rhs (the autonomous problem: t unused).

    ``fail``: the attempts (counted from 0) it refuses with -1.
    """

    def __init__(self, stepper: RK45Stepper, fail: frozenset[int] = frozenset()) -> None:
        self.stepper = stepper
        self.fail = fail
        self.calls = 0

    def __call__(self, h, Z, ay0, atol, rtol, y1, ay1) -> float:
        k = self.calls
        self.calls += 1
        assert atol.shape == (Z.shape[1],) and rtol == self.stepper.rtol
        assert ay0 is self.stepper._ay
        if k in self.fail:
            return -1.0
        y_new, a, err = self.stepper._stages(0.0, h, h, Z)
        y1[:] = y_new
        ay1[:] = a
        return err


def run(kernel_of, t_ends) -> tuple[list, RK45Stepper]:
    s = RK45Stepper(oscillators, rtol=1e-7, atol=1e-9, h_max=0.05)
    s.reset(0.0, Y0)
    kernel = kernel_of(s) if kernel_of is not None else None
    out = []
    for t_end in t_ends:
        while s.t < t_end:
            seg = s.step(t_end, kernel)
            out.append((seg.t0, seg.t1, seg.y1.copy(), seg(0.5 * (seg.t0 + seg.t1)), s.h))
    return out, s


def same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(
        x[0] == y[0]
        and x[1] == y[1]
        and np.array_equal(x[2], y[2])
        and np.array_equal(x[3], y[3])
        and x[4] == y[4]
        for x, y in zip(a, b, strict=True)
    )


T_ENDS = [0.3, 0.31, 1.0, 2.5]


def test_a_kernel_with_the_stepper_arithmetic_gives_the_same_steps_bit_for_bit() -> None:
    plain, s0 = run(None, T_ENDS)
    kern, s1 = run(NumpyKernel, T_ENDS)
    assert len(plain) > 20
    assert same(plain, kern)
    assert (s0.n_steps, s0.n_rejected, s0.n_rhs) == (s1.n_steps, s1.n_rejected, s1.n_rhs)
    assert np.array_equal(s0.f, s1.f) and s0.h == s1.h


def test_failed_kernel_attempts_take_the_python_stages() -> None:
    plain, s0 = run(None, T_ENDS)
    kernels: list[NumpyKernel] = []

    def make(s: RK45Stepper) -> NumpyKernel:
        kernels.append(NumpyKernel(s, fail=frozenset(range(0, 200, 3))))
        return kernels[0]

    kern, s1 = run(make, T_ENDS)
    assert kernels[0].calls >= len(plain) > 20
    assert same(plain, kern)
    assert s0.n_rhs == s1.n_rhs


def test_a_kernel_rejection_retries_smaller_as_without_a_kernel() -> None:
    # A first step far too long for the tolerance: rejected, then accepted.
    def first(rtol: float, kernel: bool) -> tuple[RK45Stepper, float, float]:
        s = RK45Stepper(oscillators, rtol=rtol, atol=rtol * 1e-2)
        s.reset(0.0, Y0, h=0.5)
        seg = s.step(10.0, NumpyKernel(s) if kernel else None)
        return s, seg.h, float(seg.y1[0])

    a, b = first(1e-10, False), first(1e-10, True)
    assert a[0].n_rejected >= 1 and a[0].n_rejected == b[0].n_rejected
    assert a[1] == b[1] < 0.5 and a[2] == b[2]
    assert math.isfinite(b[0].h) and b[0].h == a[0].h
