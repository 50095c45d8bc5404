"""The patches' material points made in the extension's sweep, checked on the bodies.

:meth:`ContactSet.add_pairs <packbot.contact.normal_set.ContactSet.add_pairs>` takes its patches as
material points from the compiled sweep in one call (Coal's patches, then
``src/native/material.hpp``). On the patches of named, random and collapse configurations (with
the floor alone and with obstacles of every kind), and on patches off their distance (the
witness points): each pair's points, read back in the world from their joints' frames, have their
smallest gap along the normal at the pair's signed distance (to the patch tolerance), the normal
is a unit vector fixed in its owner body, and the contact frame is orthonormal around it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_collision_sweep import LOCKED, _configurations, obstacle_env
from test_native_patches import _set

import packbot
from packbot import native_sweep
from packbot.collision import CollisionWorld
from packbot.contact import normal_set
from packbot.contact.normal_set import ContactSet
from packbot.contact.normal_tolerances import PATCH_TOL

pytestmark = pytest.mark.skipif(
    not native_sweep.available(), reason="packbot._native_coal is not available"
)


@pytest.fixture(scope="module")
def collapse_states(robot) -> np.ndarray:
    """Configurations along the contact-normal collapse (mu 0.5, the wrist locked, 1.5 s)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.5, config=cfg)
    return np.asarray(res.q)


class _Counted:
    """Counts the calls of ContactSet._add_made."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.made = 0
        real = ContactSet._add_made

        def counted(cs: ContactSet, *args):
            out = real(cs, *args)
            self.made += 1
            return out

        monkeypatch.setattr(ContactSet, "_add_made", counted)


def _check_on_the_bodies(cs: ContactSet, distances: dict[int, float]) -> None:
    """Every pair of cs (made at the q of its data's kinematics) against the pair's distance."""
    data = cs.data
    for k, p in cs.pairs.items():
        info = p.info
        M1, M2 = data.oMi[info.joint1], data.oMi[info.joint2]
        p1 = p.local1 @ M1.rotation.T + M1.translation  # the points, world [m]
        p2 = p.local2 @ M2.rotation.T + M2.translation
        n = (M1 if p.on1 else M2).rotation @ p.normal2
        assert abs(float(np.linalg.norm(n)) - 1.0) <= 1e-12
        gaps = (p2 - p1) @ n
        assert abs(float(gaps.min()) - distances[k]) <= PATCH_TOL + 1e-12, (k, gaps, distances[k])
        F = np.asarray(p.frame2)
        np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(F[2], p.normal2, atol=1e-12)


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_the_materials_are_the_patches_on_the_bodies(
    robot, collapse_states, rng, obstacles, monkeypatch
):
    env = obstacle_env() if obstacles else None
    world = CollisionWorld(robot, env)
    nat = _set(world)
    counted = _Counted(monkeypatch)
    halfspaces = {
        g
        for g, go in enumerate(world.geom_model.geometryObjects)
        if type(go.geometry).__name__ == "Halfspace"
    }
    seen = {"pairs": 0, "one point": 0, "faces": 0, "on1": 0, "on2": 0, "free": 0, "lags": 0}
    seen["halfspace"] = 0
    for q in _configurations(robot, collapse_states, rng)[::2]:
        sw = world.sweep(q, 0.005)
        pairs = sw.pairs.tolist()
        made = nat.add_pairs(q, pairs)
        assert sorted(k for k, ok in zip(pairs, made, strict=True) if ok) == sorted(nat.pairs)
        _check_on_the_bodies(nat, dict(zip(pairs, sw.distances.tolist(), strict=True)))
        for p in nat.pairs.values():
            seen["pairs"] += 1
            seen["one point"] += len(p.local1) == 1
            seen["faces"] += len(p.local1) >= 3
            seen["on1" if p.on1 else "on2"] += 1
            seen["free" if math.isinf(p.slide_tol) else "lags"] += 1
            seen["halfspace"] += p.info.geom2 in halfspaces
        for k in list(nat.pairs):
            nat.remove_pair(k)
    assert counted.made > 50
    # enough of each kind checked (the counts move with the trajectory: loose bounds)
    assert seen["pairs"] > 150 and seen["faces"] > 25 and seen["one point"] > 5, seen
    assert seen["on1"] > 5 and seen["on2"] > 50, seen
    assert seen["free"] > 20 and seen["lags"] > 20 and seen["halfspace"] > 20, seen


def test_a_patch_off_its_distance_takes_the_witness_points(robot, collapse_states, monkeypatch):
    """A negative patch tolerance puts every patch off its distance: one point each, the
    witness pair, its gap the pair's distance."""
    world = CollisionWorld(robot)
    nat = _set(world)
    monkeypatch.setattr(normal_set, "PATCH_TOL", -1.0)
    counted = _Counted(monkeypatch)
    n = 0
    for q in collapse_states[::25]:
        sw = world.sweep(q, 0.005)
        pairs = sw.pairs.tolist()
        nat.add_pairs(q, pairs)
        _check_on_the_bodies(nat, dict(zip(pairs, sw.distances.tolist(), strict=True)))
        for p in nat.pairs.values():
            assert len(p.local1) == 1  # the witness pair, one point
            n += 1
        for k in list(nat.pairs):
            nat.remove_pair(k)
    assert n > 10 and counted.made > 5


def test_bad_plane_and_material_arguments_are_refused(robot):
    world = CollisionWorld(robot)
    native = world._native
    assert native is not None
    args = native_sweep._arguments(world)
    kinematics = native_sweep._kinematics(world.robot.model)
    assert args is not None and kinematics is not None
    sweep = native_sweep._native_coal.Sweep(**kinematics, **args)  # (new: no planes yet)
    assert not sweep.has_planes
    q = np.ascontiguousarray(robot.pose("drive"))
    pairs = np.array([0], dtype=np.int64)
    with pytest.raises(ValueError, match="set_planes first"):
        sweep.materials(q, pairs, 1e-3, 1e-4, 1e-9)
    G = int(world.geom_model.ngeoms)
    N, o = np.zeros((0, 3)), np.zeros(0)
    with pytest.raises(ValueError, match="start"):
        sweep.set_planes(N, o, np.zeros(G, dtype=np.int64))  # (G + 1 entries expected)
    with pytest.raises(ValueError, match="from 0 to F"):
        sweep.set_planes(N, o, np.ones(G + 1, dtype=np.int64))
    sweep.set_planes(N, o, np.zeros(G + 1, dtype=np.int64))
    assert sweep.has_planes
    with pytest.raises(ValueError, match="out of range"):
        sweep.materials(q, np.array([len(world.pairs)], dtype=np.int64), 1e-3, 1e-4, 1e-9)
    cs = _set(world)
    with pytest.raises(packbot.ConfigurationError, match=r"q.*\(8,\)"):
        cs.add_pairs(np.zeros(robot.nq - 1), [0])
