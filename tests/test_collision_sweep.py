"""The compiled collision sweep (``packbot._native_coal``) against Coal queried directly.

Every answer of :class:`packbot.collision.CollisionWorld` that the compiled sweep computes (the
pruned sweep, the unpruned distances, one pair's query) is checked against ``coal.distance``
called through Coal's own Python bindings on the same shapes at placements computed by
Pinocchio's Python ``updateGeometryPlacements``, at named poses, random poses and states of a
collapse, with the floor alone and with obstacles of every kind (a tilted halfspace among them).
The broadphase is checked against brute force: every pair within the margin is a candidate.
Analytic cases: a piece above the floor and beside a crate at a known gap.
"""

from __future__ import annotations

import dataclasses

import coal
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_collision import _tight_world
from test_collision import obstacle_env as collision_obstacles

import packbot
from packbot import native_sweep
from packbot.collision import GJK_TOLERANCE, CollisionWorld
from packbot.environment import Environment, Obstacle
from packbot.errors import PackbotError

LOCKED = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]
MARGINS = (0.0, 0.003, 0.05, 0.2)
#: Agreement of the compiled sweep's distances with a direct Coal query [m]. Both run Coal's
#: GJK/EPA with the absolute tolerance GJK_TOLERANCE (1e-10 m) to convergence, from different
#: warm starts (the sweep's GJK starts at each pair's last answer, the direct query from
#: Coal's default guess): each result is within its stopping tolerance of the exact distance,
#: so they agree to about that tolerance, far under any physical length of the model (a
#: rounding-level assert would tie the test to one machine's sums and to the warm start).
DIST_TOL = 10 * GJK_TOLERANCE


def obstacle_env() -> Environment:
    """test_collision's floor, crate, rock and wall, and a tilted halfspace, in reach."""
    return collision_obstacles().with_obstacles(
        Obstacle(name="slope", kind="halfspace", normal=(0.3, 0.2, 1.0), offset=-0.02),
    )


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


class DirectCoal:
    """Coal's own distance on a world's pieces, placed by Pinocchio's Python calls."""

    def __init__(self, world: CollisionWorld) -> None:
        self.world = world
        self.model = world.robot.model
        self.data = self.model.createData()
        self.gdata = world.geom_model.createData()
        self.shapes = [go.geometry for go in world.geom_model.geometryObjects]
        self.request = coal.DistanceRequest()
        self.request.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
        self.request.gjk_tolerance = GJK_TOLERANCE
        self.request.epa_tolerance = GJK_TOLERANCE

    def place(self, q: np.ndarray) -> None:
        pin.updateGeometryPlacements(self.model, self.data, self.world.geom_model, self.gdata, q)

    def distance(self, k: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Pair k's signed distance [m] and nearest points at the last placement."""
        p = self.world.pairs[k]
        M1, M2 = self.gdata.oMg[p.geom1], self.gdata.oMg[p.geom2]
        res = coal.DistanceResult()
        d = coal.distance(
            self.shapes[p.geom1],
            coal.Transform3s(M1.rotation, M1.translation),
            self.shapes[p.geom2],
            coal.Transform3s(M2.rotation, M2.translation),
            self.request,
            res,
        )
        return float(d), np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2())

    def all(self, q: np.ndarray) -> np.ndarray:
        self.place(q)
        return np.array([self.distance(k)[0] for k in range(len(self.world.pairs))])


@pytest.mark.parametrize("obstacles", [False, True], ids=["floor", "obstacles"])
def test_sweep_distances_are_coals(robot, collapse_states, rng, obstacles):
    """The sweep's candidates hold every pair within the margin, with Coal's distances."""
    w = CollisionWorld(robot, obstacle_env() if obstacles else None)
    coal_ = DirectCoal(w)
    seen = {"within": 0, "penetrating": 0}
    for q in _configurations(robot, collapse_states, rng):
        ref = coal_.all(q)
        for margin in MARGINS:
            sw = w.sweep(q, margin)
            np.testing.assert_allclose(sw.distances, ref[sw.pairs], rtol=0.0, atol=DIST_TOL)
            assert set(np.flatnonzero(ref < margin - DIST_TOL)) <= set(sw.pairs.tolist())
            if len(sw.pairs):
                assert sw.min_distance == sw.distances.min()
                assert sw.min_pair == sw.pairs[int(np.argmin(sw.distances))]
            else:
                assert sw.min_pair == -1 and sw.min_distance == np.inf
            seen["within"] += int((sw.distances < margin).sum())
            seen["penetrating"] += int((sw.distances < 0).sum())
    assert seen["within"] > 100 and seen["penetrating"] > 0  # (the cases were exercised)


def test_contacts_witness_points_close_their_distance(robot, collapse_states, rng):
    """contacts(): Coal's distances; the witness points satisfy p2 - p1 = d n with a unit n.

    (The points themselves are not unique where faces are parallel: a face on the floor.)
    """
    w = CollisionWorld(robot, obstacle_env())
    coal_ = DirectCoal(w)
    n = 0
    for q in _configurations(robot, collapse_states, rng)[::2]:
        coal_.place(q)
        for c in w.contacts(q, 0.05):
            assert c.distance == pytest.approx(coal_.distance(c.pair.index)[0], abs=DIST_TOL)
            assert np.linalg.norm(c.normal) == pytest.approx(1.0, abs=1e-9)
            np.testing.assert_allclose(c.p2 - c.p1, c.distance * c.normal, atol=1e-9)
            n += 1
    assert n > 50


def test_all_distances_closest_and_pair_contact_are_coals(robot, collapse_states, rng):
    w = CollisionWorld(robot, obstacle_env())
    coal_ = DirectCoal(w)
    for q in _configurations(robot, collapse_states, rng)[::3]:
        ref = coal_.all(q)
        d = w.all_distances(q)
        np.testing.assert_allclose(d, ref, rtol=0.0, atol=DIST_TOL)
        c = w.closest(q)
        assert c.distance == pytest.approx(d.min(), abs=DIST_TOL)
        assert d[c.pair.index] == pytest.approx(d.min(), abs=DIST_TOL)
        for k in (0, int(np.argmin(ref)), len(w.pairs) - 1):
            pc = w.pair_contact(q, k)
            assert pc.distance == pytest.approx(ref[k], abs=DIST_TOL)
            np.testing.assert_allclose(pc.p2 - pc.p1, pc.distance * pc.normal, atol=1e-9)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    u=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8),
    margin=st.floats(0.0, 0.3),
    clutter=st.booleans(),
)
def test_the_candidates_hold_every_pair_within_the_margin(robot, u, margin, clutter):
    """Broadphase against brute force: every pair closer than the margin (by a direct Coal
    query of every pair) is a candidate, in candidate_pairs and in the sweep alike."""
    w = _worlds(robot)[clutter]
    lo, hi = robot.params.lower, robot.params.upper
    q = lo + np.asarray(u) * (hi - lo)
    ref = DirectCoal(w).all(q)
    within = set(np.flatnonzero(ref < margin - DIST_TOL).tolist())
    sw = w.sweep(q, margin)
    assert within <= set(sw.pairs.tolist())
    cand = w.candidate_pairs(margin)
    np.testing.assert_array_equal(cand, sw.pairs)
    assert np.all(np.diff(cand) > 0)


_WORLDS: dict[int, tuple[CollisionWorld, CollisionWorld]] = {}


def _worlds(robot) -> tuple[CollisionWorld, CollisionWorld]:
    """A world with the floor alone and one with 40 boxes and the obstacles in reach."""
    got = _WORLDS.get(id(robot))
    if got is None:
        rng = np.random.default_rng(3)
        boxes = [
            Obstacle(name=f"b{i}", kind="box", size=(0.1, 0.1, 0.1), xyz=tuple(x))
            for i, x in enumerate(rng.uniform((-1.0, -1.0, 0.05), (1.0, 1.0, 1.2), size=(40, 3)))
        ]
        got = (CollisionWorld(robot), CollisionWorld(robot, obstacle_env().with_obstacles(*boxes)))
        _WORLDS[id(robot)] = got
    return got


@pytest.mark.parametrize("d", [-0.01, 0.0, 0.004, 0.05])
@pytest.mark.parametrize("piece", ["gripper_link/palm", "camera_head/head"])
def test_a_piece_over_the_floor_is_at_its_lowest_vertex_height(robot, rng, piece, d):
    """Analytic: a convex piece's signed distance to a horizontal floor is its lowest vertex's
    height over it (negative: the depth); beside a crate, the gap to its facing side."""
    for q in (
        robot.pose("stand"),
        robot.pose("high"),
        rng.uniform(robot.params.lower, robot.params.upper),
    ):
        w, k = _tight_world(robot, q, piece, "floor", d)
        assert w.all_distances(q)[k] == pytest.approx(d, abs=DIST_TOL)
        assert w.pair_contact(q, k).distance == pytest.approx(d, abs=DIST_TOL)
        if d > 0:
            w, k = _tight_world(robot, q, piece, (0, 1), d)
            sw = w.sweep(q, 0.1)
            got = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))[k]
            assert got == pytest.approx(d, abs=DIST_TOL)


def test_line_of_sight_and_queries_place_the_pieces_where_they_were_asked(robot, rng):
    """The pieces of geom_data are placed at the last query's q on first read, whatever the
    query (a sweep, a reused sweep, a patch, one pair), and candidate_pairs follows it."""
    w = CollisionWorld(robot)
    q0, q1 = (rng.uniform(robot.params.lower, robot.params.upper) for _ in range(2))
    k = int(np.argmax([go.parentJoint for go in w.geom_model.geometryObjects]))
    ref = CollisionWorld(robot)

    def placed_at(q):
        ref.update(q)
        return ref.geom_data.oMg[k].homogeneous.copy()

    first = w.sweep(q0, reuse=True)
    assert not first.pairs.flags.writeable and w.sweep(q0, reuse=True) is first
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, placed_at(q0))
    other = w.sweep(q1)
    assert other.pairs.flags.writeable and w.sweep(q0, reuse=True) is first
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, placed_at(q0))
    np.testing.assert_array_equal(w.candidate_pairs(), first.pairs)
    w.sweep(q1, 0.2)
    np.testing.assert_array_equal(w.candidate_pairs(0.2), w.sweep(q1, 0.2).pairs)
    w.sweep(q0)
    w.pair_contact(q1, 0)
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, placed_at(q1))
    np.testing.assert_array_equal(w.candidate_pairs(), other.pairs)
    w.contact_patches(q0, [0], 1e-3)
    np.testing.assert_array_equal(w.geom_data.oMg[k].homogeneous, placed_at(q0))
    w.all_distances(q1)
    np.testing.assert_array_equal(w.candidate_pairs(), other.pairs)


def test_point_queries_between_sweeps_change_no_sweep(robot):
    """Coal warm-starts GJK from a request's last answer: pair_contact and all_distances have
    their own requests, so the sweeps give the same distances with or without those queries
    of other configurations between them (the same calls in the same order: exactly)."""
    rng = np.random.default_rng(7)
    qs = [robot.pose("drive") + rng.uniform(-0.05, 0.05, robot.nq) for _ in range(6)]
    plain, queried = CollisionWorld(robot), CollisionWorld(robot)
    for q in qs:
        a = plain.sweep(q, 0.05)
        for _ in range(3):
            for p in a.pairs[:4]:
                queried.pair_contact(q + rng.uniform(-0.02, 0.02, robot.nq), int(p))
            queried.all_distances(q + rng.uniform(-0.02, 0.02, robot.nq))
        b = queried.sweep(q, 0.05)
        assert a.pairs.tolist() == b.pairs.tolist()
        np.testing.assert_allclose(a.distances, b.distances, rtol=0.0, atol=1e-15)


def test_worlds_sharing_pieces_but_not_kinematics_sweep_with_their_own(robot):
    """Two robots with the same pieces and joint names share a geometry model; the sweep of
    each takes its own robot's kinematics (a joint origin moved by 0.15 m here)."""
    model = robot.model.copy()
    M = model.jointPlacements[3]
    model.jointPlacements[3] = pin.SE3(M.rotation, M.translation + np.array([0.0, 0.0, 0.15]))
    moved = dataclasses.replace(robot, model=model)
    w0, w1 = CollisionWorld(robot), CollisionWorld(moved)
    assert w0.geom_model is w1.geom_model  # shared: the test's premise
    q = robot.pose("drive")
    sw = w1.sweep(q, 0.05)
    np.testing.assert_allclose(sw.distances, DirectCoal(w1).all(q)[sw.pairs], atol=DIST_TOL)
    assert not np.allclose(w0.all_distances(q), w1.all_distances(q), atol=1e-3)


def test_a_wrong_size_q_is_a_configuration_error(robot):
    w = CollisionWorld(robot)
    bad = np.zeros(robot.nq - 1)
    for call in (
        lambda: w.sweep(bad),
        lambda: w.all_distances(bad),
        lambda: w.closest(bad),
        lambda: w.pair_contact(bad, 0),
        lambda: w.world_boxes(bad),
    ):
        with pytest.raises(packbot.ConfigurationError, match=r"q.*\(8,\)"):
            call()
    with pytest.raises(packbot.ConfigurationError, match="margin"):
        w.sweep(robot.pose("drive"), -1.0)


def test_a_missing_or_mismatched_extension_is_a_clear_error(robot, monkeypatch):
    """Without packbot._native_coal, or with one built against another Coal, a world refuses
    to start with a PackbotError that says how to fix it."""
    assert native_sweep.available() and native_sweep.unavailable_reason() is None
    assert coal.__version__ == native_sweep._native_coal.COAL_VERSION
    missing = native_sweep._why_not(None, ImportError("no module"), coal.__version__)
    assert missing is not None and "pip install ." in missing and "no module" in missing

    class Other:
        COAL_VERSION = "9.9.9"

    other = native_sweep._why_not(Other, None, coal.__version__)
    assert other is not None and "coal==9.9.9" in other and coal.__version__ in other
    assert native_sweep._why_not(native_sweep._native_coal, None, coal.__version__) is None
    monkeypatch.setattr(native_sweep, "_WHY_NOT", other)
    with pytest.raises(PackbotError, match=r"coal==9\.9\.9"):
        CollisionWorld(robot)


def test_an_unsupported_joint_type_names_the_valid_ones(robot):
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    with pytest.raises(packbot.ConfigurationError, match="JointModelSpherical.*JointModelRX"):
        native_sweep._kinematics(model)
