"""A JSON Schema of scenario files, generated from packbot's own definitions.

Editors (Taplo / Even Better TOML in VS Code, JetBrains IDEs, Helix, Neovim with taplo-lsp) use
it to complete keys, list the choices of a value and flag a wrong type or an unknown key while
a scenario file is being written (docs/scenarios.md, "Editor support"). It is made from what
the loader itself uses, so it cannot drift from it: the fields and type hints of
:class:`~packbot.config.SimConfig`, :class:`~packbot.failures.Failure`,
:class:`~packbot.payload.Payload`, :class:`~packbot.environment.Obstacle`,
:class:`~packbot.scenario.Outputs` and :class:`~packbot.scenario.OcclusionCheck`, their
``Attributes:`` docstrings (the hover text), the choice lists (contact modes, clamp and reset
rules, failure kinds, obstacle kinds, plot kinds, image formats, controller kinds and each
kind's parameters) and, from the robot model, the joint, pose and frame names.

The schema checks keys, types and choices; ranges and the rules that tie fields together
(``t_drop`` after ``t_pick``, a halfspace's non-zero normal...) stay with the loader
(:func:`packbot.scenario.load_scenario`), whose messages name the field, the value and what is
expected. The shipped copy is ``sims/scenario.schema.json`` (``packbot schema --out``);
a test checks that it is up to date.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import re
import types
import typing
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args, get_origin

from packbot.config import SimConfig
from packbot.environment import Obstacle
from packbot.failures import Failure
from packbot.outputs import IMAGE_FORMATS, PLOT_KINDS, OcclusionCheck, Outputs
from packbot.payload import Payload
from packbot.robots import ROBOTS

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["SCHEMA_FILE", "json_schema", "schema_text", "write_json_schema"]

#: The schema's file name beside the shipped scenarios (``sims/``).
SCHEMA_FILE = "scenario.schema.json"

_DRAFT = "http://json-schema.org/draft-07/schema#"


def _attribute_docs(cls: type) -> dict[str, str]:
    """The ``Attributes:`` section of a Google-style class docstring: name -> one line."""
    doc = inspect.cleandoc(cls.__doc__ or "")
    match = re.search(r"^Attributes:\n((?:(?: {4}.*)?\n?)+)", doc, flags=re.MULTILINE)
    if match is None:
        return {}
    docs: dict[str, str] = {}
    name = ""
    for line in match.group(1).splitlines():
        head = re.match(r"^ {4}(\w+): (.*)$", line)
        if head is not None:
            name = head.group(1)
            docs[name] = head.group(2).strip()
        elif line.startswith(" " * 8) and name:
            docs[name] += " " + line.strip()
    return {k: _plain(v) for k, v in docs.items()}


def _plain(text: str) -> str:
    """Docstring markup made plain text: ``x`` -> x, :class:`~a.B` -> a.B."""
    return re.sub(r"``([^`]*)``", r"\1", re.sub(r":\w+:`~?([^`]*)`", r"\1", text))


def _jsonable(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_jsonable(x) for x in value]
    return value


def _type_schema(hint: Any) -> dict[str, Any]:
    """The schema of a value of a field's type hint (TOML has no null: None is a missing key)."""
    origin = get_origin(hint)
    if hint is Any:
        return {}
    if origin is Literal:
        return {"type": "string", "enum": list(get_args(hint))}
    if origin in (typing.Union, types.UnionType):
        options = [_type_schema(a) for a in get_args(hint) if a is not type(None)]
        return options[0] if len(options) == 1 else {"anyOf": options}
    simple = {bool: "boolean", int: "integer", float: "number", str: "string"}
    if hint in simple:
        return {"type": simple[hint]}
    if origin is tuple:
        args = get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return {"type": "array", "items": _type_schema(args[0])}
        if len(set(args)) == 1:
            n = len(args)
            return {"type": "array", "items": _type_schema(args[0]), "minItems": n, "maxItems": n}
        return {"type": "array", "items": [_type_schema(a) for a in args], "additionalItems": False}
    if origin is dict or hint is dict:
        return {"type": "object"}
    return {}


def _dataclass_schema(
    cls: type, *, title: str, skip: tuple[str, ...] = (), override: dict[str, Any] | None = None
) -> dict[str, Any]:
    """An object schema of a dataclass's init fields: types, defaults, descriptions."""
    hints = typing.get_type_hints(cls)
    docs = _attribute_docs(cls)
    props: dict[str, Any] = {}
    required = []
    for f in dataclasses.fields(cls):
        if not f.init or f.name in skip:
            continue
        prop = _type_schema(hints[f.name])
        if f.name in docs:
            prop["description"] = docs[f.name]
        if f.default is not dataclasses.MISSING and f.default is not None:
            prop["default"] = _jsonable(f.default)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            required.append(f.name)
        props[f.name] = prop
    for name, extra in (override or {}).items():
        props[name] = {**props.get(name, {}), **extra}
    schema: dict[str, Any] = {
        "type": "object",
        "title": title,
        "properties": props,
        "additionalProperties": False,
    }
    if cls.__doc__:
        schema["description"] = _plain(inspect.cleandoc(cls.__doc__).split("\n\n")[0]).replace(
            "\n", " "
        )
    if required:
        schema["required"] = required
    return schema


def _names(names: tuple[str, ...] | list[str]) -> dict[str, Any]:
    return {"type": "string", "enum": list(names)}


def _controller_schema() -> dict[str, Any]:
    """``[controller]``: the kind, ``inform`` and the kind's own parameters (any value)."""
    from packbot.control.registry import _COMMON, CONTROLLER_KINDS, CONTROLLER_PARAMS

    every = [*_COMMON, *sorted({p for params in CONTROLLER_PARAMS.values() for p in params})]
    props: dict[str, Any] = {
        "kind": {
            **_names(CONTROLLER_KINDS),
            "default": "zero",
            "description": "The controller: zero (no torque, the default) or a kind of "
            "packbot.control.build_controller; every other key of [controller] is one of "
            "its parameters (docs/control.md).",
        },
        "inform": {
            "type": "boolean",
            "default": False,
            "description": "Whether the controller is told of each failure when it happens.",
        },
    }
    for p in every:
        kinds = [k for k, params in CONTROLLER_PARAMS.items() if p in params or p in _COMMON]
        props[p] = {"description": f"A parameter of {', '.join(kinds)} (docs/control.md)."}
    rules: list[dict[str, Any]] = []
    for kind, params in CONTROLLER_PARAMS.items():
        keys = ["kind", "inform", *_COMMON, *params]
        when: dict[str, Any] = {"properties": {"kind": {"const": kind}}, "required": ["kind"]}
        if kind == "zero":  # also when the kind is left out
            when = {"anyOf": [when, {"not": {"required": ["kind"]}}]}
        rules.append({"if": when, "then": {"propertyNames": {"enum": keys}}})
    return {
        "type": "object",
        "title": "Controller",
        "properties": props,
        "additionalProperties": False,
        "allOf": rules,
    }


def json_schema(robot: Robot | None = None) -> dict[str, Any]:
    """The JSON Schema (draft 7) of a scenario file.

    Args:
        robot: The model whose joint, pose and frame names the schema lists (default:
            :func:`packbot.load_robot`'s).

    Returns:
        The schema, as plain JSON values.
    """
    if robot is None:
        from packbot.model import load_robot

        robot = load_robot()
    joints = _names(robot.joint_names)
    frames = _names(sorted({str(f.name) for f in robot.model.frames}))
    nq = len(robot.joint_names)
    order = ", ".join(robot.joint_names)

    def joint_values(what: str, unit: str) -> dict[str, Any]:
        return {
            "description": f"{what} [{unit}]: {nq} values in joint order ({order}), or a table "
            "joint = value (the other joints as the pose, or 0).",
            "anyOf": [
                {"type": "array", "items": {"type": "number"}, "minItems": nq, "maxItems": nq},
                {
                    "type": "object",
                    "propertyNames": joints,
                    "additionalProperties": {"type": "number"},
                },
            ],
        }

    initial = {
        "type": "object",
        "title": "Initial state",
        "properties": {
            "pose": {
                **_names(sorted(robot.poses)),
                "description": "A named pose of the robot (all joints at 0 without one).",
            },
            "q": joint_values("Initial joint positions", "rad"),
            "v": joint_values("Initial joint velocities", "rad/s"),
        },
        "additionalProperties": False,
    }
    environment = {
        "type": "object",
        "title": "Environment",
        "properties": {
            "floor": {
                "type": "boolean",
                "default": True,
                "description": "Whether the floor (the plane z = 0) is there.",
            },
            "obstacles": {
                "type": "array",
                "items": _dataclass_schema(Obstacle, title="Obstacle"),
                "description": "Static convex obstacles, each a [[environment.obstacles]] table.",
            },
        },
        "additionalProperties": False,
    }
    outputs = _dataclass_schema(
        Outputs,
        title="Outputs",
        override={
            "plots": {"items": _names(PLOT_KINDS), "uniqueItems": True},
            "joints": {"items": joints, "uniqueItems": True, "minItems": 1},
            "formats": {"items": _names(IMAGE_FORMATS), "uniqueItems": True, "minItems": 1},
            "occlusion": _dataclass_schema(
                OcclusionCheck,
                title="Occlusion check",
                override={"frame": frames, "targets": {"minItems": 1}},
            ),
        },
    )
    return {
        "$schema": _DRAFT,
        "title": "packbot scenario",
        "description": "A packbot scenario file (docs/scenarios.md). Generated by `packbot "
        "schema` from packbot's own definitions; the loader checks ranges too.",
        "type": "object",
        "properties": {
            "robot": {
                "description": "The arm (docs/scenarios.md, 'Other arms'): a name "
                f"({', '.join(ROBOTS)}), a URDF path, or a [robot] table; PackBot without it. "
                "The joint, pose and frame names of this schema are PackBot's.",
                "anyOf": [
                    {"type": "string", "minLength": 1},
                    {
                        "type": "object",
                        "properties": {
                            "urdf": {"type": "string", "minLength": 1},
                            "package_dirs": {"type": "array", "items": {"type": "string"}},
                            "srdf": {"type": "string", "minLength": 1},
                            "tool_frame": {"type": "string", "minLength": 1},
                            "armature": {
                                "description": "joint -> armature [kg*m^2], or a TOML file "
                                "with an [armature] table",
                                "anyOf": [
                                    {"type": "string", "minLength": 1},
                                    {
                                        "type": "object",
                                        "additionalProperties": {"type": "number", "minimum": 0},
                                    },
                                ],
                            },
                        },
                        "required": ["urdf"],
                        "additionalProperties": False,
                    },
                ],
            },
            "description": {"type": "string", "description": "One line saying what it shows."},
            "duration": {
                "type": "number",
                "exclusiveMinimum": 0,
                "description": "Simulated time [s].",
            },
            "initial": initial,
            "config": _dataclass_schema(
                SimConfig,
                title="Simulation settings (packbot.SimConfig)",
                override={"locked_joints": {"items": joints, "uniqueItems": True}},
            ),
            "failures": {
                "type": "array",
                "description": "Joint failures, each a [[failures]] table; a joint may fail "
                "again later (docs/failures.md).",
                "items": _dataclass_schema(Failure, title="Failure", override={"joint": joints}),
            },
            "payload": _dataclass_schema(Payload, title="Payload", override={"frame": frames}),
            "controller": _controller_schema(),
            "environment": environment,
            "outputs": outputs,
        },
        "required": ["duration"],
        "additionalProperties": False,
    }


def schema_text(robot: Robot | None = None) -> str:
    """The schema as the shipped file's text (indented JSON, keys in definition order)."""
    return json.dumps(json_schema(robot), indent=2, ensure_ascii=False) + "\n"


def write_json_schema(path: str | Path, robot: Robot | None = None) -> Path:
    """Write the schema to ``path`` (a file, or a folder: ``<folder>/scenario.schema.json``).

    Returns:
        The file written.
    """
    out = Path(path)
    if out.is_dir():
        out = out / SCHEMA_FILE
    out.write_text(schema_text(robot), encoding="utf-8")
    return out
