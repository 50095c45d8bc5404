"""The contact-normal mode's compiled stretch of quiet steps.

:mod:`packbot.contact.stretch`: the steps with nothing to handle at their end, taken in one
native call (``src/native/stretch.hpp``), on runs that meet every way out of a stretch: events
and re-patches (pending steps), the stiff switch, joint limits, a scheduled failure, the run's
end. Each run keeps the physics gates (no penetration beyond ``PENETRATION_TOL``, no event gains
energy, the zero-torque arm loses energy, the joint limits hold) with most of its steps taken
in stretches; the step bound is the analytic one.
"""

import ctypes
import dataclasses

import numpy as np
import pytest
from test_normal_cascade import GAIN_TOL, start_pose

import packbot
from packbot import integrator, native_sweep
from packbot.contact import native, stretch
from packbot.contact.normal import PENETRATION_TOL
from packbot.contact.normal_law import NormalLaw
from packbot.failures import Failure
from packbot.mujoco_model import WRIST_JOINTS
from packbot.scenario import load_scenario, run_scenario

pytestmark = pytest.mark.skipif(
    not (native.available() and native_sweep.available()),
    reason="the compiled extensions are not built",
)

#: A joint angle beyond its limit by more than this [rad] breaks the stop. A limit is a row of
#: the contact problem: it sinks by up to its rows' impact tolerance (POINT_TOL, 1e-6) before
#: its impact is located, and its Baumgarte term pulls it back (measured 1.000009e-6 rad on
#: the wrist-free start): ten times that.
LIMIT_TOL = 1e-5


def _run(robot, q0, duration, cfg, monkeypatch, failures=()):
    """The run; the steps its stretches took (and their pending steps); its loop."""
    taken = {"steps": 0, "pending": 0}
    run = stretch.QuietStretch.run

    def counted(self, *args):
        done, out = run(self, *args)
        taken["steps"] += done.steps
        taken["pending"] += done.pending is not None
        return done, out

    loops = []
    loop_run = integrator._Run.run

    def kept(self):
        loops.append(self)
        loop_run(self)

    monkeypatch.setattr(stretch.QuietStretch, "run", counted)
    monkeypatch.setattr(integrator._Run, "run", kept)
    res = packbot.simulate(
        robot, q0, np.zeros(robot.nq), duration, config=cfg, failures=list(failures)
    )
    return res, taken, loops[0]


def physical(robot, res, dissipates: bool = True) -> None:
    """The physics gates of a run (test_normal_cascade's, and the joint limits)."""
    gains = [e.energy_after - e.energy_before for e in res.events]
    assert max(gains, default=0.0) <= GAIN_TOL, max(gains)
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    if dissipates:
        assert res.energy[-1] < res.energy[0]
    lower, upper = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    assert (res.q >= lower - LIMIT_TOL).all() and (res.q <= upper + LIMIT_TOL).all()


@pytest.mark.parametrize("mu", [0.5, 0.0])
def test_the_collapse_takes_most_steps_in_stretches(robot, monkeypatch, mu):
    """The drive-pose collapse (wrist locked), 5 s: most steps in stretches, its events and
    re-patches found at a stretch's step (pending), its physics kept."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST_JOINTS)
    res, taken, _ = _run(robot, robot.pose("drive"), 5.0, cfg, monkeypatch)
    physical(robot, res)
    assert taken["steps"] + taken["pending"] >= 0.6 * res.diagnostics.steps
    assert taken["pending"] > 0


def test_a_wrist_free_start_with_rosenbrock_steps_and_limits(robot, monkeypatch):
    """A random start with the wrist free, 1.5 s: its stiff slides switch to Rosenbrock steps
    (inside the stretches too), joints reach their limits and hold them."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    res, taken, loop = _run(robot, start_pose(robot, 3), 1.5, cfg, monkeypatch)
    physical(robot, res)
    assert taken["steps"] > 0
    assert any(e.kind == "limit" for e in res.events)
    assert loop.stepper.n_stiff_steps > 0


def test_a_scheduled_failure_ends_a_stretch_on_its_time(robot, monkeypatch):
    """A joint that goes loose at 0.4 s: a step ends on the failure's time."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    fail = [Failure(joint="elbow2", kind="loose", t=0.4)]
    res, taken, _ = _run(robot, robot.pose("drive"), 1.0, cfg, monkeypatch, failures=fail)
    physical(robot, res)
    assert taken["steps"] > 0
    failures = [e.t for e in res.events if e.kind == "failure"]
    assert failures == [pytest.approx(0.4, abs=1e-12)]


def test_the_step_bound_keeps_every_point_within_half_the_margin(robot, monkeypatch):
    """The native step bound: min(max_step, margin / 2 / (reach . |v|)), each joint's reach
    times its speed bounding its points' (to rounding)."""
    laws = []
    rebuild = NormalLaw.rebuild

    def kept(self, system):
        laws.append(self)
        rebuild(self, system)

    monkeypatch.setattr(NormalLaw, "rebuild", kept)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.01, config=cfg)
    law = laws[0]
    rng = np.random.default_rng(7)
    n = law.n
    for _ in range(200):
        y = np.concatenate([rng.uniform(-1, 1, n), rng.normal(0, 3, n) * (rng.random(n) < 0.7)])
        speed = max(float(law.reach @ np.abs(y[n : 2 * n])), 1e-9)
        bound = min(cfg.max_step, 0.5 * cfg.margin / speed)
        assert law.step_bound(y) == pytest.approx(bound, rel=1e-12)


def test_the_stretch_refuses_what_is_not_a_sweep_entry_point(robot):
    """Another object, or another capsule than the compiled sweep's ``api``."""
    rhs = native.native_rhs(robot.model)
    assert rhs is not None
    new_capsule = ctypes.pythonapi.PyCapsule_New
    new_capsule.restype = ctypes.py_object
    new_capsule.argtypes = (ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p)
    constants = dict(
        margin=0.05,
        atol=np.full(2 * robot.nq, 1e-8),
        rtol=1e-6,
        h_min=1e-12,
        near=1e-3,
        pen_tol=1e-5,
        crawl_steps=400,
        crawl_step=2.5e-5,
        sample_dt=0.01,
        duration=1.0,
        stiff_switch=True,
    )
    with pytest.raises(TypeError):
        native.stretch(rhs, object(), **constants)
    with pytest.raises(ValueError, match="capsule of packbot._native_coal"):
        native.stretch(rhs, new_capsule(8, b"another.capsule", None), **constants)


@pytest.mark.parametrize(
    ("name", "stretched"),
    [
        ("camera_occlusion", True),
        ("collapse_elastic", True),
        ("frozen_elbow_reach", False),
        ("loose_swing_elbow2", False),
    ],
)
def test_shipped_scenarios_in_the_contact_normal_mode(robot, monkeypatch, name, stretched):
    """Shipped scenarios in the contact-normal mode, 1 s, keep their contacts. The camera's
    environment and restitution take stretches; the controlled ones (a frozen joint's new
    phase, a loose joint) take their ticks one step at a time (the loop offers no stretch with
    a controller tick before the step's end)."""
    taken = {"steps": 0}
    run = stretch.QuietStretch.run

    def counted(self, *args):
        done, out = run(self, *args)
        taken["steps"] += done.steps
        return done, out

    monkeypatch.setattr(stretch.QuietStretch, "run", counted)
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, config=dataclasses.replace(sc.config, contact_mode="normal"))
    res = run_scenario(sc, robot, duration=1.0)
    assert res.t[-1] == pytest.approx(1.0)
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    assert (taken["steps"] > 0) == stretched
