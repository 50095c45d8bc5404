"""The compiled stretch's own re-patches.

A step whose only finding is a sliding pair's stale patch is re-patched inside the stretch
(``src/native/stretch.hpp``, ``Stretch::try_repatch``): the patches rebuilt from the sweep's
materials, the drift projection's native round and its sweep's check, the modes kept or
selected again natively, the plan loaded and the stepper restarted there; Python then takes
the contact set over (:func:`packbot.contact.stretch.adopt_repatches`). The runs that re-patch
in their stretches keep the physics gates (test_stretch's); where the stretch hands a re-patch
back, :meth:`NormalContacts.repatch <packbot.contact.normal_contacts.NormalContacts.repatch>`
takes it. Where the native re-patch hands back
(forced here through its constants), nothing it did may show: the run is the one that hands
back before doing anything.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_normal_cascade import start_pose
from test_stretch import physical

import packbot
from packbot import native_sweep
from packbot.contact import native, stretch
from packbot.contact.normal_contacts import NormalContacts
from packbot.mujoco_model import WRIST_JOINTS
from packbot.native_sweep import NativeDispatch
from packbot.system import System

pytestmark = pytest.mark.skipif(
    not (native.available() and native_sweep.available()),
    reason="the compiled extensions are not built",
)


class _Counts:
    """The re-patches taken in the stretch and in Python, and the spare sweeps kept and used."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.native = self.python = self.kept = self.used = self.relaid = 0
        self.removed = 0.0  # (the energy the stretch's projections took [J])
        adopt = stretch.adopt_repatches
        repatch = NormalContacts.repatch
        keep = NativeDispatch.keep_spare
        sweep = NativeDispatch.sweep

        def adopted(law, out):
            self.native += out["repatches"]
            if out["repatches"]:
                self.relaid += out["repatched"]["relaid"]  # (patches of another size)
                self.removed += out["repatched"]["energy_removed"]
            adopt(law, out)

        def python(nc, *args):
            self.python += 1
            return repatch(nc, *args)

        def kept(d, *args):
            self.kept += 1
            keep(d, *args)

        def swept(d, *args):
            spare = d.spare
            out = sweep(d, *args)
            self.used += spare is not None and d.spare is None
            return out

        monkeypatch.setattr(stretch, "adopt_repatches", adopted)
        monkeypatch.setattr(NormalContacts, "repatch", python)
        monkeypatch.setattr(NativeDispatch, "keep_spare", kept)
        monkeypatch.setattr(NativeDispatch, "sweep", swept)


def _run(robot, q0, duration, cfg):
    return packbot.simulate(robot, q0, np.zeros(robot.nq), duration, config=cfg)


#: The counters two runs that do the same re-patches agree on (Diagnostics' fields).
COUNTERS = (
    "steps",
    "rejected_steps",
    "rhs_calls",
    "sweeps",
    "distance_queries",
    "restarts",
    "windows",
    "window_steps",
    "min_distance",
    "min_distance_pair",
)


def _same(a, b):
    """The same run: counters, events at the same instants, samples and final state."""
    d_a, d_b = dataclasses.asdict(a.diagnostics), dataclasses.asdict(b.diagnostics)
    for name in COUNTERS:
        assert d_b[name] == d_a[name], name
    assert [(e.t, e.kind, e.piece1, e.piece2) for e in b.events] == [
        (e.t, e.kind, e.piece1, e.piece2) for e in a.events
    ]
    np.testing.assert_array_equal(b.t, a.t)
    np.testing.assert_array_equal(b.q, a.q)
    np.testing.assert_array_equal(b.v, a.v)


CASES = {  # (config, start pose, duration [s], least re-patches in the stretch, of a new shape)
    "collapse": (dict(mu=0.5, locked_joints=WRIST_JOINTS), "drive", 5.0, 20, 2),
    "frictionless": (dict(mu=0.0, locked_joints=WRIST_JOINTS), "drive", 3.0, 40, 5),
    "sticky": (dict(mu=1.2, locked_joints=WRIST_JOINTS), "high", 3.0, 10, 0),
    "wrist-free": (dict(mu=0.5), "drive", 3.0, 5, 0),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_stretch_re_patches_and_keeps_the_physics(robot, monkeypatch, case):
    kw, pose, duration, least, relaid = CASES[case]
    cfg = packbot.SimConfig(contact_mode="normal", **kw)
    counts = _Counts(monkeypatch)
    res = _run(robot, robot.pose(pose), duration, cfg)
    physical(robot, res, dissipates=kw["mu"] > 0.0)
    assert counts.native >= least, counts.native
    assert counts.relaid >= relaid, counts.relaid


def test_a_wrist_free_start_with_limits_and_rosenbrock_steps(robot, monkeypatch):
    # a start whose stretches re-patch natively (the choice moves with the trajectory)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    counts = _Counts(monkeypatch)
    res = _run(robot, start_pose(robot, 4), 1.5, cfg)
    physical(robot, res)
    assert counts.native > 0


def _hand_back_at(monkeypatch, stage: int) -> None:
    """Every stretch's re-patch handed back at ``stage`` (its test setting ``hand_back_at``)."""
    init = stretch.QuietStretch.__init__

    def init_changed(self, *args):
        init(self, *args)
        law = args[2]
        from packbot.contact import normal_tolerances as nt

        self._run.set_repatch(
            tol=law.normal.tol, patch_tol=nt.PATCH_TOL, face_align=nt.FACE_ALIGN,
            slide_tol2=nt.SLIDE_TOL**2, touch_gap=nt.TOUCH_GAP, res_tol=nt.RESIDUAL_TOL,
            mu=law.normal.mu, speed_band=nt.SPEED_BAND, stick_speed=nt.STICK_SPEED,
            force_band=nt.FORCE_BAND, stick_band=nt.STICK_BAND, baumgarte=nt.BAUMGARTE,
            mode_res_tol=nt.RESIDUAL_TOL, hand_back_at=stage,
        )  # fmt: skip

    monkeypatch.setattr(stretch.QuietStretch, "__init__", init_changed)


@pytest.mark.parametrize(
    ("stage", "why"),
    [
        (2, "after the projection's round: the patches and plan put back"),
        (3, "at the modes: put back, the projection's sweep left for the loop's re-patch"),
    ],
)
def test_a_re_patch_handed_back_leaves_no_trace(robot, monkeypatch, stage, why):
    """Forced hand-backs after the re-patch's later stages: the run is the one handed back
    before anything was done (stage 1), samples included; every re-patch then Python's."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    counts = _Counts(monkeypatch)
    _hand_back_at(monkeypatch, 1)
    first = _run(robot, robot.pose("drive"), 5.0, cfg)
    python_first, kept_first = counts.python, counts.kept
    _hand_back_at(monkeypatch, stage)
    later = _run(robot, robot.pose("drive"), 5.0, cfg)
    _same(first, later)
    assert counts.native == 0, why
    assert python_first > 0 and counts.python - python_first == python_first
    kept = counts.kept - kept_first
    if stage == 3:
        # after a projection that moved q, its sweep is left for the loop's re-patch, which
        # finds it (its warm-started GJK is not run a second time at that q)
        assert kept > 5 and counts.used == kept, (kept, counts.used)
    else:
        assert kept == 0


def test_native_inverse_mass_and_free_accelerations_are_the_systems(robot, rng):
    """The re-patch's M(q)^-1 and unconstrained accelerations: the Python path's, bit for bit."""
    for locked in (WRIST_JOINTS, []):
        cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=list(locked))
        sysm = System(robot, robot.pose("drive"), cfg, None)
        rhs = native.native_rhs(sysm.model)
        assert rhs is not None
        n = sysm.nv
        viscous = rng.uniform(0.0, 2.0, n)
        applied = rng.normal(0.0, 5.0, n)
        rhs.set_torque(applied, viscous, np.zeros(n))
        for _ in range(50):
            q = rng.uniform(sysm.lower, sysm.upper)
            v = rng.normal(0.0, 1.0, n)
            minv = np.empty((n, n))
            rhs._rhs.minv_at(q, minv)
            np.testing.assert_array_equal(minv, sysm.minv(q))
            a = np.empty(n)
            rhs._rhs.free_accel_at(q, v, a)
            np.testing.assert_array_equal(a, sysm.aba(q, v, applied + (-viscous * v - 0.0)))


def test_a_restarted_take_leaves_the_derivative_pending(robot):
    from packbot.ode import MAX_FACTOR_FIRST, RK45Stepper

    st = RK45Stepper(lambda t, y: -y, rtol=1e-6, atol=1e-9)
    st.reset(0.0, np.ones(2))
    st.take(
        0.5, np.full(2, 0.6), np.zeros(2), np.full(2, 0.6), 0.01, steps=3, rejected=0,
        rhs_calls=19, stiff_steps=0, stiff_run=0, stiff=False, restarted=True,
    )  # fmt: skip
    assert st.f_pending and st.control().max_factor == MAX_FACTOR_FIRST
    seg = st.step(1.0)
    np.testing.assert_allclose(seg.y1, 0.6 * np.exp(-(seg.t1 - 0.5)), rtol=1e-5)


def test_the_stretchs_projections_add_no_energy(robot, monkeypatch):
    """The frictionless collapse (mu 0, wrists locked), 3 s: the stretch's re-patches project
    the drift out and scale the velocity so that the energy stays as it was (the extension's
    ``neutral_velocity``, as Python's re-patch and restart): the projections do take energy
    (they lift the arm out of the surfaces gravity pressed it into), and the energy never rises
    above its running minimum by more than the integration's error (measured 9.7e-7 J, with 65
    re-patches in the stretch taking 3.3e-3 J and 0.015 J taken in all; asserted 1e-4 J)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, locked_joints=WRIST_JOINTS)
    counts = _Counts(monkeypatch)
    res = _run(robot, robot.pose("drive"), 3.0, cfg)
    assert counts.native >= 40, counts.native
    assert counts.removed > 0.0
    assert res.diagnostics.projection_energy_removed >= counts.removed
    E = np.asarray(res.energy)
    rise = float((E - np.minimum.accumulate(E)).max())
    assert rise <= 1e-4, rise
