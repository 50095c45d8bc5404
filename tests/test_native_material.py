"""The contact set's material points made in the sweep's batch or pair by pair, alike.

:meth:`ContactSet.add_pairs <packbot.contact.normal_set.ContactSet.add_pairs>` takes its patches as
material points from the compiled sweep in one call (Coal's patches, then
``src/native/material.hpp``) when ``normal_set.MATERIALS_NATIVE`` is on; off,
``packbot._native.patch_material`` (the same code) runs on the patches one by one. Both must give
the same pairs, bit for bit: points in the joints' frames, normals, contact frames, centres,
tangential offsets, the normal's owner and the slide a patch goes stale at. Checked on the patches
of named, random and collapse configurations (with the floor alone and with obstacles of every
kind), on patches off their distance (the witness points), and on whole runs, which must be the
same to the bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_collision_sweep import LOCKED, _configurations, obstacle_env
from test_native_patches import _same_sets, _set

import packbot
from packbot import native_sweep
from packbot.collision import CollisionWorld
from packbot.contact import normal_set, stretch
from packbot.contact.normal_set import ContactSet

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
    """Counts the calls of ContactSet._add_made that made the pairs (not None)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.made = 0
        real = ContactSet._add_made

        def counted(cs: ContactSet, *args):
            out = real(cs, *args)
            self.made += out is not None
            return out

        monkeypatch.setattr(ContactSet, "_add_made", counted)


def _add(cs: ContactSet, q, pairs, native: bool, monkeypatch) -> list[bool]:
    monkeypatch.setattr(normal_set, "MATERIALS_NATIVE", native)
    return cs.add_pairs(q, pairs)


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_batch_materials_are_the_pair_by_pair_ones_bit_for_bit(
    robot, collapse_states, rng, obstacles, monkeypatch
):
    env = obstacle_env() if obstacles else None
    world = CollisionWorld(robot, env)  # (one world: the same patches for both)
    assert world._native is not None
    nat, ker = _set(world), _set(world)
    counted = _Counted(monkeypatch)
    halfspaces = {
        g
        for g, go in enumerate(world.geom_model.geometryObjects)
        if type(go.geometry).__name__ == "Halfspace"
    }
    seen = {"pairs": 0, "one point": 0, "faces": 0, "on1": 0, "on2": 0, "free": 0, "lags": 0}
    seen["halfspace"] = 0
    for q in _configurations(robot, collapse_states, rng)[::2]:
        pairs = world.sweep(q, 0.005).pairs.tolist()
        a = _add(nat, q, pairs, True, monkeypatch)
        b = _add(ker, q, pairs, False, monkeypatch)
        assert a == b
        _same_sets(nat, ker)
        for p in nat.pairs.values():
            seen["pairs"] += 1
            seen["one point"] += len(p.local1) == 1
            seen["faces"] += len(p.local1) >= 3
            seen["on1" if p.on1 else "on2"] += 1
            seen["free" if math.isinf(p.slide_tol) else "lags"] += 1
            seen["halfspace"] += p.info.geom2 in halfspaces
        for k in list(nat.pairs):
            nat.remove_pair(k)
            ker.remove_pair(k)
    assert counted.made > 50
    # enough of each kind to compare (the counts move with the trajectory: loose bounds)
    assert seen["pairs"] > 150 and seen["faces"] > 25 and seen["one point"] > 5, seen
    assert seen["on1"] > 5 and seen["on2"] > 50, seen
    assert seen["free"] > 20 and seen["lags"] > 20 and seen["halfspace"] > 20, seen


def test_a_patch_off_its_distance_takes_the_witness_points_alike(
    robot, collapse_states, monkeypatch
):
    """A negative patch tolerance puts every patch off its distance: both paths fall back.

    Two worlds of the same structure, queried alike: the witness points are Coal's distance
    queries, whose result depends on the world's warm-start history.
    """
    world = CollisionWorld(robot)
    nat, ker = _set(world), _set(CollisionWorld(robot))
    monkeypatch.setattr(normal_set, "PATCH_TOL", -1.0)
    counted = _Counted(monkeypatch)
    n = 0
    for q in collapse_states[::25]:
        pairs = world.sweep(q, 0.005).pairs.tolist()
        assert ker.world is not None
        ker.world.sweep(q, 0.005)
        a = _add(nat, q, pairs, True, monkeypatch)
        b = _add(ker, q, pairs, False, monkeypatch)
        assert a == b
        _same_sets(nat, ker)
        for p in nat.pairs.values():
            assert len(p.local1) == 1  # the witness pair, one point
            n += 1
        for k in list(nat.pairs):
            nat.remove_pair(k)
            ker.remove_pair(k)
    assert n > 10 and counted.made > 5


@pytest.mark.parametrize(
    ("mu", "locked", "duration"),
    [(0.5, LOCKED, 5.0), (0.0, LOCKED, 2.0), (0.5, [], 1.5)],
    ids=["collapse", "frictionless", "wrist-free"],
)
def test_runs_are_the_same_with_native_materials(robot, mu, locked, duration, monkeypatch):
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    q0, tau = robot.pose("drive"), np.zeros(robot.nq)
    # the re-patches in Python both times (the stretch's own need the native materials:
    # tests/test_stretch_repatch.py)
    monkeypatch.setattr(stretch, "REPATCH_ENABLED", False)
    monkeypatch.setattr(normal_set, "MATERIALS_NATIVE", False)
    ref = packbot.simulate(robot, q0, tau, duration, config=cfg)
    monkeypatch.setattr(normal_set, "MATERIALS_NATIVE", True)
    counted = _Counted(monkeypatch)
    got = packbot.simulate(robot, q0, tau, duration, config=cfg)
    assert counted.made > 20
    np.testing.assert_array_equal(got.t, ref.t)
    np.testing.assert_array_equal(got.q, ref.q)
    np.testing.assert_array_equal(got.v, ref.v)
    assert [(e.t, e.kind) for e in got.events] == [(e.t, e.kind) for e in ref.events]
    assert got.diagnostics.min_distance == ref.diagnostics.min_distance


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
