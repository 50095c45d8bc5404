"""The compiled contact patches (``Sweep.patches`` of ``packbot._native_coal``) against Coal.

:meth:`CollisionWorld.contact_patches <packbot.collision.CollisionWorld.contact_patches>` asks
the compiled sweep for the patches of several pairs at one q (one forward kinematics, then per
pair Coal's ``collide`` and ``computeContactPatch``); Coal's Python bindings on the same shapes,
placed by Pinocchio's Python calls, are the reference: the same normals, points, depths and
piece placements, and None for the same far pairs, at named poses, random poses and states of
a collapse, with the floor alone and with obstacles of every kind, at several tolerances.
"""

from __future__ import annotations

import coal
import numpy as np
import pytest
from test_collision_sweep import LOCKED, DirectCoal, _configurations, obstacle_env

import packbot
from packbot import collision_queries
from packbot.collision import CollisionWorld
from packbot.contact.normal_set import ContactSet

TOLS = (0.0, 1e-4, 3e-3)


@pytest.fixture(scope="module")
def collapse_states(robot) -> np.ndarray:
    """Configurations along the contact-normal collapse (mu 0.5, the wrist locked, 1.5 s)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.5, config=cfg)
    return np.asarray(res.q)


def _coal_patch(direct: DirectCoal, k: int, tol: float):
    """Pair k's first contact patch within tol by Coal's Python bindings, or None."""
    p = direct.world.pairs[k]
    M1, M2 = direct.gdata.oMg[p.geom1], direct.gdata.oMg[p.geom2]
    T1 = coal.Transform3s(M1.rotation, M1.translation)
    T2 = coal.Transform3s(M2.rotation, M2.translation)
    g1, g2 = direct.shapes[p.geom1], direct.shapes[p.geom2]
    creq = coal.CollisionRequest()
    creq.enable_contact = True
    creq.security_margin = tol
    cres = coal.CollisionResult()
    if not coal.collide(g1, T1, g2, T2, creq, cres):
        return None
    preq = coal.ContactPatchRequest()
    pres = coal.ContactPatchResult(preq)
    coal.computeContactPatch(g1, T1, g2, T2, cres, preq, pres)
    patch = pres.getContactPatch(0)
    n = patch.size()
    pts1 = np.array([patch.getPointShape1(i) for i in range(n)]).reshape(-1, 3)
    pts2 = np.array([patch.getPointShape2(i) for i in range(n)]).reshape(-1, 3)
    return np.array(patch.getNormal()), pts1, pts2, float(patch.penetration_depth)


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_patches_are_coals(robot, collapse_states, rng, obstacles):
    """Each patch is Coal's collide + computeContactPatch on the same shapes and placements.

    The placements come from Pinocchio's Python forward kinematics and from the extension's
    own: the same products, agreeing to ~1e-15 m; a patch clipped from faces moves with them by
    as little, so 1e-9 m covers them with room (a rounding-level assert would tie the test to
    one machine's sums). Pairs whose distance is within 1e-9 m of the tolerance (where
    collide's answer flips with that rounding) are not asked.
    """
    env = obstacle_env() if obstacles else None
    w = CollisionWorld(robot, env)
    direct = DirectCoal(w)
    seen = {"patches": 0, "far": 0, "faces": 0, "penetrating": 0}
    for q in _configurations(robot, collapse_states, rng)[::2]:
        d = direct.all(q)
        for tol in TOLS:
            pairs = [k for k in w.sweep(q, 0.01).pairs.tolist() if abs(d[k] - tol) > 1e-9]
            got = w.contact_patches(q, pairs, tol)
            rot, trans = collision_queries.patch_batch(w, q, pairs, tol)[5:7]
            for i, (k, a) in enumerate(zip(pairs, got, strict=True)):
                p = w.pairs[k]
                for s, g in enumerate((p.geom1, p.geom2)):
                    M = direct.gdata.oMg[g]
                    np.testing.assert_allclose(rot[i, s], M.rotation, atol=1e-12)
                    np.testing.assert_allclose(trans[i, s], M.translation, atol=1e-12)
                b = _coal_patch(direct, k, tol)
                if b is None:
                    assert a is None, (k, tol)
                    seen["far"] += 1
                    continue
                assert a is not None, (k, tol)
                assert a.pair == p
                np.testing.assert_allclose(a.normal, b[0], atol=1e-9)
                assert a.points1.shape == b[1].shape, (k, tol)
                np.testing.assert_allclose(a.points1, b[1], atol=1e-9)
                np.testing.assert_allclose(a.points2, b[2], atol=1e-9)
                assert a.distance == pytest.approx(b[3], abs=1e-9)
                seen["patches"] += 1
                seen["faces"] += len(a.points1) >= 3
                seen["penetrating"] += a.distance < 0
    assert seen["patches"] > 150 and seen["far"] > 150, seen
    assert seen["faces"] > 50 and seen["penetrating"] > 10, seen


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


def _same_sets(a: ContactSet, b: ContactSet) -> int:
    assert list(a.pairs) == list(b.pairs)
    for k, pa in a.pairs.items():
        pb = b.pairs[k]
        for name in ("local1", "local2", "normal2", "offset0", "frame2", "centre1", "centre2"):
            np.testing.assert_array_equal(getattr(pa, name), getattr(pb, name), err_msg=name)
        same = ("on1", "slide_tol", "stick", "built")
        assert [getattr(pa, n) for n in same] == [getattr(pb, n) for n in same]
    return len(a.pairs)


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
