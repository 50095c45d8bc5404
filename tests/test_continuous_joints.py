"""A URDF continuous joint: its angle is the coordinate (as in Drake and MuJoCo), unwrapped.

The two-link arm of ``test_any_arm`` with joint1 continuous (the shoulder, about y, 1 m above
the floor): it loads, spins past a turn, agrees with Pinocchio's own (cos, sin) model of the
same URDF, strikes an obstacle in every contact mode, takes every failure kind and every
built-in controller, and runs a failure study whose report shows it.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from test_any_arm import two_link_urdf

import packbot
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.continuous_joints import continuous_as_angles, sampling_bounds
from packbot.control.registry import CONTROLLER_KINDS, build_controller
from packbot.failures import FAILURE_KINDS

#: A lid above the shoulder that a fast-spinning arm strikes.
LID = packbot.Obstacle(name="lid", kind="box", size=(0.3, 0.3, 0.1), xyz=(0.0, 0.0, 1.6))
#: The contact modes (and the report's law with its hand-off).
MODES = [("normal", {}), ("joint_clamp", {}), ("joint_clamp", {"handoff": True})]


@pytest.fixture(scope="module")
def urdf_text() -> str:
    return two_link_urdf(kind="continuous", dynamics='\n    <dynamics damping="0.1"/>')


@pytest.fixture(scope="module")
def arm(tmp_path_factory, urdf_text) -> packbot.Robot:
    path = tmp_path_factory.mktemp("arm") / "spinner.urdf"
    path.write_text(urdf_text)
    return packbot.load_robot(path)


def _pin_configuration(theta: np.ndarray) -> np.ndarray:
    """Pinocchio's own configuration of the arm: (cos, sin) of joint1, then joint2's angle."""
    return np.array([np.cos(theta[0]), np.sin(theta[0]), theta[1]])


def test_a_continuous_joint_loads_as_one_angle_without_limits(arm, urdf_text) -> None:
    """nq == nv == 2; joint1 has no position limits (its effort and velocity limits and damping
    are the URDF's); the model is Pinocchio's (cos, sin) model of the same URDF, mass matrix,
    bias forces and every frame placement, at random angles (rounding: 1e-12)."""
    model = arm.model
    assert (model.nq, model.nv) == (2, 2)
    assert model.joints[1].shortname() == "JointModelRY"
    np.testing.assert_array_equal(arm.params.lower, [-np.inf, -3.0])
    np.testing.assert_array_equal(arm.params.upper, [np.inf, 3.0])
    np.testing.assert_array_equal(arm.params.bounded, [False, True])
    np.testing.assert_array_equal(arm.params.effort, [50.0, 50.0])
    np.testing.assert_array_equal(arm.params.viscous, [0.1, 0.0])
    assert all(np.isfinite(q).all() for q in arm.poses.values())
    own = pin.buildModelFromXML(urdf_text)
    assert (own.nq, own.nv) == (3, 2)
    d1, d2 = model.createData(), own.createData()
    rng = np.random.default_rng(3)
    for _ in range(20):
        theta = rng.uniform(-10.0, 10.0, 2)  # (beyond a turn: the angle is not wrapped)
        theta[1] = np.clip(theta[1], -3.0, 3.0)
        v, tau = rng.normal(size=2), rng.normal(size=2)
        q = _pin_configuration(theta)
        np.testing.assert_allclose(
            pin.aba(model, d1, theta, v, tau), pin.aba(own, d2, q, v, tau), atol=1e-12
        )
        np.testing.assert_allclose(pin.crba(model, d1, theta), pin.crba(own, d2, q), atol=1e-12)
        pin.framesForwardKinematics(model, d1, theta)
        pin.framesForwardKinematics(own, d2, q)
        for k in range(model.nframes):
            np.testing.assert_allclose(d1.oMf[k].homogeneous, d2.oMf[k].homogeneous, atol=1e-12)
    assert continuous_as_angles(model) is model  # (no unbounded joint left: unchanged)


def test_sampling_bounds_take_one_turn_of_a_joint_without_limits() -> None:
    lo, hi = sampling_bounds(np.array([-np.inf, -3.0]), np.array([np.inf, 3.0]), [7.0, 1.0])
    np.testing.assert_allclose(lo, [7.0 - np.pi, -3.0])
    np.testing.assert_allclose(hi, [7.0 + np.pi, 3.0])


def test_a_spinning_arm_matches_pinocchios_own_model_integrated_on_its_manifold(
    arm, urdf_text
) -> None:
    """12 rad/s at the shoulder, no contact, 2 s: joint1 turns three times (the angle unwrapped
    past 6 pi); it follows classical RK4 (1e-4 s) of Pinocchio's own nq 3 model, each stage
    through ``pin.integrate``, to 1e-6 rad (cos and sin of joint1, joint2). (The URDF's damping
    acts only with ``joint_friction``: off here.)"""
    cfg = packbot.SimConfig(contact_mode="none", rtol=1e-10, atol=1e-12, sample_dt=0.05)
    theta0, v0 = np.array([0.0, 0.0]), np.array([12.0, 0.0])
    res = packbot.simulate(arm, theta0, v0, 2.0, config=cfg)
    assert res.q[-1, 0] > 6 * np.pi
    own = pin.buildModelFromXML(urdf_text)
    own.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = own.createData()

    def accel(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return pin.aba(own, data, q, v, np.zeros(2))

    h = 1e-4
    q, v = _pin_configuration(theta0), v0.copy()
    samples = {round(t / h): k for k, t in enumerate(res.t)}
    for step in range(round(2.0 / h) + 1):
        if step in samples:
            k = samples[step]
            th = res.q[k]
            assert abs(np.cos(th[0]) - q[0]) < 1e-6 and abs(np.sin(th[0]) - q[1]) < 1e-6
            assert abs(th[1] - q[2]) < 1e-6
        k1v, k1a = v, accel(q, v)
        q2 = pin.integrate(own, q, 0.5 * h * k1v)
        k2v, k2a = v + 0.5 * h * k1a, accel(q2, v + 0.5 * h * k1a)
        q3 = pin.integrate(own, q, 0.5 * h * k2v)
        k3v, k3a = v + 0.5 * h * k2a, accel(q3, v + 0.5 * h * k2a)
        q4 = pin.integrate(own, q, h * k3v)
        k4v, k4a = v + h * k3a, accel(q4, v + h * k3a)
        q = pin.integrate(own, q, h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v))
        v = v + h / 6 * (k1a + 2 * k2a + 2 * k3a + k4a)
    assert len(samples) == len(res.t)


@pytest.mark.parametrize(("mode", "extra"), MODES)
def test_every_contact_mode_takes_a_spinning_arm_into_a_lid(arm, mode, extra) -> None:
    """12 rad/s at the shoulder under a lid: the arm strikes it (an impact), penetrates no pair
    beyond PENETRATION_TOL at the samples, gains no energy at an impact beyond rounding (1e-9 J)
    and none over the run beyond the integrator's error at its default tolerances (rtol 1e-6:
    1e-6 J of the 54.5 J; measured 4.5e-8 J in the contact-normal mode, 1.5e-9 J under the
    report's law, where the lid clamps the arm at the impact)."""
    env = packbot.Environment().with_obstacles(LID)
    cfg = packbot.SimConfig(contact_mode=mode, mu=0.5, sample_dt=0.002, **extra)
    v0 = np.array([12.0, 0.0])
    res = packbot.simulate(arm, np.zeros(2), v0, 2.0, config=cfg, environment=env)
    assert any(e.kind == "impact" for e in res.events)
    assert res.diagnostics.min_distance > -PENETRATION_TOL
    assert float(np.max(res.energy - np.minimum.accumulate(res.energy))) < 1e-6
    gains = [e.energy_after - e.energy_before for e in res.events if e.kind == "impact"]
    assert max(gains) < 1e-9
    assert np.abs(res.q[:, 0]).max() > np.pi / 2  # (it swung up to the lid)


@pytest.mark.parametrize("kind", FAILURE_KINDS)
def test_every_failure_kind_is_taken_by_the_continuous_joint(arm, kind) -> None:
    """Gravity compensation holds the shoulder at 1 rad (it carries gravity torque); at 0.2 s it
    fails. Loose, weak (5 % of its effort) and stuck joints let the arm fall; frozen and braked
    (its effort limit holds) joints stay."""
    q0 = np.array([1.0, 0.0])
    fail = packbot.Failure(joint="joint1", kind=kind, t=0.2, scale=0.05)
    ctrl = build_controller("gravity", arm, {})
    res = packbot.simulate(arm, q0, np.zeros(2), 0.6, controller=ctrl, failures=[fail])
    t = np.asarray(res.t)
    before, after = t < 0.2, t > 0.2 + 1e-9
    assert np.max(np.abs(res.q[before, 0] - q0[0])) < 1e-6
    moved = float(np.max(np.abs(res.q[after, 0] - q0[0])))
    if kind in ("frozen", "brake"):
        assert moved < 1e-6
    else:
        assert moved > 0.01, f"joint1 {kind}: moved {moved:.3g} rad"


def _tip(robot: packbot.Robot, q: np.ndarray) -> np.ndarray:
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.model.getFrameId(robot.tool_frame)].translation.copy()


@pytest.mark.parametrize("kind", CONTROLLER_KINDS)
def test_every_builtin_controller_drives_the_continuous_joint(arm, kind) -> None:
    """A joint-space target past a turn is reached the long way (the angle is the coordinate:
    2 pi + 0.5 is not 0.5); the tool-frame controllers bring the tip to a point (1 mm)."""
    q0 = np.array([0.5, 0.3])
    far = np.array([2 * np.pi + 0.5, 0.3])
    x_target = (_tip(arm, q0) + np.array([0.05, 0.0, 0.05])).tolist()
    params = {
        "zero": {},
        "gravity": {},
        "pd": {"target": far.tolist()},
        "computed_torque": {"waypoints": [q0.tolist(), far.tolist()]},
        "cartesian": {"target": x_target, "kp": 1000.0, "kd": 100.0},
        "reconfig": {"target": x_target},
    }[kind]
    ctrl = build_controller(kind, arm, params)
    duration = {"zero": 0.5, "gravity": 0.5, "pd": 6.0, "computed_torque": 4.0}.get(kind, 3.0)
    res = packbot.simulate(arm, q0, np.zeros(2), duration, controller=ctrl)
    q_end = res.q[-1]
    if kind == "zero":
        assert _tip(arm, q_end)[2] < _tip(arm, q0)[2] - 0.05
    elif kind == "gravity":
        assert np.max(np.abs(res.q - q0)) < 1e-6
    elif kind in ("pd", "computed_torque"):
        assert res.q[:, 0].max() > 2 * np.pi  # (the long way: past a turn)
        assert np.max(np.abs(q_end - far)) < 1e-3
    else:
        assert arm.tool_frame == "tip"
        err = np.linalg.norm(_tip(arm, q_end) - np.array(params["target"]))
        assert err < 1e-3, f"{kind} ends {err * 1000:.2f} mm from its target"


def test_a_failure_study_of_the_arm_reports_it(tmp_path, urdf_text) -> None:
    """The study (healthy / failed / reconfigured) of the arm reaching a point while its elbow
    locks: every run completes, the failed run misses the point, and the report names the
    arm's joints and tool frame."""
    from packbot.study import study
    from packbot.viz.study_report import write_study

    (tmp_path / "spinner.urdf").write_text(urdf_text)
    scenario = tmp_path / "reach.toml"
    scenario.write_text(
        'description = "spinner: the elbow locks during a reach"\n'
        'robot = "spinner.urdf"\nduration = 2.0\n\n'
        "[initial]\nq = { joint1 = 0.5, joint2 = 0.3 }\n\n"
        '[[failures]]\njoint = "joint2"\nkind = "frozen"\nt = 0.3\n\n'
        '[controller]\nkind = "reconfig"\ntarget = [0.35, 0.0, 0.6]\nspeed_fraction = 0.2\n'
        "inform = false\n"
    )
    res = study(scenario, workspace_samples=400)
    assert res.robot.joint_names == ("joint1", "joint2")
    assert all(run.status == "ok" for run in res.runs.values())
    assert res.runs["failed"].metrics.final_task_error_m > 0.01
    written = write_study(res, tmp_path / "out", formats=("png",))
    page = written["report.html"].read_text(encoding="utf-8")
    assert "joint2 frozen at 0.3 s" in page and "tip" in page
    summary = json.loads(written["study.json"].read_text(encoding="utf-8"))
    assert summary["task_frame"] == "tip"


def test_an_srdf_is_sampled_over_one_turn_of_the_continuous_joint(arm, tmp_path) -> None:
    from packbot.srdfgen import sample_link_distances

    ranges = sample_link_distances(arm, samples=200, seed=0)
    assert ranges and all(np.isfinite(lo) and np.isfinite(hi) for lo, hi in ranges.values())


def _spin_files(folder, urdf_text: str) -> None:
    """The arm and a scenario of it (its URDF named relative to the scenario's folder)."""
    (folder / "arms").mkdir(parents=True, exist_ok=True)
    (folder / "arms" / "spinner.urdf").write_text(urdf_text)
    (folder / "spin.toml").write_text(
        'description = "spinner: the shoulder spins under a lid"\n'
        'robot = "arms/spinner.urdf"\nduration = 0.6\n\n'
        "[initial]\nq = { joint1 = 0.0, joint2 = 0.0 }\nv = { joint1 = 12.0 }\n\n"
        '[[environment.obstacles]]\nname = "lid"\nkind = "box"\n'
        "size = [0.3, 0.3, 0.1]\nxyz = [0.0, 0.0, 1.6]\n\n"
        '[[failures]]\njoint = "joint2"\nkind = "loose"\nt = 0.1\n'
    )


def test_a_batch_of_the_arm_runs_in_worker_processes(tmp_path, urdf_text, monkeypatch) -> None:
    """A matrix over the arm's scenario, run by two local worker processes from another working
    directory: the arm's relative URDF path is the scenario file's (Run.source_path), every run
    is checked against that arm before any starts, and each result names its joints."""
    from packbot.batch import run_batch
    from packbot.matrix import load_matrix

    _spin_files(tmp_path / "cases", urdf_text)
    (tmp_path / "cases" / "m.toml").write_text(
        'base = "spin.toml"\n[axes]\n"config.mu" = [0.2, 0.8]\n'
        '"config.contact_mode" = ["normal", "joint_clamp"]\n'
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    matrix = load_matrix(tmp_path / "cases" / "m.toml")
    report = run_batch(matrix, tmp_path / "out", workers=2)
    assert len(report.records) == 4
    assert all(rec.status == "ok" for rec in report.records.values())
    header = (tmp_path / "out" / "summary.csv").read_text().splitlines()[0].split(",")
    assert "q.joint1" in header and "q.joint2" in header
    rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()[1:]
    assert all(int(row.split(",")[header.index("n_impacts")]) >= 1 for row in rows)
    # a bad joint name in an axis is refused before anything runs, naming the run and field
    (tmp_path / "cases" / "bad.toml").write_text(
        'base = "spin.toml"\n[axes]\n"failures.0.joint" = ["joint2", "elbow1"]\n'
    )
    with pytest.raises(packbot.errors.ConfigurationError, match="failures"):
        run_batch(load_matrix(tmp_path / "cases" / "bad.toml"), tmp_path / "bad", workers=0)


def test_a_study_matrix_of_the_arm_studies_each_cell(tmp_path, urdf_text) -> None:
    """A study matrix over the elbow's failure kinds on the arm: each cell is a failure study
    (healthy, failed, reconfigured) of that arm, with its report."""
    from packbot.study_matrix import run_study_matrix

    _spin_files(tmp_path, urdf_text)
    (tmp_path / "reach.toml").write_text(
        'robot = "arms/spinner.urdf"\nduration = 0.8\n\n'
        "[initial]\nq = { joint1 = 0.5, joint2 = 0.3 }\n\n"
        '[[failures]]\njoint = "joint2"\nkind = "frozen"\nt = 0.3\n\n'
        '[controller]\nkind = "reconfig"\ntarget = [0.35, 0.0, 0.6]\nspeed_fraction = 0.2\n'
        "inform = false\n"
    )
    (tmp_path / "sm.toml").write_text(
        'base = "reach.toml"\n[axes]\n"failures.0.kind" = ["frozen", "loose"]\n\n'
        "[study]\nworkspace_samples = 200\n"
    )
    report = run_study_matrix(tmp_path / "sm.toml", tmp_path / "out", workers=0)
    assert len(report.batch.records) == 2
    assert all(rec.status == "ok" for rec in report.batch.records.values())
    pages = sorted((tmp_path / "out").glob("*/report.html"))
    assert len(pages) == 2 and all("joint2" in p.read_text(encoding="utf-8") for p in pages)


def _piece_placements(arm: packbot.Robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """World placements of the arm's pieces (its collision pieces: the URDF has no <visual>)."""
    data = arm.model.createData()
    gm = arm.collision_model
    gd = gm.createData()
    pin.updateGeometryPlacements(arm.model, data, gm, gd, q)
    return {go.name: gd.oMg[k].homogeneous for k, go in enumerate(gm.geometryObjects)}


def test_the_page_and_the_live_viewer_show_the_spinning_arm(arm, tmp_path) -> None:
    """The recorded page animates the arm's pieces through the spin (the last key of the upper
    link's piece is Pinocchio's placement at the last sample, 1e-6 m: the page's float32), and
    the live viewer draws them and places them at a displayed configuration (1e-12)."""
    import asyncio

    import umsgpack
    from test_viz import _clips, _commands
    from tornado.websocket import websocket_connect

    from packbot.viz import start_viewer, write_html

    cfg = packbot.SimConfig(contact_mode="normal", sample_dt=0.01)
    res = packbot.simulate(arm, np.zeros(2), np.array([12.0, 0.0]), 0.5, config=cfg)
    page = write_html(arm, res, tmp_path / "spin.html")
    clips = _clips(_commands(page.read_text(encoding="utf-8")))
    path = "/meshcat/packbot/visuals/upper/0"
    assert path in clips
    times, values = clips[path][".position"]
    assert times[-1] == pytest.approx(res.t[-1], rel=1e-6)
    end = _piece_placements(arm, res.q[-1])["upper/0"]
    np.testing.assert_allclose(values[-1], end[:3, 3], atol=1e-6)

    q = np.array([7.0, 0.4])  # (past a turn)

    async def session(port: int, viewer) -> tuple[set[str], dict]:
        ws = await websocket_connect(f"ws://127.0.0.1:{port}/")
        scene = set()
        while True:
            try:
                msg = await asyncio.wait_for(ws.read_message(), 0.5)
            except asyncio.TimeoutError:
                break
            cmd = umsgpack.unpackb(msg)
            if cmd["type"] == "set_object":
                scene.add(cmd["path"])
        await asyncio.get_running_loop().run_in_executor(None, viewer.display, q)
        while True:
            pose = umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 5.0))
            if pose["path"] == path:
                ws.close()
                return scene, pose

    with start_viewer(arm) as viewer:
        scene, pose = asyncio.run(session(viewer.port, viewer))
    assert {f"/meshcat/packbot/visuals/{name}" for name in _piece_placements(arm, q)} <= scene
    matrix = np.array(pose["matrix"]).reshape(4, 4).T
    np.testing.assert_allclose(matrix, _piece_placements(arm, q)["upper/0"], atol=1e-12)


def test_the_actuator_model_acts_on_the_continuous_joint(tmp_path) -> None:
    """With joint friction (the URDF's damping 0.1 N*m*s/rad and friction 0.2 N*m at the
    shoulder) a free spin past a turn loses the friction's work and its stop events' losses:
    E(t) - E(0) - (the events' changes) = int v . tau_friction dt (trapezoid at 1 ms: 1e-4 of
    the work). With a motor lag of 50 ms and the effort limit, a PD still takes the
    shoulder past a turn to its target; the applied torque never exceeds the limit."""
    path = tmp_path / "rubbing.urdf"
    path.write_text(
        two_link_urdf(kind="continuous", dynamics='\n    <dynamics damping="0.1" friction="0.2"/>')
    )
    arm = packbot.load_robot(path)
    cfg = packbot.SimConfig(contact_mode="none", joint_friction=True, sample_dt=0.001)
    res = packbot.simulate(arm, np.zeros(2), np.array([12.0, 0.0]), 3.0, config=cfg)
    assert res.q[:, 0].max() > 2 * np.pi
    power = np.einsum("ij,ij->i", np.asarray(res.v), np.asarray(res.tau_friction))
    t = np.asarray(res.t)
    work = float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))
    # (joint2 strikes its stops: each stop's energy change is in its event)
    stops = sum(e.energy_after - e.energy_before for e in res.events)
    loss = float(res.energy[-1] - res.energy[0]) - stops
    assert work < -1.0 and abs(loss - work) < 1e-4 * abs(work), (loss, work, stops)
    lagged = packbot.SimConfig(contact_mode="none", motor_lag=0.05, effort_saturation=True)
    target = np.array([2 * np.pi + 0.5, 0.3])
    ctrl = build_controller("pd", arm, {"target": target.tolist()})
    res = packbot.simulate(
        arm, np.array([0.5, 0.3]), np.zeros(2), 8.0, controller=ctrl, config=lagged
    )
    assert np.max(np.abs(res.q[-1] - target)) < 1e-3
    assert np.max(np.abs(np.asarray(res.tau))) <= 50.0 + 1e-9
