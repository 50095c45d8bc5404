"""The joint_clamp -> normal hand-off (``SimConfig.handoff``) on real simulation output.

Two scenarios with a secondary intersection under the report's law:

- the gripper on a tilted ramp, turret and shoulder free, a torque pushing the turret back to
  the ramp (the ``velocity`` clamp rule clamps the turret the wrong way; see
  tests/test_simulate.py): one secondary intersection, at 0.397 s;
- the collapse from "drive" with the ``momentum`` reset and restitution 0.5 (the ``velocity``
  clamp rule): at 0.309 s link 2's elbow1 casing lands on the chassis body with the turret
  turning at +0.145 rad/s, so the turret is clamped s = +1; the reset turns it back (-0.072
  rad/s), a receding joint, so its clamp is released (a clamp never does positive work), and
  the turret keeps turning the way that closes the gap (the clamp rule read the wrong direction):
  the casing reaches the body at 0.787 s, clamped (shoulder and elbow1 engaged). With the
  hand-off, the casing is a normal-mode contact from 0.787 s; link 3's elbow2 casing lands on
  the shoulder casing meanwhile (0.832 s, a joint_clamp impact), the casing leaves the body at
  0.841 s and lands again at 0.968 s, a joint_clamp impact.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact.normal import PENETRATION_TOL

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: Normal speed [m/s] accepted as "not approaching" after an inelastic impulse.
SPEED_TOL = 1e-6
#: Energy [J] accepted as rounding in an event's energy balance.
ENERGY_TOL = 1e-9


def _ramp_env():
    ramp = packbot.Obstacle(
        name="ramp", kind="box", size=(0.6, 0.8, 0.5), xyz=(1.3, 0.0, 0.2), rpy=(-0.5, 0.0, 0.0)
    )
    return packbot.Environment().with_obstacles(ramp)


def _push_back(t, q, v):
    tau = np.zeros(8)
    tau[0] = -3.0 if t > 0.2 else 0.0
    return tau


@pytest.fixture(scope="module")
def ramp_runs(robot):
    """(flag off, flag on) for the ramp scenario, 1 s."""
    env = _ramp_env()
    locked = tuple(n for n in robot.joint_names if n not in ("turret", "shoulder"))
    v0 = np.zeros(8)
    v0[0], v0[1] = 0.15, -0.3
    out = []
    for flag in (False, True):
        cfg = packbot.SimConfig(
            contact_mode="joint_clamp",
            locked_joints=locked,
            clamp_rule="velocity",
            mu=0.0,  # frictionless: the handed-off finger slides down the ramp
            handoff=flag,
        )
        out.append(
            packbot.simulate(
                robot,
                robot.pose("stand"),
                v0,
                1.0,
                environment=env,
                controller=_push_back,
                config=cfg,
            )
        )
    return tuple(out)


def _collapse_config(handoff):
    return packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=WRIST,
        reset_rule="momentum",
        restitution=0.5,
        mu=0.5,
        handoff=handoff,
    )


@pytest.fixture(scope="module")
def collapse_runs(robot):
    """(flag off, flag on) for the collapse, momentum reset, e = 0.5, mu = 0.5, 1.2 s."""
    out = []
    for flag in (False, True):
        cfg = _collapse_config(flag)
        out.append(packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.2, config=cfg))
    return tuple(out)


def _normal_speed(robot, env, q, v, pair):
    """Normal speed [m/s] of body 2 relative to body 1 at the pair's witness points."""
    world = packbot.CollisionWorld(robot, env)
    c = world.pair_contact(q, pair)
    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)

    def point_velocity(joint, p):
        if joint == 0:
            return np.zeros(3)
        J = pin.getJointJacobian(model, data, joint, pin.LOCAL_WORLD_ALIGNED)
        return J[:3] @ v + np.cross(J[3:] @ v, p - data.oMi[joint].translation)

    rel = point_velocity(c.pair.joint2, c.p2) - point_velocity(c.pair.joint1, c.p1)
    return float(c.normal @ rel)


def _samples_at(res, t):
    """Indices of the pre- and post-event samples recorded at an event time."""
    k = np.flatnonzero(res.t == t)
    assert len(k) >= 2, f"no pre/post samples at t = {t}"
    return k[0], k[-1]


def _handed_off_intervals(res):
    """[(pieces, t_handoff, t_release or inf)] of every hand-off in a run."""
    out = []
    for h in res.events_of("handoff"):
        pieces = (h.piece1, h.piece2)
        ends = [  # the pair's own release (a clamp's names its joint: the pair stays)
            e.t
            for e in res.events_of("release")
            if (e.piece1, e.piece2) == pieces and e.t > h.t and not e.relevant_joints
        ]
        out.append((pieces, h.t, min(ends, default=np.inf)))
    return out


# ------------------------------------------------------------------ flag off / on
@pytest.mark.parametrize("scenario", ["ramp_runs", "collapse_runs"])
def test_flag_off_self_diagnoses_and_flag_on_hands_off_at_the_same_instant(scenario, request):
    off, on = request.getfixturevalue(scenario)
    first = off.events_of("secondary_intersection")[0]
    (h, *_) = on.events_of("handoff")
    assert h.t == first.t and (h.piece1, h.piece2) == (first.piece1, first.piece2)
    # identical up to then: the flag changes nothing before its first use
    key = [(e.t, e.kind, e.piece1, e.piece2, e.energy_after) for e in off.events if e.t < h.t]
    assert key == [
        (e.t, e.kind, e.piece1, e.piece2, e.energy_after) for e in on.events if e.t < h.t
    ]
    np.testing.assert_array_equal(off.q[off.t < h.t], on.q[on.t < h.t])
    assert not on.events_of("secondary_intersection")


def test_flag_off_is_the_default_law(robot, ramp_runs):
    off, _ = ramp_runs
    assert off.config.handoff is False and packbot.SimConfig().handoff is False
    kinds = [e.kind for e in off.events]
    assert kinds == ["impact", "secondary_intersection"]  # the law applied again: clamped


# ------------------------------------------------------------------ after the hand-off
@pytest.mark.parametrize("scenario", ["ramp_runs", "collapse_runs"])
def test_no_penetration_after_the_hand_off(robot, scenario, request):
    _, on = request.getfixturevalue(scenario)
    env = _ramp_env() if scenario == "ramp_runs" else None
    world = packbot.CollisionWorld(robot, env)
    t_h = on.events_of("handoff")[0].t
    after = on.q[on.t >= t_h]
    assert len(after) > 10
    dmin = min(world.all_distances(q).min() for q in after)
    assert dmin > -1.01 * PENETRATION_TOL, dmin  # the normal mode's re-patch threshold
    assert on.diagnostics.min_distance > -1.01 * PENETRATION_TOL


@pytest.mark.parametrize("scenario", ["ramp_runs", "collapse_runs"])
def test_no_event_adds_energy(scenario, request):
    _, on = request.getfixturevalue(scenario)
    assert on.events_of("handoff")
    for ev in on.events:
        assert ev.energy_after <= ev.energy_before + ENERGY_TOL, ev


def test_inelastic_hand_off_impulse_leaves_no_approach(robot, ramp_runs):
    _, on = ramp_runs
    env = _ramp_env()
    world = packbot.CollisionWorld(robot, env)
    h = on.events_of("handoff")[0]
    assert on.config.restitution == 0.0
    (pair,) = world.pair_index(h.link1, h.link2, h.piece1, h.piece2)
    k0, k1 = _samples_at(on, h.t)
    np.testing.assert_array_equal(on.v[k1], h.v_after)
    before = _normal_speed(robot, env, on.q[k0], on.v[k0], pair)
    after = _normal_speed(robot, env, on.q[k1], on.v[k1], pair)
    assert before < -1e-3  # it was penetrating, clamped
    assert after >= -SPEED_TOL, after
    assert abs(after) < 1e-3 * abs(before)  # stopped along the normal, not bounced (e = 0)


def test_handed_off_contact_slides_then_is_released_to_the_report_law(ramp_runs):
    """The finger slides down the ramp as a normal contact, leaves it, and the next impact
    (the floor) is a joint_clamp impact again."""
    off, on = ramp_runs
    ((_, t_h, t_rel),) = _handed_off_intervals(on)
    assert np.isfinite(t_rel)
    rel = next(e for e in on.events_of("release") if e.t == t_rel)
    assert rel.distance == pytest.approx(on.config.proximity_tolerance, abs=1e-6)
    # while handed off the arm moved (the report's law held it clamped in place)
    turret = on.joint("turret")
    during = (on.t > t_h) & (on.t < t_rel)
    assert np.ptp(on.q[during, turret]) > 0.05
    assert np.ptp(off.q[off.t > t_h, turret]) < 1e-6
    later = [e for e in on.events_of("impact") if e.t > t_rel]
    assert later, "no impact after the release"
    nxt = later[0]
    assert nxt.distance == pytest.approx(on.config.contact_tolerance, abs=1e-9)
    assert nxt.relevant_joints  # the report's law: relevant joints reset and clamped


def test_other_contacts_keep_their_clamps_as_rows(robot, collapse_runs):
    """A joint_clamp impact while a pair is handed off: its clamped joints never move toward
    its contact until that contact is released (the clamp rows of the mixed problem)."""
    _, on = collapse_runs
    intervals = _handed_off_intervals(on)
    impacts = [
        e
        for e in on.events_of("impact")
        if np.isfinite(e.distance)
        and any(t0 < e.t < t1 and p != (e.piece1, e.piece2) for p, t0, t1 in intervals)
    ]
    assert impacts, "no joint_clamp impact while a pair was handed off"
    checked = 0
    for ev in impacts:
        ends = [
            e.t
            for e in on.events
            if (e.piece1, e.piece2) == (ev.piece1, ev.piece2)
            and e.t > ev.t
            and e.kind in ("release", "handoff")
        ]
        t_end = min(ends, default=on.t[-1])
        window = (on.t > ev.t) & (on.t < t_end)
        for name in ev.relevant_joints:
            j = on.joint(name)
            s = np.sign(ev.v_before[j])
            if s == 0.0:
                continue
            assert np.all(s * on.v[window, j] <= 1e-9), (name, (s * on.v[window, j]).max())
            checked += int(window.sum())
    assert checked > 0


# ------------------------------------------------------------------ validation
def test_validation_names_the_field():
    with pytest.raises(packbot.errors.ConfigurationError, match="handoff") as exc:
        packbot.SimConfig(contact_mode="normal", handoff=True).validate()
    assert exc.value.field == "handoff"
    with pytest.raises(packbot.errors.ConfigurationError) as exc:
        packbot.SimConfig(contact_mode="none", handoff=True).validate()
    assert exc.value.field == "handoff"
    with pytest.raises(packbot.errors.ConfigurationError) as exc:
        packbot.SimConfig(handoff="yes").validate()  # type: ignore[arg-type]
    assert exc.value.field == "handoff"
    with pytest.raises(
        packbot.errors.ConfigurationError, match="contact_mode='joint_clamp'"
    ) as exc:
        packbot.SimConfig(handoff=True)  # the default mode is "normal": say which to set
    assert exc.value.field == "handoff"
    packbot.SimConfig(contact_mode="joint_clamp", handoff=True).validate()  # fine
    # joint friction and brakes too (tests/test_handoff_holds.py)
    packbot.SimConfig(contact_mode="joint_clamp", handoff=True, joint_friction=True).validate()


def test_released_pair_comes_back_under_the_report_law(robot, collapse_runs):
    """The collapse: the elbow1 casing, handed off at 0.787 s, leaves the chassis body at
    0.841 s; its next event is a joint_clamp impact (reset, clamps) at 0.968 s."""
    _, res = collapse_runs
    cfg = res.config
    returned = 0
    for pieces, _, t_rel in _handed_off_intervals(res):
        if not np.isfinite(t_rel):
            continue
        nxt = [e for e in res.events if (e.piece1, e.piece2) == pieces and e.t > t_rel]
        if not nxt:
            continue
        first = nxt[0]
        assert first.kind == "impact", first
        assert first.distance == pytest.approx(cfg.contact_tolerance, abs=1e-9)
        assert first.relevant_joints
        assert first.energy_after <= first.energy_before + ENERGY_TOL
        returned += 1
    assert returned, "no handed-off pair came back"
    assert res.diagnostics.min_distance > -1.01 * PENETRATION_TOL


def test_clamp_rows_never_do_positive_work(robot):
    """A clamp never does positive work, as a row of the hand-off problem too: the collapse
    with the ``jacobian`` rule, e = 0.5, mu = 0.5, 3 s, a pair handed off from 0.971 s. An
    engaged clamp row on a joint moving away from its contact is released (a ``release`` naming
    the joint). Held as a locked row, elbow1 kept +1.21 rad/s for 0.43 s from 2.003 s (+1.86 J)
    and the run gained up to +8.0 J between two events; what is left is the normal mode's
    re-patching of the sliding handed-off pair (a few mJ)."""
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=WRIST,
        reset_rule="momentum",
        restitution=0.5,
        mu=0.5,
        clamp_rule="jacobian",
        handoff=True,
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 3.0, config=cfg)
    assert res.events_of("handoff")
    assert [e for e in res.events_of("release") if e.relevant_joints and e.piece1]
    work, prev, t_prev = [], res.energy[0], 0.0
    for e in res.events:
        if e.t > t_prev:
            work.append(e.energy_before - prev)
        prev, t_prev = e.energy_after, e.t
    assert max(work) < 0.01, max(work)
