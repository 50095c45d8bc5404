"""Joint failures, the actuator model and payloads, on real simulation output."""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.failures import FAILURE_KINDS, Failure
from packbot.payload import Payload
from packbot.system import System, with_payload

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def others(robot, *keep):
    return tuple(n for n in robot.joint_names if n not in keep)


def gravity_comp(robot):
    data = robot.model.createData()

    def tau(t, q, v):
        return pin.computeGeneralizedGravity(robot.model, data, q)

    return tau


def constant(robot, **torques):
    tau0 = np.zeros(robot.nq)
    for name, value in torques.items():
        tau0[robot.params.index(name)] = value
    return lambda t, q, v: tau0


def after(res, t):
    return res.t > t + 1e-9


# ------------------------------------------------------------------ loose
def test_loose_joint_applies_no_motor_torque_whatever_the_command(robot):
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    fail = Failure(joint="elbow1", kind="loose", t=0.3)
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        1.0,
        controller=gravity_comp(robot),
        config=cfg,
        failures=[fail],
    )
    j = res.joint("elbow1")
    k = after(res, 0.3)
    assert np.abs(res.tau_cmd[k, j]).max() > 1.0  # still commanded ...
    assert np.all(res.tau[k, j] == 0.0)  # ... never applied
    before = res.t < 0.3
    np.testing.assert_allclose(res.tau[before, j], res.tau_cmd[before, j])
    assert np.ptp(res.q[k, j]) > 0.05  # the loose joint falls
    assert [e.kind for e in res.events][:1] == ["failure"] and res.events[0].t == 0.3


def test_loose_shoulder_collapses_onto_the_chassis_and_comes_to_rest(robot):
    """The other joints keep compensating gravity; joint friction (which a loose joint keeps)
    brings the collapsed arm to rest (without it the turret would spin on for ever)."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST, joint_friction=True)
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        4.0,
        controller=gravity_comp(robot),
        config=cfg,
        failures=[Failure(joint="shoulder", kind="loose", t=0.2)],
    )
    assert res.events_of("impact"), "it should hit something"
    assert res.rest_time is not None and res.rest_time < 4.0
    assert res.diagnostics.min_distance >= -cfg.contact_tolerance
    assert np.ptp(res.q[:, res.joint("shoulder")]) > 0.3


# ------------------------------------------------------------------ frozen
def test_frozen_joint_stops_with_a_momentum_conserving_impulse(robot):
    cfg = packbot.SimConfig(contact_mode="none", joint_limits=False, locked_joints=WRIST)
    v0 = np.zeros(8)
    v0[:4] = [0.3, 0.4, -0.6, 0.5]
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        v0,
        0.6,
        config=cfg,
        failures=[Failure(joint="elbow1", kind="frozen", t=0.25)],
    )
    (ev,) = res.events_of("freeze")
    j = res.joint("elbow1")
    assert ev.t == pytest.approx(0.25) and ev.v_after[j] == 0.0 and ev.v_before[j] != 0.0
    # M (v+ - v-) has a component at the frozen joint only (the joint's impulse).
    k = int(np.flatnonzero(np.isclose(res.t, 0.25, rtol=0, atol=1e-12))[-1])
    sys = System(robot, res.q[k], cfg, None)
    M = sys.mass_matrix(sys.reduce(res.q[k]))
    dp = M @ sys.reduce(ev.v_after - ev.v_before)
    others_ = [i for i in range(4) if i != j]
    assert np.abs(dp[others_]).max() < 1e-9 * np.abs(dp).max()
    assert ev.energy_after <= ev.energy_before  # a plastic impact loses energy
    # After: zero relative motion across the joint.
    after_ = after(res, 0.25)
    assert np.ptp(res.q[after_, j]) == 0.0 and np.all(res.v[after_, j] == 0.0)


def test_frozen_from_the_start_equals_the_reduced_model(robot):
    """Freezing at t = 0 (joint at rest) is the same system as locking the joint."""
    q0 = robot.pose("high")
    base = dict(contact_mode="none", joint_limits=False, rtol=1e-10, atol=1e-12)
    a = packbot.simulate(
        robot,
        q0,
        np.zeros(8),
        1.0,
        config=packbot.SimConfig(locked_joints=WRIST, **base),
        failures=[Failure(joint="elbow2", kind="frozen")],
    )
    b = packbot.simulate(
        robot,
        q0,
        np.zeros(8),
        1.0,
        config=packbot.SimConfig(locked_joints=(*WRIST, "elbow2"), **base),
    )
    fa, fb = a.t == a.t, np.isin(b.t, a.t)
    qa = a.q[np.isin(a.t, b.t[fb])][-1]
    assert np.abs(qa - b.q[-1]).max() < 1e-9
    assert np.abs(a.q[-1] - b.q[-1]).max() < 1e-9
    assert fa.all()


def test_frozen_joint_with_collisions_on_deactivates_merged_pairs(robot):
    """With elbow1 frozen, links 1 and 2 are one body: no pair between them is tested, but
    link 3 still collides with link 1 (they were not neighbours)."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=(*WRIST, "elbow1"))
    sys = System(robot, robot.pose("drive"), cfg, None)
    assert sys.world is not None
    links = {frozenset((p.link1, p.link2)) for p in sys.world.pairs}
    assert frozenset(("link1", "link2")) not in links
    assert frozenset(("link1", "link3")) in links
    res = packbot.simulate(
        robot,
        robot.pose("drive"),
        np.zeros(8),
        2.0,
        config=packbot.SimConfig(
            contact_mode="joint_clamp", locked_joints=WRIST, joint_friction=True
        ),
        failures=[Failure(joint="elbow1", kind="frozen", t=0.1)],
    )
    assert res.diagnostics.min_distance >= -1e-3
    assert res.rest_time is not None


# ------------------------------------------------------------------ weak, stuck
def test_weak_joint_saturates_at_the_scaled_limit(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="none")
    j = robot.params.index("shoulder")
    effort = robot.params.effort[j]
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.4,
        config=cfg,
        controller=constant(robot, shoulder=5 * effort),
        failures=[Failure(joint="shoulder", kind="weak", scale=0.3, t=0.2)],
    )
    before, k = res.t < 0.2, after(res, 0.2)
    np.testing.assert_allclose(res.tau[before, j], effort)  # healthy: saturated at E
    np.testing.assert_allclose(res.tau[k, j], 0.3 * effort)
    np.testing.assert_allclose(res.effort[k, j], 0.3 * effort)
    assert np.all(res.tau_cmd[:, j] == 5 * effort)


# ------------------------------------------------------------------ several failures of a joint
def test_a_degrading_motor_steps_its_effort_limit_down(robot):
    """weak 0.7 at 1 s, then weak 0.3 at 2 s (each of the nominal limit): the effort column and
    the saturated torque step 1 -> 0.7 -> 0.3 of E at the failure instants (the sample pair at
    each: before, then after), and the elbow, whose gravity torque needs about 0.38 E here,
    holds until the second step and sags after it."""
    cfg = packbot.SimConfig(locked_joints=WRIST, sample_dt=0.01)
    j = robot.params.index("elbow1")
    E = robot.params.effort[j]
    fails = [
        Failure(joint="elbow1", kind="weak", scale=0.3, t=2.0),  # any order: sorted by time
        Failure(joint="elbow1", kind="weak", scale=0.7, t=1.0),
    ]
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        3.0,
        config=cfg,
        controller=gravity_comp(robot),
        failures=fails,
    )
    t, eff = res.t, res.effort[:, j] / E
    np.testing.assert_allclose(eff[t < 1.0], 1.0, rtol=1e-12)
    np.testing.assert_allclose(eff[(t > 1.0) & (t < 2.0)], 0.7, rtol=1e-12)
    np.testing.assert_allclose(eff[t > 2.0], 0.3, rtol=1e-12)
    for t_f, (pre, post) in ((1.0, (1.0, 0.7)), (2.0, (0.7, 0.3))):
        at = np.flatnonzero(t == t_f)  # the states before and after (and the regular sample)
        assert len(at) >= 2, at
        np.testing.assert_allclose(eff[at[[0, -1]]], [pre, post], rtol=1e-12)
    assert np.all(np.abs(res.tau[:, j]) <= res.effort[:, j] * (1 + 1e-12))  # within the limit
    g = np.abs(res.tau_cmd[0, j])  # the gravity torque at the start [N*m]
    assert 0.3 * E < g < 0.7 * E
    holding = (t > 1.0) & (t < 2.0)
    np.testing.assert_allclose(res.tau[holding, j], res.tau_cmd[holding, j])  # 0.7 E suffices
    late = t > 2.0
    assert np.abs(res.tau[late, j]).max() == pytest.approx(0.3 * E, rel=1e-12)  # saturated
    sag = np.abs(res.q[-1, j] - res.q[0, j])
    assert sag > 0.05  # the elbow fell after the second step [rad]
    assert [(e.t, e.link1, e.link2) for e in res.events_of("failure")] == [
        (1.0, "elbow1", "weak"),
        (2.0, "elbow1", "weak"),
    ]
    assert [f.scale for f in res.failures] == [0.7, 0.3]


def test_a_weak_joint_that_then_freezes(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="none")
    j = robot.params.index("elbow1")
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.4,
        config=cfg,
        failures=[
            Failure(joint="elbow1", kind="weak", scale=0.5, t=0.1),
            Failure(joint="elbow1", kind="frozen", t=0.2),
        ],
    )
    assert [e.kind for e in res.events_of("failure", "freeze")] == ["failure", "failure", "freeze"]
    k = after(res, 0.2)
    assert np.all(res.v[k, j] == 0.0) and np.all(res.q[k, j] == res.q[k, j][0])


def test_a_loose_motor_stops_a_stuck_one():
    from packbot.actuators import TorquePath

    robot = packbot.load_robot()
    free = np.arange(robot.nq)
    cfg = packbot.SimConfig()
    stuck = Failure(joint="turret", kind="stuck", torque=20.0, t=0.1)
    loose = Failure(joint="turret", kind="loose", t=0.2)
    j = robot.params.index("turret")
    assert TorquePath.build(robot.params, free, cfg, [stuck]).applied(np.zeros(8))[j] == 20.0
    assert TorquePath.build(robot.params, free, cfg, [stuck, loose]).applied(np.ones(8))[j] == 0.0


@pytest.mark.parametrize(
    ("second", "field", "words"),
    [
        (dict(kind="weak", scale=0.5, t=1.0), "failures[1].t", "one failure of a joint at a time"),
        (dict(kind="weak", scale=0.8, t=2.0), "failures[1].scale", "below 0.7"),
        (dict(kind="weak", scale=0.7, t=2.0), "failures[1].scale", "does not recover"),
    ],
)
def test_a_nonsensical_weak_sequence_is_refused_naming_the_field(robot, second, field, words):
    first = Failure(joint="elbow1", kind="weak", scale=0.7, t=1.0)
    with pytest.raises(packbot.ConfigurationError) as exc:
        packbot.simulate(
            robot,
            robot.pose("high"),
            np.zeros(8),
            0.1,
            config=packbot.SimConfig(locked_joints=WRIST),
            failures=[first, Failure(joint="elbow1", **second)],
        )
    assert exc.value.field == field and words in str(exc.value)


@pytest.mark.parametrize(
    ("kinds", "ok"),
    [
        (("weak", "weak"), True),
        (("weak", "frozen"), True),
        (("weak", "loose"), True),
        (("loose", "frozen"), True),
        (("loose", "brake"), True),
        (("stuck", "loose"), True),
        (("brake", "frozen"), True),
        (("brake", "weak"), True),
        (("frozen", "weak"), False),  # frozen for good
        (("frozen", "loose"), False),
        (("loose", "weak"), False),  # the motor is cut
        (("loose", "stuck"), False),
        (("stuck", "stuck"), False),  # a runaway runs away once
        (("brake", "brake"), False),  # a brake stays on: no release
    ],
)
def test_which_failure_may_follow_which(kinds, ok):
    from packbot.failures import FOLLOWERS, check_sequence

    seq = [
        Failure(joint="elbow2", kind=kinds[0], scale=0.6, t=0.5),
        Failure(joint="elbow2", kind=kinds[1], scale=0.4, t=1.5),
    ]
    assert (kinds[1] in FOLLOWERS[kinds[0]]) == ok
    if ok:
        check_sequence(seq)
        check_sequence([seq[1], Failure(joint="shoulder", kind="loose"), seq[0]])  # any order
        return
    with pytest.raises(packbot.ConfigurationError) as exc:
        check_sequence(seq, field="scenario.failures")
    assert exc.value.field == "scenario.failures[1].kind"
    assert "elbow2" in str(exc.value) and kinds[0] in str(exc.value)


def test_a_stuck_joint_runs_away_once():
    from packbot.failures import check_sequence

    seq = [
        Failure(joint="turret", kind="stuck", torque=5.0, t=0.1),
        Failure(joint="turret", kind="weak", scale=0.5, t=0.2),  # a weaker runaway
        Failure(joint="turret", kind="stuck", torque=-5.0, t=0.3),
    ]
    check_sequence(seq[:2])
    with pytest.raises(packbot.ConfigurationError, match="runs away once") as exc:
        check_sequence(seq)
    assert exc.value.field == "failures[2].kind"


def test_unsaturated_command_passes_through(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="none", effort_saturation=False)
    j = robot.params.index("shoulder")
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.1,
        config=cfg,
        controller=constant(robot, shoulder=500.0),
    )
    assert np.all(res.tau[:, j] == 500.0)


def test_stuck_joint_applies_its_constant_torque_whatever_the_command(robot):
    cfg = packbot.SimConfig(locked_joints=others(robot, "turret"), contact_mode="none")
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.5,
        config=cfg,
        controller=constant(robot, turret=-3.0),
        failures=[Failure(joint="turret", kind="stuck", torque=2.0)],
    )
    j = res.joint("turret")
    assert np.all(res.tau[:, j] == 2.0)
    # A single vertical-axis joint under a constant torque: q = q0 + tau t^2 / (2 I).
    sys = System(robot, res.q[0], cfg, None)
    inertia = sys.mass_matrix(sys.reduce(res.q[0]))[0, 0]
    np.testing.assert_allclose(res.q[-1, j] - res.q[0, j], 2.0 * 0.5**2 / (2 * inertia), rtol=1e-6)


# ------------------------------------------------------------------ brake and friction
def _elbow1_gravity(robot, q):
    g = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), q)
    return abs(g[robot.params.index("elbow1")])


def test_brake_holds_below_its_threshold(robot):
    q0 = robot.pose("high")
    cfg = packbot.SimConfig(locked_joints=others(robot, "elbow1"), contact_mode="none")
    hold = _elbow1_gravity(robot, q0)
    res = packbot.simulate(
        robot,
        q0,
        np.zeros(8),
        1.0,
        config=cfg,
        failures=[Failure(joint="elbow1", kind="brake", threshold=1.2 * hold)],
    )
    j = res.joint("elbow1")
    assert np.all(res.v[:, j] == 0.0) and np.ptp(res.q[:, j]) == 0.0
    np.testing.assert_allclose(np.abs(res.tau_friction[:, j]), hold, rtol=1e-9)
    assert not res.events_of("slip")


def test_brake_slips_above_its_threshold_with_its_kinetic_torque(robot):
    q0 = robot.pose("high")
    cfg = packbot.SimConfig(locked_joints=others(robot, "elbow1"), contact_mode="none")
    hold = _elbow1_gravity(robot, q0)
    res = packbot.simulate(
        robot,
        q0,
        np.zeros(8),
        0.3,
        config=cfg,
        failures=[Failure(joint="elbow1", kind="brake", threshold=0.5 * hold)],
    )
    j = res.joint("elbow1")
    assert [e.t for e in res.events_of("slip")] == [0.0]
    k = res.t >= 0.0
    assert np.abs(res.v[k, j]).max() > 0.01
    moving = k & (np.abs(res.v[:, j]) > 1e-6)
    np.testing.assert_allclose(np.abs(res.tau_friction[moving, j]), 0.5 * hold, rtol=1e-12)
    # The brake opposes the motion.
    assert np.all(res.tau_friction[moving, j] * res.v[moving, j] < 0)


def test_coulomb_friction_holds_below_breakaway_and_slides_above(robot):
    """Turret alone (vertical axis, no gravity torque): a torque below the Coulomb level F
    leaves it still; above, it accelerates as I a = tau - F - b v (analytic)."""
    cfg = packbot.SimConfig(
        locked_joints=others(robot, "turret"),
        contact_mode="none",
        joint_friction=True,
        rtol=1e-10,
        atol=1e-12,
    )
    j = robot.params.index("turret")
    F, b = robot.params.coulomb[j], robot.params.viscous[j]
    q0 = robot.pose("high")
    still = packbot.simulate(
        robot, q0, np.zeros(8), 1.0, config=cfg, controller=constant(robot, turret=0.9 * F)
    )
    assert np.all(still.q[:, j] == q0[j])
    np.testing.assert_allclose(still.tau_friction[1:, j], -0.9 * F, rtol=1e-9)
    tau = 2.0 * F
    slide = packbot.simulate(
        robot, q0, np.zeros(8), 1.0, config=cfg, controller=constant(robot, turret=tau)
    )
    sys = System(robot, q0, cfg, None)
    inertia = sys.mass_matrix(sys.reduce(q0))[0, 0]
    t = slide.t
    v_exact = (tau - F) / b * (1 - np.exp(-b * t / inertia))
    np.testing.assert_allclose(slide.v[:, j], v_exact, atol=1e-7)
    assert slide.events_of("slip")


def test_friction_dissipates_energy(robot):
    cfg = packbot.SimConfig(
        locked_joints=WRIST, contact_mode="none", joint_limits=False, joint_friction=True
    )
    v0 = np.zeros(8)
    v0[:4] = [0.8, 0.3, -0.2, 0.4]
    res = packbot.simulate(robot, robot.pose("stow"), v0, 2.0, config=cfg)
    de = np.diff(res.energy)
    assert de.max() <= 1e-9 * abs(res.energy).max()  # never gains
    assert res.energy[-1] < res.energy[0] - 0.01
    assert res.events_of("stick") and res.events_of("slip")


def test_spinning_turret_stops_at_the_analytic_time_and_sticks(robot):
    """I v' = -F - b v from v0 > 0: stops at t* = I / b ln(1 + b v0 / F), then stays."""
    cfg = packbot.SimConfig(
        locked_joints=others(robot, "turret"), contact_mode="none", joint_friction=True
    )
    j = robot.params.index("turret")
    F, b = robot.params.coulomb[j], robot.params.viscous[j]
    v0 = np.zeros(8)
    v0[j] = 0.8
    q0 = robot.pose("high")
    res = packbot.simulate(robot, q0, v0, 1.5, config=cfg)
    sys = System(robot, q0, cfg, None)
    inertia = sys.mass_matrix(sys.reduce(q0))[0, 0]
    t_stop = inertia / b * np.log(1 + b * v0[j] / F)
    assert t_stop < 1.0
    (stick,) = res.events_of("stick")
    assert stick.t == pytest.approx(t_stop, abs=1e-7)
    assert np.all(res.v[res.t > t_stop + 1e-6, j] == 0.0)
    assert res.rest_time is not None and res.rest_time <= t_stop + 0.011


def test_friction_collapse_comes_to_rest_without_chatter(robot):
    """The report's law with joint friction: the clamps and the joints' holds settle the arm in
    a few events."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST, joint_friction=True)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 3.0, config=cfg)
    assert res.rest_time is not None
    assert len(res.events) < 30 and res.diagnostics.steps < 1000
    assert res.diagnostics.min_distance >= -cfg.contact_tolerance


# ------------------------------------------------------------------ motor lag
def test_motor_lag_is_first_order(robot):
    T = 0.05
    cfg = packbot.SimConfig(
        locked_joints=others(robot, "turret"),
        contact_mode="none",
        motor_lag=T,
        rtol=1e-10,
        atol=1e-12,
    )
    res = packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.3,
        config=cfg,
        controller=constant(robot, turret=4.0),
    )
    j = res.joint("turret")
    np.testing.assert_allclose(res.tau[:, j], 4.0 * (1 - np.exp(-res.t / T)), atol=1e-7)


# ------------------------------------------------------------------ payload
def test_payload_changes_the_gravity_torque_by_m_g_lever(robot):
    """Each pitch joint's gravity torque grows by m g times the payload's lever arm about the
    joint axis, lever = a . ((p - o) x e_z) (a the axis, o a point on it, p the payload) [m]."""
    q = robot.pose("high")
    m, g = 2.5, 9.81
    heavy = with_payload(robot, Payload(mass=m))
    g0 = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), q)
    g1 = pin.computeGeneralizedGravity(heavy.model, heavy.model.createData(), q)
    data = robot.model.createData()
    pin.computeJointJacobians(robot.model, data, q)
    pin.framesForwardKinematics(robot.model, data, q)
    p = data.oMf[robot.model.getFrameId("gripper_tool")].translation
    levers = {}
    for name in ("turret", "shoulder", "elbow1", "elbow2"):
        jid = robot.model.getJointId(name)
        iv = robot.model.joints[jid].idx_v
        J = pin.getJointJacobian(robot.model, data, jid, pin.LOCAL_WORLD_ALIGNED)
        axis, o = J[3:, iv], data.oMi[jid].translation
        levers[name] = float(axis @ np.cross(p - o, [0.0, 0.0, 1.0]))
        assert g1[iv] - g0[iv] == pytest.approx(m * g * levers[name], abs=1e-9)
    assert levers["turret"] == pytest.approx(0.0, abs=1e-12)
    assert abs(levers["shoulder"]) > 0.3  # the check is not vacuous


def test_payload_pick_keeps_generalized_momentum_and_drop_keeps_velocity(robot):
    cfg = packbot.SimConfig(contact_mode="none", joint_limits=False, locked_joints=WRIST)
    v0 = np.zeros(8)
    v0[:4] = [0.2, 0.3, -0.3, 0.4]
    pay = Payload(mass=3.0, t_pick=0.2, t_drop=0.5)
    res = packbot.simulate(robot, robot.pose("high"), v0, 0.8, config=cfg, payload=pay)
    (pick,) = res.events_of("pick")
    (drop,) = res.events_of("drop")
    k = int(np.flatnonzero(np.isclose(res.t, 0.2))[-1])
    q = res.q[k]
    light = System(robot, q, cfg, None)
    heavy = System(robot, q, cfg, None, payload=pay)
    qr = light.reduce(q)
    p_before = light.mass_matrix(qr) @ light.reduce(pick.v_before)
    p_after = heavy.mass_matrix(qr) @ heavy.reduce(pick.v_after)
    np.testing.assert_allclose(p_after, p_before, atol=1e-10)
    kinetic_before = 0.5 * p_before @ light.reduce(pick.v_before)
    kinetic_after = 0.5 * p_after @ heavy.reduce(pick.v_after)
    assert kinetic_after < kinetic_before  # picking up is a plastic impact
    np.testing.assert_array_equal(drop.v_after, drop.v_before)
    # energy is conserved between the events (free motion), with the payload's included
    held = (res.t > 0.2 + 1e-9) & (res.t < 0.5 - 1e-9)
    assert np.ptp(res.energy[held]) < 1e-5 * abs(res.energy[held]).max()


def test_payload_changes_the_collapse(robot):
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    a = packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.5, config=cfg)
    b = packbot.simulate(
        robot, robot.pose("stand"), np.zeros(8), 0.5, config=cfg, payload=Payload(mass=4.0)
    )
    assert np.abs(a.q[-1] - b.q[-1]).max() > 1e-3


# ------------------------------------------------------------------ every kind, collisions on
@pytest.mark.parametrize("mode", ["joint_clamp", "normal"])
@pytest.mark.parametrize("kind", FAILURE_KINDS)
def test_every_failure_kind_runs_with_collisions_on(robot, kind, mode):
    cfg = packbot.SimConfig(contact_mode=mode, locked_joints=WRIST, joint_friction=True)
    fail = Failure(joint="elbow2", kind=kind, t=0.15, torque=10.0, scale=0.2)
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        1.0,
        controller=gravity_comp(robot),
        config=cfg,
        failures=[fail],
    )
    assert res.failures == (fail,)
    assert res.diagnostics.min_distance >= -cfg.contact_tolerance
    assert [e.kind for e in res.events_of("failure")] == ["failure"]


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("make", "words"),
    [
        (
            lambda: dict(failures=[Failure(joint="knee", kind="loose")]),
            ["knee", "shoulder", "elbow1"],
        ),
        (
            lambda: dict(failures=[Failure(joint="elbow1", kind="melted")]),
            ["failure.kind", "frozen"],
        ),
        (
            lambda: dict(failures=[Failure(joint="elbow1", kind="weak", scale=2.0)]),
            ["failure.scale"],
        ),
        (lambda: dict(failures=[Failure(joint="elbow1", kind="loose", t=-1.0)]), ["failure.t"]),
        (
            lambda: dict(
                failures=[
                    Failure(joint="elbow1", kind="loose"),
                    Failure(joint="elbow1", kind="weak"),
                ]
            ),
            ["failures[1].t", "one failure of a joint at a time"],
        ),
        (lambda: dict(failures=[Failure(joint="gripper_jaw", kind="loose")]), ["locked_joints"]),
        (lambda: dict(payload=Payload(mass=-1.0)), ["payload.mass"]),
        (lambda: dict(payload=Payload(mass=1.0, frame="hand")), ["hand", "gripper_tool"]),
        (lambda: dict(payload=Payload(mass=1.0, t_pick=0.5, t_drop=0.2)), ["payload.t_drop"]),
    ],
)
def test_bad_failure_and_payload_input_is_named(robot, make, words):
    cfg = packbot.SimConfig(locked_joints=WRIST)
    with pytest.raises(packbot.PackbotError) as exc:  # at construction or in simulate
        packbot.simulate(robot, robot.pose("high"), np.zeros(8), 0.1, config=cfg, **make())
    for w in words:
        assert w in str(exc.value)


def test_bad_actuator_config_is_named():
    with pytest.raises(packbot.ConfigurationError, match="motor_lag"):
        packbot.SimConfig(motor_lag=-0.1).validate()
    with pytest.raises(packbot.ConfigurationError, match="joint_friction"):
        packbot.SimConfig(joint_friction="yes").validate()  # type: ignore[arg-type]
