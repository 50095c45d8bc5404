"""The collision world: convex pieces, pair filtering, pruning, signed distances.

Convex pieces of the robot and of the static environment; bounding-volume pruning; Coal GJK/EPA
signed distances with witness points and normals.

Conventions (used everywhere in packbot):

- Every tested pair is ordered (piece 1, piece 2) with piece 1 on the *more distal* body (the
  higher Pinocchio joint index) and piece 2 on the more proximal body, the chassis or an
  obstacle (static bodies are always piece 2).
- The signed distance d is positive when separated and negative when penetrating (the depth).
- The unit normal n points from body 1 to body 2, and the witness points (world frame) satisfy
  ``p2 - p1 = d * n``. Swapping the pair flips n and swaps the points.

Pairs that are never tested: pieces of one body, bodies joined by a joint (adjacent), two static
bodies, and link pairs listed in ``urdf/packbot_eod.srdf`` (never within 5 cm of each other
over a sampling of the joint space; regenerate with ``packbot generate-srdf``).

Pruning (the report's bounding-volume hierarchy, one level finer): each piece has a bounding box
in its joint frame; per query the world boxes follow the joints' placements, are inflated by the
query margin, and only the pairs whose boxes overlap go to the narrowphase, all in one C++ call
(``pin.computeDistances`` with only those pairs active).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.environment import Environment
from packbot.errors import ConfigurationError, ResourceNotFound, UnknownNameError
from packbot.model import Robot
from packbot.resources import data_dir

__all__ = [
    "DEFAULT_MARGIN",
    "SRDF_NAME",
    "CollisionWorld",
    "Contact",
    "ContactPatch",
    "PairInfo",
    "SweepCounts",
    "SweepResult",
]

log = logging.getLogger(__name__)

SRDF_NAME = "packbot_eod.srdf"
#: Default query margin [m]: pairs farther apart than this are pruned.
DEFAULT_MARGIN = 0.05
#: Absolute GJK and EPA tolerance [m].
GJK_TOLERANCE = 1e-10


@dataclass(frozen=True)
class PairInfo:
    """One tested pair of convex pieces.

    Attributes:
        index: Index in :attr:`CollisionWorld.pairs` (and in the geometry model's pair list).
        geom1: Geometry index of piece 1 (distal body).
        geom2: Geometry index of piece 2 (proximal or static body).
        link1: Link (or obstacle) name of body 1.
        link2: Link (or obstacle) name of body 2.
        piece1: Piece name on body 1.
        piece2: Piece name on body 2.
        joint1: Pinocchio joint index moving body 1.
        joint2: Pinocchio joint index moving body 2 (0 for the chassis and obstacles).
    """

    index: int
    geom1: int
    geom2: int
    link1: str
    link2: str
    piece1: str
    piece2: str
    joint1: int
    joint2: int


@dataclass(frozen=True)
class Contact:
    """Signed distance of one pair with its witness points and normal (world frame).

    Attributes:
        pair: The pair.
        distance: Signed distance d [m] (negative: penetration depth).
        p1: Witness point on piece 1 [m].
        p2: Witness point on piece 2 [m].
        normal: Unit normal from body 1 to body 2; ``p2 - p1 = d * normal``.
    """

    pair: PairInfo
    distance: float
    p1: NDArray[np.float64]
    p2: NDArray[np.float64]
    normal: NDArray[np.float64]


@dataclass(frozen=True)
class ContactPatch:
    """Where two touching pieces meet: a polygon (4 points face on face, 2 edge on face).

    Attributes:
        pair: The pair.
        normal: Unit normal from body 1 to body 2 (world).
        points1: Patch vertices on piece 1, shape (K, 3) [m], world frame.
        points2: The matching points on piece 2, shape (K, 3) [m].
        distance: Signed distance of the pair [m].
    """

    pair: PairInfo
    normal: NDArray[np.float64]
    points1: NDArray[np.float64]
    points2: NDArray[np.float64]
    distance: float


class SweepCounts(NamedTuple):
    """Work done by one sweep: pairs considered, pruned by bounding boxes, narrowphase tests."""

    considered: int
    pruned: int
    tests: int


class SweepResult(NamedTuple):
    """Result of a pruned sweep.

    Attributes:
        min_distance: Smallest signed distance among the tested pairs [m] (``inf`` if none
            was within the margin).
        min_pair: Index of that pair, or -1.
        pairs: Indices of the pairs tested (shape (T,)).
        distances: Their signed distances [m] (shape (T,)).
        counts: The work done.
    """

    min_distance: float
    min_pair: int
    pairs: NDArray[np.intp]
    distances: NDArray[np.float64]
    counts: SweepCounts


def _link_name(model: pin.Model, geom: pin.GeometryObject) -> str:
    return str(model.frames[geom.parentFrame].name)


class CollisionWorld:
    """Convex pieces of a robot and its static environment, answering distance queries at q.

    Args:
        robot: The loaded robot.
        environment: Static obstacles; None means the floor alone.
        srdf: An SRDF file of link pairs not to test; None means the shipped one, False none.
        margin: Default query margin [m] for pruning and for witness read-back.

    Attributes:
        robot: The robot.
        environment: The environment.
        geom_model: Robot pieces followed by obstacle pieces, with the tested pairs.
        geom_data: Its data (placements, distance results).
        pairs: The tested pairs (see :class:`PairInfo`).
        margin: Default query margin [m].
    """

    def __init__(
        self,
        robot: Robot,
        environment: Environment | None = None,
        *,
        srdf: Path | str | bool | None = None,
        margin: float = DEFAULT_MARGIN,
    ) -> None:
        if not margin > 0:
            raise ConfigurationError("margin", margin, "a positive distance [m]")
        self.robot = robot
        self.environment = Environment() if environment is None else environment
        self.environment.validate()
        self.margin = float(margin)
        model = robot.model
        self._data = model.createData()
        gm = robot.collision_model.copy()
        self._n_robot = gm.ngeoms
        self._body_names = {j: str(model.names[j]) for j in range(model.njoints)}
        link_of_geom = [_link_name(model, go) for go in gm.geometryObjects]
        # Obstacles: static, one "body" each (body id -1 - k).
        body_of_geom = [int(go.parentJoint) for go in gm.geometryObjects]
        for k, ob in enumerate(self.environment.obstacles):
            if ob.name in set(link_of_geom):
                raise ConfigurationError("obstacle.name", ob.name, "a name that is not a link")
            go = pin.GeometryObject(f"{ob.name}", 0, 0, ob.placement(), ob.shape())
            gm.addGeometryObject(go)
            link_of_geom.append(ob.name)
            body_of_geom.append(-1 - k)
        self.geom_model = gm
        self._link_of_geom = link_of_geom
        self._body_of_geom = np.array(body_of_geom)
        self.links: tuple[str, ...] = tuple(dict.fromkeys(link_of_geom))
        srdf_path: Path | None = None
        if srdf is not False:
            srdf_path = data_dir("urdf") / SRDF_NAME if srdf in (None, True) else Path(str(srdf))
            if not srdf_path.is_file():
                raise ResourceNotFound(srdf_path, "run `packbot generate-srdf` to create it")
        self.srdf_path = srdf_path
        for g1, g2 in self._candidate_geom_pairs():
            gm.addCollisionPair(pin.CollisionPair(g1, g2))
        if srdf_path is not None:
            n_before = len(gm.collisionPairs)
            pin.removeCollisionPairs(robot.model, gm, str(srdf_path))
            log.debug(
                "SRDF %s removed %d of %d pairs",
                srdf_path,
                n_before - len(gm.collisionPairs),
                n_before,
            )
        self.pairs: tuple[PairInfo, ...] = tuple(
            self._pair_info(k, int(cp.first), int(cp.second))
            for k, cp in enumerate(gm.collisionPairs)
        )
        self.geom_data = gm.createData()
        for creq in self.geom_data.collisionRequests:
            creq.enable_contact = (
                True  # Coal misses deep overlaps of near-coincident centres without
            )
        for dreq in self.geom_data.distanceRequests:
            # Coal's default relative 1e-6 GJK/EPA tolerance and warm starts let one pair's
            # distance vary by ~1e-6 m between calls; absolute 1e-10 m costs nothing measurable.
            dreq.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
            dreq.gjk_tolerance = GJK_TOLERANCE
            dreq.epa_tolerance = GJK_TOLERANCE
        self._results = list(self.geom_data.distanceResults)
        self._build_bounds()

    # ------------------------------------------------------------------ pairs
    def _is_static(self, body: int) -> bool:
        return body <= 0

    def _adjacent(self, b1: int, b2: int) -> bool:
        parents = self.robot.model.parents
        return (b1 > 0 and parents[b1] == max(b2, 0) and b2 >= 0) or (
            b2 > 0 and parents[b2] == max(b1, 0) and b1 >= 0
        )

    def _candidate_geom_pairs(self) -> list[tuple[int, int]]:
        """Geometry pairs on different, non-adjacent bodies, not both static; distal first."""
        bodies = self._body_of_geom
        out = []
        n = self.geom_model.ngeoms
        for i in range(n):
            for j in range(i + 1, n):
                b_i, b_j = int(bodies[i]), int(bodies[j])
                if b_i == b_j or (self._is_static(b_i) and self._is_static(b_j)):
                    continue
                if self._adjacent(b_i, b_j):
                    continue
                # piece 1 on the more distal body; static bodies (<= 0) always second
                out.append((i, j) if b_i > b_j else (j, i))
        return out

    def _pair_info(self, index: int, g1: int, g2: int) -> PairInfo:
        gos = self.geom_model.geometryObjects
        return PairInfo(
            index=index,
            geom1=g1,
            geom2=g2,
            link1=self._link_of_geom[g1],
            link2=self._link_of_geom[g2],
            piece1=gos[g1].name,
            piece2=gos[g2].name,
            joint1=int(max(self._body_of_geom[g1], 0)),
            joint2=int(max(self._body_of_geom[g2], 0)),
        )

    # ------------------------------------------------------------------ bounds
    def _build_bounds(self) -> None:
        """Per-piece boxes: moving pieces in their joint frame, static ones in the world."""
        gm = self.geom_model
        model = self.robot.model
        gd = gm.createData()
        pin.updateGeometryPlacements(model, model.createData(), gm, gd, np.zeros(model.nq))
        lo_list, hi_list = [], []
        for g, go in enumerate(gm.geometryObjects):
            b = int(self._body_of_geom[g])
            if b > 0:  # joint frame
                M = go.placement
                pts = np.asarray(go.geometry.points(), dtype=float) @ M.rotation.T + M.translation
                lo, hi = pts.min(axis=0), pts.max(axis=0)
            elif b == 0:  # chassis piece, world frame
                M = gd.oMg[g]
                pts = np.asarray(go.geometry.points(), dtype=float) @ M.rotation.T + M.translation
                lo, hi = pts.min(axis=0), pts.max(axis=0)
            else:
                lo, hi = self.environment.obstacles[-1 - b].world_aabb()
            lo_list.append(np.clip(lo, -1e9, 1e9))
            hi_list.append(np.clip(hi, -1e9, 1e9))
        # halfspaces have unbounded boxes, clipped to +-1e9 m to keep the arithmetic finite
        lo_all, hi_all = np.array(lo_list), np.array(hi_list)
        moving = np.flatnonzero(self._body_of_geom > 0)
        self._moving_joints = sorted({int(b) for b in self._body_of_geom if b > 0})
        row = {j: k for k, j in enumerate(self._moving_joints)}
        self._moving_geoms = moving
        self._geom_row = np.array([row[int(self._body_of_geom[g])] for g in moving])
        local_lo, local_hi = lo_all[moving], hi_all[moving]
        self._c_local = ((local_lo + local_hi) / 2)[:, :, None]
        self._h_local = ((local_hi - local_lo) / 2)[:, :, None]
        # Box columns X = [lo; -hi], Y = [-hi; lo] (shape (6, G)): two boxes overlap within m
        # iff max(X[:, a] + Y[:, b]) <= m, that is lo_a - hi_b <= m and lo_b - hi_a <= m on
        # every axis. Transposed so that numpy reduces over the short axis cheaply.
        self._XT = np.vstack([lo_all.T, -hi_all.T])
        self._YT = np.vstack([-hi_all.T, lo_all.T])
        self._pair_g1 = np.array([p.geom1 for p in self.pairs], dtype=np.intp)
        self._pair_g2 = np.array([p.geom2 for p in self.pairs], dtype=np.intp)
        self._gap = np.empty((6, len(self.pairs)))
        # Activation map of pin.GeometryData.setActiveCollisionPairs (upper triangle).
        self._active = np.zeros((gm.ngeoms, gm.ngeoms), dtype=bool)
        self._map_row = np.minimum(self._pair_g1, self._pair_g2)
        self._map_col = np.maximum(self._pair_g1, self._pair_g2)
        self._all_pairs = np.arange(len(self.pairs), dtype=np.intp)
        contiguous = len(moving) > 0 and np.array_equal(
            moving, np.arange(moving[0], moving[0] + len(moving))
        )
        self._moving_slice = slice(moving[0], moving[-1] + 1) if contiguous else moving

    def _update_boxes(self) -> None:
        """World boxes of the moving pieces, from their joints' placements."""
        oMi = self._data.oMi
        H = np.array([oMi[j].homogeneous for j in self._moving_joints]).take(self._geom_row, 0)
        R = H[:, :3, :3]
        c = (R @ self._c_local)[:, :, 0] + H[:, :3, 3]
        h = (np.abs(R) @ self._h_local)[:, :, 0]
        lo, hi = (c - h).T, (c + h).T
        g = self._moving_slice
        self._XT[:3, g] = lo
        self._XT[3:, g] = -hi
        self._YT[:3, g] = -hi
        self._YT[3:, g] = lo

    def world_boxes(
        self, q: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper world-box corners of every piece at q [m], shape (G, 3) each."""
        self.update(q)
        return self._XT[:3].T.copy(), -self._XT[3:].T

    # ------------------------------------------------------------------ queries
    def update(self, q: NDArray[np.float64]) -> None:
        """Place every piece at configuration q [rad] (forward kinematics)."""
        pin.updateGeometryPlacements(
            self.robot.model, self._data, self.geom_model, self.geom_data, q
        )
        self._update_boxes()

    def candidate_pairs(self, margin: float | None = None) -> NDArray[np.intp]:
        """Indices of the pairs whose piece boxes, inflated by ``margin`` [m], overlap.

        At the configuration of the last :meth:`update`.
        """
        m = self.margin if margin is None else margin
        gap = self._gap
        np.add(self._XT.take(self._pair_g1, 1), self._YT.take(self._pair_g2, 1), out=gap)
        return np.flatnonzero(gap.max(axis=0) <= m)

    def sweep(self, q: NDArray[np.float64], margin: float | None = None) -> SweepResult:
        """Signed distances of the pairs that the bounding boxes leave, the smallest and its pair.

        Costs one forward kinematics, the box test in numpy, and one C++ call
        (``pin.computeDistances``) over the candidate pairs only.

        Args:
            q: Configuration [rad].
            margin: Query margin [m] (default: the world's).
        """
        self.update(q)
        cand = self.candidate_pairs(margin)
        n_all = len(self.pairs)
        counts = SweepCounts(n_all, n_all - len(cand), len(cand))
        if len(cand) == 0:
            return SweepResult(np.inf, -1, cand, np.zeros(0), counts)
        k = self._distances_of(cand)
        res = self._results
        d = np.array([res[p].min_distance for p in cand])
        return SweepResult(float(res[k].min_distance), k, cand, d, counts)

    def _distances_of(self, pairs: NDArray[np.intp]) -> int:
        """Compute the distances of ``pairs`` (one C++ call); returns the closest pair's index."""
        active = self._active
        active.fill(False)
        active[self._map_row[pairs], self._map_col[pairs]] = True
        self.geom_data.setActiveCollisionPairs(self.geom_model, active)
        return int(pin.computeDistances(self.geom_model, self.geom_data))

    def all_distances(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distances of every tested pair [m], unpruned, in one C++ call."""
        self.update(q)
        self._distances_of(self._all_pairs)
        return np.array([r.min_distance for r in self._results])

    def _contact(self, p: int) -> Contact:
        r = self._results[p]
        return Contact(
            self.pairs[p],
            float(r.min_distance),
            np.array(r.getNearestPoint1()),
            np.array(r.getNearestPoint2()),
            np.array(r.normal),
        )

    def contacts(self, q: NDArray[np.float64], margin: float | None = None) -> list[Contact]:
        """Every pair within ``margin`` [m] at q, with witness points and normals, closest first."""
        m = self.margin if margin is None else margin
        sw = self.sweep(q, m)
        close = sw.pairs[sw.distances < m]
        out = [self._contact(int(p)) for p in close]
        return sorted(out, key=lambda c: c.distance)

    def pair_contact(self, q: NDArray[np.float64], pair: int) -> Contact:
        """Signed distance, witness points and normal of one pair at q (no pruning)."""
        self.update(q)
        self._distances_of(np.array([int(pair)], dtype=np.intp))
        return self._contact(int(pair))

    def closest(self, q: NDArray[np.float64]) -> Contact:
        """The closest pair at q over all tested pairs."""
        self.update(q)
        return self._contact(self._distances_of(self._all_pairs))

    def in_collision(self, q: NDArray[np.float64], tol: float = 0.0) -> bool:
        """Whether any tested pair is closer than ``tol`` [m] at q (penetrating if tol = 0)."""
        sw = self.sweep(q, max(tol, 1e-9))
        return sw.min_distance < tol

    def pair_index(
        self, link1: str, link2: str, piece1: str | None = None, piece2: str | None = None
    ) -> list[int]:
        """Indices of the tested pairs between two links (or obstacles), in either order.

        Raises:
            UnknownNameError: A link or obstacle name that the world does not have.
        """
        for name in (link1, link2):
            if name not in self.links:
                raise UnknownNameError("link or obstacle", name, self.links)
        out = []
        for p in self.pairs:
            fwd = (p.link1, p.link2, p.piece1, p.piece2)
            rev = (p.link2, p.link1, p.piece2, p.piece1)
            for l1, l2, s1, s2 in (fwd, rev):
                if (l1, l2) == (link1, link2) and piece1 in (None, s1) and piece2 in (None, s2):
                    out.append(p.index)
                    break
        return out

    # ------------------------------------------------------------------ patches
    def contact_patch(self, q: NDArray[np.float64], pair: int, tol: float) -> ContactPatch | None:
        """The contact patch of a pair within ``tol`` [m] at q, or None if farther apart.

        Coal's ``computeContactPatch`` on the two convex pieces (a face on a face gives 4
        points, an edge 2, a vertex 1).
        """
        self.update(q)
        p = self.pairs[int(pair)]
        g1 = self.geom_model.geometryObjects[p.geom1].geometry
        g2 = self.geom_model.geometryObjects[p.geom2].geometry
        T1 = _to_coal(self.geom_data.oMg[p.geom1])
        T2 = _to_coal(self.geom_data.oMg[p.geom2])
        creq = coal.CollisionRequest()
        creq.security_margin = tol
        creq.enable_contact = True
        cres = coal.CollisionResult()
        if not coal.collide(g1, T1, g2, T2, creq, cres):
            return None
        preq = coal.ContactPatchRequest()
        pres = coal.ContactPatchResult(preq)
        coal.computeContactPatch(g1, T1, g2, T2, cres, preq, pres)
        patch = pres.getContactPatch(0)
        n = np.array(patch.getNormal())
        k = patch.size()
        pts1 = np.array([patch.getPointShape1(i) for i in range(k)]).reshape(-1, 3)
        pts2 = np.array([patch.getPointShape2(i) for i in range(k)]).reshape(-1, 3)
        return ContactPatch(p, n, pts1, pts2, float(patch.penetration_depth))

    # ------------------------------------------------------------------ line of sight
    def line_of_sight(
        self,
        q: NDArray[np.float64],
        target: NDArray[np.float64],
        *,
        frame: str = "camera_optical",
        radius: float = 0.0,
        ignore: tuple[str, ...] = ("camera_head",),
    ) -> str | None:
        """Whether the view from a frame to a world point is blocked.

        A capsule of ``radius`` [m] (0: the segment itself) from the frame's origin to the
        target, shortened by 1 mm at the target end, is tested against every robot piece (but
        those of the ``ignore`` links, by default the camera head itself) and every obstacle.

        Returns:
            The name of the closest blocking link or obstacle, or None if the view is clear.
        """
        model = self.robot.model
        if not model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in model.frames])
        self.update(q)
        pin.updateFramePlacement(model, self._data, model.getFrameId(frame))
        a = self._data.oMf[model.getFrameId(frame)].translation.copy()
        b = np.asarray(target, dtype=float)
        seg = b - a
        length = float(np.linalg.norm(seg)) - 1e-3
        if length <= 0:
            return None
        u = seg / np.linalg.norm(seg)
        z = np.array([0.0, 0.0, 1.0])
        R = pin.Quaternion.FromTwoVectors(z, u).matrix()
        T = coal.Transform3s(R, a + u * length / 2)
        cap = coal.Capsule(radius, length)
        best: tuple[float, str] | None = None
        req = coal.DistanceRequest()
        for g, go in enumerate(self.geom_model.geometryObjects):
            name = self._link_of_geom[g]
            if name in ignore:
                continue
            res = coal.DistanceResult()
            d = coal.distance(cap, T, go.geometry, _to_coal(self.geom_data.oMg[g]), req, res)
            if d <= 0.0:
                dist_from_eye = float(np.dot(np.array(res.getNearestPoint2()) - a, u))
                if best is None or dist_from_eye < best[0]:
                    best = (dist_from_eye, name)
        return None if best is None else best[1]


def _to_coal(M: pin.SE3) -> coal.Transform3s:
    return coal.Transform3s(M.rotation, M.translation)
