"""The native contact patches (``Sweep.patches`` of ``packbot._native_coal``) against Python's.

:meth:`CollisionWorld.contact_patches <packbot.collision.CollisionWorld.contact_patches>` asks
the compiled sweep for the patches of several pairs at one q (one forward kinematics, then per
pair Coal's ``collide`` and ``computeContactPatch``); the Python path
(:func:`packbot.collision_queries.contact_patch`, pair by pair through Coal's Python bindings)
is the reference. Both must give the same normals, points, depths and piece placements, bit
for bit, and None for the same far pairs: at named poses, random poses and states of a
collapse, with the floor alone and with obstacles of every kind (a tilted halfspace among
them), at several tolerances. The contact set built on them (:meth:`ContactSet.add_pairs
<packbot.contact.normal_set.ContactSet.add_pairs>`, ``refresh``) must be the same too.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_native_sweep import LOCKED, _configurations, obstacle_env, python_world

import packbot
from packbot import collision_queries, native_sweep
from packbot.collision import CollisionWorld
from packbot.contact.normal_set import ContactSet

pytestmark = pytest.mark.skipif(
    not native_sweep.available(), reason="packbot._native_coal is not available"
)

TOLS = (0.0, 1e-4, 3e-3)


@pytest.fixture(scope="module")
def collapse_states(robot) -> np.ndarray:
    """Configurations along the contact-normal collapse (mu 0.5, the wrist locked, 1.5 s)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.5, config=cfg)
    return np.asarray(res.q)


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_native_patches_equal_the_python_path_bit_for_bit(robot, collapse_states, rng, obstacles):
    env = obstacle_env() if obstacles else None
    nat, py = CollisionWorld(robot, env), python_world(robot, env)
    assert nat._native is not None and py._native is None
    seen = {"patches": 0, "far": 0, "faces": 0, "penetrating": 0, "halfspace": 0}
    halfspaces = {
        g
        for g, go in enumerate(nat.geom_model.geometryObjects)
        if type(go.geometry).__name__ == "Halfspace"
    }
    for q in _configurations(robot, collapse_states, rng)[::2]:
        pairs = nat.sweep(q, 0.01).pairs.tolist()  # the near pairs and a few far ones
        for tol in TOLS:
            got = nat.contact_patches(q, pairs, tol)
            assert len(got) == len(pairs)
            batch = collision_queries.patch_batch(nat, q, pairs, tol)
            assert batch is not None
            rot, trans = batch[5], batch[6]
            for i, (k, a) in enumerate(zip(pairs, got, strict=True)):
                b = py.contact_patch(q, k, tol)
                # the placements the patches were computed at: the Python path's, exactly
                p = py.pairs[k]
                for s, g in enumerate((p.geom1, p.geom2)):
                    M = py.geom_data.oMg[g]
                    assert rot[i, s].flags.f_contiguous
                    np.testing.assert_array_equal(rot[i, s], M.rotation)
                    np.testing.assert_array_equal(trans[i, s], M.translation)
                if b is None:
                    assert a is None, (k, tol)
                    seen["far"] += 1
                    continue
                assert a is not None, (k, tol)
                assert a.pair == b.pair
                # same library, same inputs: the same numbers, not merely close ones
                np.testing.assert_array_equal(a.normal, b.normal)
                np.testing.assert_array_equal(a.points1, b.points1)
                np.testing.assert_array_equal(a.points2, b.points2)
                assert a.distance == b.distance
                assert a.points1.shape == b.points1.shape and a.points1.shape[1] == 3
                seen["patches"] += 1
                seen["faces"] += len(a.points1) >= 3
                seen["penetrating"] += a.distance < 0
                seen["halfspace"] += p.geom2 in halfspaces
    assert seen["patches"] > 300 and seen["far"] > 300, seen
    assert seen["faces"] > 100 and seen["penetrating"] > 20, seen
    assert seen["halfspace"] > 50, seen


def test_one_pair_and_the_python_function_agree(robot, rng):
    """contact_patch (one pair, native) is collision_queries.contact_patch's patch."""
    w = CollisionWorld(robot)
    n = 0
    for _ in range(40):
        q = rng.uniform(robot.params.lower, robot.params.upper)
        for k in w.sweep(q, 0.003).pairs.tolist():
            a = w.contact_patch(q, k, 1e-3)
            b = collision_queries.contact_patch(w, q, k, 1e-3)
            assert (a is None) == (b is None)
            if a is not None and b is not None:
                np.testing.assert_array_equal(a.points1, b[1])
                np.testing.assert_array_equal(a.points2, b[2])
                np.testing.assert_array_equal(a.normal, b[0])
                assert a.distance == b[3]
                n += 1
    assert n > 10


def _set(world: CollisionWorld) -> ContactSet:
    """A contact set on the world (mu 0.5, contact tolerance 1 mm)."""
    model = world.robot.model
    return ContactSet(
        model,
        model.createData(),
        world,
        mu=0.5,
        restitution=0.0,
        zeno_speed=0.01,
        contact_tolerance=1e-3,
    )


def _sets(robot, env=None):
    """Two contact sets on worlds of the same structure: native patches and Python ones."""
    return [_set(world) for world in (CollisionWorld(robot, env), python_world(robot, env))]


def _same_sets(a: ContactSet, b: ContactSet) -> int:
    assert list(a.pairs) == list(b.pairs)
    for k, pa in a.pairs.items():
        pb = b.pairs[k]
        for name in ("local1", "local2", "normal2", "offset0", "frame2", "centre1", "centre2"):
            np.testing.assert_array_equal(getattr(pa, name), getattr(pb, name), err_msg=name)
        same = ("on1", "slide_tol", "stick", "built")
        assert [getattr(pa, n) for n in same] == [getattr(pb, n) for n in same]
    return len(a.pairs)


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_contact_sets_on_native_patches_are_the_python_ones(robot, collapse_states, rng, obstacles):
    env = obstacle_env() if obstacles else None
    nat, py = _sets(robot, env)
    assert nat.world is not None and py.world is not None
    assert nat.world._native is not None and py.world._native is None
    qs = list(collapse_states[::20]) + [
        rng.uniform(robot.params.lower, robot.params.upper) for _ in range(40)
    ]
    n_in = n_out = 0
    for q in qs:
        pairs = nat.world.sweep(q, 0.005).pairs.tolist()
        a = nat.add_pairs(q, pairs)
        b = py.add_pairs(q, pairs)
        assert a == b
        n_in += sum(a)
        n_out += len(a) - sum(a)
        _same_sets(nat, py)
        # the model's kinematics are at q (the rows read them), as pair by pair
        np.testing.assert_array_equal(nat.data.oMi[-1].homogeneous, py.data.oMi[-1].homogeneous)
        # a refresh at a nearby q: the same pairs dropped, the same patches kept
        q2 = q + 1e-3 * rng.standard_normal(robot.nq)
        nat.refresh(q2)
        py.refresh(q2)
        _same_sets(nat, py)
        for k in list(nat.pairs):
            nat.remove_pair(k)
            py.remove_pair(k)
    assert n_in > 50 and n_out > 50, (n_in, n_out)


def test_geom_data_is_placed_at_the_patches_q(robot, rng):
    """After native patches the world's pieces are owed at their q: read, they are there."""
    w = CollisionWorld(robot)
    q0, q1 = (rng.uniform(robot.params.lower, robot.params.upper) for _ in range(2))
    k = int(np.argmax([go.parentJoint for go in w.geom_model.geometryObjects]))
    w._fk(q1)
    at_q1 = w.geom_data.oMg[k].homogeneous.copy()
    w.sweep(q1, reuse=True)
    w.contact_patches(q0, [0, 1, 2], 1e-3)
    assert w.dispatch.pending == np.asarray(q0, dtype=np.float64).tobytes()
    placed = w.geom_data.oMg[k].homogeneous.copy()
    assert w.dispatch.pending is False
    w._fk(q0)
    np.testing.assert_array_equal(placed, w.geom_data.oMg[k].homogeneous)
    assert not np.array_equal(placed, at_q1)
    np.testing.assert_array_equal(w.candidate_pairs(), CollisionWorld(robot).sweep(q0).pairs)
    # a native sweep after the patches is unaffected by them (its own q and witness points)
    w.sweep(q1)
    w.contact_patches(q0, [0], 1e-3)
    np.testing.assert_array_equal(w._native.last_q(), q1)


def test_bad_queries_are_configuration_errors(robot):
    w = CollisionWorld(robot)
    q = robot.pose("drive")
    with pytest.raises(packbot.ConfigurationError, match=r"q.*\(8,\)"):
        w.contact_patches(np.zeros(robot.nq - 1), [0], 1e-3)
    with pytest.raises(packbot.ConfigurationError, match="pair"):
        w.contact_patches(q, [0, len(w.pairs)], 1e-3)
    with pytest.raises(packbot.ConfigurationError, match="pair"):
        w.contact_patch(q, -1, 1e-3)
    assert w.contact_patches(q, [], 1e-3) == []


def test_disabled_native_patches_take_the_python_path(robot, rng, monkeypatch):
    w = CollisionWorld(robot)
    q = robot.pose("drive")
    pairs = w.sweep(q, 0.05).pairs.tolist()
    ref = w.contact_patches(q, pairs, 0.05)
    assert any(p is not None for p in ref)

    class Broken:
        def patches(self, *args):
            raise AssertionError("the native patches ran")

    monkeypatch.setattr(w, "_native", Broken())
    monkeypatch.setattr(native_sweep, "ENABLED", False)
    got = w.contact_patches(q, pairs, 0.05)
    for a, b in zip(got, ref, strict=True):
        assert (a is None) == (b is None)
        if a is not None and b is not None:
            np.testing.assert_array_equal(a.points1, b.points1)
    monkeypatch.setattr(native_sweep, "ENABLED", True)
    with pytest.raises(AssertionError, match="native patches ran"):
        w.contact_patches(q, pairs, 0.05)
