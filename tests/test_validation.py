"""Bad input gets a clean PackbotError at construction (or in simulate), naming the field.

One test per example of issue 15, then a property-based test (hypothesis) that throws random
wrong types and values at every public constructor and at ``simulate``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import packbot
from packbot import ConfigurationError, PackbotError, UnknownNameError
from packbot.config import SimConfig
from packbot.control import (
    CartesianPD,
    ComputedTorque,
    Controller,
    GravityCompensation,
    JointPD,
    JointTrajectory,
    ModelBasedController,
    MomentumObserver,
    QuinticSegment,
    ReconfigurableController,
    Sensor,
)
from packbot.environment import FLOOR, Environment, Obstacle
from packbot.failures import Failure
from packbot.payload import Payload
from packbot.scenario import load_scenario, scenario_from_dict
from packbot.validation import (
    MAX_SAMPLES,
    MAX_STEPS,
    finite_number,
    is_number,
    joint_names,
    real_array,
)

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
ALL_JOINTS = (
    "turret",
    "shoulder",
    "elbow1",
    "elbow2",
    "camera_tilt",
    "camera_pan",
    "gripper_roll",
    "gripper_jaw",
)


class Hold(Controller):
    """A controller commanding zero torque."""

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros_like(q)


def _raises(match: str) -> Any:
    return pytest.raises(ConfigurationError, match=match)


# ---------------------------------------------------------------------------- the helpers
def test_numbers_accept_ints_and_numpy_scalars_and_refuse_bools():
    assert finite_number("x", 3) == 3.0 and isinstance(finite_number("x", 3), float)
    assert finite_number("x", np.float64(0.5)) == 0.5
    assert finite_number("x", np.int64(2)) == 2.0
    assert finite_number("x", np.float32(0.25)) == 0.25
    for bad in (True, np.bool_(False), "1", None, 1j, math.nan, math.inf, [1.0], 10**400):
        with pytest.raises(ConfigurationError) as exc:
            finite_number("x", bad)
        assert exc.value.field == "x"


def test_a_string_is_not_a_list_of_joints():
    with _raises(r"locked_joints='elbow1'.*tuple of joint names.*\('elbow1',\)"):
        joint_names("locked_joints", "elbow1")
    assert joint_names("j", ["a", "b"]) == ("a", "b")
    with pytest.raises(UnknownNameError, match="unknown joint 'c'.*a, b"):
        joint_names("j", ("c",), ("a", "b"))


def test_real_array_refuses_bools_complex_and_strings():
    assert real_array("v", [1, 2.5, np.float64(3)]).tolist() == [1.0, 2.5, 3.0]
    for bad in ([True, 1.0], [1j, 0.0], ["a", "b"], np.array([1 + 0j]), [[1.0], [1.0, 2.0]]):
        with _raises(r"invalid v="):
            real_array("v", bad)


# ---------------------------------------------------------------------------- machine limits
def test_tiny_sample_dt_is_refused_at_construction():
    with _raises(r"sample_dt=1e-09.*1e-06 \[s\]"):
        SimConfig(sample_dt=1e-9)


def test_too_many_samples_are_refused_before_the_run(robot):
    cfg = SimConfig(sample_dt=1e-5, locked_joints=WRIST)
    duration = 1.5 * MAX_SAMPLES * 1e-5
    with _raises(rf"sample_dt=1e-05.*duration / {MAX_SAMPLES:,}.*samples per run"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), duration, config=cfg)


def test_tiny_controller_dt_is_refused(robot):
    with _raises(r"controller.dt=1e-09.*1e-06"):
        JointPD(dt=1e-9)
    ctrl = Hold(dt=1e-5)
    with _raises(rf"controller.dt=1e-05.*at most {MAX_STEPS:,} control ticks"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 20.0, controller=ctrl)
    ctrl.dt = 1e-12  # changed after construction: simulate checks it again
    with _raises(r"controller.dt=1e-12"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.01, controller=ctrl)


def test_tiny_max_step_names_max_step_not_h_min(robot):
    with pytest.raises(ConfigurationError) as exc:
        SimConfig(max_step=1e-12)
    assert exc.value.field == "max_step" and "h_min" in exc.value.expected
    assert str(exc.value).startswith("invalid max_step=1e-12")
    cfg = SimConfig(max_step=1e-8)
    with _raises(rf"max_step=1e-08.*{MAX_STEPS:,} steps"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 1.0, config=cfg)


def test_max_events_and_motor_lag_are_bounded():
    with _raises("max_events=10000000"):
        SimConfig(max_events=10_000_000)
    with _raises("max_events=2.0"):
        SimConfig(max_events=2.0)  # type: ignore[arg-type]
    assert SimConfig(max_events=np.int64(5)).max_events == 5
    with _raises(r"motor_lag=1e-09.*1e-05"):
        SimConfig(motor_lag=1e-9)
    assert SimConfig(motor_lag=0).motor_lag == 0.0


# ---------------------------------------------------------------------------- defaults
def test_the_default_is_the_contact_normal_mode_with_friction():
    cfg = SimConfig()
    assert (cfg.contact_mode, cfg.mu) == ("normal", 0.5)
    assert (cfg.reset_rule, cfg.clamp_rule, cfg.handoff) == ("zero", "velocity", False)


@pytest.mark.parametrize(
    ("fields", "warned"),
    [
        ({}, False),  # the default: mu = 0.5
        ({"mu": 0.0}, True),  # frictionless contact-normal mode: it may never rest
        ({"contact_mode": "joint_clamp"}, False),  # the report's law has no friction
        ({"contact_mode": "joint_clamp", "mu": 0.0}, False),  # (warned of mu instead: below)
        ({"contact_mode": "none", "mu": 0.0}, False),
    ],
)
def test_simulate_warns_of_a_frictionless_contact_normal_mode(robot, caplog, fields, warned):
    cfg = SimConfig(locked_joints=WRIST, **fields)
    with caplog.at_level("WARNING", logger="packbot.integrator"):
        packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.01, config=cfg)
    assert ("the default is 0.5" in caplog.text) == warned
    if warned:
        assert "mu = 0" in caplog.text


@pytest.mark.parametrize(
    ("fields", "warned"),
    [
        ({"contact_mode": "joint_clamp"}, False),  # the default mu: nothing set
        ({"contact_mode": "joint_clamp", "mu": 0.0}, True),
        ({"contact_mode": "joint_clamp", "mu": 0.9}, True),
        ({"mu": 0.9}, False),  # the contact-normal mode uses it
        ({"contact_mode": "none", "mu": 0.9}, False),  # no contact law at all: nothing to say
    ],
)
def test_simulate_warns_of_mu_set_under_the_joint_clamp_law(robot, caplog, fields, warned):
    """A non-default mu under joint_clamp does nothing: the run says so (logging.warning)."""
    cfg = SimConfig(locked_joints=WRIST, **fields)
    with caplog.at_level("WARNING", logger="packbot.integrator"):
        packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.01, config=cfg)
    said = [r for r in caplog.records if "has no friction" in r.getMessage()]
    assert bool(said) == warned
    if warned:
        assert said[0].levelname == "WARNING"
        assert f"mu = {cfg.mu:g}" in said[0].getMessage()


# ---------------------------------------------------------------------------- final sample
def test_final_state_is_a_sample_when_sample_dt_exceeds_the_duration(robot):
    """sample_dt = 100 s over a 0.3 s collapse ended at the last event (0.17 s): now at 0.3 s."""
    q0 = load_scenario("collapse").initial_state(robot)[0]
    cfg = SimConfig(contact_mode="joint_clamp", locked_joints=WRIST, sample_dt=100.0)
    res = packbot.simulate(robot, q0, np.zeros(8), 0.3, config=cfg)
    fine = packbot.simulate(
        robot, q0, np.zeros(8), 0.3, config=dataclasses.replace(cfg, sample_dt=0.01)
    )
    assert res.events, "the collapse hits something before 0.3 s"
    assert res.t[-1] == 0.3
    np.testing.assert_allclose(res.q[-1], fine.q[-1], atol=1e-9)
    np.testing.assert_allclose(res.v[-1], fine.v[-1], atol=1e-9)


def test_final_state_is_a_sample_when_sample_dt_does_not_divide_the_duration(robot):
    cfg = SimConfig(locked_joints=WRIST, sample_dt=0.3, contact_mode="none", joint_limits=False)
    res = packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 1.0, config=cfg)
    assert res.t.tolist() == pytest.approx([0.0, 0.3, 0.6, 0.9, 1.0], abs=1e-12)


def test_a_duration_that_is_a_multiple_of_sample_dt_gets_no_extra_sample(robot):
    cfg = SimConfig(locked_joints=WRIST, sample_dt=0.1, contact_mode="none", joint_limits=False)
    res = packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.3, config=cfg)
    assert len(res.t) == 4 and res.t[-1] == pytest.approx(0.3, abs=1e-12)


# ---------------------------------------------------------------------------- SimConfig types
@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"restitution": "0.5"}, r"restitution='0.5'.*\[0, 1\]"),
        ({"restitution": None}, r"restitution=None.*\[0, 1\]"),
        ({"gravity": None}, r"gravity=None.*3 finite numbers"),
        ({"gravity": 9.81}, r"gravity=9.81.*3 finite numbers"),
        ({"gravity": (0.0, 0.0, -981.0)}, r"gravity.*within \+/-100"),
        ({"locked_joints": None}, r"locked_joints=None.*tuple of joint names"),
        ({"locked_joints": "camera_tilt"}, r"not a string: write \('camera_tilt',\)"),
        ({"locked_joints": ("elbow1", "elbow1")}, r"'elbow1' is given twice"),
        ({"locked_joints": ("elbow1", 3)}, r"locked_joints\[1\]=3"),
        ({"rtol": True}, r"rtol=True"),
        ({"rtol": 1000}, r"rtol=1000.*\[1e-13, 0.1\]"),
        ({"rtol": 1j}, r"rtol=1j"),
        ({"relevant_threshold": 2}, r"relevant_threshold=2.*\[0, 1\)"),
        ({"joint_limits": 1}, r"joint_limits=1.*true or false"),
        ({"contact_mode": None}, r"contact_mode=None.*'joint_clamp'"),
        ({"margin": 10.0}, r"margin=10.0"),
        ({"mu": 1e6}, r"mu=1000000.0.*\[0, 10\]"),
    ],
)
def test_simconfig_type_holes_are_closed(fields, match):
    with _raises(match):
        SimConfig(**fields)


def test_simconfig_accepts_numpy_scalars_and_ints_and_normalises():
    cfg = SimConfig(
        rtol=np.float64(1e-5),
        sample_dt=1,
        gravity=[0, np.float32(0.0), -9],
        locked_joints=["camera_tilt"],
        joint_limits=np.bool_(True),
    )
    assert cfg.rtol == 1e-5 and type(cfg.rtol) is float
    assert cfg.sample_dt == 1.0 and type(cfg.sample_dt) is float
    assert cfg.gravity == (0.0, 0.0, -9.0)
    assert cfg.locked_joints == ("camera_tilt",)
    assert cfg.joint_limits is True


def test_a_config_changed_after_construction_is_checked_by_simulate(robot):
    cfg = SimConfig(locked_joints=WRIST)
    cfg.restitution = 2.0
    with _raises(r"restitution=2.0"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.01, config=cfg)


def test_locking_every_joint_is_refused(robot):
    cfg = SimConfig(locked_joints=ALL_JOINTS)
    with _raises(r"locked_joints=.*at least one joint left free"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.1, config=cfg)
    cfg = SimConfig(locked_joints=ALL_JOINTS[1:])
    with _raises(r"at least one joint left free \(locked_joints and frozen failures"):
        packbot.simulate(
            robot,
            robot.pose("stand"),
            np.zeros(8),
            0.1,
            config=cfg,
            failures=[Failure(joint="turret", kind="frozen", t=0.05)],
        )


def test_relevant_threshold_must_leave_a_relevant_joint(robot):
    """With n free joints the largest |J_n,i| is at least ||J_n|| / sqrt(n)."""
    cfg = SimConfig(relevant_threshold=0.4)  # < 1, but >= 1/sqrt(8) = 0.354
    with _raises(r"relevant_threshold=0.4.*1/sqrt\(8\) = 0.3536"):
        packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.01, config=cfg)
    cfg = SimConfig(relevant_threshold=0.4, locked_joints=WRIST)  # 1/sqrt(4) = 0.5
    res = packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.01, config=cfg)
    assert res.t[-1] == pytest.approx(0.01)


# ---------------------------------------------------------------------------- simulate args
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"q0": ["a"] * 8}, r"q0=\['a'.*shape \(8,\)"),
        ({"q0": np.zeros(8) + 0j}, r"q0=.*shape \(8,\)"),
        ({"q0": [True] * 8}, r"q0=.*shape \(8,\)"),
        ({"v0": None}, r"v0=None"),
        ({"duration": True}, r"duration=True.*positive time"),
        ({"duration": "1"}, r"duration='1'"),
        ({"robot": "packbot"}, r"robot='packbot'.*packbot.Robot"),
        ({"config": {"rtol": 1e-6}}, r"config=.*packbot.SimConfig"),
        ({"failures": Failure(joint="elbow1", kind="loose")}, r"failures=.*list of"),
        ({"failures": "elbow1"}, r"failures='elbow1'"),
        ({"failures": [{"joint": "elbow1"}]}, r"failures=.*packbot.Failure"),
        ({"payload": {"mass": 1.0}}, r"payload=.*packbot.Payload"),
        ({"environment": [FLOOR]}, r"environment=.*packbot.Environment"),
        ({"controller": "pd"}, r"controller='pd'"),
        ({"controller": JointPD}, r"controller=.*Controller or a function"),
        ({"progress": 3}, r"progress=3"),
        ({"inform_controller": "yes"}, r"inform_controller='yes'.*true or false"),
    ],
)
def test_simulate_checks_its_arguments(robot, kwargs, match):
    args: dict[str, Any] = {
        "robot": robot,
        "q0": robot.pose("stand"),
        "v0": np.zeros(8),
        "duration": 0.01,
    }
    args.update(kwargs)
    with _raises(match):
        packbot.simulate(**args)


def test_simulate_accepts_a_tuple_of_failures_and_a_known_payload_frame(robot):
    cfg = SimConfig(locked_joints=WRIST)
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        0.02,
        config=cfg,
        failures=(Failure(joint="elbow1", kind="loose"),),
        payload=Payload(mass=np.float64(0.5)),
    )
    assert len(res.failures) == 1
    with pytest.raises(UnknownNameError, match="unknown frame 'hand'"):
        packbot.simulate(
            robot,
            robot.pose("stand"),
            np.zeros(8),
            0.02,
            config=cfg,
            payload=Payload(mass=0.5, frame="hand", t_pick=1.0),  # checked before the pick
        )


# ---------------------------------------------------------------------------- other classes
@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Failure(joint="elbow1", kind="melted"), r"failure.kind='melted'"),
        (lambda: Failure(joint=None, kind="loose"), r"failure.joint=None"),
        (lambda: Failure(joint="elbow1", kind="loose", t=True), r"failure.t=True"),
        (lambda: Failure(joint="elbow1", kind="brake", threshold=0.0), r"failure.threshold=0.0"),
        (lambda: Payload(mass="1"), r"payload.mass='1'"),
        (lambda: Payload(mass=1.0, com=(0.0, 0.0)), r"payload.com"),
        (lambda: Payload(mass=1.0, inertia=(1.0, 1.0, 3.0, 0, 0, 0)), r"each principal moment"),
        (lambda: Payload(mass=1.0, t_drop=np.nan), r"payload.t_drop=nan"),
        (lambda: Obstacle(name="b", kind="box", size=(1, 1, "1")), r"obstacle 'b': size"),
        (lambda: Obstacle(name="b", kind="box", size=(1, 1, 1), xyz=(1e9, 0, 0)), r"xyz"),
        (lambda: Obstacle(name=3, kind="box"), r"obstacle.name=3"),
        (lambda: Obstacle(name="h", kind="halfspace", points=[[0, 0, 0]]), r"only a 'convex'"),
        (lambda: Environment(obstacles=FLOOR), r"environment.obstacles=.*tuple of"),
        (lambda: Environment(obstacles=(FLOOR, FLOOR)), r"obstacle.name='floor'.*twice"),
        (lambda: Environment(obstacles=("floor",)), r"environment.obstacles\[0\]='floor'"),
        (lambda: Sensor(seed=-1), r"sensor.seed=-1"),
        (lambda: Sensor(noise_q=True), r"sensor.noise_q=True"),
        (lambda: JointPD(omega=5000.0), r"controller.omega=5000.0.*Nyquist"),
        (lambda: JointPD(target=["a"]), r"controller.target"),
        (lambda: JointPD(kp={"elbow1": -1.0}), r"controller.kp.elbow1=-1.0"),
        (lambda: JointPD(gravity=(0, 0, None)), r"controller.gravity"),
        (lambda: CartesianPD(target=(1.0, 2.0)), r"controller.target"),
        (lambda: CartesianPD(target="high", orientation=np.eye(3) * 2), r"orientation"),
        (lambda: CartesianPD(target="high", pinv_damping=1e300), r"pinv_damping"),
        (lambda: ComputedTorque(trajectory="stand"), r"controller.trajectory"),
        (lambda: ReconfigurableController(target="high", observer_gain=5000.0), r"2 / dt"),
        (lambda: ReconfigurableController(target="high", ik_seeds=10**9), r"ik_seeds"),
        (lambda: ReconfigurableController(target="high", environment=[FLOOR]), r"environment"),
        (lambda: QuinticSegment(q0=["a"], q1=[0.0]), r"trajectory.q0"),
        (lambda: JointTrajectory([[0.0], ["x"]], [0.0, 1.0]), r"trajectory.waypoints"),
        (lambda: JointTrajectory([[0.0], [1.0]], [0.0, True]), r"trajectory.times"),
    ],
)
def test_constructors_refuse_bad_values(make, match):
    with _raises(match):
        make()


def test_a_scenario_file_names_the_path_of_a_value_refused_at_construction():
    d = {"duration": 1.0, "config": {"sample_dt": 1e-9}}
    with _raises(r"config.sample_dt=1e-09"):
        scenario_from_dict(d, name="bad")
    d = {"duration": 1.0, "failures": [{"joint": "elbow1", "kind": "loose", "t": -1.0}]}
    with _raises(r"failures\[0\].t=-1.0"):
        scenario_from_dict(d, name="bad")
    box = {"name": "floor", "kind": "box", "size": [1, 1, 1], "xyz": [3, 0, 1]}
    d = {"duration": 1.0, "environment": {"obstacles": [box]}}
    with _raises(r"environment.obstacles\[0\].name='floor'"):
        scenario_from_dict(d, name="bad")


# ---------------------------------------------------------------------------- property test
_WRONG_SHAPES = [(0,), (2,), (3, 3), (9,), (8, 1)]
JUNK = st.one_of(
    st.none(),
    st.text(max_size=4),
    st.booleans(),
    st.complex_numbers(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.nan, math.inf, -math.inf, -1.0, -1e300, 1e300, 0, 0.0, 10**400, 1e-300]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**20), max_value=10**20),
    st.floats(allow_nan=False, allow_infinity=False).map(np.float64),
    st.integers(min_value=-5, max_value=5).map(np.int64),
    st.lists(st.floats(), max_size=4),
    st.lists(st.text(max_size=2), min_size=1, max_size=3),
    st.dictionaries(st.text(max_size=3), st.floats(), max_size=2),
    st.sampled_from(_WRONG_SHAPES).map(np.ones),
    st.sampled_from(_WRONG_SHAPES).map(lambda s: np.full(s, np.nan)),
    st.just(np.zeros(3, dtype=complex)),
    st.just(np.ones(8, dtype=bool)),
)
#: Examples per property test (a few seconds in all); raise it to search harder, e.g.
#: PACKBOT_HYPOTHESIS_EXAMPLES=20000 (about two minutes).
MAX_EXAMPLES = int(os.environ.get("PACKBOT_HYPOTHESIS_EXAMPLES", "150"))
SETTINGS = settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


def _sane(value: Any) -> None:
    """An accepted value is a plain, finite value (floats finite, tuples of them)."""
    if isinstance(value, float):
        assert math.isfinite(value)
    elif isinstance(value, tuple):
        for x in value:
            _sane(x)
    elif isinstance(value, np.ndarray):
        assert value.dtype == float and np.all(np.isfinite(value))
    else:
        assert value is None or isinstance(value, (bool, int, str)), value


def _accepted_or_packbot_error(make: Callable[[], Any]) -> Any:
    """Call make(); a PackbotError is fine, any other exception fails the test."""
    try:
        out = make()
    except PackbotError as exc:
        event(f"refused: {type(exc).__name__}")
        return None
    event("accepted")
    return out


SIMCONFIG_FIELDS = [f.name for f in dataclasses.fields(SimConfig)]


@SETTINGS
@given(field=st.sampled_from(SIMCONFIG_FIELDS), value=JUNK)
def test_simconfig_fields_refuse_junk_or_keep_a_sane_value(field, value):
    cfg = _accepted_or_packbot_error(lambda: SimConfig(**{field: value}))
    if cfg is not None:
        _sane(getattr(cfg, field))
        assert type(getattr(cfg, field)) is type(getattr(SimConfig(), field))  # normalised
        cfg.validate()


FAILURE_FIELDS = {"joint": "elbow1", "kind": "weak", "t": 0.1, "scale": 0.5, "torque": 1.0}
PAYLOAD_FIELDS = {"mass": 1.0, "com": (0.0, 0.0, 0.1), "inertia": (0.1,) * 3 + (0.0,) * 3}
OBSTACLE_BASES = {
    "box": {"name": "crate", "kind": "box", "size": (0.3, 0.3, 0.3), "xyz": (2.0, 0.0, 0.2)},
    "halfspace": {"name": "wall", "kind": "halfspace", "normal": (-1.0, 0.0, 0.0), "offset": -3},
    "convex": {
        "name": "rock",
        "kind": "convex",
        "points": ((0, 0, 0), (0.2, 0, 0), (0, 0.2, 0), (0, 0, 0.2)),
        "xyz": (2.0, 1.0, 0.0),
    },
}
OBSTACLE_FIELDS = ["name", "kind", "size", "xyz", "rpy", "normal", "offset", "points"]


DATACLASSES: dict[str, tuple[Callable[..., Any], list[dict[str, Any]], list[str]]] = {
    "failure": (Failure, [FAILURE_FIELDS], [*FAILURE_FIELDS, "threshold"]),
    "payload": (Payload, [PAYLOAD_FIELDS], [*PAYLOAD_FIELDS, "frame", "t_pick", "t_drop"]),
    "obstacle": (Obstacle, list(OBSTACLE_BASES.values()), OBSTACLE_FIELDS),
    "environment": (Environment, [{}], ["obstacles"]),
}


@st.composite
def _dataclass_case(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    kind = draw(st.sampled_from(sorted(DATACLASSES)))
    _, bases, fields = DATACLASSES[kind]
    base = draw(st.sampled_from(bases))
    return kind, {**base, draw(st.sampled_from(fields)): draw(JUNK)}


@SETTINGS
@given(case=_dataclass_case())
def test_failure_payload_obstacle_environment_refuse_junk(case):
    kind, kwargs = case
    cls = DATACLASSES[kind][0]
    obj = _accepted_or_packbot_error(lambda: cls(**kwargs))
    if obj is None:
        return
    if isinstance(obj, Environment):
        assert isinstance(obj.obstacles, tuple)
        assert all(isinstance(o, Obstacle) for o in obj.obstacles)
        obj.validate()
        return
    for f in dataclasses.fields(obj):
        _sane(getattr(obj, f.name))
    if isinstance(obj, Failure):
        obj.validate((*ALL_JOINTS, obj.joint))
    else:
        obj.validate()


def _trajectory() -> JointTrajectory:
    return JointTrajectory(np.zeros((2, 8)), [0.0, 1.0])


CONTROLLERS: dict[str, tuple[Callable[..., Any], dict[str, Any], list[str]]] = {
    "gravity": (GravityCompensation, {}, ["dt", "sensor", "gravity"]),
    "pd": (
        JointPD,
        {},
        ["target", "kp", "kd", "omega", "zeta", "gravity_compensation", "dt", "sensor", "gravity"],
    ),
    "computed_torque": (
        ComputedTorque,
        {"trajectory": _trajectory()},
        ["trajectory", "kp", "kd", "omega", "zeta", "dt", "gravity"],
    ),
    "cartesian": (
        CartesianPD,
        {"target": "high"},
        [
            "target",
            "frame",
            "orientation",
            "kp",
            "kd",
            "kp_rot",
            "kd_rot",
            "posture",
            "k_posture",
            "damping",
            "omega_posture",
            "pinv_damping",
            "dt",
        ],
    ),
    "reconfig": (
        ReconfigurableController,
        {"target": "high", "detect": False},
        [
            "target",
            "frame",
            "speed_fraction",
            "min_move_time",
            "omega",
            "zeta",
            "detect",
            "reconfigure",
            "observer_gain",
            "threshold",
            "persistence",
            "frozen_speed",
            "clearance",
            "environment",
            "ik_seeds",
            "seed",
            "sway_damping",
            "swing_return",
            "swing_check",
            "loose_margin",
            "dt",
        ],
    ),
    "sensor": (Sensor, {}, ["resolution", "noise_q", "noise_v", "seed"]),
    "quintic": (
        QuinticSegment,
        {"q0": np.zeros(8), "q1": np.ones(8)},
        ["q0", "q1", "t0", "duration", "v0", "v1", "a0", "a1"],
    ),
    "trajectory": (
        lambda **kw: JointTrajectory(kw["waypoints"], kw["times"], v_max=kw.get("v_max")),
        {"waypoints": np.zeros((2, 8)), "times": [0.0, 1.0]},
        ["waypoints", "times", "v_max"],
    ),
}


@st.composite
def _controller_case(draw: st.DrawFn) -> tuple[str, str, Any]:
    kind = draw(st.sampled_from(sorted(CONTROLLERS)))
    field = draw(st.sampled_from(CONTROLLERS[kind][2]))
    return kind, field, draw(JUNK)


@SETTINGS
@given(case=_controller_case())
def test_controllers_refuse_junk_at_construction_or_prepare(robot, case):
    kind, field, value = case
    cls, base, _ = CONTROLLERS[kind]
    obj = _accepted_or_packbot_error(lambda: cls(**{**base, field: value}))
    if isinstance(obj, ModelBasedController):
        _accepted_or_packbot_error(lambda: obj.prepare(robot))
        assert math.isfinite(obj.dt) and obj.dt > 0


@SETTINGS
@given(value=JUNK, which=st.sampled_from(["model", "effort", "threshold", "gain", "persistence"]))
def test_momentum_observer_refuses_junk(robot, value, which):
    kwargs: dict[str, Any] = {
        "model": robot.model,
        "effort": robot.params.effort,
        "threshold": np.ones(8),
        which: value,
    }
    _accepted_or_packbot_error(lambda: MomentumObserver(**kwargs))


def _not_slow(d: Any) -> bool:
    """Whether d is not a valid duration long enough to make the test slow."""
    return not (is_number(d) and 0.02 < d < 1e5)


_Q_ARRAYS = st.lists(st.floats(-4.0, 4.0), min_size=8, max_size=8).map(np.array)
SIM_ARGS: dict[str, Any] = {
    "robot": JUNK,
    "q0": st.one_of(JUNK, _Q_ARRAYS),
    "v0": st.one_of(JUNK, _Q_ARRAYS),
    # Junk, or durations too short to take time, or so long that a limit refuses them.
    "duration": st.one_of(JUNK.filter(_not_slow), st.floats(1e-300, 0.01), st.floats(1e5, 1e300)),
    "controller": st.one_of(JUNK, st.just(Hold), st.just(lambda t, q, v: "x")),
    "environment": st.one_of(JUNK, st.just([FLOOR]), st.just(Environment.empty())),
    "config": st.one_of(JUNK, st.just(SimConfig(sample_dt=1e-6))),
    "failures": st.one_of(
        JUNK,
        st.just([Failure(joint="elbow1", kind="loose"), Failure(joint="elbow1", kind="weak")]),
        st.just([Failure(joint="gripper_jaw", kind="loose")]),
    ),
    "payload": st.one_of(JUNK, st.just(Payload(mass=1.0, frame="nowhere"))),
    "inform_controller": JUNK,
    "progress": JUNK,
}


@SETTINGS
@given(arg=st.sampled_from(sorted(SIM_ARGS)), data=st.data())
def test_simulate_refuses_junk_arguments(robot, arg, data):
    value = data.draw(SIM_ARGS[arg], label=arg)
    args: dict[str, Any] = {
        "robot": robot,
        "q0": robot.pose("stand"),
        "v0": np.zeros(8),
        "duration": 0.01,
        "config": SimConfig(locked_joints=WRIST),
    }
    args[arg] = value
    res = _accepted_or_packbot_error(lambda: packbot.simulate(**args))
    if res is not None:
        assert res.t[-1] == pytest.approx(float(args["duration"]), abs=1e-12)
        assert np.all(np.isfinite(res.q))
