"""The contact-normal mode's compiled stretch of quiet steps takes the loop's own steps.

:mod:`packbot.contact.stretch`: the steps with nothing to handle at their end, taken in one
native call (``src/native/stretch.hpp``), must be the steps the loop takes one by one: the same
step sizes and rejections (the same counters), the same events at the same instants, the same
samples up to the rounding of their dense output (summed in another order than numpy's), the
same deepest distance, on runs that meet every way out of a stretch: events and re-patches
(pending steps), the stiff switch, joint limits, a scheduled failure, the run's end.
"""

import ctypes
import dataclasses

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot import integrator, native_sweep
from packbot.contact import native, stretch
from packbot.contact.normal_law import NormalLaw
from packbot.failures import Failure
from packbot.mujoco_model import WRIST_JOINTS
from packbot.scenario import load_scenario, run_scenario

pytestmark = pytest.mark.skipif(
    not (native.available() and native_sweep.available()),
    reason="the compiled extensions are not built",
)

#: The counters both loops must agree on (Diagnostics' fields; the wall time apart).
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


def _both(robot, q0, duration, cfg, monkeypatch, failures=()):
    """The run with the stretch off, then on; the steps the stretches took; the two loops."""
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
    res = []
    for enabled in (False, True):
        monkeypatch.setattr(stretch, "ENABLED", enabled)
        res.append(
            packbot.simulate(
                robot, q0, np.zeros(robot.nq), duration, config=cfg, failures=list(failures)
            )
        )
    return res[0], res[1], taken, loops


def _same(off, on):
    d_off, d_on = dataclasses.asdict(off.diagnostics), dataclasses.asdict(on.diagnostics)
    for name in COUNTERS:
        assert d_on[name] == d_off[name], name
    assert [(e.t, e.kind, e.piece1, e.piece2) for e in on.events] == [
        (e.t, e.kind, e.piece1, e.piece2) for e in off.events
    ]
    np.testing.assert_array_equal(on.t, off.t)
    # the samples inside steps: the dense output's sums (1e-16 rad here)
    np.testing.assert_allclose(on.q, off.q, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(on.v, off.v, rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(on.energy, off.energy, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("mu", [0.5, 0.0])
def test_the_collapse_takes_the_same_steps_in_stretches(robot, monkeypatch, mu):
    """The drive-pose collapse (wrist locked), 5 s: most steps in stretches, nothing moved."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST_JOINTS)
    off, on, taken, _ = _both(robot, robot.pose("drive"), 5.0, cfg, monkeypatch)
    _same(off, on)
    assert taken["steps"] + taken["pending"] >= 0.6 * on.diagnostics.steps
    assert taken["pending"] >= 20  # events and re-patches found at a stretch's step


def test_a_wrist_free_start_with_rosenbrock_steps_and_limits(robot, monkeypatch):
    """A random start with the wrist free, 1.5 s: its stiff slides switch to Rosenbrock steps
    (inside the stretches: the stepper's count agrees), joints reach their limits."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    off, on, taken, loops = _both(robot, start_pose(robot, 3), 1.5, cfg, monkeypatch)
    _same(off, on)
    assert taken["steps"] >= 50  # (75 of 468: its 179 restarts and 5 windows take the rest)
    assert any(e.kind == "limit" for e in on.events)
    stiff_off, stiff_on = (loop.stepper.n_stiff_steps for loop in loops)
    assert stiff_on == stiff_off > 0
    assert loops[1].stepper.n_rhs == loops[0].stepper.n_rhs


def test_a_scheduled_failure_ends_a_stretch_on_its_time(robot, monkeypatch):
    """A joint that goes loose at 0.4 s: the step ending on the failure's time is the loop's."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    fail = [Failure(joint="elbow2", kind="loose", t=0.4)]
    off, on, _, _ = _both(robot, robot.pose("drive"), 1.0, cfg, monkeypatch, failures=fail)
    _same(off, on)
    assert any(e.kind == "failure" for e in on.events)


def test_the_step_bound_is_the_same_with_and_without_the_extension(robot, monkeypatch):
    """The native step bound and the Python one sum reach . |v| in joint order: equal bits."""
    laws = []
    rebuild = NormalLaw.rebuild

    def kept(self, system):
        laws.append(self)
        rebuild(self, system)

    monkeypatch.setattr(NormalLaw, "rebuild", kept)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.01, config=cfg)
    law = laws[0]
    assert law._native is not None
    rng = np.random.default_rng(7)
    n = law.n
    for _ in range(200):
        y = np.concatenate([rng.uniform(-1, 1, n), rng.normal(0, 3, n) * (rng.random(n) < 0.7)])
        native_bound = law.step_bound(y)
        rhs, law._native = law._native, None
        python_bound = law.step_bound(y)
        law._native = rhs
        assert native_bound == python_bound


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
def test_shipped_scenarios_in_the_contact_normal_mode_run_alike(
    robot, monkeypatch, name, stretched
):
    """Shipped scenarios in the contact-normal mode, 1 s: the same run with the stretch as
    without. The camera's environment and restitution take stretches; the controlled ones
    (a frozen joint's new phase, a loose joint) take their ticks one step at a time (the loop
    offers no stretch with a controller tick before the step's end)."""
    taken = {"steps": 0}
    run = stretch.QuietStretch.run

    def counted(self, *args):
        done, out = run(self, *args)
        taken["steps"] += done.steps
        return done, out

    monkeypatch.setattr(stretch.QuietStretch, "run", counted)
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, config=dataclasses.replace(sc.config, contact_mode="normal"))
    res = []
    for enabled in (False, True):
        monkeypatch.setattr(stretch, "ENABLED", enabled)
        res.append(run_scenario(sc, robot, duration=1.0))
    _same(*res)
    assert (taken["steps"] > 0) == stretched
