"""The event-driven simulator on real simulation output: energy, analytic impacts, limits,
the report's collapse, the reset rules' energy behaviour, and bad input."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.optimize import brentq

import packbot
from packbot.contact import impact_reset
from packbot.result import rest_time

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def only(robot, joint):
    """Every joint but ``joint`` (to lock them)."""
    return tuple(n for n in robot.joint_names if n != joint)


@pytest.fixture(scope="module")
def collapse(robot):
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)  # the report's law
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)


# ------------------------------------------------------------------ smooth dynamics
def test_free_motion_conserves_energy(robot):
    cfg = packbot.SimConfig(contact_mode="none", joint_limits=False, rtol=1e-9, atol=1e-11)
    v0 = np.array([0.3, 0.2, -0.4, 0.5, 0.3, -0.2, 0.4, 0.1])
    res = packbot.simulate(robot, robot.pose("high"), v0, 5.0, config=cfg)
    assert res.t[-1] == pytest.approx(5.0)
    assert not res.events
    drift = np.abs(res.energy - res.energy[0]).max()
    assert drift < 1e-6 * (1.0 + abs(res.energy[0])), drift
    assert np.abs(res.v).max() > 0.1  # it did move


def test_free_motion_converges_with_tolerance(robot):
    v0 = np.array([0.3, 0.2, -0.4, 0.5, 0.3, -0.2, 0.4, 0.1])
    finals = {}
    for rtol in (1e-5, 1e-7, 1e-9, 1e-11):
        cfg = packbot.SimConfig(
            contact_mode="none", joint_limits=False, rtol=rtol, atol=rtol * 1e-2, max_step=1.0
        )
        finals[rtol] = packbot.simulate(robot, robot.pose("high"), v0, 2.0, config=cfg).q[-1]
    errors = [np.abs(finals[r] - finals[1e-11]).max() for r in (1e-5, 1e-7, 1e-9)]
    assert errors[1] < errors[0] / 10 and errors[2] < errors[1] / 10, errors
    assert errors[2] < 1e-4


# ------------------------------------------------------------------ analytic events
def test_turret_hits_its_limit_stop_at_the_analytic_time(robot):
    """A spinning turret (vertical axis: constant speed) hits its stop at (upper - q0) / v0."""
    cfg = packbot.SimConfig(contact_mode="none", locked_joints=only(robot, "turret"))
    v0 = np.zeros(8)
    v0[0] = 0.8
    res = packbot.simulate(robot, robot.pose("stand"), v0, 5.0, config=cfg)
    (hit,) = res.events_of("limit")
    upper = robot.params.upper[0]
    assert hit.t == pytest.approx(upper / 0.8, abs=1e-9)
    assert hit.link2 == "upper"
    assert hit.v_after[0] == pytest.approx(0.0, abs=1e-12)
    assert res.q[-1][0] == pytest.approx(upper, abs=1e-9)  # stays at the stop
    assert res.q[:, 0].max() <= upper + 1e-9


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_restitution_reverses_joint_speed_times_e(robot, e):
    cfg = packbot.SimConfig(contact_mode="none", locked_joints=only(robot, "turret"), restitution=e)
    v0 = np.zeros(8)
    v0[0] = 0.8
    res = packbot.simulate(robot, robot.pose("stand"), v0, 4.0, config=cfg)
    hit = res.events_of("limit")[0]
    assert hit.v_after[0] == pytest.approx(-e * hit.v_before[0], abs=1e-12)
    assert hit.energy_after <= hit.energy_before + 1e-12
    if e == 1.0:
        assert hit.energy_after == pytest.approx(hit.energy_before, rel=1e-12)


@pytest.fixture(scope="module")
def block_drop(robot):
    """The shoulder alone, falling from 'stand' onto a box in front of the robot."""
    box = packbot.Obstacle(name="block", kind="box", size=(0.6, 0.6, 0.5), xyz=(1.3, 0.0, 0.25))
    env = packbot.Environment().with_obstacles(box)
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp", locked_joints=only(robot, "shoulder"), rtol=1e-10, atol=1e-12
    )
    v0 = np.zeros(8)
    v0[1] = -0.3
    res = packbot.simulate(robot, robot.pose("stand"), v0, 2.0, environment=env, config=cfg)
    return res, env, cfg, v0


def test_falling_joint_hits_block_at_analytic_time_and_angle(robot, block_drop):
    res, env, cfg, v0 = block_drop
    impacts = res.events_of("impact")
    assert impacts, "no impact"
    hit = impacts[0]
    assert hit.link2 == "block"
    assert hit.relevant_joints == ("shoulder",)
    # the contact angle: where the pair's signed distance equals the contact tolerance
    world = packbot.CollisionWorld(robot, env)
    pairs = world.pair_index(hit.link1, "block", hit.piece1, hit.piece2)
    q_stand = robot.pose("stand")

    def q_at(theta):
        q = q_stand.copy()
        q[1] = theta
        return q

    def gap(theta):
        return world.pair_contact(q_at(theta), pairs[0]).distance - cfg.contact_tolerance

    theta_hit = brentq(gap, q_stand[1] - 0.4, q_stand[1], xtol=1e-14)  # the first crossing
    # the time: energy conservation of a one-joint pendulum, by quadrature
    model, data = robot.model, robot.model.createData()
    inertia = pin.crba(model, data, q_stand)[1, 1]  # constant about a fixed axis (armature incl.)
    potential0 = pin.computePotentialEnergy(model, data, q_stand)

    def dt_dtheta(theta):
        kinetic = (
            0.5 * inertia * v0[1] ** 2
            + potential0
            - pin.computePotentialEnergy(model, data, q_at(theta))
        )
        return 1.0 / np.sqrt(2.0 * kinetic / inertia)

    t_hit, _ = quad(dt_dtheta, theta_hit, q_stand[1], epsabs=1e-13, epsrel=1e-13)
    assert hit.t == pytest.approx(t_hit, abs=1e-6)
    k = int(np.flatnonzero(res.t == hit.t)[0])
    assert res.q[k, 1] == pytest.approx(theta_hit, abs=1e-6)
    # inelastic: the joint stops and stays clamped on the block
    assert hit.v_after[1] == pytest.approx(0.0, abs=1e-12)
    assert abs(res.v[-1, 1]) < 1e-9
    assert res.rest_time is not None


# ------------------------------------------------------------------ the report's collapse
def test_collapse_comes_to_rest_propped_on_the_shoulder_casing(robot, collapse):
    res = collapse
    assert res.rest_time is not None and res.rest_time < 4.0
    q = res.q[-1]
    link3_angle = q[1] + q[2] + q[3]  # from the forward horizontal, in the arm's plane [rad]
    assert np.pi / 2 < link3_angle < np.radians(160)  # upright, leaning back
    last = {(e.piece1, e.piece2): e.kind for e in res.events}
    assert last.get(("link3/tube", "link1/shoulder_casing")) == "impact"
    world = packbot.CollisionWorld(robot)
    (pair,) = world.pair_index("link3", "link1", "link3/tube", "link1/shoulder_casing")
    assert world.pair_contact(q, pair).distance < res.config.proximity_tolerance
    # link 1 lies on the chassis
    assert -0.3 < q[1] < 0.0


def test_collapse_never_penetrates(robot, collapse):
    res = collapse
    tol = res.config.contact_tolerance
    world = packbot.CollisionWorld(robot)
    dmin = min(world.all_distances(q).min() for q in res.q)
    assert dmin >= -tol, dmin
    assert res.diagnostics.min_distance >= -tol
    secondary = res.events_of("secondary_intersection")
    assert all(e.distance <= 0.0 for e in secondary)


def test_collapse_without_collisions_falls_through_the_chassis(robot):
    """The report's Figure 7: without collision detection the arm falls through the chassis."""
    cfg = packbot.SimConfig(contact_mode="none", locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)
    world = packbot.CollisionWorld(robot)
    assert min(world.all_distances(q).min() for q in res.q[::10]) < -0.05  # passes through
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, res.q[-1])
    tool = data.oMf[model.getFrameId("gripper_tool")].translation
    assert tool[2] < packbot.params.CH_H  # ends below the chassis top


def test_collapse_is_deterministic(robot, collapse):
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    again = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)
    np.testing.assert_array_equal(again.q, collapse.q)
    assert [e.t for e in again.events] == [e.t for e in collapse.events]


def test_samples_and_event_points(collapse):
    res = collapse
    assert np.all(np.diff(res.t) >= 0)
    grid = np.round(np.arange(0, 5.0 + 1e-9, res.config.sample_dt), 9)
    assert set(grid) <= set(np.round(res.t, 9))
    for e in res.events_of("impact"):
        k = np.flatnonzero(res.t == e.t)
        assert len(k) == 2  # pre- and post-event samples
        np.testing.assert_allclose(res.v[k[0]], e.v_before)
        np.testing.assert_allclose(res.v[k[1]], e.v_after)
    assert res.q.shape == (len(res.t), 8) and res.tau.shape == (len(res.t), 8)
    assert np.all(res.tau == 0.0)
    wrist = [res.joint(n) for n in WRIST]
    assert np.all(res.v[:, wrist] == 0.0)
    assert np.all(res.q[:, wrist] == res.q[0, wrist])


def test_overwhelmed_joint_is_self_diagnosed_and_fixed_by_the_jacobian_rule(robot):
    """The report's caveat: a joint moving *away* from the contact, overwhelmed by another.

    The gripper lands on a tilted ramp while the turret turns slowly away from it; a torque then
    pushes the turret back toward the ramp. The ``velocity`` rule clamps the turret in the wrong
    direction, the finger is driven into the ramp, and the simulator says so (a
    ``secondary_intersection``, then the law again). The ``jacobian`` rule clamps it right.
    """
    ramp = packbot.Obstacle(
        name="ramp", kind="box", size=(0.6, 0.8, 0.5), xyz=(1.3, 0.0, 0.2), rpy=(-0.5, 0.0, 0.0)
    )
    env = packbot.Environment().with_obstacles(ramp)
    locked = tuple(n for n in robot.joint_names if n not in ("turret", "shoulder"))
    v0 = np.zeros(8)
    v0[0], v0[1] = 0.15, -0.3

    def push_back(t, q, v):
        tau = np.zeros(8)
        tau[0] = -3.0 if t > 0.2 else 0.0
        return tau

    runs = {}
    for rule in ("velocity", "jacobian"):
        cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=locked, clamp_rule=rule)
        runs[rule] = packbot.simulate(
            robot, robot.pose("stand"), v0, 1.0, environment=env, controller=push_back, config=cfg
        )
    for res in runs.values():
        first = res.events[0]
        assert first.kind == "impact" and first.link2 == "ramp"
        assert "turret" in first.relevant_joints and first.v_before[0] > 0  # moving away
    secondary = runs["velocity"].events_of("secondary_intersection")
    assert secondary, "the wrong clamp went unnoticed"
    tol = runs["velocity"].config.contact_tolerance
    assert all(-tol <= e.distance <= 0.0 for e in secondary)
    assert runs["velocity"].diagnostics.min_distance >= -tol
    assert not runs["jacobian"].events_of("secondary_intersection")
    assert runs["jacobian"].diagnostics.min_distance > 0.0


# ------------------------------------------------------------------ reset rules
@pytest.mark.parametrize("clamp", ["velocity", "jacobian"])
@pytest.mark.parametrize("e", [0.0, 0.3])
def test_momentum_resets_never_add_energy(robot, clamp, e):
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=WRIST,
        reset_rule="momentum",
        clamp_rule=clamp,
        restitution=e,
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)
    impacts = res.events_of("impact", "limit", "secondary_intersection")
    assert impacts
    for ev in impacts:
        assert ev.energy_after <= ev.energy_before + 1e-9, ev


def test_zero_resets_log_their_energy_change(collapse):
    impacts = collapse.events_of("impact")
    assert impacts
    for ev in impacts:
        assert np.isfinite(ev.energy_before) and np.isfinite(ev.energy_after)
        assert ev.energy_change == pytest.approx(ev.energy_after - ev.energy_before)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    e=st.floats(0.0, 1.0),
    k=st.integers(1, 8),
)
def test_momentum_rule_never_adds_kinetic_energy(robot, seed, e, k):
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.params.lower, robot.params.upper)
    v = rng.normal(size=8)
    rel = np.sort(rng.choice(8, size=k, replace=False))
    data = robot.model.createData()
    M = pin.crba(robot.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    v1 = impact_reset(v, rel, e, "momentum", np.linalg.inv(M))
    assert 0.5 * v1 @ M @ v1 <= 0.5 * v @ M @ v + 1e-9
    np.testing.assert_allclose(v1[rel], -e * v[rel], atol=1e-9)
    others = np.setdiff1d(np.arange(8), rel)
    np.testing.assert_allclose((M @ v1)[others], (M @ v)[others], atol=1e-9)


def test_zero_rule_can_add_kinetic_energy_on_the_coupled_arm(robot):
    """The report's rule stops joints one by one, ignoring the coupling in M."""
    data = robot.model.createData()
    q = robot.pose("stand")
    M = pin.crba(robot.model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    v = np.zeros(8)
    v[2], v[3] = 1.0, -1.0  # elbow1 and elbow2 moving against each other
    rel = np.array([3])
    v1 = impact_reset(v, rel, 0.0, "zero", None)
    gained = 0.5 * v1 @ M @ v1 - 0.5 * v @ M @ v
    assert M[2, 3] > 0 and gained > 0
    v2 = impact_reset(v, rel, 0.0, "momentum", np.linalg.inv(M))
    assert 0.5 * v2 @ M @ v2 <= 0.5 * v @ M @ v


def test_rest_time_definition():
    t = np.linspace(0, 1, 11)
    v = np.zeros((11, 2))
    v[:4, 0] = 1.0
    assert rest_time(t, v, 1e-3) == pytest.approx(0.4)
    v[-1, 1] = 1.0
    assert rest_time(t, v, 1e-3) is None


# ------------------------------------------------------------------ bad input
def _q(robot):
    return robot.pose("stand")


BAD_CONFIGS = [
    ({"contact_mode": "bogus"}, "contact_mode.*'joint_clamp'"),
    ({"contact_mode": "normal", "mu": -0.1}, "mu"),
    ({"restitution": 1.5}, r"restitution=1.5.*\[0, 1\]"),
    ({"contact_tolerance": -1e-3}, "contact_tolerance.*positive"),
    ({"proximity_tolerance": 5e-4}, "proximity_tolerance.*greater than contact_tolerance"),
    ({"margin": 1e-3}, "margin.*greater than proximity_tolerance"),
    ({"rtol": 0.0}, "rtol.*positive"),
    ({"sample_dt": float("nan")}, "sample_dt"),
    ({"gravity": (0.0, -9.81)}, "gravity.*3 finite"),
    ({"clamp_rule": "torque"}, "clamp_rule.*'velocity', 'jacobian'"),
    ({"reset_rule": "half"}, "reset_rule.*'zero', 'momentum'"),
    ({"max_events": 0}, "max_events"),
]


@pytest.mark.parametrize(("fields", "message"), BAD_CONFIGS)
def test_bad_config_names_the_field(robot, fields, message):
    with pytest.raises(packbot.ConfigurationError, match=message):  # at construction
        packbot.SimConfig(**fields)


def test_unknown_locked_joint_lists_the_joints(robot):
    cfg = packbot.SimConfig(locked_joints=("wrist",))
    with pytest.raises(packbot.UnknownNameError, match="unknown joint 'wrist'.*elbow1"):
        packbot.simulate(robot, _q(robot), np.zeros(8), 1.0, config=cfg)


@pytest.mark.parametrize(
    ("q0", "v0", "duration", "message"),
    [
        (np.zeros(7), np.zeros(8), 1.0, r"q0=\(7,\).*shape \(8,\)"),
        (None, np.zeros(3), 1.0, r"v0=\(3,\).*shape \(8,\)"),
        (None, np.full(8, np.nan), 1.0, "v0.*finite"),
        (None, np.zeros(8), 0.0, "duration=0.0.*positive"),
        (None, np.zeros(8), float("inf"), "duration=inf"),
    ],
)
def test_bad_state_names_the_field(robot, q0, v0, duration, message):
    q0 = _q(robot) if q0 is None else q0
    with pytest.raises(packbot.ConfigurationError, match=message):
        packbot.simulate(robot, q0, v0, duration)


def test_q0_outside_limits_names_the_joint(robot):
    q = _q(robot)
    q[2] = 3.2
    with pytest.raises(packbot.ConfigurationError, match=r"q0.*elbow1=3.2000 not in"):
        packbot.simulate(robot, q, np.zeros(8), 1.0)


def test_initial_collision_names_pairs_and_depths(robot):
    q = robot.pose("stand")
    q[1] = -0.6  # shoulder down: link 1 into the chassis
    with pytest.raises(
        packbot.InitialCollisionError, match=r"link1/\w+ - base_link/\w+: -\d+\.\d+ mm"
    ):
        packbot.simulate(robot, q, np.zeros(8), 1.0)


def test_velocity_on_a_locked_joint_is_refused(robot):
    v = np.zeros(8)
    v[4] = 0.1
    cfg = packbot.SimConfig(locked_joints=WRIST)
    with pytest.raises(packbot.ConfigurationError, match="v0.*locked joints"):
        packbot.simulate(robot, _q(robot), v, 1.0, config=cfg)


def test_controller_that_raises_says_when(robot):
    def ctrl(t, q, v):
        if t > 0.2:
            raise RuntimeError("encoder lost")
        return np.zeros(8)

    with pytest.raises(packbot.ControllerError, match=r"t = 0\.2.*RuntimeError: encoder lost"):
        packbot.simulate(robot, _q(robot), np.zeros(8), 1.0, controller=ctrl)


def test_controller_nan_names_the_joint(robot):
    def ctrl(t, q, v):
        tau = np.zeros(8)
        if t > 0.1:
            tau[3] = np.nan
        return tau

    with pytest.raises(
        packbot.ControllerError, match="non-finite torque for joint 'elbow2'"
    ) as exc:
        packbot.simulate(robot, _q(robot), np.zeros(8), 1.0, controller=ctrl)
    assert exc.value.joint == "elbow2"
    assert exc.value.t == pytest.approx(0.1, abs=0.05)


def test_controller_wrong_shape(robot):
    with pytest.raises(packbot.ControllerError, match=r"shape \(3,\), expected \(8,\)"):
        packbot.simulate(robot, _q(robot), np.zeros(8), 1.0, controller=lambda t, q, v: np.zeros(3))


def test_controller_object_with_call(robot):
    class Hold:
        def __init__(self):
            self.calls = 0

        def __call__(self, t, q, v):
            self.calls += 1
            return pin.computeGeneralizedGravity(robot.model, robot.model.createData(), q)

    hold = Hold()
    res = packbot.simulate(robot, _q(robot), np.zeros(8), 0.5, controller=hold)
    assert hold.calls > 0
    assert np.abs(res.q[-1] - res.q[0]).max() < 1e-6  # gravity compensation holds the pose
    assert np.abs(res.tau).max() > 1.0


def test_step_size_underflow_stops_with_the_result_attached(robot):
    """A torque that blows up in finite time (at t = 0.5 s) cannot be integrated past it.

    (1 / (0.5 - t)^2: the step size shrinks geometrically into the singularity. A cube spins the
    turret so fast before it that the error control resolves the links' whirl for a minute.)
    """
    cfg = packbot.SimConfig(contact_mode="none", joint_limits=False, effort_saturation=False)

    def blowup(t, q, v):
        tau = np.zeros(8)
        tau[0] = 1.0 / (0.5 - t) ** 2 if t < 0.5 else np.inf
        return tau

    with pytest.raises(packbot.SimulationError) as exc:
        packbot.simulate(robot, _q(robot), np.zeros(8), 1.0, controller=blowup, config=cfg)
    assert exc.value.t <= 0.5
    assert exc.value.result is not None
    assert exc.value.result.t[-1] <= 0.5


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_limit_stops_never_add_energy(robot, e):
    """Limit stops use a joint-space impulse on the stopped joint whatever reset_rule says;
    with e > 0 the joint bounces off and is not clamped (an engaged lock on a receding joint
    would do work). The whole run (no friction, no contacts) never gains energy."""
    cfg = packbot.SimConfig(contact_mode="none", restitution=e, locked_joints=WRIST)
    v0 = np.array([0.5, 1.5, -2.0, 2.5, 0, 0, 0, 0])
    res = packbot.simulate(robot, robot.pose("stand"), v0, 2.0, config=cfg)
    stops = res.events_of("limit")
    assert len(stops) >= 2
    for ev in stops:
        assert ev.energy_after <= ev.energy_before + 1e-9 * abs(ev.energy_before)
    assert res.energy.max() <= res.energy[0] + 1e-5 * abs(res.energy[0])  # integration error
    if e == 1.0:  # elastic stops conserve energy
        assert abs(res.energy[-1] - res.energy[0]) < 1e-4 * abs(res.energy[0])
