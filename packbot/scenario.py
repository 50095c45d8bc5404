"""Scenario files: a whole simulation described in TOML, loaded into packbot's own dataclasses.

A scenario file (``sims/<name>.toml``; the format is in docs/scenarios.md) names the initial
state, the duration, the :class:`~packbot.config.SimConfig` fields, joint failures, a payload, the
controller and its parameters, the environment and the outputs::

    description = "The report's collapse: zero torque from the drive pose"
    duration = 5.0                       # [s]

    [initial]
    pose = "drive"                       # a named pose; q / v: lists or joint = value tables

    [config]                             # any SimConfig field
    contact_mode = "joint_clamp"         # the report's law (the default: "normal")
    locked_joints = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]

    [[failures]]                         # packbot.failures.Failure fields
    joint = "shoulder"
    kind = "loose"
    t = 0.5

Loading checks every key and value: an error names the field by its dotted path
(``config.restitution``, ``failures[0].kind``), the bad value and the valid choices (an unknown
key lists the table's keys, an unknown joint the joint names). The table ``[config]`` accepts
whatever fields :class:`SimConfig` has (they are introspected).

- :func:`load_scenario` (a name in ``sims/`` or a path) -> :class:`Scenario`;
- :func:`run_scenario` -> :class:`~packbot.result.SimResult`;
- :func:`save_run` writes the trajectory (``.npz``, with the scenario text and the package version
  stored beside it) and the event log (CSV); :func:`write_outputs` the plots and the
  camera-occlusion table.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import logging
import math
import types
import typing
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args, get_origin

import numpy as np
from numpy.typing import NDArray

from packbot import tomlfile
from packbot.config import SimConfig
from packbot.csv_cells import spreadsheet_row
from packbot.environment import FLOOR, Environment, Obstacle
from packbot.errors import (
    ConfigurationError,
    ConvexityError,
    KeywordError,
    UnknownNameError,
    close_match,
)
from packbot.failures import Failure, check_sequence
from packbot.keywords import checked_arguments
from packbot.outputs import IMAGE_FORMATS, PLOT_KINDS, OcclusionCheck, Outputs
from packbot.paths import atomic_write, check_stem, inside
from packbot.payload import Payload
from packbot.scenario_robot import RobotSpec, load_spec_robot, robot_spec
from packbot.scenario_schema import json_schema as _json_schema
from packbot.validation import (
    MAX_OBSTACLES,
    at_most,
    finite_number,
    name_str,
    real_array,
)

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld
    from packbot.control.base import Controller
    from packbot.model import Robot
    from packbot.result import SimResult

__all__ = [
    "PLOT_KINDS",
    "RENAMED_SCENARIOS",
    "TOP_LEVEL_KEYS",
    "OcclusionCheck",
    "Outputs",
    "Scenario",
    "json_schema",
    "list_scenarios",
    "load_scenario",
    "read_scenario_dict",
    "run_scenario",
    "save_run",
    "scenario_from_dict",
    "scenario_path",
    "scenario_robot",
    "write_outputs",
]

log = logging.getLogger(__name__)

#: The valid top-level keys of a scenario file.
TOP_LEVEL_KEYS: tuple[str, ...] = (
    "robot",
    "description",
    "duration",
    "initial",
    "config",
    "failures",
    "payload",
    "controller",
    "environment",
    "outputs",
)
_INITIAL_KEYS = ("pose", "q", "v")
_CONTROLLER_KEYS = ("kind", "inform")  # every other key of [controller] is a parameter
_ENVIRONMENT_KEYS = ("floor", "obstacles")
_FORMATS = IMAGE_FORMATS  # (its former name here: packbot.outputs defines it)


# ---------------------------------------------------------------------------------- dataclasses
@checked_arguments
@dataclass(kw_only=True)
class Scenario:
    """A simulation described by a scenario file.

    Attributes:
        name: The scenario's name (its file's stem).
        duration: Simulated time [s].
        description: One line saying what it shows.
        pose: Named initial pose (``robot.poses``), or None (all joints at zero).
        q0: Initial joint positions [rad]: a full list (nq values; then ``pose`` is None), or
            joint name -> value overriding the pose.
        v0: Initial joint velocities [rad/s]: a full list, or joint name -> value (others 0).
        config: Simulation settings.
        failures: Joint failures, each injected at its time.
        payload: A payload in the gripper, or None.
        controller: Controller kind (``"zero"``: no torque; else a kind of
            ``packbot.control.build_controller``).
        controller_params: The controller's parameters, passed to ``build_controller``.
        inform_controller: Whether the controller is told of each failure when it happens.
        environment: The static environment (the floor and obstacles).
        outputs: Plots and other outputs.
        source_text: The scenario file's text ("" when built in code).
        source_path: The scenario file, or None.
        robot: The arm (the file's ``robot``: :class:`~packbot.scenario_robot.RobotSpec`), or
            None: PackBot.
    """

    name: str
    duration: float
    description: str = ""
    pose: str | None = None
    q0: tuple[float, ...] | dict[str, float] = field(default_factory=dict)
    v0: tuple[float, ...] | dict[str, float] = field(default_factory=dict)
    config: SimConfig = field(default_factory=SimConfig)
    failures: tuple[Failure, ...] = ()
    payload: Payload | None = None
    controller: str = "zero"
    controller_params: dict[str, Any] = field(default_factory=dict)
    inform_controller: bool = False
    environment: Environment = field(default_factory=Environment)
    outputs: Outputs = field(default_factory=Outputs)
    source_text: str = ""
    source_path: Path | None = None
    robot: RobotSpec | None = None

    @checked_arguments
    def validate(self, robot: Robot | None = None) -> None:
        """Check every field; raise a :class:`ConfigurationError` naming the first bad one.

        Without ``robot`` only what needs no model is checked (values, ranges, choices); with
        it also the names (poses, joints, frames, links) and the controller's parameters.
        """
        self._check_types()
        if not (_finite(self.duration) and self.duration > 0):
            raise ConfigurationError("duration", self.duration, "a finite positive time [s]")
        _prefixed(self.config.validate, "config")
        for k, f in enumerate(self.failures):
            # joint names are checked against the robot below
            _prefixed(partial(f.validate, (f.joint,)), f"failures[{k}]")
        check_sequence(self.failures)  # a joint's several failures: a sequence that can happen
        if self.payload is not None:
            self.payload.validate()
        _validate_environment(self.environment)
        self.outputs.validate()
        if isinstance(self.q0, (tuple, list)) and self.pose is not None:
            raise ConfigurationError(
                "initial.q", list(self.q0), "a joint = value table when initial.pose is given"
            )
        if robot is None:
            return
        names = robot.joint_names
        if self.pose is not None and self.pose not in robot.poses:
            raise ConfigurationError("initial.pose", self.pose, tuple(robot.poses))
        self.initial_state(robot)
        for k, j in enumerate(self.config.locked_joints):
            if j not in names:
                raise ConfigurationError(f"config.locked_joints[{k}]", j, names)
        for k, f in enumerate(self.failures):
            if f.joint not in names:
                raise ConfigurationError(f"failures[{k}].joint", f.joint, names)
        frame = None if self.payload is None else self.payload.held_in(robot.tool_frame).frame
        if frame is not None and not robot.model.existFrame(frame):
            raise ConfigurationError(
                "payload.frame", frame, tuple(f.name for f in robot.model.frames)
            )
        for k, j in enumerate(self.outputs.joints_of(robot.joint_names, robot.is_packbot)):
            if j not in names:
                raise ConfigurationError(f"outputs.joints[{k}]", j, names)
        occ = self.outputs.occlusion
        if occ is not None:
            if not robot.model.existFrame(occ.frame):
                raise ConfigurationError(
                    "outputs.occlusion.frame", occ.frame, tuple(f.name for f in robot.model.frames)
                )
            links = (
                *(str(f.name) for f in robot.model.frames),
                *(o.name for o in self.environment.obstacles),
            )
            for k, link in enumerate(occ.ignore):
                if link not in links:
                    raise ConfigurationError(f"outputs.occlusion.ignore[{k}]", link, links)
        controller = self.build_controller(robot)
        # What simulate() checks before a run (the initial state's speeds, a failure on a locked
        # joint, the relevant-joint bound, the limits on samples, ticks and steps...), now, so
        # that a bad scenario is refused before anything is written.
        from packbot.inputs import check_arguments

        q0, v0 = self.initial_state(robot)
        try:
            check_arguments(
                robot,
                q0,
                v0,
                self.duration,
                controller=controller,
                environment=self.environment,
                config=self.config,
                failures=list(self.failures),
                payload=self.payload,
                inform_controller=self.inform_controller,
            )
        except ConfigurationError as exc:
            raise ConfigurationError(_scenario_field(exc.field), exc.value, exc.expected) from None

    def _check_types(self) -> None:
        """The type of each field (a Scenario built in code is not checked at construction)."""
        kinds: tuple[tuple[str, object, type | tuple[type, ...], str], ...] = (
            ("name", self.name, str, "a string"),
            ("description", self.description, str, "a string"),
            ("initial.pose", self.pose, (str, type(None)), "a pose name or None"),
            ("initial.q", self.q0, (tuple, list, dict), "a list or a {joint: angle} table"),
            ("initial.v", self.v0, (tuple, list, dict), "a list or a {joint: speed} table"),
            ("config", self.config, SimConfig, "a packbot.SimConfig"),
            ("failures", self.failures, (tuple, list), "a list of packbot.Failure"),
            ("payload", self.payload, (Payload, type(None)), "a packbot.Payload or None"),
            ("controller.kind", self.controller, str, "a controller kind"),
            ("controller", self.controller_params, dict, "a table of parameters"),
            ("controller.inform", self.inform_controller, bool, "true or false"),
            ("environment", self.environment, Environment, "a packbot.Environment"),
            ("outputs", self.outputs, Outputs, "a packbot.scenario.Outputs"),
        )
        for path, value, types_, expected in kinds:
            if not isinstance(value, types_):
                raise ConfigurationError(path, value, expected)
        for k, f in enumerate(self.failures):
            if not isinstance(f, Failure):
                raise ConfigurationError(f"failures[{k}]", f, "a packbot.Failure")

    @checked_arguments
    def initial_state(self, robot: Robot) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The initial joint positions [rad] and velocities [rad/s], shape (nq,) each.

        Raises:
            ConfigurationError: An unknown pose or joint, a list of the wrong length, or angles
                outside the joint limits (``initial.q``, ``initial.v``).
        """
        names, nq = robot.joint_names, robot.nq
        if self.pose is not None and self.pose not in robot.poses:
            raise ConfigurationError("initial.pose", self.pose, tuple(robot.poses))
        q = robot.pose(self.pose) if self.pose is not None else np.zeros(nq)
        v = np.zeros(nq)
        for key, arr, unit in (("q", q, "rad"), ("v", v, "rad/s")):
            given = self.q0 if key == "q" else self.v0
            if isinstance(given, Mapping):
                for j, val in given.items():
                    if j not in names:
                        raise ConfigurationError(f"initial.{key}.{j}", val, names)
                    arr[names.index(j)] = finite_number(f"initial.{key}.{j}", val, unit=unit)
            else:
                expected = (
                    f"{nq} values [{unit}] in joint order ({', '.join(names)}), or a table "
                    "joint = value"
                )
                if not isinstance(given, (list, tuple)) or len(given) != nq:
                    shown = list(given) if isinstance(given, (list, tuple)) else given
                    raise ConfigurationError(f"initial.{key}", shown, expected)
                arr[:] = real_array(f"initial.{key}", list(given), shape=(nq,), expected=expected)
        robot.check_within_limits(q, "initial.q")
        return q, v

    @checked_arguments
    def build_controller(self, robot: Robot) -> Controller | None:
        """The controller (None for ``"zero"``), built by ``packbot.control.build_controller``.

        Raises:
            ConfigurationError: An unknown kind (``controller.kind``, listing the kinds) or a bad
                parameter (``controller.<param>``).
        """
        try:
            from packbot.control import build_controller
        except ImportError:  # the registry is not there: only the zero-torque "controller"
            if self.controller != "zero":
                raise ConfigurationError("controller.kind", self.controller, ("zero",)) from None
            if self.controller_params:
                key = next(iter(self.controller_params))
                raise ConfigurationError(
                    f"controller.{key}",
                    self.controller_params[key],
                    "no parameter: kind 'zero' takes none",
                ) from None
            return None
        ctrl: Controller | None = build_controller(
            self.controller, robot, dict(self.controller_params), environment=self.environment
        )
        return ctrl

    def plot_kinds(self) -> tuple[str, ...]:
        """The plots to draw: ``outputs.plots``, or the automatic choice."""
        if self.outputs.plots is not None:
            return self.outputs.plots
        kinds = ["joints", "distance", "energy"]
        if self.config.contact_mode == "normal":
            kinds.append("contacts")
        if self.controller != "zero":
            kinds += ["tracking", "torques", "tool_path"]
        if self.outputs.occlusion is not None:
            kinds.append("occlusion")
        return tuple(kinds)


def _validate_environment(env: Environment) -> None:
    seen: set[str] = set()
    # the implicit floor by value (a scenario sent to a worker process holds an equal copy)
    for k, ob in enumerate(o for o in env.obstacles if o != FLOOR):  # as in the file
        path = f"environment.obstacles[{k}]"
        try:
            ob.validate()
        except ConvexityError as exc:
            raise ConfigurationError(f"{path}.points", ob.name, str(exc)) from None
        except ConfigurationError as exc:
            raise ConfigurationError(
                f"{path}.{_last(exc.field)}", exc.value, exc.expected
            ) from None
        if ob.name in seen or ob.name == FLOOR.name:
            raise ConfigurationError(f"{path}.name", ob.name, "a name not used twice ('floor' too)")
        seen.add(ob.name)


def _scenario_field(name: str) -> str:
    """The dotted path in a scenario file of a field named by ``simulate``'s checks."""
    if name in ("q0", "v0"):
        return f"initial.{name[0]}"
    if name in {f.name for f in dataclasses.fields(SimConfig)}:
        return f"config.{name}"
    return name


def _last(field_name: str) -> str:
    return field_name.rsplit(": ", 1)[-1].rsplit(".", 1)[-1]


def _prefixed(check: Callable[[], None], prefix: str) -> None:
    """Run a dataclass's ``validate``; re-raise its error with the field under ``prefix``."""
    try:
        check()
    except ConfigurationError as exc:
        raise ConfigurationError(f"{prefix}.{_last(exc.field)}", exc.value, exc.expected) from None


def _finite(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


# ---------------------------------------------------------------------------------- parsing
def _hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # a field type that cannot be resolved: no type checks for this class
        log.debug("no type hints for %s", cls.__name__, exc_info=True)
        return {}


def _describe(hint: Any) -> str:
    origin = get_origin(hint)
    if hint is bool:
        return "true or false"
    if hint is int:
        return "an integer"
    if hint is float:
        return "a number"
    if hint is str:
        return "a string"
    if origin is tuple:
        args = get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_plural(args[0])}"
        return f"a list of {len(args)} {_plural(args[0])}"
    if origin in (dict, Mapping) or hint is dict:
        return "a table"
    return str(hint)


def _plural(hint: Any) -> str:
    return {float: "numbers", int: "integers", str: "strings", bool: "booleans"}.get(hint, "values")


def _coerce(path: str, value: Any, hint: Any) -> Any:
    """Check a TOML value against a type hint; return it converted (lists become tuples)."""
    origin = get_origin(hint)
    if hint is Any or hint is None:
        return _freeze(value)
    if origin is Literal:
        choices = get_args(hint)
        if value not in choices or isinstance(value, bool) != isinstance(choices[0], bool):
            raise ConfigurationError(path, value, choices)
        return value
    if origin in (typing.Union, types.UnionType):
        options = [a for a in get_args(hint) if a is not type(None)]
        if value is None and len(options) < len(get_args(hint)):
            return None
        first: ConfigurationError | None = None
        for opt in options:
            try:
                return _coerce(path, value, opt)
            except ConfigurationError as exc:
                first = first or exc
        assert first is not None
        raise first
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigurationError(path, value, "true or false")
        return value
    if hint is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigurationError(path, value, "an integer")
        return value
    if hint is float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise ConfigurationError(path, value, "a number")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigurationError(path, value, "a string")
        return value
    if origin is tuple:
        args = get_args(hint)
        if not isinstance(value, (list, tuple)):
            raise ConfigurationError(path, value, _describe(hint))
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(f"{path}[{k}]", x, args[0]) for k, x in enumerate(value))
        if len(value) != len(args):
            raise ConfigurationError(path, list(value), _describe(hint))
        return tuple(
            _coerce(f"{path}[{k}]", x, a) for k, (x, a) in enumerate(zip(value, args, strict=True))
        )
    if origin in (dict, Mapping) or hint is dict:
        if not isinstance(value, dict):
            raise ConfigurationError(path, value, "a table")
        return dict(value)
    return _freeze(value)


def _freeze(value: Any) -> Any:
    if isinstance(value, list):
        return tuple(_freeze(x) for x in value)
    return value


def _table(data: Any, path: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise ConfigurationError(path, data, "a table")
    return data


def _check_keys(data: Mapping[str, Any], path: str, valid: Sequence[str]) -> None:
    for key, value in data.items():
        if key not in valid:
            where = f"[{path}]" if path else "the top level"
            match = close_match(key, valid)
            hint = f" (did you mean {match!r}?)" if match else ""
            raise ConfigurationError(
                f"{path}.{key}" if path else key,
                value,
                f"a key of {where}{hint}, one of: {', '.join(valid)}",
            )


def _dataclass_from(
    cls: type, data: Any, path: str, *, skip: Sequence[str] = (), extra: Mapping[str, Any] = {}
) -> Any:
    """Build a dataclass from a TOML table: every key a field, each value type-checked."""
    table = _table(data, path)
    names = [f.name for f in dataclasses.fields(cls) if f.init and f.name not in skip]
    _check_keys(table, path, names)
    hints = _hints(cls)
    kwargs = {k: _coerce(f"{path}.{k}", v, hints.get(k, Any)) for k, v in table.items()}
    try:
        return cls(**kwargs, **extra)
    except KeywordError as exc:  # a required field is missing (the keys are checked above)
        if exc.missing:
            name = exc.missing[0]
            raise ConfigurationError(
                f"{path}.{name}", None, f"a value: {path}.{name} is required"
            ) from None
        raise ConfigurationError(path, table, str(exc)) from None
    except ConvexityError as exc:  # an obstacle's points (checked at construction)
        raise ConfigurationError(f"{path}.points", table.get("name"), str(exc)) from None
    except ConfigurationError as exc:  # a bad value (checked at construction): name its path
        raise ConfigurationError(f"{path}.{_last(exc.field)}", exc.value, exc.expected) from None


def _joint_values(data: Any, path: str) -> tuple[float, ...] | dict[str, float]:
    if isinstance(data, list):
        return tuple(_coerce(f"{path}[{k}]", x, float) for k, x in enumerate(data))
    if isinstance(data, dict):
        return {str(k): _coerce(f"{path}.{k}", x, float) for k, x in data.items()}
    raise ConfigurationError(path, data, "a list of joint values or a table joint = value")


@checked_arguments
def scenario_from_dict(data: Mapping[str, Any], *, name: str, source_text: str = "") -> Scenario:
    """Build a :class:`Scenario` from a scenario file's table (as parsed from TOML).

    Checks keys, types and the values that need no robot model; names, joints and the
    controller's parameters are checked by :meth:`Scenario.validate` with a robot.

    Args:
        data: The parsed TOML (see docs/scenarios.md).
        name: The scenario's name.
        source_text: The file's text, stored with the results.

    Raises:
        ConfigurationError: A bad key or value; the message names its dotted path.
    """
    if not isinstance(data, Mapping):
        raise ConfigurationError("scenario", data, "a table (the parsed TOML of a scenario file)")
    name_str("name", name, "a non-empty string")
    data = dict(data)
    _check_keys(data, "", TOP_LEVEL_KEYS)
    if "duration" not in data:
        raise ConfigurationError("duration", None, "a finite positive time [s] (required)")
    duration = _coerce("duration", data["duration"], float)
    description = _coerce("description", data.get("description", ""), str)
    robot = robot_spec(data["robot"]) if "robot" in data else None

    initial = _table(data.get("initial", {}), "initial")
    _check_keys(initial, "initial", _INITIAL_KEYS)
    pose = _coerce("initial.pose", initial["pose"], str) if "pose" in initial else None
    q0 = _joint_values(initial["q"], "initial.q") if "q" in initial else {}
    v0 = _joint_values(initial["v"], "initial.v") if "v" in initial else {}

    config = _dataclass_from(SimConfig, data.get("config", {}), "config")

    raw_failures = data.get("failures", [])
    if not isinstance(raw_failures, list):
        raise ConfigurationError("failures", raw_failures, "an array of tables [[failures]]")
    failures = tuple(
        _dataclass_from(Failure, f, f"failures[{k}]") for k, f in enumerate(raw_failures)
    )
    payload = _dataclass_from(Payload, data["payload"], "payload") if "payload" in data else None

    ctrl = _table(data.get("controller", {}), "controller")
    kind = _coerce("controller.kind", ctrl.get("kind", "zero"), str)
    inform = _coerce("controller.inform", ctrl.get("inform", False), bool)
    params = {k: v for k, v in ctrl.items() if k not in _CONTROLLER_KEYS}

    env = _table(data.get("environment", {}), "environment")
    _check_keys(env, "environment", _ENVIRONMENT_KEYS)
    floor = _coerce("environment.floor", env.get("floor", True), bool)
    raw_obstacles = env.get("obstacles", [])
    if not isinstance(raw_obstacles, list):
        raise ConfigurationError(
            "environment.obstacles", raw_obstacles, "an array of tables [[environment.obstacles]]"
        )
    at_most("environment.obstacles", raw_obstacles, len(raw_obstacles), MAX_OBSTACLES, "obstacles")
    obstacles = tuple(
        _dataclass_from(Obstacle, o, f"environment.obstacles[{k}]")
        for k, o in enumerate(raw_obstacles)
    )
    for k, ob in enumerate(obstacles):  # before Environment() refuses them without the path
        if ob.name == FLOOR.name or ob.name in [o.name for o in obstacles[:k]]:
            raise ConfigurationError(
                f"environment.obstacles[{k}].name", ob.name, "a name not used twice ('floor' too)"
            )
    environment = Environment(obstacles=((FLOOR,) if floor else ()) + obstacles)

    out = dict(_table(data.get("outputs", {}), "outputs"))
    occlusion = None
    if "occlusion" in out:
        occlusion = _dataclass_from(OcclusionCheck, out.pop("occlusion"), "outputs.occlusion")
    outputs = _dataclass_from(Outputs, out, "outputs", extra={"occlusion": occlusion})

    scenario = Scenario(
        name=name,
        duration=duration,
        description=description,
        pose=pose,
        q0=q0,
        v0=v0,
        config=config,
        failures=failures,
        payload=payload,
        controller=kind,
        controller_params=params,
        inform_controller=inform,
        environment=environment,
        outputs=outputs,
        source_text=source_text,
        robot=robot,
    )
    scenario.validate()
    return scenario


@checked_arguments
def json_schema(robot: Robot | None = None) -> dict[str, Any]:
    """The JSON Schema (draft 7) of scenario files, for editors (docs/scenarios.md).

    Generated from the dataclasses, choice lists and robot names this module loads into
    (:mod:`packbot.scenario_schema`); ``packbot schema`` prints it, and
    ``sims/scenario.schema.json`` is the shipped copy.

    Args:
        robot: The model whose joint, pose and frame names it lists (default: the shipped one).
    """
    return _json_schema(robot)


# ---------------------------------------------------------------------------------- files
def _sims_dir() -> Path:
    from packbot.resources import data_dir

    return data_dir("sims")


#: Former names of shipped scenarios -> their current name. A former name still loads the
#: scenario (its results are named after the current one) with a ``FutureWarning`` (shown by
#: default, also on the command line).
RENAMED_SCENARIOS: dict[str, str] = {"collapse_normal": "collapse_physical"}


@checked_arguments
def list_scenarios() -> dict[str, Path]:
    """The shipped scenarios: name -> file (``sims/*.toml``), sorted by name."""
    return {p.stem: p for p in sorted(_sims_dir().glob("*.toml"))}


@checked_arguments
def scenario_path(name_or_path: str | Path) -> Path:
    """The file of a scenario: a name in ``sims/`` (``"collapse"``) or a path to a TOML file.

    A former name (:data:`RENAMED_SCENARIOS`) gives the renamed scenario's file, with a
    ``FutureWarning``.

    Raises:
        UnknownNameError: A name that is not a shipped scenario (lists them).
        ConfigurationError: A path that is not an existing file.
    """
    text = str(name_or_path)
    p = Path(text)
    if p.is_file():
        return p
    looks_like_path = isinstance(name_or_path, Path) or "/" in text or "\\" in text
    if looks_like_path or text.endswith(".toml"):
        raise ConfigurationError(
            "scenario", text, f"an existing file, or one of: {', '.join(list_scenarios())}"
        )
    shipped = list_scenarios()
    if text not in shipped and RENAMED_SCENARIOS.get(text) in shipped:
        current = RENAMED_SCENARIOS[text]
        warnings.warn(
            f"scenario {text!r} is now called {current!r}; the old name will be removed",
            FutureWarning,
            stacklevel=3,  # the caller of load_scenario / read_scenario_dict
        )
        text = current
    if text not in shipped:
        raise UnknownNameError("scenario", text, shipped)
    return shipped[text]


@checked_arguments
def read_scenario_dict(name_or_path: str | Path) -> dict[str, Any]:
    """The raw table of a scenario file (parsed TOML, not checked).

    Raises:
        ConfigurationError: Not valid TOML (says where), or no such file.
        UnknownNameError: An unknown scenario name.
    """
    return _parse(scenario_path(name_or_path))[0]


def _parse(path: Path) -> tuple[dict[str, Any], str]:
    tomlfile.check_file_size(path, "scenario", str(path))
    text = path.read_bytes().decode("utf-8", errors="replace")
    return tomlfile.loads(text, "scenario", str(path)), text


@checked_arguments
def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and check a scenario (a name in ``sims/`` or a path); see :func:`scenario_from_dict`.

    Raises:
        ConfigurationError: A bad key or value (its dotted path named), or a bad file.
        UnknownNameError: An unknown scenario name.
    """
    path = scenario_path(name_or_path)
    data, text = _parse(path)
    scenario = scenario_from_dict(data, name=path.stem, source_text=text)
    scenario.source_path = path
    return scenario


# ---------------------------------------------------------------------------------- running
@checked_arguments
def scenario_robot(scenario: Scenario) -> Robot:
    """The arm a scenario runs on: its file's ``robot``, or PackBot.

    Relative paths are taken from the scenario file's folder.

    Raises:
        ModelError: The arm cannot be loaded (:func:`packbot.load_robot`'s errors).
    """
    return load_spec_robot(scenario.robot, scenario.source_path)


@checked_arguments
def run_scenario(
    scenario: Scenario,
    robot: Robot | None = None,
    *,
    duration: float | None = None,
    progress: Callable[[float], None] | None = None,
    controller: Controller | None = None,
) -> SimResult:
    """Simulate a scenario.

    Args:
        scenario: The scenario.
        robot: The robot (default: the scenario's, :func:`scenario_robot`).
        duration: Simulated time [s] instead of the scenario's (e.g. shortened in tests).
        progress: Called with the simulated time [s] after each accepted step.
        controller: Your controller instead of the scenario's (built for ``robot``); None: the
            scenario's.

    Returns:
        The result of :func:`packbot.simulate`, with ``scenario_text`` the file's text.

    Raises:
        ConfigurationError: A bad scenario (names the field).
        SimulationError: The run could not continue (says what and when).
    """
    from packbot.integrator import simulate
    from packbot.model import Robot

    if not isinstance(scenario, Scenario):
        raise ConfigurationError(
            "scenario", scenario, "a packbot.scenario.Scenario (from load_scenario())"
        )
    if robot is None:
        robot = scenario_robot(scenario)
    elif not isinstance(robot, Robot):
        raise ConfigurationError("robot", robot, "None or a packbot.Robot (from load_robot())")
    scenario.validate(robot)
    if duration is not None and not (_finite(duration) and duration > 0):
        raise ConfigurationError("duration", duration, "a finite positive time [s]")
    q0, v0 = scenario.initial_state(robot)
    kwargs: dict[str, Any] = {
        "controller": scenario.build_controller(robot) if controller is None else controller,
        "environment": scenario.environment,
        "config": scenario.config,
    }
    # The optional arguments are passed only when used.
    if scenario.failures:
        kwargs["failures"] = list(scenario.failures)
    if scenario.payload is not None:
        kwargs["payload"] = scenario.payload
    if scenario.inform_controller:
        kwargs["inform_controller"] = True
    if progress is not None:
        kwargs["progress"] = progress
    T = scenario.duration if duration is None else float(duration)
    result = simulate(robot, q0, v0, T, **kwargs)
    result.scenario_text = scenario.source_text
    return result


# ---------------------------------------------------------------------------------- saving
_EVENT_COLUMNS = (
    "time_s",
    "kind",
    "link1",
    "link2",
    "piece1",
    "piece2",
    "distance_m_or_rad",
    "relevant_joints",
    "energy_before_J",
    "energy_after_J",
    "energy_change_J",
)


@checked_arguments
def save_run(
    result: SimResult, scenario: Scenario, out_dir: str | Path, stem: str | None = None
) -> dict[str, Path]:
    """Write a run's trajectory and event log, each atomically (temp file + rename).

    - ``<stem>.npz``: the whole result, by :meth:`SimResult.save` (compressed; read it back
      with :meth:`SimResult.load`), with the scenario's text (when the result has none) and
      name: for a reader with NumPy alone, ``t`` [s] (N,), ``q`` [rad], ``v`` [rad/s], ``tau``
      [N*m] (N, nv), ``energy`` [J] (N,), ``joint_names``, ``tau_cmd``, ``tau_friction``,
      ``effort``, ``scenario_name``, ``scenario_text`` (the file's text),
      ``packbot_version``, ``config_json`` (the settings) and ``rest_time`` [s] (NaN: none).
      The diagnostics' wall time is stored as 0, so that a rerun writes the same bytes;
    - ``<stem>_events.csv``: one row per event (time, kind, pair, distance, relevant joints,
      energy before, after and change). A text cell a spreadsheet would run as a formula (an
      obstacle named ``=cmd|...``: beginning with ``=``, ``+``, ``-``, ``@``, a tab or a carriage
      return, and not a number) is written with a leading ``'``
      (:func:`packbot.csv_cells.spreadsheet_safe`).

    Both files are inside ``out_dir``: the stem must be a single file name
    (:func:`packbot.paths.check_stem`: no separator, not ``..``).

    Args:
        result: The run's result.
        scenario: Its scenario.
        out_dir: Output directory (created if missing).
        stem: File name stem (default: the scenario's name).

    Returns:
        ``{"trajectory": path, "events": path}``.

    Raises:
        ConfigurationError: ``out_dir`` is a file, or the stem (``stem``, or ``scenario.name``
            by default) is not a single file name; nothing is written.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigurationError("out_dir", str(out), "a directory (this is a file)")
    stem = _checked_stem(scenario, stem)
    inside("out_dir", out, out / f"{stem}.npz")
    if not result.scenario_text:  # a partial result, or one made outside run_scenario
        result = dataclasses.replace(result, scenario_text=scenario.source_text)
    # The wall time is left out (0): the file is then a function of the run's inputs, so a
    # rerun writes the same bytes (the batch compares files by their hash).
    diagnostics = dataclasses.replace(result.diagnostics, wall_time=0.0)
    result = dataclasses.replace(result, diagnostics=diagnostics)
    traj = result.save(out / f"{stem}.npz", extra={"scenario_name": scenario.name})

    def write_events(fh: io.TextIOBase) -> None:
        w = csv.writer(fh)
        w.writerow(_EVENT_COLUMNS)
        for e in result.events:
            w.writerow(
                spreadsheet_row(
                    [
                        f"{e.t:.10f}",
                        e.kind,
                        e.link1,
                        e.link2,
                        e.piece1,
                        e.piece2,
                        f"{e.distance:.6g}",
                        " ".join(e.relevant_joints),
                        f"{e.energy_before:.6f}",
                        f"{e.energy_after:.6f}",
                        f"{e.energy_change:.6f}",
                    ]
                )
            )

    events = out / f"{stem}_events.csv"
    atomic_write(events, write_events, binary=False)
    return {"trajectory": traj, "events": events}


def _checked_stem(scenario: Scenario, stem: Any) -> str:
    """The stem of a run's files: ``stem``, or the scenario's name; a single file name."""
    if stem is None:
        return check_stem("scenario.name", scenario.name)
    return check_stem("stem", stem)


@checked_arguments
def write_outputs(
    result: SimResult,
    scenario: Scenario,
    robot: Robot,
    out_dir: str | Path,
    stem: str | None = None,
    *,
    plots: bool = True,
    world: CollisionWorld | None = None,
) -> dict[str, Any]:
    """Write a run's plots and its camera-occlusion table (if the scenario asks for one).

    Files: ``<stem>_<kind>.png``/``.svg`` for each of :meth:`Scenario.plot_kinds`, and
    ``<stem>_occlusion.csv`` (time [s], then per target the blocking link or obstacle, or "").

    Args:
        result: The run's result.
        scenario: Its scenario.
        robot: The robot it ran.
        out_dir: Output directory.
        stem: File name stem (default: the scenario's name).
        plots: Whether to draw the plots (False: only the occlusion table).
        world: A collision world of the robot and the scenario's environment (built if None).

    Returns:
        Name -> path of each file written, plus ``"min_distance"``: the sampled distances [m]
        when the distance plot was drawn.
    """
    from packbot.collision import CollisionWorld

    out = Path(out_dir)
    stem = _checked_stem(scenario, stem)
    inside("out_dir", out, out / stem)
    written: dict[str, Any] = {}
    kinds = scenario.plot_kinds() if plots else ()
    occ = scenario.outputs.occlusion
    if not kinds and occ is None:
        return written  # nothing to draw: matplotlib (~0.3 s of import) is not loaded
    from packbot import plots as P

    need_world = occ is not None or "distance" in kinds
    if need_world and world is None:
        world = CollisionWorld(robot, scenario.environment)
    fmts = scenario.outputs.formats
    blocked = None
    if occ is not None:
        assert world is not None
        blocked = P.sample_occlusion(
            result, world, occ.targets, frame=occ.frame, radius=occ.radius, ignore=occ.ignore
        )
        path = out / f"{stem}_occlusion.csv"

        def write_table(fh: io.TextIOBase) -> None:
            w = csv.writer(fh)
            w.writerow(["time_s", *(f"target{k} {list(p)}" for k, p in enumerate(occ.targets))])
            for i, t in enumerate(result.t):
                w.writerow(spreadsheet_row([f"{t:.6f}", *(col[i] or "" for col in blocked)]))

        atomic_write(path, write_table, binary=False)
        written["occlusion_table"] = path
    joints = scenario.outputs.joints_of(robot.joint_names, robot.is_packbot)
    for kind in kinds:
        base = out / f"{stem}_{kind}"
        if kind == "joints":
            P.plot_joints(result, joints, path=base, formats=fmts)
        elif kind == "distance":
            assert world is not None
            d = P.sample_distances(result, world)
            written["min_distance"] = d
            P.plot_distance(result, world, path=base, distances=d, formats=fmts)
        elif kind == "energy":
            P.plot_energy(result, path=base, formats=fmts)
        elif kind == "torques":
            P.plot_torques(result, joints, path=base, formats=fmts)  # limits: result.effort
        elif kind == "tracking":
            q_ref = _reference(scenario, robot, result)
            if q_ref is None:
                log.info("no tracking plot: the controller has no reference(t) method")
                continue
            P.plot_tracking(result, q_ref, joints, path=base, formats=fmts)
        elif kind == "tool_path":
            frame, target = _tool_target(scenario, robot)
            P.plot_tool_path(
                result, path=base, frame=frame, robot=robot, target=target, formats=fmts
            )
        elif kind == "occlusion":
            assert occ is not None and blocked is not None
            P.plot_occlusion(result, blocked, occ.targets, path=base, formats=fmts)
        elif kind == "contacts":
            P.plot_contacts(result, path=base, formats=fmts)
        written[kind] = base.with_suffix(f".{fmts[0]}")
    return written


def _tool_target(scenario: Scenario, robot: Robot) -> tuple[str, NDArray[np.float64] | None]:
    """The frame a controller places (default ``gripper_tool``) and its target [m], if any.

    A controller's ``target`` of 3 coordinates is the frame's target (world frame [m]); a
    joint target (shape (nq,), a regulator) or the last waypoint of a joint trajectory gives
    the frame's position there.
    """
    import pinocchio as pin

    ctrl = scenario.build_controller(robot)
    frame = getattr(ctrl, "frame", None)
    if not isinstance(frame, str) or not robot.model.existFrame(frame):
        frame = "gripper_tool"
    target = getattr(ctrl, "target", None)
    waypoints = getattr(getattr(ctrl, "trajectory", None), "waypoints", None)
    if target is None and isinstance(waypoints, np.ndarray) and waypoints.ndim == 2:
        target = waypoints[-1]
    if not isinstance(target, np.ndarray):
        return frame, None
    if target.shape == (3,):
        return frame, target.astype(float)
    if target.shape == (robot.nq,):
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, target.astype(float))
        return frame, np.array(data.oMf[robot.model.getFrameId(frame)].translation)
    return frame, None


def _reference(scenario: Scenario, robot: Robot, result: SimResult) -> NDArray[np.float64] | None:
    """The controller's reference q_ref(t) [rad] at the result's samples, if it has one.

    A controller with a ``reference(t)`` or ``trajectory(t)`` method (returning q_ref, shape
    (nq,), or a tuple whose first item is q_ref), or a fixed joint ``target`` (shape (nq,)),
    gets a tracking plot; it is rebuilt from the scenario and reset at the initial state first.
    """
    ctrl = scenario.build_controller(robot)
    if ctrl is None:
        return None
    q0, v0 = scenario.initial_state(robot)
    ctrl.reset(robot, 0.0, q0, v0)
    ref = getattr(ctrl, "reference", None) or getattr(ctrl, "trajectory", None)
    target = getattr(ctrl, "target", None)
    if not callable(ref):
        if isinstance(target, np.ndarray) and target.shape == (robot.nq,):  # a regulator
            return np.tile(target.astype(float), (len(result.t), 1))
        return None
    try:
        rows = []
        for t in result.t:
            r = ref(float(t))
            rows.append(np.asarray(r[0] if isinstance(r, tuple) else r, dtype=float))
        q_ref = np.array(rows)
    except Exception as exc:  # the reference is the controller's code: report and go on
        log.warning("no tracking plot: the reference raised %s: %s", type(exc).__name__, exc)
        return None
    if q_ref.shape != result.q.shape:
        log.warning("no tracking plot: the reference has shape %s", q_ref.shape[1:])
        return None
    return q_ref
