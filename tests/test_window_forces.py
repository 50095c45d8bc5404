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
from packbot.contact import native, normal_law, timestep
from packbot.contact.window_forces import step_forces
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


def test_window_samples_are_known_and_in_their_cones(windowed) -> None:
    """Every sample inside a window carries its step's forces: known, with contacts, each
    pushing (normal part >= 0) and in its friction cone (|f_t| <= mu f_n, to 1e-9 relative:
    the ADMM's cone projection is exact up to rounding)."""
    res = windowed
    inside = _inside(res)
    assert inside.sum() > 100, inside.sum()
    assert res.contacts_known[inside].all()
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
    """Per step (the stepper's own, not the native runs'), the recorded forces and stop
    torques at q0 give the step's velocity change exactly: h (J^T f + tau_stops) =
    M(q0) (v1 - v_f), to 1e-9 of the gravity torque's size (rounding: measured 1e-13)."""
    monkeypatch.setattr(normal_law, "run_native", lambda *a, **k: None)
    steps: list[tuple] = []
    real = timestep.MoreauJeanStepper._finish

    def finish(self, t, y, h, tail, target, applied, end, *args, **kwargs):
        n = self.n
        v_f, v1 = end[0], end[1]
        t0, t1, q0, x, pairs, limits = self.forces._steps[-1]
        assert t0 == t and abs(t1 - t0 - h) < 1e-15
        found = step_forces(self.sys.model, self.sys.model.createData(), q0, x, h, pairs,
                            limits, n)  # fmt: skip
        steps.append((y[:n].copy(), v_f.copy(), v1.copy(), h, found))
        return real(self, t, y, h, tail, target, applied, end, *args, **kwargs)

    monkeypatch.setattr(timestep.MoreauJeanStepper, "_finish", finish)
    _run(robot, 16, 0.5, 0.6)
    assert len(steps) > 50, len(steps)
    model = robot.model
    data = model.createData()
    worst, with_contacts = 0.0, 0
    for q0, v_f, v1, h, found in steps:
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
