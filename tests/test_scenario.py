"""Scenario files: every shipped one loads, validates and runs; bad fields give clear messages."""

import copy
import csv
import dataclasses
import itertools
import math
import os

import numpy as np
import pytest

import packbot
from packbot.config import CONTACT_MODES, SimConfig
from packbot.matrix import load_matrix, matrix_names
from packbot.plots import sample_distances
from packbot.scenario import (
    RENAMED_SCENARIOS,
    list_scenarios,
    load_scenario,
    read_scenario_dict,
    run_scenario,
    save_run,
    scenario_from_dict,
    scenario_path,
    write_outputs,
)

SHIPPED = sorted(list_scenarios())
#: Shortened run in the tests [s]: long enough for the failures injected at 0.5 s and 1.0 s.
SHORT = 1.2


def test_the_required_scenarios_are_shipped():
    names = set(SHIPPED)
    assert any(n.startswith("collapse") for n in names)
    assert {"collapse", "collapse_no_collisions", "loose_shoulder", "frozen_elbow_reach"} <= names
    assert {"collapse_elastic", "camera_occlusion"} <= names


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenario_validates_and_runs(robot, name):
    sc = load_scenario(name)
    assert sc.name == name and sc.description and sc.source_text
    sc.validate(robot)
    T = min(sc.duration, SHORT)
    res = run_scenario(sc, robot, duration=T)
    assert res.t[-1] == pytest.approx(T)
    assert np.all(np.isfinite(res.q)) and res.q.shape == (len(res.t), robot.nq)
    q0, v0 = sc.initial_state(robot)
    np.testing.assert_allclose(res.q[0], q0)
    np.testing.assert_allclose(res.v[0], v0)
    injected = [f for f in sc.failures if f.t < T]
    assert len(res.events_of("failure")) == len(injected)
    if sc.config.contact_mode != "none":
        assert res.diagnostics.min_distance >= -sc.config.contact_tolerance


def _collapse_dict():
    return read_scenario_dict("collapse")


def test_collapse_file_is_the_reports_collapse(robot):
    sc = load_scenario("collapse")
    assert sc.pose == "drive" and sc.controller == "zero" and not sc.failures
    assert sc.config.contact_mode == "joint_clamp"
    assert set(sc.config.locked_joints) == {
        "camera_tilt",
        "camera_pan",
        "gripper_roll",
        "gripper_jaw",
    }
    ref = packbot.simulate(
        robot,
        robot.pose("drive"),
        np.zeros(8),
        0.8,
        config=SimConfig(contact_mode="joint_clamp", locked_joints=sc.config.locked_joints),
    )
    res = run_scenario(sc, robot, duration=0.8)
    np.testing.assert_allclose(res.q, ref.q)
    assert [e.kind for e in res.events] == [e.kind for e in ref.events]


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenario_states_its_contact_mode(name):
    """A file without [config] contact_mode takes SimConfig's default, which has changed once
    (the report's law -> the contact-normal mode): each shipped one says which it means."""
    config = read_scenario_dict(name).get("config", {})
    assert config.get("contact_mode") in CONTACT_MODES
    if config["contact_mode"] == "normal":
        assert "mu" in config


@pytest.mark.parametrize("name", matrix_names())
def test_shipped_matrix_states_its_contact_mode(name):
    matrix = load_matrix(name)
    stated = "config.contact_mode" in matrix.axes or "config.contact_mode" in matrix.fixed
    config = read_scenario_dict(matrix.base_path()).get("config", {})
    assert stated or "contact_mode" in config
    modes = matrix.axes.get("config.contact_mode", [config.get("contact_mode")])
    if "normal" in modes:
        assert "config.mu" in matrix.axes or "config.mu" in matrix.fixed or "mu" in config


def test_collapse_physical_is_the_collapse_in_the_default_mode():
    """The same start as the report's collapse, in SimConfig's default mode and friction."""
    report, physical = load_scenario("collapse"), load_scenario("collapse_physical")
    assert physical.config.contact_mode == SimConfig().contact_mode == "normal"
    assert physical.config.mu == SimConfig().mu == 0.5
    assert report.config.contact_mode == "joint_clamp"
    assert physical.pose == report.pose and physical.controller == report.controller == "zero"
    assert physical.config.locked_joints == report.config.locked_joints
    assert physical.config.restitution == report.config.restitution
    assert not physical.failures and not report.failures


def test_a_renamed_scenario_still_loads_under_its_former_name():
    with pytest.warns(FutureWarning, match="'collapse_normal' is now called 'collapse_physical'"):
        sc = load_scenario("collapse_normal")
    assert sc.name == "collapse_physical" and sc.source_path == scenario_path("collapse_physical")
    assert "collapse_normal" not in list_scenarios()
    with pytest.warns(FutureWarning):
        assert read_scenario_dict("collapse_normal") == read_scenario_dict("collapse_physical")
    assert all(new in list_scenarios() for new in RENAMED_SCENARIOS.values())
    assert not set(RENAMED_SCENARIOS) & set(list_scenarios())


def test_collapse_without_collisions_falls_through_the_chassis(robot):
    sc = load_scenario("collapse_no_collisions")
    res = run_scenario(sc, robot, duration=SHORT)
    d = sample_distances(res, packbot.CollisionWorld(robot, sc.environment))
    assert d[0] > 0 and d.min() < -0.05  # deep penetration: nothing stops the links
    assert not res.events_of("impact")


def test_every_simconfig_field_is_accepted_in_config():
    """[config] takes SimConfig's fields as they are now (introspected, not listed)."""
    for f in dataclasses.fields(SimConfig):
        default = getattr(SimConfig(), f.name)
        if default is None:
            continue
        value = list(default) if isinstance(default, tuple) else default
        sc = scenario_from_dict({"duration": 1.0, "config": {f.name: value}}, name="t")
        assert getattr(sc.config, f.name) == default


def test_initial_state_by_list_table_and_pose(robot):
    q = [0.0, 0.3, 1.0, -0.5, 0.0, 0.0, 0.0, 0.1]
    sc = scenario_from_dict({"duration": 1.0, "initial": {"q": q, "v": {"elbow2": 0.25}}}, name="t")
    q0, v0 = sc.initial_state(robot)
    np.testing.assert_allclose(q0, q)
    assert v0[robot.params.index("elbow2")] == 0.25 and np.count_nonzero(v0) == 1
    sc = scenario_from_dict(
        {"duration": 1.0, "initial": {"pose": "stand", "q": {"elbow2": -0.9}}}, name="t"
    )
    q0, _ = sc.initial_state(robot)
    with pytest.raises(packbot.ConfigurationError, match=r"initial.q=\[0.1, 0.2\].*8 values"):
        d = {"duration": 1.0, "initial": {"q": [0.1, 0.2]}}
        scenario_from_dict(d, name="t").validate(robot)
    with pytest.raises(packbot.ConfigurationError, match="initial.q.*elbow1=3.5"):
        scenario_from_dict({"duration": 1.0, "initial": {"q": {"elbow1": 3.5}}}, name="t").validate(
            robot
        )
    expected = robot.pose("stand")
    expected[robot.params.index("elbow2")] = -0.9
    np.testing.assert_allclose(q0, expected)


def test_environment_and_outputs_load():
    sc = load_scenario("camera_occlusion")
    names = [o.name for o in sc.environment.obstacles]
    assert names[0] == "floor" and "crate" in names
    crate = sc.environment.obstacles[names.index("crate")]
    assert crate.kind == "box" and crate.size == (0.3, 0.6, 0.5)
    assert sc.outputs.occlusion is not None and len(sc.outputs.occlusion.targets) >= 2
    d = _collapse_dict()
    d["environment"] = {"floor": False}
    assert scenario_from_dict(d, name="t").environment.obstacles == ()


def _set(d, dotted, value):
    keys = dotted.replace("]", "").replace("[", ".").split(".")
    node = d
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
    node[keys[-1]] = value


BAD = [
    # (dotted key, value, words the message must hold)
    ("config.restitution", 1.5, ["config.restitution", "1.5", "[0, 1]"]),
    ("config.contact_mode", "springs", ["config.contact_mode", "springs", "joint_clamp", "none"]),
    ("config.restitutio", 0.5, ["config.restitutio", "restitution", "contact_mode"]),
    ("config.joint_limits", "yes", ["config.joint_limits", "yes", "true or false"]),
    ("config.gravity", [0.0, -9.81], ["config.gravity", "3"]),
    ("config.locked_joints", ["wrist"], ["config.locked_joints[0]", "wrist", "shoulder", "elbow1"]),
    ("config.contact_tolerance", -1.0, ["config.contact_tolerance", "-1.0", "positive"]),
    ("duration", 0.0, ["duration", "0.0", "positive"]),
    ("duration", "long", ["duration", "long", "a number"]),
    ("initial.pose", "sit", ["initial.pose", "sit", "drive", "stand"]),
    ("initial.q", {"wrist": 0.1}, ["initial.q.wrist", "shoulder", "gripper_jaw"]),
    ("initial.q", [0.0, 0.1], ["initial.q", "[0.0, 0.1]", "joint = value"]),
    ("initial.speed", 1.0, ["initial.speed", "pose", "q", "v"]),
    (
        "failures",
        [{"joint": "shoulder", "kind": "broken"}],
        ["failures[0].kind", "broken", "loose"],
    ),
    ("failures", [{"joint": "wrist", "kind": "loose"}], ["failures[0].joint", "wrist", "elbow2"]),
    ("failures", [{"joint": "elbow1", "kind": "weak", "scale": 2.0}], ["failures[0].scale", "2.0"]),
    ("failures", [{"kind": "loose"}], ["failures[0].joint", "required"]),
    ("failures", [{"joint": "elbow1", "kind": "loose", "when": 1}], ["failures[0].when", "t"]),
    ("payload", {"mass": -1.0}, ["payload.mass", "-1.0", "positive"]),
    ("payload", {"mass": 1.0, "frame": "hand"}, ["payload.frame", "hand", "gripper_tool"]),
    ("controller", {"kind": "telepathy"}, ["controller.kind", "telepathy", "zero"]),
    ("controller", {"kind": "zero", "gain": 3}, ["controller.gain", "3"]),
    ("environment.floor", "no", ["environment.floor", "true or false"]),
    (
        "environment.obstacles",
        [{"name": "wall", "kind": "cylinder"}],
        ["environment.obstacles[0].kind", "cylinder", "box", "halfspace"],
    ),
    (
        "environment.obstacles",
        [{"name": "wall", "kind": "box", "size": [1.0, 0.0, 1.0], "xyz": [3, 0, 1]}],
        ["environment.obstacles[0].size", "positive"],
    ),
    ("outputs.plots", ["joints", "pie"], ["outputs.plots[1]", "pie", "energy", "occlusion"]),
    ("outputs.joints", ["elbow3"], ["outputs.joints[0]", "elbow3", "elbow2"]),
    ("outputs.formats", ["pdf"], ["outputs.formats[0]", "pdf", "png", "svg"]),
    ("outputs.occlusion", {"targets": [[1.0, 0.0]]}, ["outputs.occlusion.targets[0]", "3"]),
    ("outputs.occlusion", {"targets": [[1, 0, 0]], "frame": "eye"}, ["occlusion.frame", "eye"]),
    ("outputs.html", 1, ["outputs.html", "true or false"]),
    ("speed", 2.0, ["speed", "duration", "config", "failures"]),
]


@pytest.mark.parametrize(("key", "value", "words"), BAD, ids=[f"{k}={v!r}" for k, v, _ in BAD])
def test_bad_field_names_the_field_value_and_choices(robot, key, value, words):
    d = copy.deepcopy(_collapse_dict())
    _set(d, key, value)
    with pytest.raises(packbot.ConfigurationError) as exc:
        sc = scenario_from_dict(d, name="bad")
        sc.validate(robot)
    msg = str(exc.value)
    for w in words:
        assert w in msg, (w, msg)


def test_missing_duration_is_named():
    with pytest.raises(packbot.ConfigurationError, match="duration"):
        scenario_from_dict({"initial": {"pose": "drive"}}, name="t")


def test_unknown_scenario_lists_the_shipped_ones():
    with pytest.raises(packbot.UnknownNameError) as exc:
        scenario_path("colapse")
    assert "colapse" in str(exc.value) and "collapse" in str(exc.value)
    with pytest.raises(packbot.ConfigurationError, match="existing file"):
        scenario_path("no/such/file.toml")


def test_bad_toml_says_where(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text('duration = 1.0\n[initial\npose = "drive"\n')
    with pytest.raises(packbot.ConfigurationError, match="line 2"):
        load_scenario(p)


def test_a_path_outside_sims_loads(tmp_path):
    p = tmp_path / "mine.toml"
    p.write_text('description = "mine"\nduration = 0.2\n[initial]\npose = "stow"\n')
    sc = load_scenario(p)
    assert sc.name == "mine" and sc.source_path == p and sc.pose == "stow"


def test_save_run_stores_trajectory_text_version_and_events(robot, tmp_path):
    sc = load_scenario("collapse")
    res = run_scenario(sc, robot, duration=0.8)
    paths = save_run(res, sc, tmp_path / "out")
    data = np.load(paths["trajectory"])
    np.testing.assert_array_equal(data["t"], res.t)
    np.testing.assert_array_equal(data["q"], res.q)
    assert str(data["scenario_text"]) == scenario_path("collapse").read_text()
    assert str(data["packbot_version"]) == packbot.__version__
    assert str(data["scenario_name"]) == "collapse"
    assert "joint_clamp" in str(data["config_json"])
    assert float(data["rest_time"]) == pytest.approx(res.rest_time)
    with paths["events"].open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["kind"] for r in rows] == [e.kind for e in res.events]
    assert float(rows[0]["time_s"]) == pytest.approx(res.events[0].t)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "collapse.npz",
        "collapse_events.csv",
    ]  # no temporary file left
    # the trajectory is the whole result (SimResult.save), its wall time stored as 0
    back = packbot.SimResult.load(paths["trajectory"])
    np.testing.assert_array_equal(back.v, res.v)
    assert back.environment == res.environment and back.config == res.config
    assert [e.t for e in back.events] == [e.t for e in res.events]
    assert back.scenario_text == scenario_path("collapse").read_text()
    assert back.diagnostics == dataclasses.replace(res.diagnostics, wall_time=0.0)
    umask = os.umask(0o022)
    os.umask(umask)
    assert paths["trajectory"].stat().st_mode & 0o777 == 0o666 & ~umask  # not private
    first = paths["trajectory"].read_bytes()
    save_run(res, sc, tmp_path / "out")
    assert paths["trajectory"].read_bytes() == first  # the same run: the same bytes


def test_occlusion_table_matches_line_of_sight(robot, tmp_path):
    sc = load_scenario("camera_occlusion")
    res = run_scenario(sc, robot, duration=0.6)
    paths = write_outputs(res, sc, robot, tmp_path, plots=False)
    with paths["occlusion_table"].open() as fh:
        rows = list(csv.reader(fh))
    occ = sc.outputs.occlusion
    assert len(rows) == len(res.t) + 1 and len(rows[0]) == 1 + len(occ.targets)
    world = packbot.CollisionWorld(robot, sc.environment)
    for i in (0, len(res.t) // 2, len(res.t) - 1):
        for k, target in enumerate(occ.targets):
            expected = world.line_of_sight(res.q[i], np.array(target)) or ""
            assert rows[i + 1][k + 1] == expected
    blocked = {cell for row in rows[1:] for cell in row[1:]}
    assert "" in blocked and len(blocked) >= 3  # some views clear, several different blockers
    assert not any(k in paths for k in ("joints", "occlusion"))  # plots=False


def test_run_scenario_duration_override_and_progress(robot):
    sc = load_scenario("collapse")
    seen: list[float] = []
    res = run_scenario(sc, robot, duration=0.3, progress=seen.append)
    assert res.t[-1] == pytest.approx(0.3)
    assert seen and all(b >= a for a, b in itertools.pairwise(seen))
    assert seen[-1] == pytest.approx(0.3) and math.isfinite(seen[0])
    with pytest.raises(packbot.ConfigurationError, match="duration"):
        run_scenario(sc, robot, duration=-1.0)


DEGRADING = """
description = "elbow1's motor degrading while the arm holds the stand pose"
duration = 1.2

[initial]
pose = "stand"

[config]
locked_joints = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]
sample_dt = 0.01

[[failures]]
joint = "elbow1"
kind = "weak"
scale = 0.7
t = 0.4

[[failures]]
joint = "elbow1"
kind = "weak"
scale = {second}
t = 0.8

[controller]
kind = "gravity"
"""


def test_a_scenario_with_two_failures_of_one_joint_loads_and_runs(robot, tmp_path):
    path = tmp_path / "degrading.toml"
    path.write_text(DEGRADING.format(second=0.3))
    sc = load_scenario(path)
    assert [(f.kind, f.scale, f.t) for f in sc.failures] == [("weak", 0.7, 0.4), ("weak", 0.3, 0.8)]
    res = run_scenario(sc, robot)
    j = res.joint("elbow1")
    ratio = res.effort[:, j] / robot.params.effort[j]
    for lo, hi, scale in ((0.0, 0.4, 1.0), (0.4, 0.8, 0.7), (0.8, 1.2, 0.3)):
        inside = (res.t > lo) & (res.t < hi)
        np.testing.assert_allclose(ratio[inside], scale, rtol=1e-12)
    assert len(res.events_of("failure")) == 2


def test_a_weak_joint_growing_stronger_in_a_file_names_the_field(tmp_path):
    path = tmp_path / "recovering.toml"
    path.write_text(DEGRADING.format(second=0.9))
    with pytest.raises(packbot.ConfigurationError) as exc:
        load_scenario(path)
    assert "failures[1].scale" in str(exc.value) and "below 0.7" in str(exc.value)
