"""SimResult carries its environment, failures, payload and scenario; save/load round-trips
exactly; to_dataframe; a wrong or corrupt file gives a PackbotError."""

import dataclasses
import json
import sys
import zipfile

import numpy as np
import pytest

import packbot
from packbot.errors import ConfigurationError, PackbotError
from packbot.result import _ARRAYS, RESULT_FORMAT, ResultFileError, SimResult
from packbot.scenario import load_scenario, run_scenario, scenario_path

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def rich_run(robot):
    """The arm falling onto a box, a loose elbow1 at 0.05 s and a payload picked at 0.02 s."""
    box = packbot.Obstacle(name="block", kind="box", size=(0.6, 0.6, 0.5), xyz=(1.3, 0.0, 0.25))
    env = packbot.Environment().with_obstacles(box)
    cfg = packbot.SimConfig(locked_joints=WRIST, sample_dt=0.02)
    fail = packbot.Failure(joint="elbow1", kind="loose", t=0.05)
    pay = packbot.Payload(mass=0.5, com=(0.01, 0.0, 0.02), t_pick=0.02, t_drop=0.4)
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        0.8,
        environment=env,
        config=cfg,
        failures=[fail],
        payload=pay,
    )
    return res, env, cfg, fail, pay


def _assert_same(a: SimResult, b: SimResult) -> None:
    for name in _ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert np.array_equal(x, y), name
    assert len(a.events) == len(b.events)
    for ea, eb in zip(a.events, b.events, strict=True):
        for f in dataclasses.fields(ea):
            va, vb = getattr(ea, f.name), getattr(eb, f.name)
            if isinstance(va, np.ndarray):
                assert va.shape == vb.shape and np.array_equal(va, vb), f.name
            elif isinstance(va, float):
                assert np.array_equal(va, vb, equal_nan=True), f.name  # NaN == NaN here
                assert type(vb) is float
            else:
                assert va == vb, f.name
    assert a.config == b.config
    assert a.environment == b.environment
    assert a.failures == b.failures
    assert a.payload == b.payload
    assert a.diagnostics == b.diagnostics
    assert a.joint_names == b.joint_names
    assert a.rest_time == b.rest_time
    assert a.control_ticks == b.control_ticks
    assert a.scenario_text == b.scenario_text


def test_result_carries_environment_failures_and_payload(rich_run):
    res, env, _cfg, fail, pay = rich_run
    assert res.environment == env
    assert [o.name for o in res.environment.obstacles] == ["floor", "block"]
    assert res.failures == (fail,)
    # the payload as simulated: its frame named (None: the robot's tool frame)
    assert pay.frame is None and res.payload == pay.held_in("gripper_tool")
    assert {"failure", "pick", "drop"} <= {e.kind for e in res.events}
    assert res.events_of("impact"), "the run should hit something"


def test_simulate_without_environment_records_the_floor(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, sample_dt=0.05)
    res = packbot.simulate(robot, robot.pose("stand"), np.zeros(8), 0.1, config=cfg)
    assert res.environment == packbot.Environment()
    assert res.payload is None and res.scenario_text == ""


def test_save_load_round_trips_exactly(rich_run, tmp_path):
    res = rich_run[0]
    res.scenario_text = 'name = "x"\n# ünïcode and "quotes"\n'
    try:
        path = res.save(tmp_path / "sub" / "run.npz")
        assert path == tmp_path / "sub" / "run.npz" and path.is_file()
        back = SimResult.load(path)
    finally:
        res.scenario_text = ""
    _assert_same(res, dataclasses.replace(back, scenario_text=""))
    assert back.scenario_text == 'name = "x"\n# ünïcode and "quotes"\n'
    # the objects were rebuilt by their constructors (real types, not dicts)
    assert isinstance(back.environment, packbot.Environment)
    assert isinstance(back.environment.obstacles[1], packbot.Obstacle)
    assert isinstance(back.failures[0], packbot.Failure)
    assert isinstance(back.payload, packbot.Payload)
    assert isinstance(back.config, packbot.SimConfig)
    # saving the loaded result again gives the same content
    again = SimResult.load(back.save(tmp_path / "again"))
    _assert_same(back, again)


def test_file_is_tagged_and_not_pickled(rich_run, tmp_path):
    path = rich_run[0].save(tmp_path / "run.npz")
    with np.load(path, allow_pickle=False) as data:
        assert str(data["format"]) == RESULT_FORMAT
        meta = json.loads(str(data["meta_json"]))
        # plain entries for a reader with NumPy alone
        assert tuple(data["joint_names"]) == rich_run[0].joint_names
        assert np.array_equal(data["q"], rich_run[0].q)
        assert json.loads(str(data["config_json"]))["locked_joints"] == list(WRIST)
    assert meta["packbot_version"] == packbot.__version__
    assert meta["environment"]["obstacles"][1]["name"] == "block"
    assert zipfile.ZipFile(path).infolist()[0].compress_type == zipfile.ZIP_DEFLATED


def test_result_without_environment_or_events_round_trips(rich_run, tmp_path):
    res = dataclasses.replace(rich_run[0], events=[], environment=None, payload=None, failures=())
    back = SimResult.load(res.save(tmp_path / "bare.npz"))
    _assert_same(res, back)
    assert back.environment is None and back.events == []


def test_scenario_run_carries_its_text_and_saves(robot, tmp_path):
    sc = load_scenario("collapse")
    res = run_scenario(sc, robot=robot, duration=0.05)
    assert res.scenario_text == scenario_path("collapse").read_text()
    back = SimResult.load(res.save(tmp_path / "c.npz"))
    _assert_same(res, back)


def test_load_missing_file(tmp_path):
    with pytest.raises(ResultFileError, match="no such file"):
        SimResult.load(tmp_path / "nope.npz")


def test_load_not_an_npz(tmp_path):
    p = tmp_path / "junk.npz"
    p.write_bytes(b"this is not a zip file at all")
    with pytest.raises(ResultFileError, match="not a readable"):
        SimResult.load(p)


def test_load_npz_without_tag(tmp_path):
    p = tmp_path / "other.npz"
    with p.open("wb") as fh:
        np.savez(fh, t=np.zeros(3))
    with pytest.raises(ResultFileError, match="no format tag"):
        SimResult.load(p)


def test_load_wrong_tag(rich_run, tmp_path):
    p = rich_run[0].save(tmp_path / "run.npz")
    with np.load(p) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["format"] = np.array("packbot.SimResult/999")
    with p.open("wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ResultFileError, match="SimResult/999"):
        SimResult.load(p)


@pytest.mark.parametrize("drop", ["q", "event_v_before", "event_t"])
def test_load_missing_entry_is_corrupt(rich_run, tmp_path, drop):
    p = rich_run[0].save(tmp_path / "run.npz")
    with np.load(p) as data:
        arrays = {k: data[k] for k in data.files if k != drop}
    with p.open("wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ResultFileError, match="corrupt"):
        SimResult.load(p)


def test_load_truncated_file(rich_run, tmp_path):
    p = rich_run[0].save(tmp_path / "run.npz")
    raw = p.read_bytes()
    p.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ResultFileError):
        SimResult.load(p)


def test_load_revalidates_stored_objects(rich_run, tmp_path):
    p = rich_run[0].save(tmp_path / "run.npz")
    with np.load(p) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["meta_json"]))
    meta["payload"]["mass"] = -1.0
    arrays["meta_json"] = np.array(json.dumps(meta))
    with p.open("wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ConfigurationError, match="payload.mass"):
        SimResult.load(p)


def test_save_to_a_directory_is_an_error(rich_run, tmp_path):
    with pytest.raises(PackbotError, match="directory"):
        rich_run[0].save(tmp_path)


def test_save_extra_entries(rich_run, tmp_path):
    res = rich_run[0]
    p = res.save(tmp_path / "r.npz", extra={"scenario_name": "mine"})
    with np.load(p) as data:
        assert str(data["scenario_name"]) == "mine"
    _assert_same(SimResult.load(p), res)  # load ignores them
    for taken in ("t", "meta_json", "event_t", "event_new"):
        with pytest.raises(ConfigurationError, match="extra"):
            res.save(tmp_path / "bad.npz", extra={taken: "x"})
    assert not (tmp_path / "bad.npz").exists()


def test_to_dataframe_columns_and_values(rich_run):
    pd = pytest.importorskip("pandas")
    res = rich_run[0]
    df = res.to_dataframe()
    assert isinstance(df, pd.DataFrame)
    assert df.index.name == "t" and np.array_equal(df.index.to_numpy(), res.t)
    assert len(df.columns) == 6 * len(res.joint_names) + 1
    k = res.joint("elbow1")
    assert np.array_equal(df["q:elbow1"].to_numpy(), res.q[:, k])
    assert np.array_equal(df["tau_cmd:elbow1"].to_numpy(), res.tau_cmd[:, k])
    assert np.array_equal(df["energy"].to_numpy(), res.energy)


def test_to_dataframe_without_pandas_says_how_to_install(rich_run, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas -> ImportError
    with pytest.raises(PackbotError, match=r'pip install "packbot\[pandas\]"'):
        rich_run[0].to_dataframe()


# ---------------------------------------------------------------------------- frame positions
def test_frame_positions_follow_the_joints(rich_run, robot):
    """The tool's world position at every sample: FK at the start, and its motion between two
    samples is the frame Jacobian times the joint velocities (to first order)."""
    import pinocchio as pin

    res = rich_run[0]
    xyz = res.frame_positions("gripper_tool")
    assert xyz.shape == (len(res.t), 3)
    data = robot.model.createData()
    fid = robot.model.getFrameId("gripper_tool")
    pin.framesForwardKinematics(robot.model, data, robot.pose("stand"))
    np.testing.assert_allclose(xyz[0], data.oMf[fid].translation, atol=1e-12)
    np.testing.assert_allclose(res.frame_positions("gripper_tool", robot), xyz, atol=0.0)
    # a step without an event (distinct times): dp ~ J v dt, the second-order rest below 20 %
    # of the displacement (the arm accelerates at a few rad/s^2 over 20 ms)
    k = next(i for i in range(len(res.t) - 1) if res.t[i + 1] - res.t[i] > 0.019 and i > 3)
    dt = res.t[k + 1] - res.t[k]
    J = pin.computeFrameJacobian(robot.model, data, res.q[k], fid, pin.LOCAL_WORLD_ALIGNED)[:3]
    v_mid = 0.5 * (res.v[k] + res.v[k + 1])
    dp = xyz[k + 1] - xyz[k]
    assert np.linalg.norm(dp) > 1e-4  # the arm is falling: it moves
    assert np.linalg.norm(dp - J @ v_mid * dt) < 0.2 * np.linalg.norm(dp)
    # another frame: the camera does not move with the arm's joints below the turret here
    assert res.frame_positions("camera_optical").shape == (len(res.t), 3)


def test_frame_positions_of_a_loaded_result(rich_run, tmp_path):
    res = rich_run[0]
    back = SimResult.load(res.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.frame_positions(), res.frame_positions())


def test_frame_positions_unknown_frame_or_robot(rich_run):
    res = rich_run[0]
    with pytest.raises(packbot.UnknownNameError, match="gripper_tool") as exc:
        res.frame_positions("gripper_toll")
    assert exc.value.suggestion == "gripper_tool"
    with pytest.raises(ConfigurationError, match="robot"):
        res.frame_positions("gripper_tool", robot="packbot")
    renamed = dataclasses.replace(res, joint_names=tuple(f"j{k}" for k in range(8)))
    with pytest.raises(ConfigurationError, match="the result's joints"):
        renamed.frame_positions()
