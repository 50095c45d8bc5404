"""The native right-hand side of the contact-normal mode.

:class:`packbot.contact.native.NativeRhs` (``packbot._native``: ABA, M^-1, the Jacobians, the
contact rows and the constrained accelerations in one compiled call): its rebuilt Pinocchio model
against Pinocchio's own results, the physics of collapses run on it (frictionless and with
friction), and the models and plans it refuses.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native
from packbot.contact.normal import PENETRATION_TOL
from packbot.errors import ModelError
from packbot.system import System

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native is not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: Energy gained at one event beyond this counts as a gain [J] (test_normal_cascade's).
GAIN_TOL = 1e-6


@pytest.mark.parametrize(
    ("mu", "locked", "duration"),
    [(0.0, WRIST, 1.5), (0.5, WRIST, 1.5), (0.5, (), 0.6)],
    ids=["mu0", "mu0.5", "mu0.5-wrist-free"],
)
def test_a_collapse_on_the_native_rhs_keeps_its_contacts_and_gains_no_energy(
    robot, mu, locked, duration
):
    """The drive-pose collapse, zero torque, frictionless and with friction, wrist locked and
    free: its contacts hold (no penetration beyond PENETRATION_TOL), no event adds energy
    beyond GAIN_TOL (test_normal_cascade's: rounding of the energies at an event), and the
    arm loses energy (the contacts only dissipate)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)
    assert len(res.events_of("impact")) > 0
    gains = [e.energy_after - e.energy_before for e in res.events]
    assert max(gains) <= GAIN_TOL, max(gains)
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    assert res.energy[-1] < res.energy[0]


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
        self._row_mode = self._nc._row_mode

    def _layout(self):
        return self._nc._layout()


def test_unsupported_joints_are_refused(caplog):
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    with pytest.raises(ModelError, match="JointModelSpherical"):
        native.NativeRhs(model)
    with pytest.raises(ModelError, match="JointModelSpherical"):
        native.native_rhs(model)


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
