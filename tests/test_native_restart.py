"""The restart's impacts, projections and mode selection on real runs, against physics.

The restart's projection rounds, impact and stop of the slow slides are one native call each
(``ContactRhs.project_round``, ``ContactRhs.impact``, ``ContactRhs.stop_slow``), the mode
selection too (``ContactRhs.select_modes``); :class:`~packbot.contact.normal_steps.RestartSteps`
and :class:`~packbot.contact.normal_modes.ModeSelection` take over where they hand back. Checked
here on what the runs do: an impact never gains kinetic energy, leaves no touching row
approaching (inelastic) or gives Newton's restitution (frictionless, e > 0), and the runs go
no deeper than the penetration tolerance and gain no energy at an event.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native, normal_steps
from packbot.contact.normal_tolerances import PENETRATION_TOL, TOUCH_GAP

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def _impacts(robot, q0, mu: float, duration: float, **cfg_kw) -> tuple[list[dict], object]:
    """Every impact of a run: the touching rows' normal velocities before and after [m/s], the
    kinetic energy's change [J] relative to max(1, v M v), whether it bounced."""
    seen: list[dict] = []
    real = normal_steps.RestartSteps.impulse

    def impulse(self, q, v, minv):
        out = real(self, q, v, minv)
        Jn, _, gap, _, _ = self._problem(q, v)
        touch = gap <= TOUCH_GAP
        if not bool(touch.any()) or out is v:
            return out
        M = pin.crba(self.model, pin.Data(self.model), q)
        M = np.triu(M) + np.triu(M, 1).T
        seen.append(
            {
                "vn0": Jn[touch] @ v,
                "vn1": Jn[touch] @ out,
                "energy": 0.5 * float(out @ M @ out - v @ M @ v) / max(1.0, float(v @ M @ v)),
                "bounced": bool(self.bounced),
                "e": float(self.e),
            }
        )
        return out

    mp = pytest.MonkeyPatch()
    mp.setattr(normal_steps.RestartSteps, "impulse", impulse)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, **{"restitution": 0.0, **cfg_kw})
    try:
        res = packbot.simulate(robot, q0, np.zeros(robot.model.nv), duration, config=cfg)
    finally:
        mp.undo()
    return seen, res


def _no_event_gains(res) -> None:
    for e in res.events:
        assert e.energy_after <= e.energy_before + 1e-9, (e.kind, e.t)


@pytest.mark.parametrize(
    ("start", "mu"),
    [("collapse", 0.5), (21, 0.0), (16, 0.5), (5, 1.2)],
    ids=["collapse", "start21-mu0", "start16-mu0.5", "start5-mu1.2"],
)
def test_an_inelastic_impact_stops_every_touching_row_and_gains_no_energy(robot, start, mu):
    from test_normal_cascade import start_pose

    if start == "collapse":
        q0, kw = robot.pose("drive"), {"locked_joints": WRIST}
    else:
        q0, kw = start_pose(robot, start), {}
    impacts, res = _impacts(robot, q0, mu, 1.0, **kw)
    assert len(impacts) >= 5, len(impacts)
    for i in impacts:
        scale = max(1.0, float(np.abs(i["vn0"]).max()))
        # (the frictionless impact is Lemke's pivots, exact to rounding; the frictional one the
        # conic solver's, stopped at a residual of IMPACT_CONIC_TOL of the problem's scale,
        # accepted to IMPACT_ADMM_ACCEPT: measured down to -1.1e-8 m/s at mu = 1.2)
        tol = 1e-9 if mu == 0.0 else 1e-7
        assert float(i["vn1"].min()) >= -tol * scale, (i["vn1"], i["vn0"])
        assert i["energy"] <= 1e-9
    assert res.diagnostics.min_distance >= -PENETRATION_TOL
    _no_event_gains(res)


def test_a_frictionless_bounce_follows_newtons_restitution(robot):
    """A frictionless impact with restitution e: the touching rows' velocities after it, w =
    vn+ + e min(vn-, 0), solve the impact's complementarity problem: none negative, and the
    rows the impulse pushes leave at exactly e times their approach speed (some row does: the
    impulse is not zero), so min w = 0 to rounding. Energy is lost or kept, never gained."""
    from test_normal_cascade import start_pose

    impacts, res = _impacts(robot, start_pose(robot, 21), 0.0, 1.0, restitution=0.5)
    bounces = [i for i in impacts if i["bounced"]]
    assert len(bounces) >= 3, len(impacts)
    for i in bounces:
        w = i["vn1"] + i["e"] * np.minimum(i["vn0"], 0.0)
        scale = max(1.0, float(np.abs(i["vn0"]).max()))
        assert float(w.min()) >= -1e-9 * scale, (w, i["vn0"])
        assert float(w.min()) <= 1e-9 * scale, (w, i["vn0"])
        assert i["energy"] <= 1e-9
    single = [i for i in bounces if len(i["vn0"]) == 1]
    for i in single:  # one row: vn+ = -e vn-
        assert i["vn1"][0] == pytest.approx(-i["e"] * i["vn0"][0], rel=1e-9, abs=1e-12)
    assert res.diagnostics.min_distance >= -PENETRATION_TOL
    _no_event_gains(res)


def test_the_collapse_comes_to_rest_without_penetrating_or_gaining_energy(robot):
    """The collapse (mu = 0.5, wrist locked, no torque): it comes to rest, no deeper than the
    penetration tolerance, and its energy does not rise between events beyond the integration's
    tolerance (1e-6 J over a sample interval: measured 1.1e-7 J at most; the events themselves
    gain nothing)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)
    assert res.rest_time is not None
    assert np.abs(res.v[-1]).max() <= 1e-6
    assert res.diagnostics.min_distance >= -PENETRATION_TOL
    _no_event_gains(res)
    t, E = np.asarray(res.t), np.asarray(res.energy)
    flows = np.diff(t) > 0.0  # (an event's pre and post samples share a time)
    assert float(np.diff(E)[flows].max()) <= 1e-6
    assert E[-1] < E[0]


def _lifted(robot, rng):
    """(q0, q1, v): a configuration, one moved by a small step against gravity (its potential
    energy higher, as a projection out of a surface gravity pressed the arm into), a velocity."""
    model, data = robot.model, robot.model.createData()
    q0 = pin.neutral(model) + 0.3 * rng.standard_normal(model.nq)
    g = pin.computeGeneralizedGravity(model, data, q0)  # dV/dq [N*m]
    q1 = q0 + 1e-5 * g / np.linalg.norm(g)  # (up the potential's gradient)
    return q0, q1, rng.standard_normal(model.nv)


def test_a_projections_velocity_leaves_the_energy_as_it_was(robot, rng):
    """``neutral_velocity``: a projection q0 -> q1 that would raise the energy by moving the arm
    against gravity with v kept scales v (its direction kept: every velocity condition of a
    contact set is homogeneous) so that E(q1, v1) = E(q0, v), measured by Pinocchio's Python
    bindings (armature included); the energy removed is the kinetic energy's
    fall. Where the kinetic energy is smaller than the rise, v goes to zero; a move that lowers
    the energy is left as it is. Tolerances: rounding of energies of ~10 J (1e-12 relative)."""
    model, data = robot.model, robot.model.createData()

    def mass(q):
        M = pin.crba(model, data, q)  # (armature on its diagonal; the upper triangle)
        return np.triu(M) + np.triu(M, 1).T

    def energy(q, v):  # (as Pinocchio's Python bindings give it)
        return 0.5 * float(v @ mass(q) @ v) + pin.computePotentialEnergy(model, data, q)

    rhs = native.native_rhs(robot.model)
    for _ in range(5):
        q0, q1, v = _lifted(robot, rng)
        rise = energy(q1, v) - energy(q0, v)
        assert rise > 1e-6  # (the lift does raise it)
        v1, removed = rhs.neutral_velocity(q0, q1, v)
        e0 = energy(q0, v)
        assert energy(q1, v1) == pytest.approx(e0, rel=1e-12, abs=1e-12)
        s = float(v1 @ v) / float(v @ v)
        assert 0.0 < s < 1.0
        np.testing.assert_allclose(v1, s * v, rtol=0.0, atol=1e-14 * np.abs(v).max())
        kin = 0.5 * float(v @ mass(q1) @ v)
        assert removed == pytest.approx(kin * (1.0 - s * s), rel=1e-9)
        assert removed == pytest.approx(rise, rel=1e-9)
        # too slow to pay for the lift: at rest, the kinetic energy all removed
        slow = 1e-6 * v
        v2, removed2 = rhs.neutral_velocity(q0, q1, slow)
        assert not v2.any()
        assert removed2 == pytest.approx(0.5 * float(slow @ mass(q1) @ slow))
        # the move back down lowers the energy: left as it is
        v3, removed3 = rhs.neutral_velocity(q1, q0, v)
        np.testing.assert_array_equal(v3, v)
        assert removed3 == 0.0
