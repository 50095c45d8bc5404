"""The native collision sweep (``packbot._native_coal``) against the sweep's Python path.

:class:`packbot.native_sweep.NativeSweep` (forward kinematics, the broadphase boxes, their
overlaps and Coal's distances in one compiled call) is compared with the Python path
(Pinocchio's broadphase manager and ``pin.computeDistances``) in two worlds of the same
structure queried in the same order: at named poses, random poses and states of a collapse,
with the floor alone and with obstacles of every kind (a tilted halfspace among them), at
margins from 0 to 0.2 m. The candidates, the distances, the witness points and the closest
pair must be the same, bit for bit: the same library computes them from the same inputs.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest
from test_collision import obstacle_env as collision_obstacles

import packbot
from packbot import native_sweep
from packbot.collision import CollisionWorld
from packbot.environment import Environment, Obstacle


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


pytestmark = pytest.mark.skipif(
    not native_sweep.available(), reason="packbot._native_coal is not available"
)

LOCKED = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]
MARGINS = (0.0, 0.003, 0.05, 0.2)


def obstacle_env() -> Environment:
    """test_collision's floor, crate, rock and wall, and a tilted halfspace, in reach."""
    return collision_obstacles().with_obstacles(
        Obstacle(name="slope", kind="halfspace", normal=(0.3, 0.2, 1.0), offset=-0.02),
    )


def python_world(robot: packbot.Robot, env: Environment | None) -> CollisionWorld:
    w = CollisionWorld(robot, env)
    w._native = None  # this world's sweep takes the Python path
    return w


@pytest.fixture(scope="module")
def collapse_states(robot) -> np.ndarray:
    """Configurations along the contact-normal collapse (mu 0.5, the wrist locked, 1.5 s)."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.5, config=cfg)
    return np.asarray(res.q)


def _configurations(robot, collapse_states, rng) -> list[np.ndarray]:
    named = [robot.pose(name) for name in ("drive", "stow", "stand", "high", "low")]
    rand = [rng.uniform(robot.params.lower, robot.params.upper) for _ in range(150)]
    return named + list(collapse_states[:: max(1, len(collapse_states) // 60)]) + rand


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_native_sweep_equals_the_python_path_bit_for_bit(robot, collapse_states, rng, obstacles):
    env = obstacle_env() if obstacles else None
    nat, py = CollisionWorld(robot, env), python_world(robot, env)
    assert nat._native is not None and py._native is None
    seen = {"tests": 0, "within": 0, "penetrating": 0, "empty": 0}
    for q in _configurations(robot, collapse_states, rng):
        for m in MARGINS:
            a, b = nat.sweep(q, m), py.sweep(q, m)
            np.testing.assert_array_equal(a.pairs, b.pairs)
            assert a.pairs.dtype == b.pairs.dtype
            # same library, same inputs: the same numbers, not merely close ones
            np.testing.assert_array_equal(a.distances, b.distances)
            assert (a.min_pair, a.min_distance, a.counts) == (b.min_pair, b.min_distance, b.counts)
            seen["tests"] += len(a.pairs)
            seen["within"] += int(np.sum(a.distances < m))
            seen["penetrating"] += int(np.sum(a.distances < 0))
            seen["empty"] += len(a.pairs) == 0
    assert seen["tests"] > 10_000 and seen["within"] > 500, seen
    assert seen["penetrating"] > 20, seen
    assert seen["empty"] > 0 or obstacles, seen  # (the tilted slope is a candidate everywhere)


def test_witness_points_and_normals_are_the_python_paths(robot, collapse_states, rng):
    env = obstacle_env()
    nat, py = CollisionWorld(robot, env), python_world(robot, env)
    n = 0
    for q in _configurations(robot, collapse_states, rng)[::3]:
        a, b = nat.contacts(q, 0.05), py.contacts(q, 0.05)
        assert [c.pair for c in a] == [c.pair for c in b]
        for ca, cb in zip(a, b, strict=True):
            assert ca.distance == cb.distance
            np.testing.assert_array_equal(ca.p1, cb.p1)
            np.testing.assert_array_equal(ca.p2, cb.p2)
            np.testing.assert_array_equal(ca.normal, cb.normal)
        n += len(a)
    assert n > 100


def test_a_cluttered_world_prunes_alike(robot, rng):
    """110 box obstacles (136 pieces, 2,104 pairs): the same candidates and distances."""
    boxes = [
        Obstacle(name=f"b{i}", kind="box", size=(0.1, 0.1, 0.1), xyz=tuple(x))
        for i, x in enumerate(rng.uniform((-1.0, -1.0, 0.05), (1.0, 1.0, 1.2), size=(110, 3)))
    ]
    env = Environment().with_obstacles(*boxes)
    nat, py = CollisionWorld(robot, env), python_world(robot, env)
    n = 0
    for _ in range(40):
        q = rng.uniform(robot.params.lower, robot.params.upper)
        a, b = nat.sweep(q), py.sweep(q)
        np.testing.assert_array_equal(a.pairs, b.pairs)
        np.testing.assert_array_equal(a.distances, b.distances)
        n += int(np.sum(a.pairs >= 0) and np.sum(a.distances < nat.margin))
    assert n > 40


def test_native_boxes_are_the_broadphase_managers(robot, rng):
    """The extension's world boxes are those of Pinocchio's manager, to the bit."""
    env = obstacle_env()
    nat = CollisionWorld(robot, env)
    assert nat._native is not None
    for _ in range(20):
        q = rng.uniform(robot.params.lower, robot.params.upper)
        for m in (0.0, 0.05):
            nat.sweep(q, m)
            lo, hi = nat._native.boxes()
            nat._fk(q)
            nat._place_broadphase(m)
            boxes = [co.getAABB() for co in nat._bp.getCollisionObjects()]
            np.testing.assert_array_equal(lo, [np.asarray(b.min_) for b in boxes])
            np.testing.assert_array_equal(hi, [np.asarray(b.max_) for b in boxes])


def test_reuse_placement_and_candidate_pairs_after_native_sweeps(robot, rng):
    w = CollisionWorld(robot)
    assert w._native is not None
    q0, q1 = (rng.uniform(robot.params.lower, robot.params.upper) for _ in range(2))
    first = w.sweep(q0, reuse=True)
    assert not first.pairs.flags.writeable and not first.distances.flags.writeable
    assert w.sweep(q0, reuse=True) is first
    # a sweep without reuse does not replace the reused one, and its arrays are its own
    other = w.sweep(q1)
    assert other.pairs.flags.writeable and w.sweep(q0, reuse=True) is first
    # the pieces are placed on demand at the last query's q (a reused sweep's included)
    np.testing.assert_array_equal(w.candidate_pairs(), first.pairs)
    # geom_data read after a native sweep holds the pieces at that sweep's q (a piece on a
    # moving joint: the last joint's)
    joints = [go.parentJoint for go in w.geom_model.geometryObjects]
    k = int(np.argmax(joints))
    assert joints[k] == robot.model.njoints - 1
    w.sweep(q1)
    placed = w.geom_data.oMg[k].homogeneous.copy()  # (oMg[k] is a live view)
    w._fk(q1)
    np.testing.assert_array_equal(placed, w.geom_data.oMg[k].homogeneous)
    w._fk(q0)
    assert not np.array_equal(placed, w.geom_data.oMg[k].homogeneous)
    w.sweep(q1)
    np.testing.assert_array_equal(w.candidate_pairs(), other.pairs)
    w.sweep(q1, 0.2)
    np.testing.assert_array_equal(w.candidate_pairs(0.2), w._collect(0.2))
    # a query of the Python path in between (pair_contact) places the pieces itself
    w.sweep(q0)
    w.pair_contact(q1, 0)
    np.testing.assert_array_equal(w.candidate_pairs(), other.pairs)


def test_disabled_or_unavailable_native_sweep_takes_the_python_path(robot, rng, monkeypatch):
    w = CollisionWorld(robot)
    q = rng.uniform(robot.params.lower, robot.params.upper)
    ref = w.sweep(q)

    class Broken:
        def sweep(self, *args):
            raise AssertionError("the native sweep ran")

    monkeypatch.setattr(w, "_native", Broken())
    monkeypatch.setattr(native_sweep, "ENABLED", False)
    got = w.sweep(q)
    np.testing.assert_array_equal(got.pairs, ref.pairs)
    np.testing.assert_array_equal(got.distances, ref.distances)
    monkeypatch.setattr(native_sweep, "ENABLED", True)
    with pytest.raises(AssertionError, match="native sweep ran"):
        w.sweep(q)
    # an extension that cannot serve (not loaded, another coal version): no native sweep
    monkeypatch.setattr(native_sweep, "_WHY_NOT", "built against another Coal")
    assert not native_sweep.available()
    w2 = CollisionWorld(robot)
    assert w2._native is None
    np.testing.assert_array_equal(w2.sweep(q).distances, ref.distances)


def test_other_manager_types_and_unsupported_worlds_keep_the_python_path(robot):
    cls = type(
        "WorldTree",
        (CollisionWorld,),
        {"_broadphase_type": pin.BroadPhaseManager_DynamicAABBTreeCollisionManager},
    )
    assert cls(robot)._native is None
    assert native_sweep.native_sweep(CollisionWorld(robot)) is not None
    assert coal.__version__ == native_sweep._native_coal.COAL_VERSION


def test_a_wrong_size_q_is_a_configuration_error(robot):
    w = CollisionWorld(robot)
    assert w._native is not None
    with pytest.raises(packbot.ConfigurationError, match=r"q.*\(8,\)"):
        w.sweep(np.zeros(robot.nq - 1))
    with pytest.raises(packbot.ConfigurationError, match="margin"):
        w.sweep(robot.pose("drive"), -1.0)


def test_a_collapse_runs_alike_with_and_without_the_native_sweep(robot, monkeypatch):
    """The contact-normal collapse (1 s): the same events and the same trajectory."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    q0 = robot.pose("drive")
    runs = []
    for enabled in (True, False):
        monkeypatch.setattr(native_sweep, "ENABLED", enabled)
        runs.append(packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg))
    a, b = runs
    assert [(e.t, e.kind) for e in a.events] == [(e.t, e.kind) for e in b.events]
    np.testing.assert_array_equal(np.asarray(a.q), np.asarray(b.q))
    np.testing.assert_array_equal(a.diagnostics.min_distance, b.diagnostics.min_distance)


def test_worlds_sharing_pieces_but_not_kinematics_sweep_with_their_own(robot):
    """Two robots with the same pieces and joint names share a geometry model; the native
    sweep of each takes its own robot's kinematics (a joint origin moved by 0.15 m here)."""
    import dataclasses

    model = robot.model.copy()
    M = model.jointPlacements[3]
    model.jointPlacements[3] = pin.SE3(M.rotation, M.translation + np.array([0.0, 0.0, 0.15]))
    moved = dataclasses.replace(robot, model=model)
    w0, w1 = CollisionWorld(robot), CollisionWorld(moved)
    assert w0.geom_model is w1.geom_model  # shared: the test's premise
    q = robot.pose("drive")
    native = w1.sweep(q, 0.05)
    native_sweep.ENABLED = False
    try:
        python = CollisionWorld(moved).sweep(q, 0.05)
    finally:
        native_sweep.ENABLED = True
    assert native.pairs.tolist() == python.pairs.tolist()
    np.testing.assert_array_equal(native.distances, python.distances)
    assert not np.array_equal(w0.sweep(q, 0.05).distances[:3], native.distances[:3])


def test_the_dispatch_owes_the_placement_until_a_reader_places_the_pieces(robot, rng):
    """The world's NativeDispatch: after a native sweep the pieces are owed at its q (True),
    after a reused one at that sweep's q (its bytes); reading geom_data places them there and
    clears the debt; a sweep of the Python path places them itself."""
    w = CollisionWorld(robot)
    dispatch = w.dispatch
    assert w._native is not None and dispatch.pending is False
    q0, q1 = (rng.uniform(robot.params.lower, robot.params.upper) for _ in range(2))
    k = int(np.argmax([go.parentJoint for go in w.geom_model.geometryObjects]))
    w.sweep(q0, reuse=True)
    assert dispatch.pending is True
    at_q0 = w.geom_data.oMg[k].homogeneous.copy()
    assert dispatch.pending is False
    w.sweep(q1)
    w.sweep(q0, reuse=True)  # the reused result: owed at q0, not at the last call's q1
    assert dispatch.pending == np.asarray(q0, dtype=np.float64).tobytes()
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, at_q0)
    assert dispatch.pending is False
    w.sweep(q1)
    native_sweep.ENABLED = False
    try:
        w.sweep(q0)
    finally:
        native_sweep.ENABLED = True
    assert dispatch.pending is False
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, at_q0)


@pytest.mark.parametrize("enabled", [True, False])
def test_point_queries_between_sweeps_change_no_sweep(robot, enabled, monkeypatch):
    """Coal warm-starts GJK from a request's last answer: pair_contact has its own requests,
    so the sweeps (native or Python) give the same distances with or without point queries of
    other configurations between them."""
    monkeypatch.setattr(native_sweep, "ENABLED", enabled)
    rng = np.random.default_rng(7)
    qs = [robot.pose("drive") + rng.uniform(-0.05, 0.05, robot.nq) for _ in range(6)]
    plain, queried = CollisionWorld(robot), CollisionWorld(robot)
    for q in qs:
        a = plain.sweep(q, 0.05)
        for _ in range(3):
            for p in a.pairs[:4]:
                queried.pair_contact(q + rng.uniform(-0.02, 0.02, robot.nq), int(p))
        b = queried.sweep(q, 0.05)
        assert a.pairs.tolist() == b.pairs.tolist()
        np.testing.assert_array_equal(a.distances, b.distances)


def test_a_fresh_sweep_is_a_new_one(robot, rng):
    """``Sweep.fresh`` (a world's sweep copied from the first one built for its pieces and
    kinematics, sharing its hulls) sweeps and patches as a Sweep built anew, to the bit, over
    a sequence of sweeps (each pair's GJK warm start its own), and a sweep of one copy leaves
    another as it was."""
    if not native_sweep.available():
        pytest.skip("packbot._native_coal not built")
    from packbot import _native_coal

    world = CollisionWorld(robot)
    args = {**native_sweep._kinematics(robot.model), **native_sweep._arguments(world)}
    built, proto = _native_coal.Sweep(**args), _native_coal.Sweep(**args)
    copy, other = proto.fresh(), proto.fresh()
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    qs = [rng.uniform(lo, hi) for _ in range(40)]
    for q in qs:
        a, b = built.sweep(q, 0.05), copy.sweep(q, 0.05)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
        assert a[2:] == b[2:]
        close = a[0][a[1] < 0.01]
        if len(close):
            for x, y in zip(
                built.patches(q, close, 0.01), copy.patches(q, close, 0.01), strict=True
            ):
                np.testing.assert_array_equal(x, y)
    # the other copy, untouched by the sweeps above, sweeps the first q as a new one
    first = _native_coal.Sweep(**args).sweep(qs[0], 0.05)
    again = other.sweep(qs[0], 0.05)
    np.testing.assert_array_equal(first[1], again[1])
    assert copy.n_pairs == built.n_pairs


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_native_point_queries_are_the_python_paths_bit_for_bit(
    robot, collapse_states, rng, obstacles
):
    """pair_contact in one native call (Sweep.point_distance: the point queries' own requests
    and GJK warm starts) against the Python path's second GeometryData, queried alike: the
    same distances, witness points and normals, bit for bit, sweeps in between included."""
    env = obstacle_env() if obstacles else None
    nat, py = CollisionWorld(robot, env), python_world(robot, env)
    n = 0
    for q in _configurations(robot, collapse_states, rng)[::3]:
        pairs = nat.sweep(q, 0.02).pairs.tolist()
        py.sweep(q, 0.02)
        for k in pairs[:6]:
            for qq in (q, q + 1e-4):  # (a second query of the pair: its warm start)
                a, b = nat.pair_contact(qq, k), py.pair_contact(qq, k)
                assert a.pair == b.pair and a.distance == b.distance
                np.testing.assert_array_equal(a.p1, b.p1)
                np.testing.assert_array_equal(a.p2, b.p2)
                np.testing.assert_array_equal(a.normal, b.normal)
                n += 1
        # the pieces are owed at the last query's q: read, they are there
        M = nat.geom_data.oMg[-1].homogeneous
        np.testing.assert_array_equal(M, py.geom_data.oMg[-1].homogeneous)
    assert n > 200
    with pytest.raises(packbot.ConfigurationError, match="q"):
        nat.pair_contact(np.zeros(robot.nq - 1), 0)


def test_a_run_is_the_same_with_native_point_queries(robot, monkeypatch):
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    runs = []
    for on in (False, True):
        monkeypatch.setattr(native_sweep, "POINT_ENABLED", on)
        runs.append(
            packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 2.0, config=cfg)
        )
    off, on = runs
    assert off.diagnostics.distance_queries > 50
    for name in ("t", "q", "v", "energy"):
        np.testing.assert_array_equal(getattr(on, name), getattr(off, name))
    assert [(e.t, e.kind) for e in on.events] == [(e.t, e.kind) for e in off.events]
