"""Shared helpers of the controllers: their Pinocchio model, and parsing of targets and gains.

Targets and gains can be given the way a scenario file writes them:

- a configuration q [rad]: a list of nq numbers, a named pose (``"stand"``), or a table
  ``{joint: angle}`` (the other joints from the initial configuration);
- a per-joint gain: one number (every joint), a list of nv numbers, or a table
  ``{joint: gain}`` (the other joints keep the default).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, UnknownNameError
from packbot.validation import (
    GRAVITY_MAX,
    finite_number,
    is_number,
    name_str,
    real_array,
    vector,
)

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = [
    "DEFAULT_GRAVITY",
    "GainLike",
    "QLike",
    "check_gain_spec",
    "check_q_spec",
    "controlled_frame",
    "controller_model",
    "damping_ratio",
    "frame_spec",
    "loop_frequency",
    "resolve_gains",
    "resolve_gravity",
    "resolve_q",
    "resolve_vector3",
]

FloatArray = NDArray[np.float64]

#: Gravity the controllers assume by default [m/s^2], world frame (SimConfig's default).
DEFAULT_GRAVITY: tuple[float, float, float] = (0.0, 0.0, -9.81)

#: A configuration: a list of nq angles [rad], a pose name, or a {joint: angle} table.
QLike = str | Sequence[float] | Mapping[str, float] | FloatArray
#: A per-joint gain: a number, a list of nv numbers, or a {joint: gain} table.
GainLike = float | Sequence[float] | Mapping[str, float] | FloatArray


def frame_spec(field: str, frame: str | None) -> str | None:
    """A controller's ``frame`` argument checked: a frame name, or None (the robot's tool frame).

    Raises:
        ConfigurationError: Neither None nor a non-empty string (names ``field``).
    """
    if frame is None:
        return None
    return name_str(field, frame, "a frame name (a non-empty string), or None: the tool frame")


def controlled_frame(model: pin.Model, robot: Robot, frame: str | None) -> tuple[str, int]:
    """The frame a controller moves, by name and id in ``model``.

    ``frame``, or ``robot``'s tool frame (:attr:`packbot.Robot.tool_frame`) for None.

    Raises:
        UnknownNameError: ``frame`` is not a frame of the model (lists the frames).
    """
    name = robot.tool_frame if frame is None else frame
    if not isinstance(name, str) or not model.existFrame(name):
        raise UnknownNameError("frame", name, [f.name for f in model.frames])
    return name, int(model.getFrameId(name))


def _finite(x: object) -> bool:
    return is_number(x) and math.isfinite(float(x))  # type: ignore[arg-type]


def resolve_gravity(gravity: Any, field: str = "controller.gravity") -> FloatArray:
    """Validate a gravity vector [m/s^2] and return it as an array of shape (3,)."""
    return np.array(vector(field, gravity, 3, bound=GRAVITY_MAX, unit="m/s^2"))


def resolve_vector3(value: Any, field: str, expected: str = "3 finite numbers") -> FloatArray:
    """Validate a 3-vector and return it as an array of shape (3,)."""
    return real_array(field, value, shape=(3,), expected=expected)


#: Largest damping ratio of a controller's default gains [-] (critical damping is 1).
ZETA_MAX = 100.0


def damping_ratio(value: Any, field: str) -> float:
    """A damping ratio zeta [-], in (0, ZETA_MAX]."""
    return finite_number(field, value, low=0.0, high=ZETA_MAX, low_open=True, what="a ratio")


def loop_frequency(value: Any, field: str, dt: float) -> float:
    """A loop's natural frequency omega [rad/s]: > 0 and below the Nyquist rate pi / dt.

    A sampled loop cannot act faster than half its sampling rate: omega * dt < pi.
    """
    return finite_number(
        field,
        value,
        low=0.0,
        high=math.pi / dt,
        low_open=True,
        high_open=True,
        unit="rad/s",
        what=f"a frequency below the Nyquist rate pi / dt of the control period dt={dt:g} s",
    )


def check_q_spec(value: Any, field: str, *, optional: bool = True) -> None:
    """Check the form of a configuration before the robot is known (see :func:`resolve_q`).

    A pose name, a {joint: angle} table of finite numbers, or a list of finite angles.

    Raises:
        ConfigurationError: Any other value.
    """
    expected = "a pose name, a {joint: angle} table or a list of angles [rad]"
    if value is None and optional:
        return
    if isinstance(value, str):
        if not value:
            raise ConfigurationError(field, value, expected)
        return
    if isinstance(value, Mapping):
        for key, x in value.items():
            if not isinstance(key, str):
                raise ConfigurationError(field, value, expected + " (joint names are strings)")
            finite_number(f"{field}.{key}", x, unit="rad", what="a finite angle")
        return
    real_array(field, value, ndim=1, expected=expected)


def check_gain_spec(value: Any, field: str, *, positive: bool = False) -> None:
    """Check the form of a per-joint gain before the robot is known (see :func:`resolve_gains`).

    None, a number, a {joint: gain} table or a list of gains; each finite and >= 0 (> 0 if
    ``positive``).

    Raises:
        ConfigurationError: Any other value.
    """
    what = "a finite gain"
    if value is None:
        return
    if isinstance(value, Mapping):
        for key, x in value.items():
            if not isinstance(key, str):
                raise ConfigurationError(field, value, "a {joint: gain} table (joint names)")
            finite_number(f"{field}.{key}", x, low=0.0, low_open=positive, what=what)
        return
    if is_number(value):
        finite_number(field, value, low=0.0, low_open=positive, what=what)
        return
    expected = "a number, a {joint: gain} table or a list of finite gains " + (
        "> 0" if positive else ">= 0"
    )
    arr = real_array(field, value, ndim=1, expected=expected)
    if np.any(arr < 0) or (positive and np.any(arr == 0)):
        raise ConfigurationError(field, value, expected)


def controller_model(robot: Robot, gravity: FloatArray) -> tuple[pin.Model, pin.Data]:
    """A copy of the robot's model (armature included) with the controller's gravity.

    Args:
        robot: The full robot.
        gravity: Gravity [m/s^2], world frame.

    Returns:
        The model and a fresh data.
    """
    model = robot.model.copy()
    model.gravity.linear = np.asarray(gravity, dtype=float)
    return model, model.createData()


def resolve_q(robot: Robot, value: QLike, field: str, base: FloatArray | None = None) -> FloatArray:
    """A configuration [rad], shape (nq,), from a list, a pose name or a {joint: angle} table.

    Args:
        robot: The robot (names, poses, limits).
        value: The configuration as written.
        field: Name of the field, for error messages (``"controller.target"``).
        base: Configuration supplying the joints a table leaves out (default: zeros).

    Raises:
        ConfigurationError: Wrong length, non-finite, or outside the joint limits.
        UnknownNameError: An unknown pose or joint name.
    """
    nq = robot.nq
    if isinstance(value, str):
        if value not in robot.poses:
            raise UnknownNameError("pose", value, robot.poses)
        q = robot.pose(value)
    elif isinstance(value, Mapping):
        q = np.zeros(nq) if base is None else np.array(base, dtype=float)
        for name, x in value.items():
            if name not in robot.joint_names:
                raise UnknownNameError("joint", name, robot.joint_names)
            if not _finite(x):
                raise ConfigurationError(f"{field}.{name}", x, "a finite angle [rad]")
            q[robot.params.index(name)] = float(x)
    else:
        q = real_array(
            field,
            value,
            shape=(nq,),
            expected=f"a pose name, a {{joint: angle}} table or {nq} angles [rad]",
        )
    robot.check_within_limits(q, field)
    return np.array(q, dtype=float)


def resolve_gains(
    robot: Robot, value: GainLike | None, field: str, default: FloatArray
) -> FloatArray:
    """Per-joint gains, shape (nv,), from a number, a list or a {joint: gain} table.

    Args:
        robot: The robot (joint names).
        value: The gains as written; None: ``default``.
        field: Name of the field, for error messages (``"controller.kp"``).
        default: Gains of the joints a table leaves out, shape (nv,).

    Raises:
        ConfigurationError: Wrong length, negative or non-finite gains.
        UnknownNameError: An unknown joint name in a table.
    """
    nv = robot.nq
    out = np.array(default, dtype=float)
    if value is None:
        pass
    elif isinstance(value, Mapping):
        for name, x in value.items():
            if name not in robot.joint_names:
                raise UnknownNameError("joint", name, robot.joint_names)
            if not _finite(x) or float(x) < 0:
                raise ConfigurationError(f"{field}.{name}", x, "a finite gain >= 0")
            out[robot.params.index(name)] = float(x)
    elif _finite(value):
        out[:] = float(value)  # type: ignore[arg-type]
    else:
        arr = real_array(
            field,
            value,
            shape=(nv,),
            expected=f"a number, a {{joint: gain}} table or {nv} finite gains",
        )
        out = arr.copy()
    if np.any(out < 0) or not np.all(np.isfinite(out)):
        raise ConfigurationError(field, value, "finite gains >= 0")
    return out
