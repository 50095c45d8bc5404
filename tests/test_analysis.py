"""Failure analysis: loose-joint equilibria and workspaces."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.analysis import loose_joint_equilibria, plot_workspace, workspace
from packbot.config import SimConfig
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.failures import Failure


@pytest.mark.parametrize("joint", ["shoulder", "elbow1", "elbow2"])
def test_equilibria_have_zero_torque_and_stated_stability(robot, joint) -> None:
    q_hold = robot.pose("stand")
    eqs = loose_joint_equilibria(robot, joint, q_hold)
    roots = [e for e in eqs if e.kind == "root"]
    assert roots, "a pitch joint under gravity has equilibria"
    data = robot.model.createData()
    j = robot.params.index(joint)
    for e in roots:
        g = pin.computeGeneralizedGravity(robot.model, data, e.q)
        assert abs(g[j]) < 1e-8
        assert np.allclose(np.delete(e.q, j), np.delete(q_hold, j))
        # stability from the potential: V(angle +- h) above V(angle) iff stable
        h = 1e-3
        V = []
        for d in (-h, 0.0, h):
            q = e.q.copy()
            q[j] += d
            V.append(pin.computePotentialEnergy(robot.model, data, q))
        assert (V[0] > V[1] and V[2] > V[1]) == e.stable
        assert e.in_collision == (e.min_distance < 0)
    stab = [e.stable for e in roots]
    assert True in stab or any(e.kind == "limit" for e in eqs)


def test_turret_is_neutral_and_errors(robot) -> None:
    assert loose_joint_equilibria(robot, "turret", robot.pose("stand")) == []
    with pytest.raises(UnknownNameError):
        loose_joint_equilibria(robot, "wrist", robot.pose("stand"))
    with pytest.raises(ConfigurationError, match="q_hold"):
        loose_joint_equilibria(robot, "elbow1", [0.0, 1.0])


def test_loose_elbow2_settles_at_its_stable_equilibrium(robot) -> None:
    """Simulate: other joints held by PD, elbow2 loose with friction: it settles where predicted."""
    q0 = robot.q_from({"shoulder": 1.45, "elbow1": -0.3, "elbow2": -2.5}, base="high")
    eqs = [
        e
        for e in loose_joint_equilibria(robot, "elbow2", q0)
        if e.stable and e.kind == "root" and not e.in_collision
    ]
    assert eqs
    res = packbot.simulate(
        robot,
        q0,
        np.zeros(8),
        6.0,
        controller=packbot.control.JointPD(target=q0, omega=20.0),
        failures=[Failure(joint="elbow2", kind="loose", t=0.0)],
        config=SimConfig(joint_friction=True, locked_joints=("gripper_jaw",)),
    )
    final = res.q[-1, robot.params.index("elbow2")]
    nearest = min(eqs, key=lambda e: abs(e.angle - final))
    # Coulomb friction stops it within tau_c / stiffness of the equilibrium
    band = robot.params.coulomb[3] / nearest.stiffness + 0.02
    assert abs(final - nearest.angle) < band


def test_workspace_frozen_is_smaller_and_collision_free(robot, tmp_path) -> None:
    healthy = workspace(robot, samples=1500, seed=1)
    frozen = workspace(robot, ("elbow1", -0.9), samples=1500, seed=1)
    assert frozen.joints == ("turret", "shoulder", "elbow2", "gripper_roll")
    assert np.all(frozen.q[:, 2] == -0.9)
    world = packbot.collision.CollisionWorld(robot)
    for q in frozen.q[:50]:
        assert not world.in_collision(q)
    assert 0 < len(frozen.points) <= frozen.n_samples
    assert frozen.volume() < healthy.volume()
    again = workspace(robot, ("elbow1", -0.9), samples=1500, seed=1)
    assert np.array_equal(again.points, frozen.points)
    plot_workspace([healthy, frozen], tmp_path / "ws", formats=("png",))
    assert (tmp_path / "ws.png").stat().st_size > 1000
    with pytest.raises(ConfigurationError, match="frozen"):
        workspace(robot, ("elbow1", 9.0), samples=10)
