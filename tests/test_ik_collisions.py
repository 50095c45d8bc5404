"""Collision-free inverse kinematics and the first collision along a joint path.

The targets are chosen with margins far above any rounding: a tool target inside the chassis
(every solution penetrates by centimetres), and one whose first solution from the drive pose
puts link1 8 cm into the chassis while other starts reach it with the arm clear.
"""

import logging

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control import (
    IKResult,
    PathCollision,
    build_controller,
    check_path,
    reach_bounds,
    solve_position_ik,
)
from packbot.errors import ConfigurationError, IKCollisionError

#: gripper_tool inside the chassis body, 37 mm above the floor [m]
INSIDE = (0.213, 0.052, 0.037)
#: reached from the drive pose first with link1 in the chassis, clear from other starts [m]
BEHIND = (1.328, 0.321, 0.301)


def tool(robot, q):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.model.getFrameId("gripper_tool")].translation.copy()


@pytest.fixture(scope="module")
def into_chassis(robot):
    """A configuration with the gripper inside the chassis (the IK's flagged solution)."""
    res = solve_position_ik(
        robot.model,
        "gripper_tool",
        INSIDE,
        robot.pose("stand"),
        active=[0, 1, 2, 3],
        collision_free=False,
    )
    assert res.success and res.colliding and res.clearance < -0.05
    return res.q


# ------------------------------------------------------------------ inverse kinematics
def test_a_colliding_solution_is_rejected_for_a_clear_one(robot):
    q0 = robot.pose("drive")
    flagged = solve_position_ik(robot.model, "gripper_tool", BEHIND, q0, collision_free=False)
    assert flagged.success and flagged.colliding is True and flagged.clearance < -0.05
    assert flagged.start == 0 and "/" in flagged.pair[0]
    res = solve_position_ik(robot.model, "gripper_tool", BEHIND, q0)  # collision_free=True
    assert isinstance(res, IKResult)
    assert res.success and res.colliding is False and res.clearance >= 0.0
    assert res.start > 0  # another seed
    assert np.linalg.norm(tool(robot, res.q) - BEHIND) <= 1e-4
    world = packbot.CollisionWorld(robot)
    assert world.closest(res.q).distance >= 0.0
    again = solve_position_ik(robot, "gripper_tool", BEHIND, q0)  # the Robot as model
    np.testing.assert_array_equal(again.q, res.q)  # the same seeds: the same solution


def test_no_collision_free_solution_names_the_target_and_the_pair(robot):
    with pytest.raises(IKCollisionError) as exc:
        solve_position_ik(robot.model, "gripper_tool", INSIDE, robot.pose("stand"), seeds=4)
    err = exc.value
    assert isinstance(err, packbot.PackbotError)
    assert "gripper_tool" in str(err) and "(0.213, 0.052, 0.037) m" in str(err)
    assert err.pair[0] in str(err) and err.pair[1] in str(err) and err.distance < 0
    assert err.seeds == 5 and err.result.colliding
    assert "collision_free=False" in str(err)


def test_an_obstacle_of_the_environment_counts(robot):
    """A target the arm reaches clear of the floor and chassis; a box around the solution's
    elbow makes that solution collide, so another is found or the error names the box."""
    q0 = robot.pose("stand")
    target = (1.0, 0.2, 0.6)
    free = solve_position_ik(robot.model, "gripper_tool", target, q0)
    assert free.success and free.start == 0
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, free.q)
    elbow = data.oMi[robot.model.getJointId("elbow2")].translation
    box = packbot.Obstacle(name="crate", kind="box", size=(0.2, 0.2, 0.2), xyz=tuple(elbow))
    env = packbot.Environment().with_obstacles(box)
    flagged = solve_position_ik(
        robot.model, "gripper_tool", target, q0, environment=env, collision_free=False
    )
    assert flagged.colliding and "crate" in flagged.pair[1]
    try:
        res = solve_position_ik(robot.model, "gripper_tool", target, q0, environment=env)
    except IKCollisionError as exc:  # every solution collides with something
        assert exc.distance < 0 and exc.result.colliding
    else:
        assert res.success and not res.colliding
        assert packbot.CollisionWorld(robot, env).closest(res.q).distance >= 0.0


def test_a_model_without_collision_pieces_must_say_so(robot):
    q = robot.pose("stand")
    red = pin.buildReducedModel(robot.model, [robot.model.getJointId("elbow1")], q)
    with pytest.raises(ConfigurationError, match="collision_free") as exc:
        solve_position_ik(red, "gripper_tool", (0.8, 0.3, 0.5), np.delete(q, 2))
    assert "reduced" in str(exc.value)
    res = solve_position_ik(
        red, "gripper_tool", (0.8, 0.3, 0.5), np.delete(q, 2), collision_free=False
    )
    assert res.success and res.colliding is None and np.isnan(res.clearance)
    with pytest.raises(ConfigurationError, match="robot"):
        solve_position_ik(red, "gripper_tool", (0.8, 0.3, 0.5), np.delete(q, 2), robot=robot)
    with pytest.raises(ConfigurationError, match="seeds"):
        solve_position_ik(robot.model, "gripper_tool", (0.8, 0.3, 0.5), q, seeds=-1)
    copy = robot.model.copy()  # a copy of the shipped arm: its pieces are known
    assert solve_position_ik(copy, "gripper_tool", (1.0, 0.2, 0.6), q).colliding is False


# ------------------------------------------------------------------ paths
def test_reach_bounds_bound_the_tool(robot, rng):
    """r_j bounds the distance of every piece from joint j's origin, so the tool's too."""
    r = reach_bounds(robot)
    assert r.shape == (8,) and np.all(r > 0)
    assert 1.5 < r[0] < 3.0  # the turret carries the whole arm (about 2 m)
    data = robot.model.createData()
    lo, hi = robot.params.lower, robot.params.upper
    for _ in range(50):
        q = rng.uniform(lo, hi)
        pin.framesForwardKinematics(robot.model, data, q)
        p = data.oMf[robot.model.getFrameId("gripper_tool")].translation
        for name in ("turret", "shoulder", "elbow1", "elbow2"):
            jid = robot.model.getJointId(name)
            gap = np.linalg.norm(p - data.oMi[jid].translation)
            assert gap <= r[robot.params.index(name)]


def test_a_clear_path_is_clear(robot):
    path = [robot.pose("stand"), robot.pose("high"), robot.pose("stand")]
    assert check_path(robot, path) is None
    assert check_path(robot, robot.pose("stand")) is None  # one configuration


def test_the_first_collision_along_a_path_and_nothing_deeper_before_it(robot, into_chassis):
    """Into the chassis: found on segment 1 of (high, stand, inside); a dense check (exact
    distances of every pair) sees nothing deeper than the tolerance before it."""
    tol = 1e-3
    path = np.array([robot.pose("high"), robot.pose("stand"), into_chassis])
    hit = check_path(robot, path, tolerance=tol)
    assert isinstance(hit, PathCollision)
    assert hit.index == 1 and 0.0 < hit.fraction <= 1.0 and hit.distance < 0.0
    np.testing.assert_allclose(hit.q, path[1] + hit.fraction * (path[2] - path[1]))
    assert "base_link" in hit.links or "floor" in hit.links
    assert hit.pair[0] in str(hit)
    world = packbot.CollisionWorld(robot)
    assert world.closest(hit.q).distance < 0.0
    for s in np.linspace(0.0, hit.fraction, 400, endpoint=False):
        assert world.closest(path[1] + s * (path[2] - path[1])).distance >= -tol
    start = check_path(robot, [into_chassis, robot.pose("stand")])
    assert start is not None and (start.index, start.fraction) == (0, 0.0)


def test_a_plate_thinner_than_a_naive_step_is_found(robot):
    """A 4 mm plate where the jaw crosses it during a 1 rad turret swing: ten evenly spaced
    checks (13 cm of tool motion apart) all miss it; the bounded steps do not."""
    qa = robot.pose("stand")
    qb = qa.copy()
    qb[0] += 1.0
    p = tool(robot, qa + 0.3 * (qb - qa))
    yaw = float(np.arctan2(p[1], p[0]))
    plate = packbot.Obstacle(
        name="plate", kind="box", size=(0.12, 0.004, 0.12), xyz=tuple(p), rpy=(0.0, 0.0, yaw)
    )
    env = packbot.Environment().with_obstacles(plate)
    world = packbot.CollisionWorld(robot, env)
    naive = [world.closest(qa + s * (qb - qa)).distance for s in np.linspace(0, 1, 10)]
    assert min(naive) > 0.0
    hit = check_path(robot, [qa, qb], env)
    assert hit is not None and "plate" in hit.links and 0.2 < hit.fraction < 0.4
    with pytest.raises(ConfigurationError, match="q_path"):
        check_path(robot, np.zeros((3, 5)))
    with pytest.raises(ConfigurationError, match="tolerance"):
        check_path(robot, [qa, qb], tolerance=0.0)


# ------------------------------------------------------------------ controllers warn
def test_a_computed_torque_plan_into_the_chassis_warns(robot, into_chassis, caplog):
    params = {"waypoints": ["stand", [float(x) for x in into_chassis]], "times": [0.0, 3.0]}
    with caplog.at_level(logging.WARNING, logger="packbot.control"):
        build_controller("computed_torque", robot, params)
    said = [r.getMessage() for r in caplog.records if "collides" in r.getMessage()]
    assert len(said) == 1 and "controller.waypoints" in said[0] and "segment 0" in said[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="packbot.control"):
        build_controller("computed_torque", robot, {"waypoints": ["stand", "high"]})
    assert not [r for r in caplog.records if "collides" in r.getMessage()]


def test_a_reconfigurable_plan_into_the_chassis_warns(robot, caplog):
    ctrl = build_controller("reconfig", robot, {"target": list(INSIDE)})
    with caplog.at_level(logging.WARNING, logger="packbot"):
        ctrl.reset(robot, 0.0, robot.pose("stand"), np.zeros(8))
    text = caplog.text
    assert "no collision-free IK solution" in text
    assert "reconfigurable controller's planned move" in text and "collides" in text
