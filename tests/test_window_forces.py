"""The contact forces inside time-stepping windows: each step's impulses over its length.

Checked on window steps of wrist-free random starts (the collapse's cascades open windows):
every window sample's forces are known, lie in their cones, and close the equations of motion,
exactly per step (h (J^T f + the stops' torques) = M (v1 - v_f) at the step's start) and
approximately on the samples (the sampled motion's inverse dynamics).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot.contact import native, normal_windows, timestep
from packbot.contact.window_forces import WindowForces
from packbot.contact_forces import joint_torque

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")


@pytest.fixture(scope="module")
def robot() -> packbot.Robot:
    return packbot.load_robot()


def _run(robot, k: int, mu: float, duration: float, **kw) -> packbot.SimResult:
    cfg = packbot.SimConfig(
        contact_mode="normal", mu=mu, restitution=0.0, sample_dt=timestep.WINDOW_STEP, **kw
    )
    return packbot.simulate(
        robot, start_pose(robot, k), np.zeros(robot.model.nv), duration, config=cfg
    )


def _inside(res: packbot.SimResult) -> np.ndarray:
    """Samples strictly inside a window (between its ``timestep`` and ``resume`` events)."""
    inside = np.zeros(len(res.t), dtype=bool)
    ends = [e.t for e in res.events_of("resume")]
    for i, t0 in enumerate(e.t for e in res.events_of("timestep")):
        t1 = ends[i] if i < len(ends) else np.inf
        inside |= (res.t > t0 + 1e-9) & (res.t < t1 - 1e-9)
    return inside


@pytest.fixture(scope="module")
def windowed(robot) -> packbot.SimResult:
    return _run(robot, 16, 0.5, 1.5)


class _Set:
    """A stand-in contact set: no pairs, one limit row (joint 1, upper) in a 2-dof model."""

    def __init__(self) -> None:
        self.model = pin.Model()
        for k in range(2):
            parent = k
            self.model.addJoint(parent, pin.JointModelRY(), pin.SE3.Identity(), f"j{k}")
        self.pairs: dict = {}
        self.limits = {(1, 1): 0.5}
        self.nv = 2


def test_a_sample_reads_the_step_that_holds_it() -> None:
    """The loop's rule: a sample at t belongs to the first step whose end + 1e-12 s reaches
    t (a sample at a step's end is that step's); none before the first step, after the last
    or at a time that is not finite. Each step's own impulse tells which one was read."""
    c = _Set()
    wf = WindowForces(c, c.model.createData())  # type: ignore[arg-type]
    for k, (t0, t1) in enumerate([(0.0, 1e-3), (1e-3, 2e-3), (2e-3, 2.5e-3)]):
        x = np.array([0.0, 0.0, k + 1.0])  # the limit row's normal impulse [N*m*s]
        wf.keep(t0, t1, np.zeros(2), x)

    def which(t: float) -> float | None:
        found = wf.at(t)
        return None if found is None else float(-found.limit_torque[1] * 1e-3)

    assert which(0.0) == which(5e-4) == which(1e-3) == pytest.approx(1.0)
    assert which(1e-3 + 1e-13) == pytest.approx(1.0)  # (within the 1e-12 s of its end)
    assert which(1e-3 + 1e-9) == which(2e-3) == pytest.approx(2.0)
    # the last step is 0.5 ms long: its mean torque is x / h
    assert float(-wf.at(2.4e-3).limit_torque[1]) == pytest.approx(3.0 / 5e-4)
    assert wf.at(-1e-9) is None and wf.at(2.6e-3) is None and wf.at(float("nan")) is None
    wf.clear()
    assert wf.at(5e-4) is None


def test_window_samples_are_known_and_in_their_cones(windowed) -> None:
    """Every sample inside a window carries its step's forces: known, with contacts, each
    pushing (normal part >= 0) and in its friction cone (|f_t| <= mu f_n, to 1e-9 relative:
    the ADMM's cone projection is exact up to rounding). Unknown: only a window's opening
    instant, recorded before the window's first step."""
    res = windowed
    inside = _inside(res)
    assert inside.sum() > 100, inside.sum()
    assert res.contacts_known[inside].all()
    opening = np.zeros(len(res.t), dtype=bool)
    for e in res.events_of("timestep"):
        opening |= res.t == e.t
    assert opening.any() and res.contacts_known[~opening].all()
    with_contacts = 0
    for k in np.flatnonzero(inside):
        cs = res.contacts_at(res.t[k])
        with_contacts += bool(cs)
        for c in cs:
            fn = float(c.force @ c.normal)
            ft = np.linalg.norm(c.force - fn * c.normal)
            assert fn >= 0.0
            assert ft <= 0.5 * fn * (1 + 1e-9) + 1e-12, (res.t[k], fn, ft)
    assert with_contacts > 0.5 * inside.sum()


def test_each_window_step_closes_its_equations(robot, monkeypatch) -> None:
    """Per step (the stepper's own, native runs off), the forces a sample inside the step and
    at its end reads (``WindowForces.at``) give the step's velocity change exactly at q0:
    h (J^T f + tau_stops) = M(q0) (v1 - v_f), to 1e-9 of the gravity torque's size (rounding:
    measured 1e-13); steps with limit rows among them."""
    monkeypatch.setattr(normal_windows, "run_native", lambda *a, **k: None)
    steps: list[tuple] = []
    real = timestep.MoreauJeanStepper._finish

    def finish(self, t, y, h, tail, target, applied, end, *args, **kwargs):
        n = self.n
        v_f, v1 = end[0], end[1]
        for t_s in (t + 0.5 * h, t + h):  # (a sample inside the step, one at its end)
            found = self.forces.at(t_s)
            assert found is not None
            limits = bool(self.forces._steps[-1][5])
            steps.append((y[:n].copy(), v_f.copy(), v1.copy(), h, found, limits))
        return real(self, t, y, h, tail, target, applied, end, *args, **kwargs)

    monkeypatch.setattr(timestep.MoreauJeanStepper, "_finish", finish)
    _run(robot, 16, 0.5, 1.5)
    assert len(steps) > 100, len(steps)
    assert sum(s[5] for s in steps) > 10  # (steps whose rows include a limit)
    model = robot.model
    data = model.createData()
    worst, with_contacts = 0.0, 0
    for q0, v_f, v1, h, found, _ in steps:
        g = pin.computeGeneralizedGravity(model, data, q0)
        Q = joint_torque(model, model.createData(), q0, found.contacts)
        M = pin.crba(model, data, q0)
        M = np.triu(M) + np.triu(M, 1).T
        resid = h * (Q + found.limit_torque) - M @ (v1 - v_f)
        worst = max(worst, float(np.linalg.norm(resid) / (h * np.linalg.norm(g))))
        with_contacts += bool(found.contacts)
    assert with_contacts > 0.5 * len(steps)
    assert worst <= 1e-9, worst


def test_window_samples_close_the_sampled_motion(robot, windowed) -> None:
    """On the samples (native runs included), the inverse dynamics of the sampled motion
    (accelerations from consecutive samples, one window step apart) matches the recorded
    contact and stop torques: median residual <= 1e-3 of the gravity torque's size (the
    window step's free velocity is the midpoint rule's, the difference reads it at the
    interval's start; measured 1.0e-5 on 2,291 sample pairs)."""
    res = windowed
    inside = _inside(res)
    Q = res.contact_torques(robot)
    model = robot.model
    data = model.createData()
    out = []
    for k in np.flatnonzero(inside[:-1] & inside[1:]):
        dt = res.t[k + 1] - res.t[k]
        if abs(dt - timestep.WINDOW_STEP) > 1e-9:
            continue
        q, v = res.q[k], res.v[k]
        a = (res.v[k + 1] - v) / dt
        tau = pin.rnea(model, data, q, v, a)
        g = pin.computeGeneralizedGravity(model, data, q)
        applied = res.tau[k + 1] + res.tau_friction[k + 1]
        resid = tau - applied - Q[k + 1] - res.limit_torque[k + 1]
        out.append(np.linalg.norm(resid) / np.linalg.norm(g))
    assert len(out) > 100, len(out)
    assert float(np.median(out)) <= 1e-3, float(np.median(out))


def test_native_runs_record_the_forces_of_their_own_steps(robot, windowed, monkeypatch) -> None:
    """The native runs of window steps (one call for many steps) record the same forces as the
    steps taken one by one (their arithmetic is the same): every window sample's contacts
    equal, to 1e-9 of the largest force (a step's impulses shifted onto another step would
    differ by the change over a step, 1e-3 of it and more)."""
    monkeypatch.setattr(normal_windows, "run_native", lambda *a, **k: None)
    one_by_one = _run(robot, 16, 0.5, 1.5)
    a, b = windowed, one_by_one
    assert len(a.t) == len(b.t)
    inside = _inside(a)
    scale = float(np.abs(a.contacts.force).max())
    for k in np.flatnonzero(inside):
        ca, cb = a.contacts_at(a.t[k]), b.contacts_at(b.t[k])
        assert [c.pair for c in ca] == [c.pair for c in cb], a.t[k]
        for x, y in zip(ca, cb, strict=True):
            assert np.abs(x.force - y.force).max() <= 1e-9 * scale, (a.t[k], x.pair)
    np.testing.assert_allclose(a.limit_torque[inside], b.limit_torque[inside], atol=1e-9 * scale)
