"""The native right-hand side of the contact-normal mode against the Python path.

:class:`packbot.contact.native.NativeRhs` (``packbot._native``: ABA, M^-1, the Jacobians, the
contact rows and the constrained accelerations in one compiled call) is compared with the Python
path (Pinocchio's Python calls and the extension's rows and accelerations) at every right-hand-side
call of a collapse, frictionless and with friction; its rebuilt Pinocchio model with Pinocchio's
own results; and whole runs with and without it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native, normal_modes, normal_steps
from packbot.contact.normal import NormalLaw
from packbot.errors import ModelError
from packbot.system import System

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.mark.parametrize(
    ("mu", "locked", "duration"),
    [(0.0, WRIST, 1.5), (0.5, WRIST, 1.5), (0.5, (), 0.6)],
    ids=["mu0", "mu0.5", "mu0.5-wrist-free"],
)
def test_every_rhs_of_a_collapse_matches_the_python_path(robot, monkeypatch, mu, locked, duration):
    seen = {"calls": 0, "slip": 0, "stick": 0, "limit": 0, "pairs2": 0}
    worst = {"a": 0.0, "a_from_free": 0.0, "lam": 0.0, "rows": 0.0}
    python_path = NormalLaw.torque_accel

    def both(self, q, v, tau):
        a_py = self.accel(q, v, self.sys.aba(q, v, tau))
        nc, rhs = self.normal, self._native
        assert rhs is not None
        if nc.engaged and not nc.resting and not self.locks.any_locked:
            plan = nc._plan()
            rhs.load(nc, plan)
            a_nat = rhs.accel(q, v, tau, True)
            assert a_nat is not None
            scale = max(1.0, float(np.abs(a_py).max()))
            worst["a"] = max(worst["a"], float(np.abs(a_nat - a_py).max()) / scale)
            # the kernel's own outputs against NormalContacts.evaluate's (forces, rows)
            _, _, lam, gap, vn, vt, _, _ = rhs.last()
            a_free = self.sys.aba(q, v, tau)
            ev = nc.evaluate(q, v, a_free, self.sys.minv(q))
            lscale = max(1.0, float(np.abs(ev.lam).max()))
            worst["lam"] = max(worst["lam"], float(np.abs(lam - ev.lam).max()) / lscale)
            rows = np.concatenate([gap - ev.gap, vn - ev.vn, (vt - ev.vt).ravel()])
            worst["rows"] = max(worst["rows"], float(np.abs(rows).max()))
            a_ff = rhs.accel(q, v, a_free, False)
            assert a_ff is not None
            worst["a_from_free"] = max(
                worst["a_from_free"], float(np.abs(a_ff - a_py).max()) / scale
            )
            seen["calls"] += 1
            seen["slip"] += bool(plan.slips)
            seen["stick"] += bool(len(plan.sticks))
            seen["limit"] += bool(len(nc.limits))
            seen["pairs2"] += len(nc.pairs) >= 2
        return a_py

    monkeypatch.setattr(NormalLaw, "torque_accel", both)
    monkeypatch.setattr(native, "STEP_ENABLED", False)  # every stage through torque_accel
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)
    monkeypatch.setattr(NormalLaw, "torque_accel", python_path)
    assert seen["calls"] > 500
    assert seen["pairs2"] > 0
    if mu > 0.0:
        assert seen["slip"] > 0
        if locked:  # the wrist-locked collapse sticks too (link 3 on the shoulder casing)
            assert seen["stick"] > 0
    assert worst["a"] <= 1e-12, worst
    assert worst["a_from_free"] <= 1e-12, worst
    assert worst["lam"] <= 1e-10, worst
    assert worst["rows"] <= 1e-12, worst


def test_the_rebuilt_model_gives_pinocchios_dynamics(robot, rng):
    for locked in (WRIST, ()):  # the reduced model and the full arm
        cfg = packbot.SimConfig(contact_mode="normal", locked_joints=locked)
        sysm = System(robot, robot.pose("drive"), cfg, None)
        rhs = native.NativeRhs(sysm.model)
        empty = _EmptySet(sysm)
        rhs.load(empty, empty.plan)  # type: ignore[arg-type]
        for _ in range(5):
            q = rng.uniform(sysm.lower, sysm.upper)
            v = rng.standard_normal(sysm.nv)
            tau = rng.standard_normal(sysm.nv)
            a = rhs.accel(q, v, tau, True)
            assert a is not None
            a_free, minv, lam, *_ = rhs.last()
            np.testing.assert_allclose(a, pin.aba(sysm.model, sysm.data, q, v, tau), atol=1e-12)
            np.testing.assert_array_equal(a_free, a)  # no contact: the free accelerations
            np.testing.assert_allclose(minv, sysm.minv(q), rtol=1e-12, atol=1e-12)
            assert lam.shape == (0,)


class _EmptySet:
    """A contact set with no pair and no limit (the layout of NormalContacts)."""

    def __init__(self, sysm: System) -> None:
        from packbot.contact.normal import NormalContacts

        self._nc = NormalContacts.from_config(sysm.model, sysm.data, None, packbot.SimConfig())
        self.mu = 0.5
        self._pair_list: list = []
        self.pairs: dict = {}
        self.plan = self._nc._plan()

    def _layout(self):
        return self._nc._layout()


def test_unsupported_joints_are_refused(caplog):
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    with pytest.raises(ModelError, match="JointModelSpherical"):
        native.NativeRhs(model)
    assert native.native_rhs(model) is None


def test_a_collapse_is_the_same_with_and_without_the_native_rhs(robot, monkeypatch):
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    monkeypatch.setattr(native, "STEP_ENABLED", False)  # (the native step: test_native_step)
    # (the native restart steps' frictional impacts differ by rounding: test_native_restart)
    monkeypatch.setattr(normal_steps, "NATIVE_RESTART", False)
    # (and the native mode selection's: test_native_modes)
    monkeypatch.setattr(normal_modes, "NATIVE_MODES", False)
    runs = []
    for enabled in (False, True):
        monkeypatch.setattr(native, "ENABLED", enabled)
        runs.append(packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg))
    off, on = runs
    assert len(off.t) == len(on.t) and len(off.events) == len(on.events)
    np.testing.assert_allclose(on.q, off.q, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(on.v, off.v, rtol=0.0, atol=1e-9)


def test_bad_plans_are_refused(robot):
    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.NativeRhs(sysm.model)
    empty = _EmptySet(sysm)
    rhs.load(empty, empty.plan)  # type: ignore[arg-type]
    z = np.zeros(0, dtype=np.int64)
    with pytest.raises(ValueError, match="engaged row out of range"):
        rhs._rhs.set_plan(np.array([0], dtype=np.int64), np.array([-1]), z, 0.5, 1e-3, 20.0)
    with pytest.raises(ValueError, match="nv entries"):
        rhs.accel(np.zeros(3), np.zeros(3), np.zeros(3), True)


def test_a_repatch_loads_its_patches_alone_and_changes_nothing(robot, monkeypatch):
    """A re-patch of the layout's shape loads its patches alone (``ContactRhs.set_patches``):
    the collapse is the same to the bit as with every layout loaded in full."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    real = native.NativeRhs.load_layout
    partial = {"n": 0}
    set_patches = native._native.ContactRhs.set_patches

    def counted(self, *a, **kw):
        partial["n"] += 1
        return set_patches(self, *a, **kw)

    def full(self, contacts):
        if contacts._layout() is not self._layout_id:
            self._layout_id = None
        return real(self, contacts)

    runs = []
    for load in (real, full):
        monkeypatch.setattr(native.NativeRhs, "load_layout", load)
        monkeypatch.setattr(native._native.ContactRhs, "set_patches", counted)
        runs.append(packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg))
    a, b = runs
    assert partial["n"] > 10, partial  # (the first run's re-patches)
    for k in ("t", "q", "v"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert [e.kind for e in a.events] == [e.kind for e in b.events]
