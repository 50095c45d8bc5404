"""The native Dormand-Prince step of the report's law's lock modes.

:meth:`packbot.contact.stops.JointStops.step_kernel` hands the stepper one compiled call per
attempt when the mode's accelerations are the joint locks' alone (``ContactRhs.set_locks``:
ABA with no lock, ABA and M^-1's rank-one correction with one, the unlocked joints' block of
M from CRBA and the bias forces with all but at most 3 locked). At every attempt of real
runs its solution is checked against the ODE's (finer steps on the integrator's right-hand
side, :meth:`JointStops.torque_accel`) within the stepper's tolerance; the step end's screen of
the lock conditions against :meth:`JointStops.lock_conditions`; and where it must not be offered.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from test_native_step import ACCURACY_MEDIAN, ACCURACY_WORST, _checked_attempt

import packbot
from packbot import ode
from packbot.contact import native
from packbot.contact.locks import ACCEL_BAND, TORQUE_BAND
from packbot.contact.stops import SCREEN_MARGIN, JointStops
from packbot.control.base import Controller
from packbot.system import System

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: A joint angle beyond its limit by more than this [rad] breaks the stop (the event location's
#: tolerance is far below it).
LIMIT_TOL = 1e-6


def _find_stepper(monkeypatch) -> dict:
    """Let a law find its run's stepper (for the Python stages): ``box["stepper"]``."""
    box: dict = {}
    original_init = ode.RK45Stepper.__init__

    def init(self, rhs, **kw):
        original_init(self, rhs, **kw)
        box["stepper"] = self

    monkeypatch.setattr(ode.RK45Stepper, "__init__", init)
    return box


CASES = {
    # the report's collapse: no lock, one, then three of four joints locked
    "collapse": ({"locked_joints": WRIST}, 1.0, None),
    # joint friction: held joints (two or more locked with the clamps)
    "friction": ({"locked_joints": WRIST, "joint_friction": True}, 1.0, None),
    # a held command from a controller (applied torques fixed over each step)
    "held command": ({"locked_joints": WRIST}, 0.6, "held"),
}


class _Held(Controller):
    def compute(self, t, q, v):
        tau = np.zeros(8)
        tau[1] = 20.0 * math.sin(3.0 * t)
        return tau


@pytest.mark.parametrize("case", list(CASES))
def test_every_native_lock_attempt_solves_the_ode_within_its_tolerance(robot, monkeypatch, case):
    """Each accepted native attempt of the lock modes (no lock, one, a block) is the solution
    of the ODE it integrates within the stepper's tolerance, its last stage the right-hand side
    at its end (test_native_step's check); the joint limits hold."""
    extra, duration, ctrl = CASES[case]
    seen: dict[str, int] = {"attempts": 0, "none": 0, "one": 0, "block": 0}
    worst: dict = {"errors": [], "fsal": 0.0}
    box = _find_stepper(monkeypatch)
    original = JointStops.step_kernel

    def checked(self, t, y):
        kernel = original(self, t, y)
        if kernel is None:
            return None
        stepper = box["stepper"]
        k = self.locks.n_locked

        def attempt(*args):
            seen["attempts"] += 1
            seen["none" if k == 0 else ("one" if k == 1 else "block")] += 1
            err = _checked_attempt(stepper, kernel, worst, *args)
            assert err >= 0.0  # every stage in closed form here
            return err

        return attempt

    monkeypatch.setattr(JointStops, "step_kernel", checked)
    cfg = packbot.SimConfig(contact_mode="joint_clamp", **extra)
    controller = _Held(dt=0.01) if ctrl else None
    res = packbot.simulate(
        robot, robot.pose("drive"), np.zeros(8), duration, config=cfg, controller=controller
    )
    assert res.t[-1] == pytest.approx(duration)
    assert seen["attempts"] > 50, seen
    assert seen["block"] > 0, seen
    if case == "collapse":
        assert seen["none"] > 0 and seen["one"] > 0, seen
    errors = np.array(worst["errors"])
    assert np.median(errors) <= ACCURACY_MEDIAN and errors.max() <= ACCURACY_WORST, (
        np.median(errors),
        errors.max(),
    )
    assert worst["fsal"] <= 1e-12, worst  # the same function of the same input: rounding
    lower, upper = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    assert (res.q >= lower - LIMIT_TOL).all() and (res.q <= upper + LIMIT_TOL).all()


@pytest.mark.parametrize("case", ["collapse", "friction"])
def test_the_screened_step_ends_keep_every_lock_condition(robot, monkeypatch, case):
    """Where the native step's end says no lock condition changed sign, none did: the
    Python conditions at that state are all >= 0, and equal the screen's to rounding."""
    extra, duration, _ = CASES[case]
    seen = {"screened": 0, "evaluated": 0}
    worst = {"cond": 0.0}
    original = JointStops._screened

    def checked(self, y1):
        ok = original(self, y1)
        end = self._lock_step.rhs.locks.end(y1) if self._lock_step.rhs is not None else None
        if end is None:
            assert not ok
            return ok
        py = self.lock_conditions(0.0, y1)  # a held command: the torques do not depend on t
        nat = self.locks.conditions_of(*end)
        assert py.keys() == nat.keys()
        for key, g in py.items():
            worst["cond"] = max(worst["cond"], abs(g - nat[key]) / (1.0 + abs(g)))
        a, lam = end
        scale = 1.0 + np.abs(a).max() + np.abs(lam).max(initial=0.0)
        screen = self._lock_step.rhs.locks.end_screen(
            self.locks.screen_rows(), y1, SCREEN_MARGIN, TORQUE_BAND, ACCEL_BAND
        )
        if nat:  # the extension's smallest condition is conditions_of's
            assert screen == pytest.approx(min(nat.values()) - SCREEN_MARGIN * scale, abs=1e-12)
        assert ok == (screen > 0.0)
        if ok:
            assert min(py.values(), default=1.0) >= 0.0
            seen["screened"] += 1
        else:
            seen["evaluated"] += 1
        return ok

    monkeypatch.setattr(JointStops, "_screened", checked)
    cfg = packbot.SimConfig(contact_mode="joint_clamp", **extra)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)
    assert seen["screened"] > 50, seen
    assert worst["cond"] <= 1e-11, worst


def test_the_lock_step_is_offered_only_where_it_serves_every_stage(robot, monkeypatch):
    offered: dict[str, int] = {}
    original = JointStops.step_kernel
    label = ["?"]

    def counted(self, t, y):
        kernel = original(self, t, y)
        offered[label[0]] = offered.get(label[0], 0) + (kernel is not None)
        return kernel

    monkeypatch.setattr(JointStops, "step_kernel", counted)
    q0, v0 = robot.pose("drive"), np.zeros(8)
    base = {"contact_mode": "joint_clamp", "locked_joints": WRIST}
    cases = {
        "plain": ({}, None),
        "no contact law": ({"contact_mode": "none"}, None),
        "torque function": ({}, lambda t, q, v: np.zeros(8)),
        "motor lag": ({"motor_lag": 0.01}, None),
    }
    for name, (extra, ctrl) in cases.items():
        label[0] = name
        packbot.simulate(
            robot, q0, v0, 0.3, config=packbot.SimConfig(**{**base, **extra}), controller=ctrl
        )
    assert offered["plain"] > 20
    assert offered["no contact law"] > 5  # contact_mode="none" steps natively too (13)
    assert offered["torque function"] == 0
    assert offered["motor lag"] == 0


def test_bad_lock_sets_are_refused(robot):
    sysm = System(robot, robot.pose("drive"), packbot.SimConfig(contact_mode="none"), None)
    rhs = native.NativeRhs(sysm.model)  # all 8 joints
    for bad in ([2, 1], [1, 1], [8], [-1]):
        with pytest.raises(ValueError, match="sorted distinct"):
            rhs.locks.set(np.array(bad))
    with pytest.raises(ValueError, match="at most 3"):
        rhs.locks.set(np.array([0, 1]))  # 6 unlocked: the locks' M^-1 solve, not native
    rhs.locks.set(np.array([0, 1, 2, 3, 4]))
    with pytest.raises(ValueError, match="contact rows"):
        rhs.accel(np.zeros(8), np.zeros(8), np.zeros(8), True)
    assert rhs.locks.end(np.zeros(16)) is None  # no step yet


def test_the_screen_has_every_kind_of_lock_condition(robot):
    """A held joint clamped both ways (a constant), a held joint with a one-sided clamp, an
    engaged clamp and a free clamped joint: the extension's smallest condition at a native
    step's end is JointLocks.conditions_of's there, whichever kind is the smallest."""
    from packbot.contact.locks import JointLocks

    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    n = sysm.nv  # 4: turret, shoulder, elbow1, elbow2
    rhs = native.NativeRhs(sysm.model)
    y0 = np.concatenate([sysm.reduce(robot.pose("drive")), np.zeros(n)])
    cases = [
        ({0: 1e3, 1: 0.5}, [(0, 1), (0, -1), (1, 1), (2, -1), (3, 1)], (2,)),
        ({1: 1e3}, [(0, 1), (1, -1), (3, -1)], (0,)),
        ({}, [(1, 1), (2, 1)], (1, 2)),
    ]
    kinds = set()
    for held, clamps, engaged in cases:
        locks = JointLocks(n)
        locks.set_held(held)
        locks.set_clamps(clamps)
        locks._set_engaged(engaged)
        rows = locks.screen_rows()
        kinds |= set(rows[:, 0].astype(int).tolist())
        if len(locks.locked_index) >= 2 and n - len(locks.locked_index) > 3:
            continue
        rhs.locks.set(locks.locked_index)
        rhs.set_torque(np.zeros(n), np.zeros(n), np.zeros(n))
        Z = np.zeros((8, 2 * n))  # (k0 = 0: any attempt serves; the screen is at its y1)
        Z[0] = y0
        y1, ay1 = np.empty(2 * n), np.empty(2 * n)
        err = rhs.step(1e-3, Z, np.abs(y0), np.full(2 * n, 1e-8), 1e-6, y1, ay1)
        assert err >= 0.0
        a, lam = rhs.locks.end(y1)
        cond = locks.conditions_of(a, lam)
        got = rhs.locks.end_screen(rows, y1, 0.0, TORQUE_BAND, ACCEL_BAND)
        assert got == pytest.approx(min(cond.values()), rel=1e-12, abs=1e-12)
        assert math.isnan(rhs.locks.end_screen(rows, y1 + 1e-9, 0.0, TORQUE_BAND, ACCEL_BAND))
    assert kinds == {0, 1, 2, 3}


def test_the_lock_step_loads_each_held_command_once_and_screens_only_its_lock_set(
    robot, monkeypatch
):
    """The law's NativeLockStep: one per phase; a held command's torques are loaded into the
    extension when they change (at a controller tick), not at every step; its end screen
    answers only for the lock set of its last step, and a phase's new one, before any step,
    answers False (the conditions are then evaluated)."""
    from packbot.contact.lock_step import NativeLockStep
    from packbot.contact.locks import JointLocks

    loads: list[np.ndarray] = []
    set_torque = native.NativeRhs.set_torque

    def counted(self, applied, viscous, coulomb_dir):
        loads.append(applied.copy())
        return set_torque(self, applied, viscous, coulomb_dir)

    monkeypatch.setattr(native.NativeRhs, "set_torque", counted)
    laws: list[JointStops] = []
    step_kernel = JointStops.step_kernel

    def kept(self, t, y):
        laws.append(self)
        return step_kernel(self, t, y)

    monkeypatch.setattr(JointStops, "step_kernel", kept)
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    res = packbot.simulate(
        robot, robot.pose("drive"), np.zeros(8), 0.6, config=cfg, controller=_Held(dt=0.01)
    )
    assert len({id(law._lock_step) for law in laws}) == 1  # one phase, one lock step
    assert 0 < len(loads) <= res.control_ticks < res.diagnostics.steps
    assert not any(np.array_equal(a, b) for a, b in itertools.pairwise(loads))
    law = laws[-1]
    step = law._lock_step
    y = np.concatenate([law.sys.reduce(res.q[-1]), law.sys.reduce(res.v[-1])])
    other = JointLocks(law.n)
    other.set_held({0: 1.0})  # another lock set than the last step's
    assert step.rhs is not None and not step.screened(y, other)
    fresh = NativeLockStep(law.sys, law.drive)
    assert fresh.rhs is None and not fresh.screened(y, law.locks)


@pytest.mark.parametrize("locked", [(), (2,), (0, 1, 2, 3, 4)])
def test_the_lock_torques_at_a_sample_are_the_locks_solve(robot, locked):
    """The extension's lock torques at a state (a sample between steps) equal the locks' own
    solve (M a = tau - h + S^T lambda, a_S = 0) to rounding, in each lock mode, and leave the
    loaded mode's state alone."""
    from packbot.contact.locks import JointLocks

    sysm = System(robot, robot.pose("drive"), packbot.SimConfig(contact_mode="none"), None)
    rhs = native.NativeRhs(sysm.model)
    rng = np.random.default_rng(7)
    with pytest.raises(ValueError, match="lock mode"):
        rhs.locks.torques_at(np.zeros(8), np.zeros(8), np.zeros(8))
    locks = JointLocks(8)
    locks.set_held({j: 1e3 for j in locked})  # (held: locked both ways, whatever the sign)
    rhs.locks.set(locks.locked_index)
    for _ in range(5):
        q = robot.pose("drive") + rng.uniform(-0.3, 0.3, 8)
        v, tau = rng.normal(size=8), rng.normal(scale=5.0, size=8)
        lam = rhs.locks.torques_at(q, v, tau)
        assert lam is not None and lam.shape == (len(locked),)
        _, want = locks.torques(sysm.aba(q, v, tau), sysm.minv(q))
        scale = 1.0 + max((abs(x) for x in want.values()), default=0.0)
        np.testing.assert_allclose(lam, [want[j] for j in locked], atol=1e-10 * scale)
    assert rhs.locks.end(np.zeros(16)) is None  # (still no step: nothing was made up)
    with pytest.raises(ValueError, match="nv entries"):
        rhs.locks.torques_at(np.zeros(7), np.zeros(8), np.zeros(8))
