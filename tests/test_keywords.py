"""The argument binding checks (packbot/keywords.py) and KeywordError."""

from __future__ import annotations

import dataclasses
import inspect
import pickle

import numpy as np
import pytest

import packbot
from packbot import Failure, SimConfig, simulate
from packbot.control import Controller, GravityCompensation, JointPD, Sensor
from packbot.errors import (
    ConfigurationError,
    KeywordError,
    PackbotError,
    UnknownNameError,
    close_match,
)
from packbot.keywords import checked_arguments


def test_a_misspelt_keyword_gets_the_closest_valid_one():
    with pytest.raises(KeywordError) as info:
        SimConfig(restitutio=0.5)
    e = info.value
    assert e.keyword == "restitutio" and e.suggestion == "restitution"
    assert "did you mean 'restitution'?" in str(e) and "of SimConfig" in str(e)
    assert "valid keywords: contact_mode, restitution" in str(e)
    assert e.valid == tuple(f.name for f in dataclasses.fields(SimConfig))
    assert (e.field, e.value) == ("restitutio", 0.5)
    assert e.missing == () and e.given is None


def test_an_unknown_keyword_without_a_close_one_lists_the_valid_ones():
    with pytest.raises(KeywordError) as info:
        SimConfig(bogus=1)
    assert info.value.suggestion is None
    assert str(info.value).startswith("unknown keyword 'bogus' of SimConfig; valid keywords: ")


def test_a_missing_keyword_is_named_with_the_required_ones():
    with pytest.raises(KeywordError) as info:
        Failure(joint="shoulder")
    e = info.value
    assert e.missing == ("kind",) and e.keyword is None
    assert "missing keyword 'kind' of Failure (required: joint, kind;" in str(e)
    with pytest.raises(KeywordError, match="missing keywords 'joint', 'kind' of Failure"):
        Failure()


def test_too_many_positional_arguments():
    with pytest.raises(KeywordError, match="too many positional arguments to SimConfig: 1 given"):
        SimConfig(0.5)
    with pytest.raises(KeywordError, match=r"it takes at most 4 \(robot, q0, v0, duration\)"):
        simulate(None, None, None, None, None)
    with pytest.raises(KeywordError) as info:
        packbot.load_robot(None, None)
    assert info.value.given == 2


def test_a_value_given_twice():
    with pytest.raises(KeywordError, match="keyword 'robot' of simulate given twice"):
        simulate(None, robot=None)


def test_it_is_a_type_error_and_a_configuration_error():
    with pytest.raises(TypeError):
        SimConfig(bogus=1)
    with pytest.raises(ConfigurationError):
        SimConfig(bogus=1)
    assert issubclass(KeywordError, PackbotError) and issubclass(KeywordError, ValueError)
    try:
        JointPD(kpp=1.0)
    except TypeError as e:  # what code written for Python's own error catches
        assert isinstance(e, KeywordError) and e.suggestion == "kp"


def test_a_type_error_of_the_body_passes_unchanged():
    @checked_arguments
    def f(x: int, *, y: int = 0) -> int:
        return x + "a"  # type: ignore[operator, return-value]

    with pytest.raises(TypeError) as info:
        f(1, y=2)
    assert not isinstance(info.value, KeywordError)
    assert "unsupported operand" in str(info.value)
    with pytest.raises(KeywordError, match="unknown keyword 'yy' of f; did you mean 'y'"):
        f(1, yy=2)


def test_valid_calls_are_unaffected():
    c = SimConfig(restitution=0.5, mu=0.3)
    assert (c.restitution, c.mu) == (0.5, 0.3)
    assert Failure(joint="elbow1", kind="loose", t=0.5).t == 0.5
    ctrl = JointPD(kp=2.0, dt=2e-3)
    assert ctrl.dt == 2e-3
    assert GravityCompensation().dt == 1e-3


def test_a_dataclass_keeps_its_repr_eq_fields_and_signature():
    a, b = SimConfig(restitution=0.5), SimConfig(restitution=0.5)
    assert a == b and repr(a).startswith("SimConfig(contact_mode='normal', restitution=0.5")
    assert [f.name for f in dataclasses.fields(Failure)][:2] == ["joint", "kind"]
    assert list(inspect.signature(SimConfig).parameters)[:2] == ["contact_mode", "restitution"]
    assert SimConfig.__init__.__wrapped__.__qualname__ == "SimConfig.__init__"  # type: ignore[attr-defined]
    assert dataclasses.replace(a, mu=0.2).mu == 0.2
    with pytest.raises(KeywordError, match="unknown keyword 'muu' of SimConfig"):
        dataclasses.replace(a, muu=0.2)
    assert simulate.__name__ == "simulate" and "Simulate" in (simulate.__doc__ or "")


def test_pickling_is_unchanged():
    for obj in (SimConfig(restitution=0.3), Failure(joint="elbow1", kind="weak"), JointPD()):
        back = pickle.loads(pickle.dumps(obj))
        assert type(back) is type(obj)
    assert pickle.loads(pickle.dumps(simulate)) is simulate
    assert pickle.loads(pickle.dumps(SimConfig)) is SimConfig


class _Mine(Controller):
    """A user's controller: its own keyword, the rest passed to Controller."""

    def __init__(self, gain: float = 1.0, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.gain = gain

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return -self.gain * v


class _Yours(_Mine):
    """Inherits _Mine's constructor."""


def test_a_user_controller_subclass_is_checked():
    with pytest.raises(KeywordError) as info:
        _Mine(dtt=1e-3)
    assert info.value.suggestion == "dt"
    assert "of Controller (from _Mine.__init__)" in str(info.value)
    with pytest.raises(KeywordError, match="too many positional arguments to _Yours"):
        _Yours(1.0, 2.0)
    ctrl = _Yours(gain=2.0, dt=2e-3, sensor=Sensor(seed=3))
    assert (ctrl.gain, ctrl.dt, ctrl.sensor.seed) == (2.0, 2e-3, 3)
    back = pickle.loads(pickle.dumps(ctrl))
    assert (back.gain, back.dt) == (2.0, 2e-3)


def test_a_built_in_controller_names_itself_not_its_base():
    with pytest.raises(KeywordError) as info:
        GravityCompensation(dtt=1e-3)  # GravityCompensation inherits its constructor
    assert "of GravityCompensation;" in str(info.value)


def test_methods_and_classmethods_name_their_class():
    robot = packbot.load_robot()
    with pytest.raises(KeywordError, match=r"unknown keyword 'bse' of Robot.q_from; did you mean"):
        robot.q_from({}, bse="drive")
    with pytest.raises(KeywordError, match="unknown keyword 'pth' of SimResult.load"):
        packbot.SimResult.load(pth="x.npz")


def test_an_unknown_name_suggests_the_closest():
    robot = packbot.load_robot()
    with pytest.raises(UnknownNameError) as info:
        robot.pose("stnd")
    assert info.value.suggestion == "stand" and "did you mean 'stand'?" in str(info.value)
    assert close_match("sitting", ["drive", "stand"]) is None
    assert close_match("Restitution", ["restitution"]) == "restitution"
    assert close_match(5, ["restitution"]) is None


def test_a_large_value_is_shortened_in_the_message():
    e = ConfigurationError("initial.q", [0.0] * 1_000_000, "8 joint angles")
    assert len(str(e)) < 300 and "list of 1,000,000 items" in str(e)
    assert len(e.value) == 1_000_000  # the attribute keeps the value
    e = ConfigurationError("q", np.zeros(10**6), "8 joint angles")
    assert "array of 1,000,000 float64 values" in str(e)
    e = ConfigurationError("name", "x" * 10**6, "a short name")
    assert len(str(e)) < 300 and "1,000,000 characters" in str(e)
    e = ConfigurationError("q", [0.1, 0.2], "8 joint angles")
    assert str(e) == "invalid q=[0.1, 0.2]: expected 8 joint angles"  # a short one unchanged
    e = UnknownNameError("joint", "w" * 100_000, ["shoulder"])
    assert len(str(e)) < 300
