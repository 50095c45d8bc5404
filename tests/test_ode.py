"""Tests of packbot.ode: the Dormand-Prince 5(4) stepper, its dense output and locate_root."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import RK45

import packbot.ode as ode
from packbot.errors import ConfigurationError, PackbotError
from packbot.ode import (
    DenseSegment,
    RK45Stepper,
    StepSizeUnderflow,
    locate_earliest,
    locate_root,
)

# --- test problems ------------------------------------------------------------------------------

W = np.arange(1.0, 9.0)  # angular frequencies of 8 uncoupled oscillators [rad/s]


def decay(t: float, y: np.ndarray) -> np.ndarray:
    return -y


def oscillator(t: float, y: np.ndarray) -> np.ndarray:
    """Harmonic oscillator q'' = -q, y = [q, v]."""
    return np.array([y[1], -y[0]])


def oscillator_exact(t: float) -> np.ndarray:
    return np.array([math.cos(t), -math.sin(t)])


def oscillators16(t: float, y: np.ndarray) -> np.ndarray:
    """8 uncoupled oscillators q_i'' = -w_i^2 q_i, y = [q, v] of dimension 16."""
    return np.concatenate((y[8:], -W * W * y[:8]))


Y16 = np.concatenate((np.ones(8), np.zeros(8)))


def oscillators16_exact(t: float) -> np.ndarray:
    return np.concatenate((np.cos(W * t), -W * np.sin(W * t)))


def integrate(stepper: RK45Stepper, t_end: float) -> list[DenseSegment]:
    segments = []
    while stepper.t < t_end:
        segments.append(stepper.step(t_end))
    return segments


# --- convergence --------------------------------------------------------------------------------


def test_fixed_step_global_error_is_fifth_order() -> None:
    """With h_max forcing a constant step (loose tolerance), halving h divides the error by 32."""
    errors = []
    for h in (0.2, 0.1, 0.05, 0.025):
        s = RK45Stepper(oscillator, rtol=1.0, atol=1e6, h_max=h)
        s.reset(0.0, [1.0, 0.0], h=h)
        integrate(s, 4.0)
        assert s.n_steps == round(4.0 / h)
        errors.append(np.abs(s.y - oscillator_exact(4.0)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 4.6) & (orders < 5.5)), orders


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8, 1e-10])
def test_decay_error_is_of_the_order_of_the_tolerance(tol: float) -> None:
    s = RK45Stepper(decay, rtol=tol, atol=tol * 1e-3)
    s.reset(0.0, [1.0])
    integrate(s, 5.0)
    rel_err = abs(s.y[0] - math.exp(-5.0)) / math.exp(-5.0)
    assert 1e-2 * tol < rel_err < 10 * tol


def test_error_and_work_scale_with_the_tolerance() -> None:
    """Error ~ tol and steps ~ tol^(-1/5) (an order-4 error estimator) on the oscillator."""
    errs, steps = [], []
    for tol in (1e-5, 1e-7, 1e-9):
        s = RK45Stepper(oscillator, rtol=tol, atol=tol)
        s.reset(0.0, [1.0, 0.0])
        integrate(s, 20.0)
        errs.append(np.abs(s.y - oscillator_exact(20.0)).max())
        steps.append(s.n_steps)
        assert errs[-1] < 200 * tol  # global error over 3 periods
    err_ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((err_ratios > 100 / 3) & (err_ratios < 300)), err_ratios
    step_ratios = np.array(steps[1:]) / np.array(steps[:-1])
    assert np.all((step_ratios > 2.0) & (step_ratios < 3.2)), step_ratios  # 100^(1/5) = 2.51


# --- agreement with scipy -----------------------------------------------------------------------


@pytest.mark.parametrize("tol", [1e-3, 1e-6, 1e-9])
def test_agrees_with_scipy_rk45(tol: float) -> None:
    s = RK45Stepper(oscillators16, rtol=tol, atol=tol * 1e-3)
    s.reset(0.0, Y16)
    integrate(s, 10.0)
    r = RK45(oscillators16, 0.0, Y16, 10.0, rtol=tol, atol=tol * 1e-3)
    n_scipy = 0
    while r.status == "running":
        r.step()
        n_scipy += 1
    assert r.status == "finished"
    assert abs(s.n_steps - n_scipy) <= 3
    assert abs(s.n_rhs - r.nfev) <= 3 * 6
    assert s.t == r.t == 10.0
    scale = np.abs(oscillators16_exact(10.0)).max()
    assert np.abs(s.y - r.y).max() < tol * scale
    # Both are as accurate as each other.
    e_pb = np.abs(s.y - oscillators16_exact(10.0)).max()
    e_sp = np.abs(r.y - oscillators16_exact(10.0)).max()
    assert 0.5 < e_pb / e_sp < 2.0


def test_same_steps_as_scipy_with_its_growth_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    """scipy lets the first step grow by 10, not 5; with that, the step sequences coincide."""
    monkeypatch.setattr(ode, "MAX_FACTOR_FIRST", 10.0)
    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, Y16)
    r = RK45(oscillators16, 0.0, Y16, 10.0, rtol=1e-6, atol=1e-9)
    assert s.h == pytest.approx(r.h_abs, rel=1e-14)  # Hairer's initial step
    for _ in range(2):  # bit-for-bit up to rounding before the error estimates' noise builds up
        seg = s.step(10.0)
        r.step()
        assert seg.t1 == pytest.approx(r.t, rel=1e-14)
        np.testing.assert_allclose(s.y, r.y, rtol=0, atol=1e-14)
    integrate(s, 10.0)
    while r.status == "running":
        r.step()
    assert abs(s.n_rhs - r.nfev) <= 6


def test_dense_output_is_scipys_polynomial() -> None:
    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, Y16)
    r = RK45(oscillators16, 0.0, Y16, 10.0, rtol=1e-6, atol=1e-9, first_step=s.h)
    seg = s.step(10.0)
    r.step()
    assert seg.t1 == r.t
    dense = r.dense_output()
    for theta in np.linspace(0.0, 1.0, 11):
        t = seg.t0 + theta * seg.h
        np.testing.assert_allclose(seg(t), dense(t), rtol=0, atol=1e-14)


# --- dense output -------------------------------------------------------------------------------


@pytest.mark.parametrize("tol", [1e-5, 1e-8])
def test_dense_output_accuracy_at_interior_points(tol: float) -> None:
    s = RK45Stepper(oscillator, rtol=tol, atol=tol)
    s.reset(0.0, [1.0, 0.0])
    segments = integrate(s, 20.0)
    step_err = max(np.abs(seg.y1 - oscillator_exact(seg.t1)).max() for seg in segments)
    worst = 0.0
    for seg in segments:
        for theta in (0.1, 0.25, 0.5, 0.75, 0.9):
            t = seg.t0 + theta * seg.h
            worst = max(worst, np.abs(seg(t) - oscillator_exact(t)).max())
    # Interpolation adds little to the global error at the steps (~ 100 tol over 20 s).
    assert worst < 1.5 * step_err
    assert worst < 200 * tol


def test_dense_output_local_error_is_fifth_power_of_h() -> None:
    """From an exact start, the interpolant's error at mid-step is O(h^5) (order 4)."""
    errs = []
    hs = (0.2, 0.1, 0.05)
    for h in hs:
        s = RK45Stepper(oscillator, rtol=1.0, atol=1e6, h_max=h)
        s.reset(0.0, [1.0, 0.0], h=h)
        seg = s.step(1.0)
        tm = 0.5 * h
        errs.append(np.abs(seg(tm) - oscillator_exact(tm)).max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 4.5) & (orders < 5.6)), orders


def test_dense_output_ends_derivative_and_sample() -> None:
    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, Y16)
    for _ in range(6):  # past the small first steps
        seg = s.step(10.0)
    assert seg.h > 0.01
    assert np.array_equal(seg(seg.t0), seg.y0)
    assert np.array_equal(seg(seg.t1), seg.y1)
    assert seg(seg.t1) is not seg.y1  # a copy
    # The interpolant matches f at both ends (C1 joins between segments).
    np.testing.assert_allclose(seg.derivative(seg.t0), oscillators16(seg.t0, seg.y0), atol=1e-12)
    np.testing.assert_allclose(seg.derivative(seg.t1), oscillators16(seg.t1, seg.y1), atol=1e-12)
    assert np.array_equal(s.f, oscillators16(s.t, s.y))  # FSAL stage
    # Derivative of the interpolant against a central difference of it.
    tm, d = seg.t0 + 0.3 * seg.h, 1e-4 * seg.h
    fd = (seg(tm + d) - seg(tm - d)) / (2 * d)
    np.testing.assert_allclose(seg.derivative(tm), fd, rtol=0, atol=1e-7)
    ts = seg.t0 + seg.h * np.array([0.0, 0.2, 0.7, 1.0])
    np.testing.assert_allclose(seg.sample(ts), np.array([seg(t) for t in ts]), atol=1e-14)


# --- landing on t_end ---------------------------------------------------------------------------


def test_steps_land_exactly_on_each_output_time() -> None:
    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, Y16)
    t_out = np.linspace(0.0, 3.0, 31)[1:]  # 0.1, 0.2, ... (inexact binary fractions)
    t_prev = 0.0
    for t_end in t_out:
        while s.t < t_end:
            seg = s.step(t_end)
            assert seg.t0 == t_prev
            assert seg.t1 <= t_end
            assert seg.t1 - seg.t0 == seg.h > 0
            t_prev = seg.t1
        assert s.t == t_end  # exactly, not within rounding
    np.testing.assert_allclose(s.y, oscillators16_exact(3.0), atol=1e-4)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(1e-9, 2.0), min_size=1, max_size=8))
def test_never_overshoots_random_end_times(increments: list[float]) -> None:
    s = RK45Stepper(oscillator, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [1.0, 0.0])
    t_end = 0.0
    for dt in increments:
        t_end += dt
        while s.t < t_end:
            seg = s.step(t_end)
            assert seg.t1 <= t_end
        assert s.t == t_end
    np.testing.assert_allclose(s.y, oscillator_exact(t_end), atol=1e-5)


def test_short_landing_keeps_the_step_size() -> None:
    """A step cut short to land on t_end does not shrink the next step."""
    s = RK45Stepper(oscillator, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [1.0, 0.0])
    for _ in range(3):
        s.step(10.0)
    h = s.h
    seg = s.step(s.t + 1e-3 * h)
    assert seg.h == pytest.approx(1e-3 * h)
    assert s.h >= h


def test_stretches_onto_t_end_instead_of_a_sliver_step() -> None:
    s = RK45Stepper(oscillator, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [1.0, 0.0])
    s.step(10.0)
    h = s.h
    t_end = s.t + 1.005 * h  # a normal step would leave a sliver of 0.005 h
    seg = s.step(t_end)
    assert seg.t1 == t_end


def test_h_max_bounds_every_step() -> None:
    s = RK45Stepper(oscillator, rtol=1e-3, atol=1e-6, h_max=0.05)
    s.reset(0.0, [1.0, 0.0])
    assert s.h <= 0.05
    segments = integrate(s, 2.0)
    assert max(seg.h for seg in segments[:-1]) <= 0.05 * (1 + 1e-12)
    assert segments[-1].h <= 0.05 * 1.01  # the last one may be stretched onto t_end
    assert len(segments) >= 40


# --- rejection and underflow --------------------------------------------------------------------


def test_rejected_steps_are_retried_smaller_without_growth() -> None:
    s = RK45Stepper(decay, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [1.0], h=5.0)  # far too large
    seg = s.step(100.0)
    assert s.n_rejected >= 1
    assert s.n_steps == 1
    assert s.n_rhs == 1 + 6 * (1 + s.n_rejected)
    assert seg.h < 5.0
    assert s.h <= seg.h  # no growth right after a rejection
    assert abs(seg.y1[0] - math.exp(-seg.h)) < 1e-6
    h_after = s.h
    s.step(100.0)  # an accepted step after an accepted step may grow again
    assert s.h > h_after


def test_singular_rhs_raises_step_size_underflow() -> None:
    """y' = 1/(1 - t) has a pole at t = 1: the step size collapses there."""
    s = RK45Stepper(lambda t, y: np.array([1.0 / (1.0 - t)]), rtol=1e-6, atol=1e-9, h_min=1e-9)
    s.reset(0.0, [0.0])
    with pytest.raises(StepSizeUnderflow) as info:
        integrate(s, 2.0)
    err = info.value
    assert isinstance(err, PackbotError)
    assert 0.99 < err.t < 1.0
    assert err.h < err.h_min == 1e-9
    assert "t=0.99" in str(err) and "h_min" in str(err)
    assert s.t == err.t  # the state stays at the last accepted step
    assert s.n_rejected > 0
    assert s.y[0] == pytest.approx(-math.log(1.0 - s.t), rel=1e-4)


def test_nan_rhs_is_rejected_not_accepted() -> None:
    """A right-hand side that returns nan beyond t = 1 never lets a step cross t = 1."""

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([1.0 if t <= 1.0 else math.nan])

    s = RK45Stepper(rhs, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [0.0])
    integrate(s, 1.0)  # up to t = 1 exactly: fine
    assert s.y[0] == pytest.approx(1.0, abs=1e-12)
    s.reset(0.0, [0.0])
    with pytest.raises(StepSizeUnderflow) as info:
        integrate(s, 2.0)
    assert 1.0 - 1e-9 < info.value.t <= 1.0
    assert np.all(np.isfinite(s.y))


# --- reset / restrict ---------------------------------------------------------------------------


def test_reset_restarts_cleanly_and_counters_accumulate() -> None:
    fresh = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    fresh.reset(1.0, 0.5 * Y16)
    integrate(fresh, 3.0)

    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, Y16)
    integrate(s, 2.0)
    steps, rhs, rejected = s.n_steps, s.n_rhs, s.n_rejected
    s.reset(1.0, 0.5 * Y16)  # back in time, new state
    assert s.n_rhs == rhs + 2  # f and Hairer's probe
    assert s.t == 1.0
    integrate(s, 3.0)
    # Exactly the same steps as a fresh stepper: nothing of the old run leaks.
    assert np.array_equal(s.y, fresh.y)
    assert s.n_steps == steps + fresh.n_steps
    assert s.n_rhs == rhs + fresh.n_rhs
    assert s.n_rejected == rejected + fresh.n_rejected
    s.reset(3.0, 0.5 * Y16, h=0.01)  # a given step: 1 rhs call
    assert s.n_rhs == rhs + fresh.n_rhs + 1
    assert s.h == 0.01


def test_reset_may_change_the_dimension() -> None:
    s = RK45Stepper(decay, rtol=1e-8, atol=1e-12)
    s.reset(0.0, [1.0])
    integrate(s, 1.0)
    s.reset(1.0, [1.0, 2.0, 3.0])
    integrate(s, 2.0)
    np.testing.assert_allclose(s.y, np.array([1.0, 2.0, 3.0]) * math.exp(-1.0), rtol=1e-7)


def test_reset_copies_its_input() -> None:
    y = Y16.copy()
    s = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    s.reset(0.0, y)
    y[:] = 0.0
    assert np.array_equal(s.y, Y16)


def test_restrict_is_reset_with_the_current_h() -> None:
    a = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    b = RK45Stepper(oscillators16, rtol=1e-6, atol=1e-9)
    for s in (a, b):
        s.reset(0.0, Y16)
        s.step(1.0)
    seg = a.step(1.0)
    b.step(1.0)
    t_ev = seg.t0 + 0.4 * seg.h
    h = a.h
    a.restrict(t_ev, seg(t_ev))
    b.reset(t_ev, seg(t_ev), h=b.h)
    assert a.t == t_ev and a.h == h
    integrate(a, 2.0)
    integrate(b, 2.0)
    assert np.array_equal(a.y, b.y)
    assert a.n_steps == b.n_steps and a.n_rhs == b.n_rhs


def test_falling_ball_event_located_through_dense_output() -> None:
    """Ball dropped from 1 m: x(t) is quadratic, so dense output and locate_root are exact."""
    g_acc = 9.81

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -g_acc])

    s = RK45Stepper(rhs, rtol=1e-6, atol=1e-9)
    s.reset(0.0, [1.0, 0.0])
    t_hit = math.sqrt(2.0 / g_acc)
    while True:
        seg = s.step(2.0)
        if seg.y1[0] <= 0.0:
            break
    t_ev = locate_root(lambda t: float(seg(t)[0]), seg.t0, seg.t1, seg.y0[0], seg.y1[0])
    assert t_hit <= t_ev < t_hit + 2e-10
    y_ev = seg(t_ev)
    assert y_ev[0] <= 0.0
    s.restrict(t_ev, [0.0, -0.8 * y_ev[1]])  # bounce
    steps = s.n_steps
    seg = s.step(2.0)
    assert s.n_steps == steps + 1
    assert seg.t0 == t_ev and seg.y0[1] > 0.0


# --- locate_root --------------------------------------------------------------------------------


@pytest.mark.parametrize("xtol", [1e-10, 1e-12])
def test_locate_root_sine_crossing(xtol: float) -> None:
    t = locate_root(math.sin, 3.0, 3.5, math.sin(3.0), math.sin(3.5), xtol=xtol)
    assert abs(t - math.pi) < max(1e-9 * xtol / 1e-10, 1e-15)
    assert math.sin(t) <= 0.0  # the event side
    assert t >= math.pi - 1e-15


def test_locate_root_returns_the_event_side_of_a_tight_bracket() -> None:
    evaluated: list[tuple[float, float]] = []

    def g(t: float) -> float:
        v = math.cos(t)
        evaluated.append((t, v))
        return v

    t = locate_root(g, 0.0, 3.0, 1.0, math.cos(3.0), xtol=1e-10)
    assert g(t) <= 0.0
    # Some evaluated point within xtol before t is on the positive side.
    assert any(0.0 < t - ti <= 1e-10 * (1 + 1e-6) and gi > 0.0 for ti, gi in evaluated)


def test_locate_root_zero_counts_as_event_side() -> None:
    assert locate_root(lambda t: 1.0 - t, 0.0, 1.0, 1.0, 0.0) == 1.0
    # g reaches 0 at 0.5 and stays there: the first point of the event side is found.
    t = locate_root(lambda t: max(0.5 - t, 0.0), 0.0, 1.0, 0.5, 0.0)
    assert 0.5 <= t < 0.5 + 1e-10


@pytest.mark.parametrize("t_end", [8.0, 9.0, 10.0, 10.8])
def test_locate_root_several_crossings_gives_a_falling_one(t_end: float) -> None:
    t = locate_root(math.cos, 0.0, t_end, 1.0, math.cos(t_end))
    assert min(abs(t - 0.5 * math.pi), abs(t - 2.5 * math.pi)) < 1e-10
    assert math.cos(t) <= 0.0 < math.cos(t - 1e-10 * (1 + 1e-6))


def test_locate_root_rejects_a_non_bracket() -> None:
    with pytest.raises(ConfigurationError, match="g0 > 0 >= g1"):
        locate_root(math.sin, 0.5, 1.0, math.sin(0.5), math.sin(1.0))
    with pytest.raises(ConfigurationError, match="t1"):
        locate_root(math.sin, 1.0, 1.0, 1.0, -1.0)


def _locate_each(gs, g0s, g1s, t0, t1, xtol, at_tol):
    """The reference: every crossing located on the whole step, then the earliest kept."""
    times = [t0 if g0 <= 0.0 else locate_root(g, t0, t1, g0, g1, xtol=xtol)
             for g, g0, g1 in zip(gs, g0s, g1s, strict=True)]  # fmt: skip
    t_star = min(times)
    return t_star, [i for i, tc in enumerate(times) if tc <= t_star + at_tol]


@settings(max_examples=200, deadline=None)
@given(
    roots=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=6),
    slopes=st.lists(st.floats(0.1, 10.0), min_size=6, max_size=6),
    curv=st.floats(-0.4, 0.4),
    near=st.booleans(),
)
def test_locate_earliest_equals_locating_every_crossing(roots, slopes, curv, near) -> None:
    """Falling functions with one crossing each on [0, 1] (some already <= 0 at 0, some within
    the tolerance of another, some at the step's end): the same time and crossings, to the bit,
    with at most one more evaluation per crossing (the test of one that is at the event)."""
    at_tol = 1e-9
    if near and len(roots) > 1:
        roots[1] = min(roots[0] + 0.5 * at_tol, 1.0)  # a crossing within at_tol of another
    gs, g0s, g1s = [], [], []
    for r, k in zip(roots, slopes, strict=False):

        def g(t: float, r: float = r, k: float = k) -> float:
            return k * (r - t) * (1.0 + curv * (t - r) ** 2)

        gs.append(g)
        g0s.append(g(0.0) if r > 0.0 else -1.0)
        g1s.append(min(g(1.0), 0.0))
    count = [0, 0]

    def counted(fs, slot):
        def wrap(f):
            def h(t: float) -> float:
                count[slot] += 1
                return f(t)

            return h

        return [wrap(f) for f in fs]

    ref = _locate_each(counted(gs, 0), g0s, g1s, 0.0, 1.0, 1e-10, at_tol)
    got = locate_earliest(counted(gs, 1), g0s, g1s, 0.0, 1.0, xtol=1e-10, at_tol=at_tol)
    assert got == ref
    assert count[1] <= count[0] + len(gs)


def test_locate_earliest_tests_the_later_crossings_with_one_evaluation() -> None:
    """Three crossings far apart: the earliest is located, the two others cost one evaluation
    each (their value just after it is still positive)."""
    calls = {0: 0, 1: 0, 2: 0}

    def make(i: int, r: float):
        def g(t: float) -> float:
            calls[i] += 1
            return r - t

        return g

    gs = [make(0, 0.7), make(1, 0.2), make(2, 0.5)]
    t_star, at = locate_earliest(gs, [0.7, 0.2, 0.5], [-0.3, -0.8, -0.5], 0.0, 1.0)
    assert at == [1] and 0.2 <= t_star < 0.2 + 1e-10
    assert calls[0] == 1 and calls[2] == 1 and calls[1] > 1
    # one already on its event side at the step start: t_star is the start, the others tested
    t_star, at = locate_earliest(gs, [0.7, -0.1, 0.5], [-0.3, -0.8, -0.5], 0.0, 1.0)
    assert (t_star, at) == (0.0, [1])


def test_locate_earliest_rejects_bad_arguments() -> None:
    with pytest.raises(ConfigurationError, match="gs"):
        locate_earliest([], [], [], 0.0, 1.0)
    with pytest.raises(ConfigurationError, match="len"):
        locate_earliest([math.cos], [1.0, 2.0], [-1.0], 0.0, 2.0)
    with pytest.raises(ConfigurationError, match="at_tol"):
        locate_earliest([math.cos], [1.0], [math.cos(2.0)], 0.0, 2.0, at_tol=-1.0)
    with pytest.raises(ConfigurationError, match="g0 > 0 >= g1"):
        locate_earliest([math.cos], [1.0], [0.5], 0.0, 1.0)


# --- configuration errors -----------------------------------------------------------------------


def test_bad_settings_raise_configuration_errors() -> None:
    with pytest.raises(ConfigurationError, match="rtol"):
        RK45Stepper(decay, rtol=0.0, atol=1e-9)
    with pytest.raises(ConfigurationError, match="atol"):
        RK45Stepper(decay, rtol=1e-6, atol=-1.0)
    with pytest.raises(ConfigurationError, match="h_min"):
        RK45Stepper(decay, rtol=1e-6, atol=1e-9, h_max=1e-3, h_min=1e-2)
    s = RK45Stepper(decay, rtol=1e-6, atol=np.full(3, 1e-9))
    with pytest.raises(ConfigurationError, match="reset"):
        s.step(1.0)
    with pytest.raises(ConfigurationError, match=r"shape \(2,\)"):
        s.reset(0.0, [1.0, 2.0])
    with pytest.raises(ConfigurationError, match="y="):
        s.reset(0.0, [1.0, math.nan, 0.0])
    s.reset(0.0, [1.0, 2.0, 3.0])
    with pytest.raises(ConfigurationError, match="t_end"):
        s.step(0.0)
    bad = RK45Stepper(lambda t, y: np.zeros(2), rtol=1e-6, atol=1e-9)
    with pytest.raises(ConfigurationError, match="rhs"):
        bad.reset(0.0, [1.0])


def test_vector_atol_is_used_per_component() -> None:
    y0 = [1.0, 1.0]
    runs = {}
    for name, atol in (
        ("scalar", 1e-12),
        ("vector", np.array([1e-12, 1e-12])),
        ("one loose", np.array([1e-12, 1e-2])),
        ("all loose", 1e-2),
    ):
        s = RK45Stepper(decay, rtol=1e-3, atol=atol)
        s.reset(0.0, y0)
        integrate(s, 30.0)
        runs[name] = s
    assert np.array_equal(runs["scalar"].y, runs["vector"].y)
    assert runs["scalar"].n_steps == runs["vector"].n_steps
    # y decays to 1e-13: the loose component stops mattering, and the work drops.
    assert runs["all loose"].n_steps < runs["one loose"].n_steps < runs["vector"].n_steps
