"""The JSON Schema of scenario files: made from packbot's definitions, shipped up to date.

The validation tests need the ``jsonschema`` package (the ``test`` extra) and are skipped
without it; the others read the schema as plain JSON.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from packbot.cli import main
from packbot.config import CLAMP_RULES, CONTACT_MODES, RESET_RULES, SimConfig
from packbot.control.registry import _COMMON, CONTROLLER_KINDS, CONTROLLER_PARAMS
from packbot.environment import OBSTACLE_KINDS, Obstacle
from packbot.errors import PackbotError
from packbot.failures import FAILURE_KINDS, Failure
from packbot.payload import Payload
from packbot.scenario import (
    _ENVIRONMENT_KEYS,
    _FORMATS,
    _INITIAL_KEYS,
    PLOT_KINDS,
    TOP_LEVEL_KEYS,
    OcclusionCheck,
    Outputs,
    json_schema,
    list_scenarios,
    load_scenario,
)
from packbot.scenario_schema import SCHEMA_FILE, schema_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SIMS = Path(__file__).resolve().parents[1] / "sims"


@pytest.fixture(scope="module")
def schema(robot) -> dict[str, Any]:
    return json_schema(robot)


def _props(schema: dict[str, Any], *path: str) -> dict[str, Any]:
    node = schema
    for key in path:
        node = node["items"] if key == "[]" else node["properties"][key]
    return node


def test_the_shipped_schema_is_up_to_date(robot) -> None:
    assert (SIMS / SCHEMA_FILE).read_text(encoding="utf-8") == schema_text(robot)


def test_the_enums_are_packbots_choice_lists(schema: dict[str, Any], robot) -> None:
    def enum(*path: str) -> list[str]:
        return _props(schema, *path)["enum"]

    assert enum("config", "contact_mode") == list(CONTACT_MODES)
    assert enum("config", "clamp_rule") == list(CLAMP_RULES)
    assert enum("config", "reset_rule") == list(RESET_RULES)
    assert enum("failures", "[]", "kind") == list(FAILURE_KINDS)
    assert enum("environment", "obstacles", "[]", "kind") == list(OBSTACLE_KINDS)
    assert enum("outputs", "plots", "[]") == list(PLOT_KINDS)
    assert enum("outputs", "formats", "[]") == list(_FORMATS)
    assert enum("controller", "kind") == list(CONTROLLER_KINDS)
    joints = list(robot.joint_names)
    assert enum("failures", "[]", "joint") == joints
    assert enum("config", "locked_joints", "[]") == joints
    assert enum("outputs", "joints", "[]") == joints
    table = _props(schema, "initial", "q")["anyOf"][1]
    assert table["propertyNames"]["enum"] == joints
    assert sorted(enum("initial", "pose")) == sorted(robot.poses)
    frames = sorted({str(f.name) for f in robot.model.frames})
    assert enum("payload", "frame") == frames == enum("outputs", "occlusion", "frame")


def test_each_kind_of_controller_takes_its_own_parameters(schema: dict[str, Any]) -> None:
    ctrl = schema["properties"]["controller"]
    allowed: dict[str, set[str]] = {}
    for rule in ctrl["allOf"]:
        when = rule["if"]
        kind = (when["anyOf"][0] if "anyOf" in when else when)["properties"]["kind"]["const"]
        allowed[kind] = set(rule["then"]["propertyNames"]["enum"])
    assert allowed == {
        k: {"kind", "inform", *_COMMON, *params} for k, params in CONTROLLER_PARAMS.items()
    }


@pytest.mark.parametrize(
    ("path", "cls"),
    [
        (("config",), SimConfig),
        (("failures", "[]"), Failure),
        (("payload",), Payload),
        (("environment", "obstacles", "[]"), Obstacle),
        (("outputs",), Outputs),
        (("outputs", "occlusion"), OcclusionCheck),
    ],
)
def test_the_tables_have_the_dataclasses_fields(schema, path, cls) -> None:
    node = _props(schema, *path)
    fields = [f.name for f in dataclasses.fields(cls) if f.init]
    assert list(node["properties"]) == fields
    assert node["additionalProperties"] is False
    required = [
        f.name
        for f in dataclasses.fields(cls)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    assert node.get("required", []) == required
    # every field has its docstring line as the editor's hover text
    assert all(p.get("description") for p in node["properties"].values())


def test_the_other_tables_have_the_loaders_keys(schema: dict[str, Any]) -> None:
    assert list(schema["properties"]) == list(TOP_LEVEL_KEYS)
    assert list(_props(schema, "initial")["properties"]) == list(_INITIAL_KEYS)
    assert list(_props(schema, "environment")["properties"]) == list(_ENVIRONMENT_KEYS)
    assert schema["required"] == ["duration"] and schema["additionalProperties"] is False
    assert _props(schema, "config", "sample_dt")["default"] == SimConfig().sample_dt
    assert _props(schema, "config", "gravity")["default"] == list(SimConfig().gravity)


def test_packbot_schema_prints_it_and_checks_a_copy(tmp_path: Path, capsys, robot) -> None:
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(schema_text(robot))
    assert main(["schema", "--out", str(tmp_path)]) == 0
    written = tmp_path / SCHEMA_FILE
    assert written.read_text(encoding="utf-8") == schema_text(robot)
    assert main(["schema", "--out", str(tmp_path), "--check"]) == 0
    written.write_text("{}", encoding="utf-8")
    assert main(["schema", "--out", str(written), "--check"]) == 1
    assert "out of date" in capsys.readouterr().out


# ---------------------------------------------------------------------------------- validation
@pytest.fixture(scope="module")
def validator(schema: dict[str, Any]) -> Any:
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


@pytest.mark.parametrize("name", sorted(list_scenarios()))
def test_every_shipped_scenario_validates(validator, name: str) -> None:
    data = tomllib.loads(list_scenarios()[name].read_text(encoding="utf-8"))
    assert [e.message for e in validator.iter_errors(data)] == []


def test_a_scenario_using_every_table_validates_and_loads(validator, robot, tmp_path) -> None:
    text = """
description = "every table"
duration = 0.1
[initial]
pose = "drive"
q = { shoulder = 0.1 }
v = { elbow1 = -0.2 }
[config]
contact_mode = "joint_clamp"
clamp_rule = "jacobian"
locked_joints = ["camera_pan"]
gravity = [0, 0, -9.81]
max_events = 100
[[failures]]
joint = "elbow2"
kind = "brake"
t = 0.05
threshold = 2.0
[payload]
mass = 1.5
com = [0, 0, 0.05]
t_drop = 0.08
[controller]
kind = "pd"
kp = 50.0
dt = 0.001
inform = true
[environment]
floor = true
[[environment.obstacles]]
name = "wall"
kind = "halfspace"
normal = [1, 0, 0]
offset = 2.0
[outputs]
plots = ["joints", "occlusion"]
formats = ["svg"]
[outputs.occlusion]
targets = [[1.0, 0.0, 0.2]]
radius = 0.01
"""
    path = tmp_path / "every.toml"
    path.write_text(text, encoding="utf-8")
    assert [e.message for e in validator.iter_errors(tomllib.loads(text))] == []
    load_scenario(path).validate(robot)  # and packbot takes it


@pytest.mark.parametrize(
    ("text", "where", "words"),
    [
        ("durations = 1.0", [], "durations"),
        ('[config]\ncontact_mode = "nromal"', ["config", "contact_mode"], "nromal"),
        ("[config]\nrtol = true", ["config", "rtol"], "number"),
        ('[config]\nlocked_joints = "camera_pan"', ["config", "locked_joints"], "array"),
        ('[[failures]]\njoint = "elbow3"\nkind = "loose"', ["failures", 0, "joint"], "elbow3"),
        ('[[failures]]\njoint = "elbow1"', ["failures", 0], "kind"),
        ('[controller]\nkind = "pd"\nspeed_fraction = 0.5', ["controller"], "speed_fraction"),
        ("[controller]\nkp = 5.0", ["controller"], "kp"),
        ("[payload]\nmass = 1\ncom = [0, 0]", ["payload", "com"], "short"),
        ('[outputs]\nplots = ["joints", "joints"]', ["outputs", "plots"], "non-unique"),
        ("[initial]\nq = [0.0, 0.1]", ["initial", "q"], "not valid"),
    ],
)
def test_the_schema_flags_what_the_loader_refuses(validator, robot, tmp_path, text, where, words):
    body = "duration = 0.05\n" + text
    if "[initial]" not in text:
        body += '\n[initial]\npose = "drive"\n'
    errors = list(validator.iter_errors(tomllib.loads(body)))
    assert len(errors) == 1, [e.message for e in errors]
    assert list(errors[0].absolute_path) == where
    assert words in errors[0].message
    path = tmp_path / "bad.toml"
    path.write_text(body, encoding="utf-8")
    with pytest.raises(PackbotError):  # packbot refuses it too
        load_scenario(path).validate(robot)
