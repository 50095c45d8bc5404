"""Failure analysis: loose-joint equilibria and workspaces."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.analysis import (
    VolumeEstimate,
    loose_joint_equilibria,
    monte_carlo_volume,
    plot_workspace,
    reach,
    reachable,
    reachable_volume,
    workspace,
)
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
        config=SimConfig(
            contact_mode="joint_clamp", joint_friction=True, locked_joints=("gripper_jaw",)
        ),
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
    with pytest.warns(DeprecationWarning, match="grows with the sample count"):
        assert frozen.volume() < healthy.volume()
    again = workspace(robot, ("elbow1", -0.9), samples=1500, seed=1)
    assert np.array_equal(again.points, frozen.points)
    plot_workspace([healthy, frozen], tmp_path / "ws", formats=("png",))
    assert (tmp_path / "ws.png").stat().st_size > 1000
    with pytest.raises(ConfigurationError, match="frozen"):
        workspace(robot, ("elbow1", 9.0), samples=10)


def _shell(r_in: float, r_out: float):
    def inside(p):
        r = np.linalg.norm(p, axis=1)
        return (r >= r_in) & (r <= r_out)

    return inside


def test_monte_carlo_volume_of_a_shell_is_right_and_does_not_grow() -> None:
    """A spherical shell 0.3-0.7 m: the estimate is within 4 standard errors of the exact volume
    at every point count, and more points shrink the error instead of growing the volume."""
    exact = 4.0 / 3.0 * np.pi * (0.7**3 - 0.3**3)
    inside = _shell(0.3, 0.7)
    ests = [
        monte_carlo_volume(inside, [-0.8] * 3, [0.8] * 3, rel_tol=1e-6, max_points=n, seed=n)
        for n in (1000, 8000, 64000)
    ]
    for e in ests:
        assert isinstance(e, VolumeEstimate)
        assert not e.converged  # rel_tol 1e-6 is out of reach: stopped at max_points
        assert e.box_m3 == pytest.approx(1.6**3)
        assert abs(e.volume_m3 - exact) < 4 * e.stderr_m3
    assert [e.samples for e in ests] == [1000, 8000, 64000]
    # the standard error falls as 1/sqrt(n); the volume does not drift with n
    assert ests[2].stderr_m3 < 0.5 * ests[0].stderr_m3
    for a, b in itertools.pairwise(ests):
        assert abs(a.volume_m3 - b.volume_m3) < 4 * np.hypot(a.stderr_m3, b.stderr_m3)


def test_monte_carlo_volume_stops_when_converged() -> None:
    """A half ball of radius 0.5 m: sampling stops at the asked relative error."""
    exact = 2.0 / 3.0 * np.pi * 0.5**3

    def half_ball(p):
        return (np.linalg.norm(p, axis=1) <= 0.5) & (p[:, 2] >= 0)

    est = monte_carlo_volume(half_ball, [-0.6, -0.6, 0.0], [0.6, 0.6, 0.6], rel_tol=0.02, seed=3)
    assert est.converged
    assert est.stderr_m3 <= 0.02 * est.volume_m3
    assert est.samples < 20000
    assert abs(est.volume_m3 - exact) < 4 * est.stderr_m3
    assert "+-" in str(est)


def test_monte_carlo_volume_rejects_bad_input() -> None:
    inside = _shell(0.1, 0.2)
    with pytest.raises(ConfigurationError, match="box"):
        monte_carlo_volume(inside, [0, 0, 0], [1, 0, 1])
    with pytest.raises(ConfigurationError, match="rel_tol"):
        monte_carlo_volume(inside, [0, 0, 0], [1, 1, 1], rel_tol=0.0)
    with pytest.raises(ConfigurationError, match="max_points"):
        monte_carlo_volume(inside, [0, 0, 0], [1, 1, 1], batch=100, max_points=10)
    with pytest.raises(ConfigurationError, match="inside"):
        monte_carlo_volume(lambda p: np.ones(3, bool), [0, 0, 0], [1, 1, 1])


def test_reach_gives_a_witness_or_the_closest_approach(robot) -> None:
    ws = workspace(robot, ("elbow1", -0.9), samples=1500, seed=2)
    held = workspace(robot, ("elbow1", -0.9), samples=300, seed=7)
    # positions of other collision-free samples are reachable by construction: the IK finds them
    ok = reachable(robot, ws, held.points)
    assert ok.mean() >= 0.97
    world = packbot.collision.CollisionWorld(robot)
    data = robot.model.createData()
    fid = robot.model.getFrameId("gripper_tool")
    ans = reach(robot, ws, held.points[0])
    assert ans.reachable
    pin.framesForwardKinematics(robot.model, data, ans.q)
    assert np.linalg.norm(data.oMf[fid].translation - held.points[0]) <= ans.tol_m
    assert ans.error_m <= ans.tol_m
    assert not world.in_collision(ans.q)
    assert ans.q[robot.params.index("elbow1")] == -0.9
    assert np.all(ans.q >= robot.params.lower) and np.all(ans.q <= robot.params.upper)
    far = reach(robot, ws, [0.0, 0.0, 6.0])
    assert not far.reachable
    top = float(ws.points[:, 2].max())
    assert far.error_m > 6.0 - top - 0.05
    with pytest.raises(ConfigurationError, match="point"):
        reach(robot, ws, [0.0, 1.0])
    with pytest.raises(ConfigurationError, match="seeds"):
        reach(robot, ws, [0.0, 0.0, 1.0], seeds=0)


def test_frozen_reaches_a_subset_of_the_healthy_arm(robot) -> None:
    healthy = workspace(robot, samples=1500, seed=1)
    frozen = workspace(robot, ("elbow1", -0.9), samples=1500, seed=1)
    rng = np.random.default_rng(5)
    pts = rng.uniform(healthy.points.min(axis=0), healthy.points.max(axis=0), size=(300, 3))
    h = reachable(robot, healthy, pts)
    f = reachable(robot, frozen, pts)
    assert f.sum() < h.sum()
    assert np.sum(f & ~h) <= 3  # frozen configurations are healthy ones (IK misses aside)


def test_reachable_volume_does_not_grow_with_the_sample_count(robot) -> None:
    """The voxel count grows with the samples; the Monte Carlo volume does not."""
    small = workspace(robot, samples=600, seed=0)
    large = workspace(robot, samples=4000, seed=0)
    with pytest.warns(DeprecationWarning):
        assert large.volume() > 4 * small.volume()
    a = reachable_volume(robot, small, rel_tol=0.05, seed=1)
    b = reachable_volume(robot, large, rel_tol=0.05, seed=2)
    assert a.converged and b.converged
    assert a.stderr_m3 <= 0.05 * a.volume_m3
    assert abs(a.volume_m3 - b.volume_m3) < 4 * np.hypot(a.stderr_m3, b.stderr_m3)
    # physically bounded: within a ball of the farthest sample's reach, above the floor
    r = np.linalg.norm(large.points - large.points.mean(axis=0), axis=1).max()
    assert 0 < b.volume_m3 < 4.0 / 3.0 * np.pi * r**3
    with pytest.raises(ConfigurationError, match="pad"):
        reachable_volume(robot, small, pad=-1.0)
