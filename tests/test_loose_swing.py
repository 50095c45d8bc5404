"""Loose elbow2: the arm hangs link 3 over a ground target and damps its swing.

Runs ``sims/loose_swing_elbow2.toml`` once (4 s simulated, a few seconds of wall time) with
collisions and joint friction on, and checks the outcome against the file's own target, failure
time and the robot's parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control import ReconfigurableController
from packbot.control._common import controller_model
from packbot.integrator import simulate
from packbot.result import SimResult
from packbot.scenario import Scenario, load_scenario


@dataclass
class Run:
    scenario: Scenario
    controller: ReconfigurableController
    result: SimResult
    tool: np.ndarray  # gripper_tool positions [m], (N, 3)
    g_loose: np.ndarray  # gravity torque on the loose joint [N*m], (N,)
    stiffness: float  # d g_u / d q_u at the planned rest [N*m/rad]
    arm: float  # distance from the loose joint's axis to gripper_tool at the end [m]


@pytest.fixture(scope="module")
def run(robot: packbot.Robot) -> Run:
    scenario = load_scenario("loose_swing_elbow2")
    ctrl = scenario.build_controller(robot)
    assert isinstance(ctrl, ReconfigurableController)
    q0, v0 = scenario.initial_state(robot)
    result = simulate(
        robot,
        q0,
        v0,
        scenario.duration,
        controller=ctrl,
        environment=scenario.environment,
        config=scenario.config,
        failures=list(scenario.failures),
        inform_controller=scenario.inform_controller,
    )
    model, data = controller_model(robot, np.array(scenario.config.gravity))
    fid = model.getFrameId("gripper_tool")
    j = robot.params.index(scenario.failures[0].joint)
    tool, g = [], []
    for q in result.q:
        pin.framesForwardKinematics(model, data, q)
        tool.append(data.oMf[fid].translation.copy())
        g.append(pin.computeGeneralizedGravity(model, data, q)[j])
    goal = [e.q_goal for e in ctrl.events if e.kind == "replan"][-1]
    assert goal is not None
    k = pin.computeGeneralizedGravityDerivatives(model, data, goal)[j, j]
    pin.framesForwardKinematics(model, data, result.q[-1])
    jid = model.getJointId("elbow2")
    arm = np.linalg.norm(data.oMf[fid].translation - data.oMi[jid].translation)
    return Run(scenario, ctrl, result, np.array(tool), np.array(g), float(k), float(arm))


def test_scenario_is_a_loose_elbow2_with_collisions_and_friction(run: Run) -> None:
    (failure,) = run.scenario.failures
    assert (failure.joint, failure.kind) == ("elbow2", "loose")
    assert run.scenario.config.joint_friction
    assert run.scenario.config.contact_mode != "none"
    assert not run.scenario.inform_controller


def test_detected_once_and_replanned_to_a_stable_hanging_rest(run: Run, robot) -> None:
    t_fail = run.scenario.failures[0].t
    detections = [e for e in run.controller.events if e.kind == "detect"]
    assert [(e.joint, e.detail.split(":")[0]) for e in detections] == [("elbow2", "loose")]
    assert t_fail < detections[0].t < t_fail + 0.1
    (replan,) = [e for e in run.controller.events if e.kind == "replan"]
    assert replan.q_goal is not None
    model, data = controller_model(robot, np.array(run.scenario.config.gravity))
    j = robot.params.index("elbow2")
    g = pin.computeGeneralizedGravity(model, data, replan.q_goal)[j]
    stiffness = pin.computeGeneralizedGravityDerivatives(model, data, replan.q_goal)[j, j]
    assert abs(g) < 1e-3
    assert stiffness > 0  # hanging: a minimum of the potential energy
    margin = run.controller.loose_margin
    assert robot.params.lower[j] + margin <= replan.q_goal[j] <= robot.params.upper[j] - margin


def test_loose_joint_applies_no_torque_after_the_failure(run: Run, robot) -> None:
    res = run.result
    j = robot.params.index("elbow2")
    after = res.t > run.scenario.failures[0].t
    before = res.t < run.scenario.failures[0].t
    assert np.all(res.tau[after, j] == 0.0)
    assert np.max(np.abs(res.tau[before, j])) > 1.0  # it was holding link 3 before


def test_swing_decays_and_gripper_ends_over_the_target(run: Run, robot) -> None:
    res, t = run.result, run.result.t
    t_fail = run.scenario.failures[0].t
    target = np.asarray(run.controller.target)
    # The swing: the loose joint's distance from its equilibrium, g_u / (dg_u/dq_u) [rad].
    swing = np.abs(run.g_loose) / run.stiffness
    early = swing[(t > t_fail) & (t < t_fail + 1.0)].max()
    late = swing[t > t[-1] - 0.5].max()
    assert early > 0.05  # link 3 fell and swung
    assert late < 0.1 * early
    # Settled: every joint at rest at the end.
    assert np.max(np.abs(res.v[t > t[-1] - 0.5])) < 0.01
    # The gripper hangs over the target: within the Coulomb deadband of the loose joint
    # (coulomb / stiffness * arm, about 3 cm) and 5-15 cm above the floor.
    j = robot.params.index("elbow2")
    deadband = robot.params.coulomb[j] / run.stiffness * run.arm
    err = np.linalg.norm(run.tool[-1] - target)
    assert err < deadband + 0.005
    assert 0.05 <= run.tool[-1, 2] <= 0.15
    # Collision free throughout (collisions on): no penetration.
    assert res.diagnostics.min_distance >= -res.config.contact_tolerance
