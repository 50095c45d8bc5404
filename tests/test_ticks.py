"""Controller ticks inside long steps: a held command costs no step, the ticks stay exact.

The reference for "exact" is the loop that ends a step at every tick and restarts the stepper
there (``Ticks.same`` patched to say every command changed): the controller then sees the
integrated state at each tick, not a dense-output one.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control import Controller
from packbot.ticks import HOLD_FRACTION, Ticks

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


class Hold(Controller):
    """Gravity compensation recomputed every ``every`` ticks and held in between.

    Records (t, q, v) of every call and the ticks whose command it changed.
    """

    def __init__(self, every: int, ramp: float = 0.0, **kw):
        super().__init__(**kw)
        self.every = every
        self.ramp = ramp  # [N*m/s] added to every joint's command

    def on_reset(self, robot, t0, q0, v0):
        self.data = robot.model.createData()
        self.calls = []
        self.changes = []
        self.tau = np.zeros(robot.nq)

    def compute(self, t, q, v):
        k = len(self.calls)
        self.calls.append((t, q.copy(), v.copy()))
        if self.every and k % self.every == 0:
            g = pin.computeGeneralizedGravity(self.robot.model, self.data, q)
            self.tau = g + self.ramp * t
            self.changes.append(k)
        return self.tau


def cut_every_tick(monkeypatch):
    """The reference loop: every tick ends a step and restarts the stepper."""
    monkeypatch.setattr(Ticks, "same", lambda self, tau: False)


def run(robot, ctrl, duration, pose="high", **cfg):
    config = packbot.SimConfig(locked_joints=WRIST, **cfg)
    q0 = robot.pose(pose)
    return packbot.simulate(robot, q0, np.zeros(8), duration, controller=ctrl, config=config)


def calls(ctrl):
    t = np.array([c[0] for c in ctrl.calls])
    return t, np.array([c[1] for c in ctrl.calls]), np.array([c[2] for c in ctrl.calls])


def test_a_held_command_takes_long_steps_and_no_restart(robot, monkeypatch):
    ctrl = Hold(every=0, dt=1e-3)  # the zero command, held from t = 0
    res = run(robot, ctrl, 0.5, contact_mode="none")
    assert res.control_ticks == 500 and len(ctrl.calls) == 500
    # max_step is 0.05 s: about ten steps for 500 ticks, one restart (the start) in all.
    assert res.diagnostics.steps <= 20
    assert res.diagnostics.rhs_calls <= 7 * 20
    cut_every_tick(monkeypatch)
    ref_ctrl = Hold(every=0, dt=1e-3)
    ref = run(robot, ref_ctrl, 0.5, contact_mode="none")
    assert ref.diagnostics.steps >= 500
    assert ref.diagnostics.rhs_calls >= 7 * 500  # 6 a step, 1 a restart
    np.testing.assert_allclose(res.q, ref.q, atol=1e-6)
    np.testing.assert_allclose(res.v, ref.v, atol=1e-5)


def test_controller_called_once_per_tick_in_order_on_the_state_at_the_tick(robot, monkeypatch):
    ctrl = Hold(every=25, dt=1e-3)
    res = run(robot, ctrl, 0.3)
    t, q, v = calls(ctrl)
    # Once per tick, in order, at the tick's time.
    np.testing.assert_allclose(t, 1e-3 * np.arange(300), atol=1e-12)
    assert res.control_ticks == 300 and ctrl.changes == list(range(0, 300, 25))
    # The states at the ticks are those of the loop that ends a step at every tick, to the
    # integrator's tolerance; in particular where the command changes.
    cut_every_tick(monkeypatch)
    ref_ctrl = Hold(every=25, dt=1e-3)
    ref = run(robot, ref_ctrl, 0.3)
    t_ref, q_ref, v_ref = calls(ref_ctrl)
    np.testing.assert_allclose(t, t_ref, atol=1e-12)
    np.testing.assert_allclose(q, q_ref, atol=1e-7)
    np.testing.assert_allclose(v, v_ref, atol=1e-6)
    assert res.diagnostics.steps < ref.diagnostics.steps / 3
    np.testing.assert_allclose(res.tau_cmd, ref.tau_cmd, atol=1e-5)
    np.testing.assert_allclose(res.q, ref.q, atol=1e-7)


def test_a_command_that_changes_every_tick_ends_a_step_at_every_tick(robot):
    ctrl = Hold(every=1, ramp=0.01, dt=2e-3)
    res = run(robot, ctrl, 0.1)
    assert res.control_ticks == 50
    assert res.diagnostics.steps >= 50  # the exact semantics of the sampled-data law
    # Gravity compensation of an arm at rest: the same command at every tick, long steps.
    still = Hold(every=1, dt=2e-3)
    res = run(robot, still, 0.1)
    assert res.control_ticks == 50 and len(still.changes) == 50
    assert res.diagnostics.steps <= 10


def test_events_inside_a_long_step_come_before_the_ticks_after_them(robot, monkeypatch):
    # The zero command held while the arm collapses onto its stops and the floor: the ticks
    # after each event see the state after it.
    ctrl = Hold(every=0, dt=1e-3)
    res = run(robot, ctrl, 0.6, pose="stand", joint_friction=False)
    kinds = {e.kind for e in res.events}
    assert kinds & {"impact", "limit"}, kinds
    t, q, v = calls(ctrl)
    np.testing.assert_allclose(t, 1e-3 * np.arange(600), atol=1e-12)
    cut_every_tick(monkeypatch)
    ref_ctrl = Hold(every=0, dt=1e-3)
    ref = run(robot, ref_ctrl, 0.6, pose="stand", joint_friction=False)
    _, q_ref, v_ref = calls(ref_ctrl)
    assert [e.kind for e in res.events] == [e.kind for e in ref.events]
    np.testing.assert_allclose([e.t for e in res.events], [e.t for e in ref.events], atol=1e-6)
    np.testing.assert_allclose(q, q_ref, atol=1e-5)
    np.testing.assert_allclose(v, v_ref, atol=1e-3)
    assert res.diagnostics.steps < ref.diagnostics.steps


def test_a_change_below_the_bound_is_held_and_above_it_applied(robot):
    ctrl = Hold(every=0, dt=1e-3)
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="none")
    sim = packbot.integrator._Run(robot, robot.pose("high"), np.zeros(8), 0.01, ctrl, None, cfg)
    ticks = sim.ticks
    lam = float(np.min(sim.sys.model.armature))
    bound = HOLD_FRACTION * cfg.atol * lam / cfg.max_step
    held = sim.drive.hold_full
    assert ticks.same(held.copy())
    du = np.zeros(8)
    du[1] = 0.5 * bound
    assert ticks.same(held + du)
    du[1] = 2.0 * bound
    assert not ticks.same(held + du)
    # elbow2's armature, the smallest of the integrated joints (the wrist is locked)
    assert lam == pytest.approx(0.01584)
    assert bound == pytest.approx(1e-3 * 1e-8 * 0.01584 / 0.05)


class Fails(Hold):
    """The zero command, held, until the tick at ``t_fail``, where it raises."""

    def __init__(self, t_fail: float, **kw):
        super().__init__(every=0, **kw)
        self.t_fail = t_fail

    def compute(self, t, q, v):
        if t >= self.t_fail - 1e-12:
            raise RuntimeError("sensor lost")
        return super().compute(t, q, v)


def test_a_controller_error_inside_a_long_step_keeps_the_samples_before_its_tick(robot):
    ctrl = Fails(0.237, dt=1e-3)
    with pytest.raises(packbot.ControllerError) as info:
        run(robot, ctrl, 0.5, contact_mode="none")
    assert info.value.t == pytest.approx(0.237, abs=1e-12)
    assert len(ctrl.calls) == 237
    part = info.value.result
    assert part is not None and part.t[-1] == pytest.approx(0.23)  # sample_dt is 0.01 s
