"""The built-in strategy for a weak joint (issue 36): a holdable posture on the task, a move the
weak motor drives, on a real study.

The case: tests/testbed_user.py's ``Reach`` (computed torque, drive pose to (1.2, 0, 1.0) m in
3 s) with elbow2 weak at 25 % from 1.5 s, 6 s simulated: the observer flags elbow2 at 2.13 s,
and the planned move to the holdable posture takes 3.87 s, so 6 s is the shortest run in which
it ends (in a 4 s run the arm is still on its way at the end: docs/study.md). The posture and
the move are read from the strategy's own controller (a ``BaselineRecovery`` that records what
it returns) and checked independently of the planner: the gravity torques with Pinocchio, the
path with the collision world and inverse dynamics.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pinocchio as pin
import pytest
import testbed_user

import packbot
from packbot.collision import CollisionWorld
from packbot.control import BaselineRecovery, WeakJointTracker
from packbot.control.context import FailureReport
from packbot.control.weak_transition import (
    CLEARANCE,
    HOLD_MARGIN,
    Transition,
    moving_joints,
)
from packbot.scenario import Scenario, scenario_from_dict
from packbot.study import StudyResult, study

#: The study's simulated time [s] (module docstring).
DURATION = 6.0


def base() -> Scenario:
    """tests/test_testbed.py's case: the reach, elbow2 weak at 25 % from 1.5 s."""
    return scenario_from_dict(
        {
            "description": "computed-torque reach drive -> (1.2, 0, 1.0) m, elbow2 weak 25 %",
            "duration": DURATION,
            "initial": {"pose": "drive"},
            "config": {"locked_joints": ["gripper_jaw"]},
            "failures": [{"joint": "elbow2", "kind": "weak", "t": 1.5, "scale": 0.25}],
        },
        name="weak_reach",
    )


class Recording(BaselineRecovery):
    """The built-in strategy, remembering the controllers it hands over (class-level: the
    study makes the instances)."""

    handed: ClassVar[list[Any]] = []

    def on_failure(self, report: FailureReport, controller: Any) -> Any:
        out = super().on_failure(report, controller)
        Recording.handed.append(out)
        return out


@pytest.fixture(scope="module")
def weak_study(robot: packbot.Robot) -> tuple[StudyResult, WeakJointTracker]:
    Recording.handed.clear()
    res = study(
        base(),
        robot=robot,
        duration=DURATION,
        controller=testbed_user.Reach,
        recovery=Recording,
        workspace_samples=300,
    )
    (tracker,) = Recording.handed  # one detection, one hand-over
    assert isinstance(tracker, WeakJointTracker) and tracker.transition is not None
    return res, tracker


def test_transition_meets_the_measured_state_and_ends_at_rest(robot: packbot.Robot) -> None:
    """A shaped quintic starts at (q0, v0) and ends at the posture at rest, whatever its
    bumps; the joints that move gripper_tool's origin are turret, shoulder, elbow1 and elbow2
    (the roll's axis passes through it, the camera is on another branch)."""
    model = robot.model
    assert moving_joints(model, model.getFrameId("gripper_tool")) == {0, 1, 2, 3}
    rng = np.random.default_rng(7)
    q0 = robot.pose("stand")
    v0 = rng.normal(0.0, 0.5, 8)
    coeffs = rng.normal(0.0, 0.5, (4, 5))
    tr = Transition(q0=q0, v0=v0, t0=1.0, duration=2.0, joints=(0, 1, 2, 3), coeffs=coeffs)
    q, v, _ = tr(1.0)
    assert np.allclose(q, q0) and np.allclose(v, v0)
    t, qs, vs, acc = tr.states(5)
    assert np.allclose(qs[-1, :4], coeffs[:, 0]) and np.allclose(qs[-1, 4:], q0[4:])
    assert np.allclose(vs[-1], 0.0) and np.allclose(acc[-1], 0.0)
    assert np.allclose(tr(float(t[2]))[0], qs[2])
    assert np.allclose(tr(5.0)[0], tr.goal) and np.allclose(tr(5.0)[1], 0.0)


def test_weak_elbow2_strategy_reaches_the_target(
    weak_study: tuple[StudyResult, WeakJointTracker],
) -> None:
    """The strategy's own run ends on the target: measured 0.0 mm (to 0.1 mm) against 356 mm
    unaware. Tolerance: the study's recovery tolerance, 10 mm: the move ends at 6.00 s, where
    the error is the tracking's (computed torque at 20 rad/s on a plan within 89 % of the
    limits: below a millimetre here); a change of the detection time by a control period or
    two moves the end by a few milliseconds of a move that arrives at rest."""
    res, _ = weak_study
    failed, reconf = res.failed.metrics, res.reconfigured.metrics
    assert failed is not None and reconf is not None
    assert res.reconfiguration is not None and res.reconfiguration.applied
    assert reconf.final_task_error_m <= 0.010
    assert failed.final_task_error_m > 0.3  # the sagging link: 356 mm
    assert reconf.false_detections == 0
    log = [e for e in res.reconfigured.controller_log if e.kind == "weak"]
    assert log and log[0].detail.startswith("on the target")


def test_holdable_posture_within_the_torque_bound(
    weak_study: tuple[StudyResult, WeakJointTracker], robot: packbot.Robot
) -> None:
    """At the posture, every motor's gravity torque (Pinocchio's, computed here) is within
    HOLD_MARGIN of its limit in force, the weak elbow2's its estimated reduced one, and
    gripper_tool is on the task's final point (1 mm: the search's tolerance)."""
    res, tracker = weak_study
    assert tracker.transition is not None
    goal = tracker.transition.goal
    model = robot.model.copy()
    data = model.createData()
    g = np.asarray(pin.computeGeneralizedGravity(model, data, goal))
    limits = np.asarray(robot.params.effort, dtype=float).copy()
    limits[3] = tracker.limit_names["elbow2"]
    assert limits[3] == pytest.approx(0.25 * 90.0, rel=0.05)  # the estimated scale
    assert np.all(np.abs(g[:7]) <= HOLD_MARGIN * limits[:7] + 1e-9), (g, limits)
    pin.framesForwardKinematics(model, data, goal)
    tool = data.oMf[model.getFrameId("gripper_tool")].translation
    assert np.linalg.norm(tool - res.task_x[-1]) < 1e-3


def test_transition_collision_free_and_within_the_weak_limit(
    weak_study: tuple[StudyResult, WeakJointTracker], robot: packbot.Robot
) -> None:
    """Along the planned move (400 points), the collision world's smallest distance stays
    above the clearance less 2 mm (the planner's fine check) and elbow2's inverse-dynamics
    torque within its reduced limit (planned within 97 %); the other motors within theirs."""
    _, tracker = weak_study
    tr = tracker.transition
    assert tr is not None
    world = CollisionWorld(robot)
    model = robot.model.copy()
    data = model.createData()
    limits = np.asarray(robot.params.effort, dtype=float).copy()
    limits[3] = tracker.limit_names["elbow2"]
    _, q, v, a = tr.states(400)
    dist = min(world.closest(qk).distance for qk in q)
    assert dist >= CLEARANCE - 2e-3
    tau = np.array([pin.rnea(model, data, qk, vk, ak) for qk, vk, ak in zip(q, v, a, strict=True)])
    assert np.max(np.abs(tau[:, 3])) <= limits[3]
    assert np.all(np.abs(tau[:, :7]) <= limits[:7])
