"""The native Dormand-Prince step of the contact-normal mode.

:meth:`packbot.contact.normal.NormalLaw.step_kernel` hands the stepper one compiled call per
attempt (``ContactRhs.dopri``: the six stages with the native right-hand side, the 5th-order
solution, the FSAL slope and the error norm). At every attempt of real collapses its solution is
checked against the ODE's (finer steps on the same right-hand side) within the stepper's
tolerance; the native evaluations of the step's end and of its root finding against the
contact set's; and the cases where it must not be offered.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot import ode
from packbot.contact import native
from packbot.contact.normal import PENETRATION_TOL, NormalLaw
from packbot.control.base import Controller
from packbot.drive import Drive
from packbot.system import System


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: The accepted native attempts' 5th-order solution against the ODE's, in the scaled RMS norm of
#: the stepper's error control (1: the tolerance): its median, and its worst. The step size
#: follows the embedded 4th-order estimate, which the true error follows, but not everywhere: on
#: a step where a slip turns it was 8 for an estimate of 0.02 (the drive-pose collapse, mu 0.5;
#: median 0.09, 99th percentile 0.97). A wrong stage coefficient or a stale plan gives 1e3 or
#: more.
ACCURACY_MEDIAN = 0.5
ACCURACY_WORST = 50.0


def _reference(rhs, t: float, y0: np.ndarray, h: float, k: int = 16) -> np.ndarray:
    """The ODE's solution at t + h from y0: k Dormand-Prince steps of h / k on ``rhs`` (the
    stepper's right-hand side, its modes fixed), whose error is ~k^5 times the attempt's."""
    y, hs = y0.copy(), h / k
    Ah = ode._A8 * hs
    Ah[:, 0] = 1.0
    Z = np.empty((7, len(y0)))
    for i in range(k):
        ti = t + i * hs
        Z[0] = y
        Z[1] = rhs(ti, y)
        for s in range(1, 6):
            Z[1 + s] = rhs(ti + ode._C[s] * hs, np.dot(Ah[s, : s + 1], Z[: s + 1]))
        y = np.dot(Ah[6, :7], Z[:7])
    return y


def _checked_attempt(stepper, kernel, worst: dict, h, Z, ay0, atol, rtol, y1, ay1) -> float:
    """The native attempt, its 5th-order solution against the ODE's (accepted attempts) and its
    FSAL slope against the right-hand side at its y1: ``worst["errors"]`` (appended), and
    ``worst["fsal"]``."""
    t, y0 = stepper.t, Z[0].copy()
    err = kernel(h, Z, ay0, atol, rtol, y1, ay1)
    if err < 0.0 or err >= 1.0:  # (refused: the stepper's own stages; or rejected)
        return err
    ref = _reference(stepper._rhs, t, y0, h)
    sc = np.maximum(np.abs(y0), np.abs(y1)) * rtol + atol
    worst["errors"].append(math.sqrt(float(np.mean(((y1 - ref) / sc) ** 2))))
    f1 = stepper._rhs(t + h, y1.copy())
    scale = max(1.0, float(np.abs(f1).max()))
    worst["fsal"] = max(worst["fsal"], float(np.abs(Z[7] - f1).max()) / scale)
    np.testing.assert_array_equal(ay1, np.abs(y1))
    return err


@pytest.mark.parametrize(
    ("mu", "locked", "duration"),
    [(0.5, WRIST, 1.2), (0.0, WRIST, 0.8), (0.5, (), 0.5)],
    ids=["mu0.5", "mu0", "mu0.5-wrist-free"],
)
def test_every_native_attempt_solves_the_ode_within_its_tolerance(
    robot, monkeypatch, mu, locked, duration
):
    """The accepted native Dormand-Prince attempts of real collapses (stick, slip, limits) are
    the solutions of the ODE they integrate (their modes fixed) within the stepper's tolerance
    (ACCURACY_MEDIAN, ACCURACY_WORST), and each one's last stage is the right-hand side at its
    end (to rounding)."""
    seen = {"attempts": 0, "slip": 0, "stick": 0}
    worst: dict = {"errors": [], "fsal": 0.0}
    original = NormalLaw.step_kernel

    def checked(self, t, y):
        kernel = original(self, t, y)
        if kernel is None:
            return None
        stepper = self._test_stepper
        plan = self.normal._plan()

        def attempt(*args):
            seen["attempts"] += 1
            seen["slip"] += bool(plan.slips)
            seen["stick"] += bool(len(plan.sticks))
            return _checked_attempt(stepper, kernel, worst, *args)

        return attempt

    original_init = ode.RK45Stepper.__init__

    def init(self, rhs, **kw):  # let the law find the run's stepper (its right-hand side)
        original_init(self, rhs, **kw)
        init.stepper = self

    monkeypatch.setattr(ode.RK45Stepper, "__init__", init)
    original_rebuild = NormalLaw.rebuild

    def rebuild(self, system):
        original_rebuild(self, system)
        self._test_stepper = init.stepper

    monkeypatch.setattr(NormalLaw, "rebuild", rebuild)
    monkeypatch.setattr(NormalLaw, "step_kernel", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)
    assert seen["attempts"] > 100, seen
    if mu > 0.0:
        assert seen["slip"] > 0, seen
        if locked:
            assert seen["stick"] > 0, seen
    errors = np.array(worst["errors"])
    assert np.median(errors) <= ACCURACY_MEDIAN and errors.max() <= ACCURACY_WORST, (
        np.median(errors),
        errors.max(),
    )
    # the same function of the same input: rounding (the stiff rows amplify it to ~1e-13)
    assert worst["fsal"] <= 1e-10, worst


def test_the_step_kernel_is_offered_only_where_the_native_rhs_serves_every_stage(
    robot, monkeypatch
):
    offered: dict[str, int] = {}
    original = NormalLaw.step_kernel
    label = ["?"]

    def counted(self, t, y):
        kernel = original(self, t, y)
        offered[label[0]] = offered.get(label[0], 0) + (kernel is not None)
        return kernel

    monkeypatch.setattr(NormalLaw, "step_kernel", counted)
    q0, v0 = robot.pose("drive"), np.zeros(8)
    base = {"contact_mode": "normal", "mu": 0.5, "locked_joints": WRIST}
    cases = {
        "plain": ({}, None),
        "torque function": ({}, lambda t, q, v: np.zeros(8)),
        "motor lag": ({"motor_lag": 0.01}, None),
    }
    for name, (extra, ctrl) in cases.items():
        label[0] = name
        cfg = packbot.SimConfig(**base, **extra)
        packbot.simulate(robot, q0, v0, 0.3, config=cfg, controller=ctrl)
    assert offered["plain"] > 20
    assert offered["torque function"] == 0
    assert offered["motor lag"] == 0


def test_step_torques_are_the_drives_torques(robot, rng):
    cfg = packbot.SimConfig(contact_mode="normal", joint_friction=True, locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)

    class Held(Controller):
        def compute(self, t, q, v):  # pragma: no cover - not ticked here
            return np.zeros(8)

    for controller in (None, Held()):
        drive = Drive(robot, cfg, controller)
        drive.phase(sysm, [])
        if controller is not None:
            drive.hold(rng.standard_normal(8), 0.0)
        drive.fdir[:] = rng.choice([-1.0, 0.0, 1.0], sysm.nv)
        y = np.concatenate([sysm.reduce(robot.pose("drive")), rng.standard_normal(sysm.nv)])
        torques = drive.step_torques(0.0, y)
        assert torques is not None
        applied, viscous, coulomb_dir = torques
        assert np.abs(viscous).max() > 0.0 and np.abs(coulomb_dir).max() > 0.0
        for _ in range(3):
            v = rng.standard_normal(sysm.nv)
            y[sysm.nv :] = v
            _, _, a, f = drive.torques(0.0, y)
            np.testing.assert_array_equal(applied + (-viscous * v - coulomb_dir), a + f)


def _note_differences(ev, py, worst: dict[str, float]) -> None:
    """Keep in ``worst`` the largest differences of a native evaluation from the Python one:
    forces (relative to max(1, |lambda|)), rows (gaps, normal and centre velocities), the
    smallest condition and the slides."""
    lscale = max(1.0, float(np.abs(py.lam).max()))
    worst["lam"] = max(worst["lam"], float(np.abs(ev.lam - py.lam).max()) / lscale)
    rows = np.concatenate([ev.gap - py.gap, ev.vn - py.vn, (ev.vt - py.vt).ravel()])
    worst["rows"] = max(worst["rows"], float(np.abs(rows).max()))
    worst["cond"] = max(worst["cond"], abs(ev.cond - py.cond))
    slides = np.abs(ev.slide2 - py.slide2)  # (no pair: a limit row alone)
    worst["slide2"] = max(worst["slide2"], float(slides.max(initial=0.0)))


def _compare_with_python(monkeypatch, method, tol, also=None):
    """Patch ``NativeRhs.<method>`` (``end_eval`` or ``eval_at``): each evaluation it returns
    must be the contact set's last one and equal ``NormalContacts.evaluate`` at that state (the
    accelerations to ``tol``, the rest noted in ``worst``: :func:`_note_differences`);
    ``also(ev, py, contacts, q)`` adds the caller's checks.

    Returns:
        The counts ({"calls": ...}) and the worst differences, filled as the run goes.
    """
    seen = {"calls": 0}
    worst = {"lam": 0.0, "rows": 0.0, "cond": 0.0, "slide2": 0.0}
    original = getattr(native.NativeRhs, method)
    laws: list[NormalLaw] = []

    def checked(self, contacts, y):
        ev = original(self, contacts, y)
        if ev is None:
            return None
        n = self.nv
        law = laws[-1]
        q, v = y[:n], y[n:]
        assert contacts._last_eval[6] is ev
        py = contacts.evaluate(q, v, law.free_accel(0.0, y), law.sys.minv(q))
        np.testing.assert_allclose(ev.a, py.a, rtol=tol, atol=tol)
        _note_differences(ev, py, worst)
        if also is not None:
            also(ev, py, contacts, q)
        seen["calls"] += 1
        return ev

    original_rebuild = NormalLaw.rebuild

    def rebuild(self, system):
        original_rebuild(self, system)
        laws.append(self)

    monkeypatch.setattr(NormalLaw, "rebuild", rebuild)
    monkeypatch.setattr(native.NativeRhs, method, checked)
    return seen, worst


def test_the_root_findings_native_evaluations_are_the_python_ones(robot, monkeypatch):
    """Inside a native step, the mode conditions' root finding evaluates them natively
    (NativeRhs.eval_at, the loaded modes and torques): the same forces, rows, smallest
    condition and slides as NormalContacts.evaluate at that state, to rounding. (A contact
    row's condition alone comes from NativeWatch.row_condition_at: the next test.)"""
    seen, worst = _compare_with_python(monkeypatch, "eval_at", 1e-10)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)
    # enough root-finding evaluations to compare (17 on the collapse; the count moves with
    # the trajectory's events, so the bound is loose)
    assert seen["calls"] >= 8, seen
    assert worst["lam"] <= 1e-9, worst
    assert worst["rows"] <= 1e-12, worst
    assert worst["cond"] <= 1e-8, worst
    assert worst["slide2"] <= 1e-20, worst


@pytest.mark.parametrize(
    ("mu", "locked", "duration"), [(0.5, WRIST, 5.0), (0.0, (), 2.0)], ids=["mu0.5", "mu0-free"]
)
def test_a_rows_native_root_is_the_python_root(robot, monkeypatch, mu, locked, duration):
    """A contact row's crossing inside a native step is located in one native call
    (NativeWatch.row_root: Brent's iterates on the row's condition at the step's dense output):
    the time packbot.ode.locate_root finds on the same function in Python, to rounding (the
    interpolant is summed in another order): most within 1e-12 s (measured: 0 to 1e-14 s; how
    many are the same float depends on the machine's numpy), 98 % within 1e-9 s, all within
    1e-6 s (a condition falling to 0 twice inside its step, where locate_root may return either
    root)."""
    from packbot import integrator, ode

    diffs: list[float] = []
    earliest = ode.locate_earliest

    def compared(gs, g0s, g1s, t0, t1, *, xtol, at_tol, roots=None):
        for g, g0, g1, root in zip(gs, g0s, g1s, roots or [None] * len(gs), strict=True):
            if root is not None and g0 > 0.0:
                diffs.append(
                    abs(root(t0, t1, g0, g1, xtol) - ode.locate_root(g, t0, t1, g0, g1, xtol=xtol))
                )
        return earliest(gs, g0s, g1s, t0, t1, xtol=xtol, at_tol=at_tol, roots=roots)

    monkeypatch.setattr(integrator, "locate_earliest", compared)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    q0 = robot.pose("drive") if locked else start_pose(robot, 0)
    packbot.simulate(robot, q0, np.zeros(8), duration, config=cfg)
    d = np.array(diffs)
    assert len(d) >= 5, len(d)  # (the collapse: 7; the wrist-free start: 100 and more)
    assert (d <= 1e-12).mean() > 0.8, np.sort(d)[-5:]
    assert np.quantile(d, 0.98) <= 1e-9 and d.max() <= 1e-6, np.sort(d)[-5:]


def test_a_rows_native_root_refuses_bad_arguments(robot):
    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.NativeRhs(sysm.model)
    n = 2 * sysm.nv
    Z, y1 = np.zeros((8, n)), np.zeros(n)
    with pytest.raises(ValueError, match="torques and conditions"):
        rhs._rhs.row_root(Z, 0.0, 1e-3, 1e-3, y1, False, 0, 1.0, -1.0, 1e-10)
    rhs.set_torque(np.zeros(sysm.nv), np.zeros(sysm.nv), np.zeros(sysm.nv))
    with pytest.raises(ValueError, match=r"Z \(8, 2 nv\)"):
        rhs._rhs.row_root(Z[:7], 0.0, 1e-3, 1e-3, y1, False, 0, 1.0, -1.0, 1e-10)


def test_eval_at_refuses_a_wrong_state_and_needs_the_torques(robot):
    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.NativeRhs(sysm.model)
    n = 2 * sysm.nv
    with pytest.raises(ValueError, match="set_torque"):
        rhs._rhs.eval_at(np.zeros(n))
    rhs.set_torque(np.zeros(sysm.nv), np.zeros(sysm.nv), np.zeros(sysm.nv))
    with pytest.raises(ValueError, match="2 nv"):
        rhs._rhs.eval_at(np.zeros(n - 1))
    with pytest.raises(ValueError, match="2 nv"):
        rhs._rhs.row_condition_at(np.zeros(n - 1), 0)


def test_bad_step_arguments_are_refused(robot):
    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.NativeRhs(sysm.model)
    n = 2 * sysm.nv
    z = np.zeros(n)
    with pytest.raises(ValueError, match="set_torque"):
        rhs.step(1e-3, np.zeros((8, n)), z, z + 1e-9, 1e-6, np.zeros(n), np.zeros(n))
    rhs.set_torque(np.zeros(sysm.nv), np.zeros(sysm.nv), np.zeros(sysm.nv))
    with pytest.raises(ValueError, match=r"Z \(8, 2 nv\)"):
        rhs.step(1e-3, np.zeros((7, n)), z, z + 1e-9, 1e-6, np.zeros(n), np.zeros(n))
    with pytest.raises(ValueError, match="nv entries"):
        rhs.set_torque(np.zeros(3), np.zeros(3), np.zeros(3))


@pytest.mark.parametrize(
    ("mu", "locked", "duration"),
    [(0.5, WRIST, 1.2), (0.5, (), 1.0)],
    ids=["mu0.5", "mu0.5-wrist-free"],
)
def test_the_step_ends_conditions_are_the_python_evaluations(
    robot, monkeypatch, mu, locked, duration
):
    seen = {"violated": 0}

    def also(ev, py, contacts, q):
        # kept as the contact set's last evaluation at (q, v), for sliding() and stale()
        np.testing.assert_array_equal(contacts._last_eval[0], q)
        assert contacts.violated(ev) == contacts.violated(py)
        seen["violated"] += ev.cond < 0.0

    ends, worst = _compare_with_python(monkeypatch, "end_eval", 1e-12, also)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)
    # (67 and 76 step ends evaluated: the ends the screen finds clear are not; more before
    # the slow-slide stop stopped lifting contacts and a vertex on a face kept its patch)
    assert ends["calls"] > 50, ends
    assert seen["violated"] > 0, seen
    assert worst["lam"] <= 1e-10, worst
    assert worst["rows"] <= 1e-12, worst
    assert worst["cond"] <= 1e-10, worst
    assert worst["slide2"] <= 1e-20, worst


def test_a_tick_inside_a_window_restarts_on_the_free_accelerations(robot, monkeypatch):
    """A command change inside a time-stepping window restarts the stepper (one right-hand
    side) while the window's steps have re-patched pairs under the event-driven modes' engaged
    rows: those rows no longer index the contact set (the native call refused them: "engaged
    row out of range"). The run with a command change every 10 ms finishes, in windows."""

    class Push(Controller):
        def compute(self, t, q, v):
            tau = np.zeros(8)
            tau[1] = -5.0 + 3.0 * np.sin(20.0 * t)
            tau[2] = 2.0
            return tau

    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST, joint_friction=True)
    res = packbot.simulate(
        robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg, controller=Push(dt=0.01)
    )
    assert res.t[-1] == pytest.approx(2.0)
    assert res.diagnostics.windows > 0
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
