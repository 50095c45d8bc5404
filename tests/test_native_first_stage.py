"""A restart's derivative left to the next native step (``ContactRhs.first``), bit for bit.

After an event or a re-patch the loop restarts the stepper; in the contact-normal mode the
derivative there is no longer computed at the restart through the integrator's right-hand side
(``_Run.rhs`` -> ``NormalLaw.torque_accel`` -> ``NativeRhs.accel``) but by the next native step's
first stage, on the same modes and torques. Checked at every restart of real collapses against
the right-hand side at the same state, whole runs against the eager restart, and the stepper's
deferred reset on its own.
"""

from __future__ import annotations

import numpy as np
import pytest

import packbot
from packbot import integrator, ode
from packbot.contact import native


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def _collapse(robot, mu: float, duration: float):
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)


@pytest.fixture(scope="module")
def robot():
    return packbot.load_robot()


@pytest.mark.parametrize("mu", [0.5, 0.0])
def test_every_first_stage_is_the_right_hand_side_at_the_restart(robot, monkeypatch, mu) -> None:
    seen = {"first": 0, "rhs": 0}
    step = ode.RK45Stepper.step

    def checked(self, t_end, kernel=None, first=None, stiff=None):
        if not self.f_pending:
            return step(self, t_end, kernel, first, stiff)
        # the right-hand side the eager restart computed, at the same state, before the step
        f_eager = np.array(self._rhs(self.t, self.y), dtype=np.float64)
        seg = step(self, t_end, kernel, first, stiff)
        assert np.array_equal(seg._Z[1], f_eager)
        seen["first" if first is not None else "rhs"] += 1
        return seg

    monkeypatch.setattr(ode.RK45Stepper, "step", checked)
    res = _collapse(robot, mu, 2.0)
    assert res.diagnostics.restarts > 20
    assert seen["first"] > 20  # most restarts: the native first stage


def test_a_collapse_with_deferred_restarts_is_the_eager_one_bit_for_bit(robot, monkeypatch) -> None:
    a = _collapse(robot, 0.5, 2.5)

    def eager(self) -> None:
        self.stepper.reset(self.t, self.y, h=max(self.stepper.h, 1e-6))

    monkeypatch.setattr(integrator._Run, "restart", eager)
    b = _collapse(robot, 0.5, 2.5)
    for k in ("t", "q", "v", "tau", "energy"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert [(e.t, e.kind) for e in a.events] == [(e.t, e.kind) for e in b.events]
    da, db = a.diagnostics, b.diagnostics
    assert (da.steps, da.rhs_calls, da.restarts) == (db.steps, db.rhs_calls, db.restarts)
    assert da.restarts > 20


def test_a_deferred_reset_calls_rhs_at_the_next_step_without_a_first_stage() -> None:
    calls: list[float] = []

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        calls.append(t)
        return -y

    y0 = np.array([1.0, 2.0])
    a = ode.RK45Stepper(rhs, rtol=1e-8, atol=1e-10)
    a.reset(0.0, y0, h=0.01)
    b = ode.RK45Stepper(rhs, rtol=1e-8, atol=1e-10)
    b.reset(0.0, y0, h=0.01, defer=True)
    assert b.f_pending and not a.f_pending and b.f.shape == (0,)
    assert a.n_rhs == b.n_rhs == 1
    calls.clear()
    sb = b.step(1.0)
    assert calls[0] == 0.0  # (b's derivative at the restart, computed by its step)
    sa = a.step(1.0)
    assert not b.f_pending
    assert sa.t1 == sb.t1 and np.array_equal(sa.y1, sb.y1) and a.n_rhs == b.n_rhs
    # a first stage that fails: the right-hand side instead; without h: not deferred
    b.reset(sb.t1, sb.y1, h=0.01, defer=True)
    a.reset(sa.t1, sa.y1, h=0.01)
    sb = b.step(2.0, lambda *args: -1.0, lambda Z: False)
    sa = a.step(2.0)
    assert np.array_equal(sa.y1, sb.y1) and a.n_rhs == b.n_rhs
    b.reset(0.0, y0, defer=True)
    assert not b.f_pending and b.f.shape == (2,)


def test_the_first_stage_refuses_a_wrong_shape_and_a_lock_mode(robot) -> None:
    from packbot.system import System

    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sys_ = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.native_rhs(sys_.model)
    assert rhs is not None
    n = 2 * rhs.nv
    zeros = np.zeros(rhs.nv)
    with pytest.raises(ValueError):  # no torques set
        rhs.first(np.zeros((8, n)))
    rhs.set_torque(zeros, zeros, zeros)
    with pytest.raises(ValueError):
        rhs.first(np.zeros((7, n)))
    rhs.locks.set(np.zeros(0, dtype=np.intp))
    with pytest.raises(ValueError):
        rhs.first(np.zeros((8, n)))
