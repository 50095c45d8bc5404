"""The native RODAS4 attempt and the stepper's switch to it in stiff stretches.

``ContactRhs.rosenbrock`` (:attr:`packbot.contact.native.NativeRhs.stiff`) on a problem with a
known solution: one prismatic joint with no contact under a constant force and a viscous
damper, ``x' = v``, ``v' = (F - c v) / m`` (linear, its eigenvalue ``-c / m`` made as stiff as
wanted). Then :class:`packbot.ode.RK45Stepper` switching to it and back, the cubic Hermite
dense output of its steps, and the contact-normal collapse that switches to it.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot import ode
from packbot.contact import native
from packbot.contact.normal import PENETRATION_TOL
from packbot.errors import ConfigurationError


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
MASS = 2.0  # [kg]
FORCE = 3.0  # [N]


def _slider(damping: float) -> native.NativeRhs:
    """A prismatic joint along z (no gravity, no contact) with a viscous damper [N*s/m]."""
    model = pin.Model()
    jid = model.addJoint(0, pin.JointModelPZ(), pin.SE3.Identity(), "slide")
    model.appendBodyToJoint(jid, pin.Inertia.FromSphere(MASS, 0.1), pin.SE3.Identity())
    model.gravity.linear = np.zeros(3)
    rhs = native.NativeRhs(model)
    raw = rhs._rhs
    e_i, e_f2, e_f3 = np.zeros(0, np.int64), np.zeros((0, 1)), np.zeros((0, 3, 3))
    raw.set_layout(
        e_i, e_f2, e_i, np.zeros((0, 4)), e_i, e_i, e_i, e_i, e_f3, e_i, np.zeros(0), np.zeros(0)
    )
    raw.set_plan(e_i, e_i, e_i, 0.0, 1e-3, 0.0)
    rhs.set_torque(np.array([FORCE]), np.array([damping]), np.zeros(1))
    return rhs


def _exact(y0: np.ndarray, damping: float, t: float) -> np.ndarray:
    """(x, v) at t of x' = v, v' = (F - c v) / m from y0."""
    k = damping / MASS
    v_inf = FORCE / damping
    dv = y0[1] - v_inf
    decay = math.exp(-k * t)
    return np.array([y0[0] + v_inf * t + dv * (1.0 - decay) / k, v_inf + dv * decay])


def _attempt(
    rhs: native.NativeRhs, y0: np.ndarray, h: float
) -> tuple[np.ndarray, float, np.ndarray]:
    """One Rosenbrock attempt from y0: (y1, error norm, Z)."""
    Z = np.zeros((8, 2))
    Z[0] = y0
    assert rhs.first(Z)
    y1, ay1 = np.empty(2), np.empty(2)
    err = rhs.stiff.attempt(h, Z, np.abs(y0), np.full(2, 1e-9), 1e-6, y1, ay1)
    return y1, err, Z


def test_rosenbrock_local_error_is_fifth_order_and_its_estimate_fourth():
    damping = 100.0  # k = 50 1/s: h k from 0.4 down to 0.05 (not stiff: the order shows)
    rhs = _slider(damping)
    y0 = np.array([0.1, 2.0])
    errors, estimates = [], []
    for h in (8e-3, 4e-3, 2e-3, 1e-3):
        y1, est, _ = _attempt(rhs, y0, h)
        errors.append(float(np.abs(y1 - _exact(y0, damping, h)).max()))
        estimates.append(est)
    orders = [math.log2(a / b) for a, b in itertools.pairwise(errors)]
    est_orders = [math.log2(a / b) for a, b in itertools.pairwise(estimates)]
    # local error O(h^5) (order 4), the embedded order-3 estimate O(h^4)
    assert all(4.5 < p < 5.6 for p in orders), (errors, orders)
    assert all(3.5 < p < 4.6 for p in est_orders), (estimates, est_orders)
    assert errors[-1] < 1e-9


def test_rosenbrock_is_stable_and_accurate_far_beyond_the_explicit_bound():
    damping = 2e4  # k = 1e4 1/s, as the collapse's sliding friction direction
    rhs = _slider(damping)
    v_inf = FORCE / damping
    for z in (10.0, 100.0, 1000.0, 1e4):  # h k; Dormand-Prince's bound is about 3.3
        h = z * MASS / damping
        # an unresolved transient decays (L-stable: R(z) -> 0 as z -> -inf, about 9 / z) ...
        y1, err, _ = _attempt(rhs, np.array([0.0, v_inf + 1e-4]), h)
        ratio = (y1[1] - v_inf) / 1e-4
        assert abs(ratio) < (0.2 if z < 100.0 else 10.0 / z), (z, ratio)
        assert err > 1.0  # ... and the error estimate says it was not resolved
        # on the slow solution the step is exact to rounding, whatever h k
        y0 = np.array([0.0, v_inf])
        y1, err, Z = _attempt(rhs, y0, h)
        np.testing.assert_allclose(y1, _exact(y0, damping, h), rtol=1e-10, atol=1e-15)
        assert err < 1.0
        np.testing.assert_array_equal(Z[2], y1)  # the step's end, for the dense output
        # the accepted attempt's last stage: f(y1), the next step's first stage
        np.testing.assert_allclose(Z[7], [y1[1], (FORCE - damping * y1[1]) / MASS], atol=1e-9)
    # the Jacobian's spectral radius is the decay rate
    assert rhs.stiff.radius() == pytest.approx(damping / MASS, rel=1e-5)


def _integrate(damping: float, stiff: bool, t_end: float) -> ode.RK45Stepper:
    rhs = _slider(damping)
    stepper = ode.RK45Stepper(
        lambda t, y: np.array([y[1], (FORCE - damping * y[1]) / MASS]), rtol=1e-6, atol=1e-9
    )
    stepper.reset(0.0, np.array([0.0, 1e-3]), h=1e-5)
    while stepper.t < t_end:
        stepper.step(t_end, rhs.step, None, rhs.stiff if stiff else None)
    return stepper


def test_the_stepper_switches_to_rosenbrock_on_a_stiff_problem():
    damping, t_end = 2e4, 0.5
    explicit = _integrate(damping, False, t_end)
    switched = _integrate(damping, True, t_end)
    assert explicit.n_stiff_steps == 0
    assert switched.stiff and switched.n_stiff_steps > 0
    assert switched.n_steps < explicit.n_steps / 5  # held at h k ~ 3.3 without the switch
    exact = _exact(np.array([0.0, 1e-3]), damping, t_end)
    np.testing.assert_allclose(switched.y, exact, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(explicit.y, exact, rtol=1e-6, atol=1e-8)
    # a reset goes back to the explicit steps
    switched.reset(switched.t, switched.y, h=1e-5)
    assert not switched.stiff


def test_no_switch_on_a_non_stiff_problem():
    stepper = _integrate(1.0, True, 0.5)  # k = 0.5 1/s
    assert stepper.n_stiff_steps == 0 and not stepper.stiff


def test_hermite_segment_joins_values_and_slopes_at_its_ends():
    damping = 100.0
    rhs = _slider(damping)
    y0 = np.array([0.1, 2.0])
    h = 1e-3
    y1, err, Z = _attempt(rhs, y0, h)
    assert err < 1.0
    seg = ode.HermiteSegment(1.0, 1.0 + h, h, y0, y1, Z)
    np.testing.assert_array_equal(seg(1.0), y0)
    np.testing.assert_array_equal(seg(1.0 + h), y1)
    np.testing.assert_allclose(seg(1.0 + 1e-12 * h), y0, atol=1e-12)
    np.testing.assert_allclose(seg.derivative(1.0), Z[1], rtol=1e-12)
    np.testing.assert_allclose(seg.derivative(1.0 + h), Z[7], rtol=1e-9, atol=1e-12)
    ts = np.linspace(1.0, 1.0 + h, 7)
    np.testing.assert_allclose(seg.sample(ts), np.array([seg(t) for t in ts]), rtol=1e-13)
    # a truncated segment keeps the cubic of the whole step
    cut = seg.truncated(1.0 + 0.4 * h)
    assert isinstance(cut, ode.HermiteSegment)
    np.testing.assert_allclose(cut(1.0 + 0.2 * h), seg(1.0 + 0.2 * h), rtol=1e-14)
    np.testing.assert_array_equal(cut.y1, seg(1.0 + 0.4 * h))
    # the position stays between its ends' values (v > 0 all along), close to the exact one
    assert np.all(np.diff(seg.sample(ts)[:, 0]) > 0.0)
    exact = np.array([_exact(y0, damping, t - 1.0) for t in ts])
    np.testing.assert_allclose(seg.sample(ts), exact, rtol=0.0, atol=1e-7)


def test_bad_stiff_arguments_are_refused():
    rhs = _slider(1.0)
    stepper = ode.RK45Stepper(lambda t, y: np.array([y[1], 0.0]), rtol=1e-6, atol=1e-9)
    stepper.reset(0.0, np.array([0.0, 1.0]), h=1e-3)
    with pytest.raises(ConfigurationError, match="stiff"):
        stepper.step(1.0, None, None, rhs.stiff)  # no kernel
    with pytest.raises(ConfigurationError, match="stiff"):
        stepper.step(1.0, rhs.step, None, rhs.stiff.attempt)  # type: ignore[arg-type]


_STEP = ode.RK45Stepper.step


def test_the_collapse_switches_and_keeps_its_physics(robot, monkeypatch):
    """The drive-pose collapse (mu 0.5) takes Rosenbrock steps in its stiff slides, and keeps
    the physics gates: no penetration beyond PENETRATION_TOL, no event gains energy (beyond
    the energies' rounding), the arm loses energy."""
    kinds: list[str] = []

    def spy(self, t_end, kernel=None, first=None, stiff_kernel=None):
        seg = _STEP(self, t_end, kernel, first, stiff_kernel)
        kinds.append(type(seg).__name__)
        return seg

    monkeypatch.setattr(ode.RK45Stepper, "step", spy)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)
    assert kinds.count("HermiteSegment") >= 10
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    for ev in res.events:
        if math.isfinite(ev.energy_before) and math.isfinite(ev.energy_after):
            assert ev.energy_after <= ev.energy_before + 1e-9 * max(1.0, abs(ev.energy_before))
    assert res.energy[-1] < res.energy[0]
