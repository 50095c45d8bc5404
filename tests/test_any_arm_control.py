"""Every built-in controller, every failure kind and the failure study on arms other than
PackBot (UR5 and Panda from example-robot-data), checked on the simulation's output."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control.registry import CONTROLLER_KINDS, build_controller
from packbot.errors import ResourceNotFound
from packbot.failures import FAILURE_KINDS
from packbot.robots import robot_files

#: Start poses clear of the floor and of the arm itself [rad].
RAISED = {
    "ur5": {"shoulder_lift_joint": -1.2, "elbow_joint": 0.6, "wrist_1_joint": -1.0},
    "panda": {"panda_joint2": 0.3, "panda_joint4": -1.2, "panda_joint6": 1.5},
}
#: A joint that carries gravity torque at the raised pose (a failure there shows).
LOADED_JOINT = {"ur5": "shoulder_lift_joint", "panda": "panda_joint2"}
#: The Cartesian targets' offset from the raised pose's tool position [m].
OFFSET = np.array([0.05, 0.05, -0.05])
#: The Panda's locked-joint study (sims/arms/).
PANDA_STUDY = Path(__file__).resolve().parents[1] / "sims" / "arms" / "panda_locked_joint.toml"

ARMS = ["ur5", "panda"]
_LOADED: dict[str, packbot.Robot] = {}


def _arm(name: str) -> packbot.Robot:
    if name not in _LOADED:
        try:
            robot_files(name)
        except ResourceNotFound:
            pytest.skip("example-robot-data is not installed (the arms extra)")
        _LOADED[name] = packbot.load_robot(name)
    return _LOADED[name]


def _tool(robot: packbot.Robot, q: np.ndarray) -> np.ndarray:
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.model.getFrameId(robot.tool_frame)].translation.copy()


def _arm_joints(robot: packbot.Robot) -> np.ndarray:
    """The joints with a range over 0.5 rad (the arm's; not the Panda's 4 cm fingers)."""
    return (robot.params.upper - robot.params.lower) > 0.5


# ------------------------------------------------------------------ controllers
def _params(kind: str, robot: packbot.Robot, q0: np.ndarray) -> dict:
    """The scenario-file parameters of each kind, moving the arm from q0."""
    step = 0.1 * _arm_joints(robot)
    x_target = (_tool(robot, q0) + OFFSET).tolist()
    return {
        "zero": {},
        "gravity": {},
        "pd": {"target": (q0 + step).tolist()},
        "computed_torque": {"waypoints": [q0.tolist(), (q0 + 2 * step).tolist()]},
        "cartesian": {"target": x_target, "kp": 1000.0, "kd": 100.0},  # (overdamped: it creeps)
        "reconfig": {"target": x_target},
    }[kind]


def test_the_registry_lists_the_kinds_checked_here() -> None:
    assert set(CONTROLLER_KINDS) == {
        "zero",
        "gravity",
        "pd",
        "computed_torque",
        "cartesian",
        "reconfig",
    }


@pytest.mark.parametrize("kind", CONTROLLER_KINDS)
@pytest.mark.parametrize("name", ARMS)
def test_every_builtin_controller_does_what_it_claims(name: str, kind: str) -> None:
    """Each kind built from plain values (as a scenario file gives them) on the arm, simulated
    in the contact-normal mode with the floor, its claim checked at the end of the run."""
    robot = _arm(name)
    q0 = robot.q_from(RAISED[name], base="zero")
    params = _params(kind, robot, q0)
    ctrl = build_controller(kind, robot, params)
    duration = {"zero": 1.0, "gravity": 1.0}.get(kind, 3.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.model.nv), duration, controller=ctrl)
    q_end = res.q[-1]
    if kind == "zero":  # no torque: the arm falls, the tool ends lower
        assert ctrl is None
        assert _tool(robot, q_end)[2] < _tool(robot, q0)[2] - 0.05
    elif kind == "gravity":  # g(q) exactly: the arm stays; 1 urad covers the integrator's error
        assert np.max(np.abs(res.q - q0)) < 1e-6
    elif kind in ("pd", "computed_torque"):  # at the (last) target: 1 mrad, gains' settling
        target = np.array(params["target"] if kind == "pd" else params["waypoints"][-1])
        assert np.max(np.abs(q_end - target)) < 1e-3
    else:  # the tool frame at the target: 1 mm, the controllers' settling after 3 s
        assert ctrl.frame == robot.tool_frame
        err = np.linalg.norm(_tool(robot, q_end) - np.array(params["target"]))
        assert err < 1e-3, f"{kind} ends {err * 1000:.2f} mm from its target"


def test_the_tool_frame_controllers_take_the_arms_tool_frame() -> None:
    from packbot.control import CartesianPD
    from packbot.control.recovery import TaskRecovery

    robot = _arm("panda")
    q0 = robot.q_from(RAISED["panda"], base="zero")
    cart = CartesianPD(target="zero")
    cart.prepare(robot)  # before a run: the posture from the arm's first pose ("zero")
    assert cart.frame == "panda_hand_tcp"
    np.testing.assert_allclose(cart.target, _tool(robot, robot.pose("zero")))
    x = np.array([_tool(robot, q0)] * 2)
    rec = TaskRecovery(nominal=None, task_t=[0.0, 1.0], task_x=x)
    rec.reset(robot, 0.0, q0, np.zeros(robot.model.nv))
    assert rec.frame == rec.context.frame == "panda_hand_tcp"
    with pytest.raises(packbot.errors.UnknownNameError, match="gripper_tool"):
        CartesianPD(target=[0.5, 0.0, 0.5], frame="gripper_tool").prepare(robot)


# ------------------------------------------------------------------ failures
@pytest.mark.parametrize("kind", FAILURE_KINDS)
@pytest.mark.parametrize("name", ARMS)
def test_every_failure_kind_is_taken_on_another_arm(name: str, kind: str) -> None:
    """Gravity compensation holds the raised pose; at 0.2 s a joint that carries gravity
    torque fails. Loose, weak (5 % of its effort) and stuck (its driver's torque 0) joints sag;
    a frozen and a braked (the effort limit holds) joint stay where they were."""
    robot = _arm(name)
    joint = LOADED_JOINT[name]
    j = robot.params.index(joint)
    q0 = robot.q_from(RAISED[name], base="zero")
    fail = packbot.Failure(joint=joint, kind=kind, t=0.2, scale=0.05)
    ctrl = build_controller("gravity", robot, {})
    res = packbot.simulate(
        robot, q0, np.zeros(robot.model.nv), 0.6, controller=ctrl, failures=[fail]
    )
    t = np.asarray(res.t)
    before, after = t < 0.2, t > 0.2 + 1e-9
    assert np.max(np.abs(res.q[before, j] - q0[j])) < 1e-6  # held until the failure
    moved = float(np.max(np.abs(res.q[after, j] - q0[j])))
    if kind in ("frozen", "brake"):
        assert moved < 1e-6 and np.max(np.abs(res.v[after, j])) < 1e-6
    else:
        assert moved > 0.01, f"{joint} {kind}: moved {moved:.3g} rad"
    if kind == "weak":  # the limit in force drops to the scale of the effort limit
        np.testing.assert_allclose(np.asarray(res.effort)[after, j], 0.05 * robot.params.effort[j])
    if kind == "stuck":  # the driver's torque, whatever the command
        np.testing.assert_allclose(np.asarray(res.tau)[after, j], 0.0, atol=1e-12)


# ------------------------------------------------------------------ the failure study
@pytest.fixture(scope="module")
def panda_study():
    from packbot.study import study

    _arm("panda")
    return study(PANDA_STUDY, workspace_samples=800)


def test_the_panda_recovers_its_task_after_a_joint_locks(panda_study) -> None:
    """panda_joint4 locks at 0.4 s during a reach: unaware, the controller ends 44 mm off (its
    plan needs the locked joint); reconfigured, the six other joints bring the tool back onto
    the healthy path (0.0001 mm at the end). The bounds: the failed run more than 20 mm off
    (half its measured error: any integrator or platform difference is far below that), the
    reconfigured one within the study's tolerance (10 mm) and less than a tenth of it."""
    res = panda_study
    assert res.robot.joint_names[:7] == tuple(f"panda_joint{k}" for k in range(1, 8))
    assert all(run.status == "ok" for run in res.runs.values())
    healthy, failed, reconf = (res.runs[n].metrics for n in ("healthy", "failed", "reconfigured"))
    assert healthy.final_task_error_m == 0.0
    assert failed.final_task_error_m > 0.02 and not failed.recovered
    assert reconf.final_task_error_m < min(res.tolerance_m, 0.1 * failed.final_task_error_m)
    assert reconf.recovered and res.reconfiguration.applied
    assert (reconf.detected_joint, reconf.detected_kind) == ("panda_joint4", "frozen")
    assert 0.0 < reconf.detect_delay_s < 0.1
    assert res.recovery.possible is True  # the task's points reachable with joint 4 locked
    assert res.summary()["task_frame"] == "panda_hand_tcp"


def test_the_panda_studys_report_shows_the_arm(panda_study, tmp_path) -> None:
    import json

    from packbot.viz.study_report import study_figures, write_study

    written = write_study(panda_study, tmp_path, formats=("png",))
    page = written["report.html"].read_text(encoding="utf-8")
    assert "panda_hand_tcp" in page and "panda_joint4 frozen at 0.4 s" in page
    summary = json.loads(written["study.json"].read_text(encoding="utf-8"))
    assert summary["task_frame"] == "panda_hand_tcp"
    assert summary["failures"][0]["joint"] == "panda_joint4"
    figs = study_figures(panda_study)
    labels = [ax.get_ylabel() for ax in figs["study_joints"].axes]
    assert all(any(n in lab for lab in labels) for n in panda_study.robot.joint_names)
