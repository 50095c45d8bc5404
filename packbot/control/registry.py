"""Build a controller from plain values (a scenario file's ``[controller]`` table).

``build_controller(kind, robot, params)`` with kind one of :data:`CONTROLLER_KINDS`:

- ``zero``: None (zero torque, the collapse);
- ``gravity``: :class:`GravityCompensation`;
- ``pd``: :class:`JointPD` (target, kp, kd, omega, zeta, gravity_compensation);
- ``computed_torque``: :class:`ComputedTorque` (waypoints, times, speed_fraction, kp, kd, omega,
  zeta);
- ``cartesian``: :class:`CartesianPD` (target, frame, orientation, kp, kd, kp_rot, kd_rot,
  posture, k_posture, damping, omega_posture, pinv_damping);
- ``reconfig``: :class:`ReconfigurableController` (target, frame, speed_fraction, min_move_time,
  omega, zeta, detect, reconfigure, observer_gain, threshold, persistence, frozen_speed,
  clearance, ik_seeds, seed, sway_damping, swing_return, swing_check,
  loose_margin); see :data:`CONTROLLER_PARAMS`.

Every kind also takes ``dt`` (control period [s]), ``gravity`` (3 numbers [m/s^2], which must
match the simulation's) and ``sensor`` (a table: resolution, noise_q, noise_v, seed). Vectors are
lists; a configuration can be a pose name or a {joint: angle} table; per-joint gains a number, a
list or a {joint: gain} table. ``computed_torque`` waypoints are configurations (the first
is usually the scenario's initial pose); ``times`` [s] are their times (default: each segment
as fast as ``speed_fraction`` of the speed limits allows, from t = 0).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from packbot.control._common import resolve_q
from packbot.control.base import Controller, Sensor
from packbot.control.cartesian import CartesianPD
from packbot.control.computed_torque import ComputedTorque
from packbot.control.gravity import GravityCompensation
from packbot.control.path_check import path_warning
from packbot.control.pd import JointPD
from packbot.control.reconfig import ReconfigurableController
from packbot.control.trajectory import JointTrajectory, min_jerk_duration
from packbot.errors import ConfigurationError, PackbotError, close_match
from packbot.keywords import checked_arguments
from packbot.validation import finite_number

if TYPE_CHECKING:
    from packbot.environment import Environment
    from packbot.model import Robot

__all__ = ["CONTROLLER_KINDS", "CONTROLLER_PARAMS", "build_controller"]

_COMMON = ("dt", "gravity", "sensor")

#: Parameters each kind accepts (besides dt, gravity and sensor).
CONTROLLER_PARAMS: dict[str, tuple[str, ...]] = {
    "zero": (),
    "gravity": (),
    "pd": ("target", "kp", "kd", "omega", "zeta", "gravity_compensation"),
    "computed_torque": ("waypoints", "times", "speed_fraction", "kp", "kd", "omega", "zeta"),
    "cartesian": (
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
    ),
    "reconfig": (
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
        "ik_seeds",
        "seed",
        "sway_damping",
        "swing_return",
        "swing_check",
        "loose_margin",
    ),
}
#: The valid controller kinds.
CONTROLLER_KINDS: tuple[str, ...] = tuple(CONTROLLER_PARAMS)


def _unknown_key(field: str, value: Any, valid: Sequence[str]) -> ConfigurationError:
    """The error of an unknown parameter: the valid ones, and the closest if one is close."""
    choices = "one of " + ", ".join(repr(v) for v in valid)
    match = close_match(field.rsplit(".", 1)[-1], valid)
    return ConfigurationError(
        field, value, f"did you mean {match!r}? {choices}" if match else choices
    )


def _sensor(value: Any) -> Sensor:
    if not isinstance(value, Mapping):
        raise ConfigurationError("controller.sensor", value, "a table (resolution, noise_q, ...)")
    valid = ("resolution", "noise_q", "noise_v", "seed")
    for key in value:
        if key not in valid:
            raise _unknown_key(f"controller.sensor.{key}", value[key], valid)
    seed = value.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise ConfigurationError("controller.sensor.seed", seed, "an integer")
    return Sensor(**dict(value))


def _trajectory(robot: Robot, p: dict[str, Any]) -> JointTrajectory:
    wps = p.pop("waypoints", None)
    if not isinstance(wps, Sequence) or isinstance(wps, str) or len(wps) < 2:
        raise ConfigurationError(
            "controller.waypoints", wps, "a list of >= 2 configurations (pose names, lists, tables)"
        )
    W: list[np.ndarray] = []
    for k, w in enumerate(wps):
        base = W[-1] if W else None
        W.append(resolve_q(robot, w, f"controller.waypoints[{k}]", base))
    frac = finite_number(
        "controller.speed_fraction", p.pop("speed_fraction", 0.5), low=0.0, high=1.0, low_open=True
    )
    times = p.pop("times", None)
    vmax = robot.params.velocity
    if times is None:
        ts = [0.0]
        for a, b in itertools.pairwise(W):
            ts.append(ts[-1] + min_jerk_duration(a, b, frac * vmax, minimum=0.2))
        times = ts
    try:
        return JointTrajectory(
            np.array(W), times, lower=robot.params.lower, upper=robot.params.upper, v_max=vmax
        )
    except ConfigurationError as exc:
        field = exc.field.replace("trajectory.", "controller.")
        raise ConfigurationError(field, exc.value, exc.expected) from None


@checked_arguments
def build_controller(
    kind: str,
    robot: Robot,
    params: Mapping[str, Any],
    *,
    environment: Environment | None = None,
) -> Controller | None:
    """A controller from plain (TOML) values; None for ``"zero"``.

    Args:
        kind: One of :data:`CONTROLLER_KINDS`.
        robot: The robot (names, poses, limits; the controller is prepared for it).
        params: The parameters (see the module docstring).
        environment: Obstacles a planning controller (``reconfig``) avoids (None: the floor).

    Raises:
        ConfigurationError: Unknown kind (``controller.kind``), unknown or bad parameter
            (``controller.<param>``).
        UnknownNameError: An unknown pose, joint or frame name in a parameter.
    """
    if kind not in CONTROLLER_PARAMS:
        raise ConfigurationError("controller.kind", kind, CONTROLLER_KINDS)
    if not isinstance(params, Mapping):
        raise ConfigurationError("controller", params, "a table of parameters")
    valid = CONTROLLER_PARAMS[kind] + _COMMON
    for key in params:
        if key not in valid:
            raise _unknown_key(f"controller.{key}", params[key], valid)
    if kind == "zero":
        return None
    p = dict(params)
    if "sensor" in p:
        p["sensor"] = _sensor(p["sensor"])
    ctrl: Controller
    try:
        if kind == "gravity":
            ctrl = GravityCompensation(**p)
        elif kind == "pd":
            ctrl = JointPD(**p)
        elif kind == "computed_torque":
            trajectory = _trajectory(robot, p)
            path_warning(  # rest-to-rest segments: straight in joint space
                robot,
                trajectory.waypoints,
                environment,
                "controller.waypoints: the computed-torque trajectory",
            )
            ctrl = ComputedTorque(trajectory=trajectory, **p)
        elif kind == "cartesian":
            if "target" not in p:
                raise ConfigurationError("controller.target", None, "a position [m] or pose name")
            ctrl = CartesianPD(**p)
        else:
            if "target" not in p:
                raise ConfigurationError("controller.target", None, "a position [m] or pose name")
            ctrl = ReconfigurableController(environment=environment, **p)
        ctrl.prepare(robot)
    except PackbotError:
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"controller ({kind})", dict(params), str(exc)) from exc
    return ctrl
