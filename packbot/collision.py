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
bodies, and link pairs listed in ``urdf/packbot/packbot_eod.srdf`` (never within 5 cm of each other
over a sampling of the joint space; regenerate with ``packbot generate-srdf``).

Pruning: Pinocchio's broadphase manager over Coal's ``SSaPCollisionManager`` (sweep and prune)
keeps, in C++, the pairs whose world boxes, each inflated by half the query margin, overlap;
the narrowphase then runs on those pairs only, in one C++ call (``pin.computeDistances`` with
only those pairs active). When the compiled ``packbot._native_coal`` is available
(:mod:`packbot.native_sweep`), :meth:`CollisionWorld.sweep` does all of it in one native call
instead, with the same boxes, candidates and distances.

The world's fixed parts (pieces, pairs, broadphase boxes) are built in
``packbot.collision_build``, once per robot, environment and SRDF; the contact patches and the
line of sight query Coal in ``packbot.collision_queries``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import collision_build as _cb
from packbot import collision_queries as _cq
from packbot import native_sweep as _ns
from packbot.collision_build import BOX_PAD as BOX_PAD  # (importable from here as before)
from packbot.collision_build import HALFSPACE_BOX as HALFSPACE_BOX
from packbot.collision_queries import LOS_SHORTEN as LOS_SHORTEN
from packbot.collision_records import Contact, ContactPatch, PairInfo, SweepCounts, SweepResult
from packbot.environment import Environment
from packbot.errors import ConfigurationError, ResourceNotFound, UnknownNameError
from packbot.keywords import checked_arguments
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

#: File name of the SRDF beside the URDF (its disabled collision pairs).
SRDF_NAME = "packbot_eod.srdf"
#: Default query margin [m]: pairs farther apart than this are pruned.
DEFAULT_MARGIN = 0.05
#: Absolute GJK and EPA tolerance [m].
GJK_TOLERANCE = _cb.GJK_TOLERANCE


@checked_arguments
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
        geom_data: Its data (placements, distance results), placed at the last query's q
            when read.
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
        self._body_names = {j: str(model.names[j]) for j in range(model.njoints)}
        srdf_path: Path | None = None
        if srdf is not False:
            srdf_path = data_dir("urdf") / SRDF_NAME if srdf in (None, True) else Path(str(srdf))
            if not srdf_path.is_file():
                raise ResourceNotFound(srdf_path, "run `packbot generate-srdf` to create it")
        self.srdf_path = srdf_path
        # the fixed parts (shared with the worlds of the same robot, environment and SRDF)
        (
            self.geom_model,
            self._bp_model,
            self._link_of_geom,
            self._body_of_geom,
            self.links,
            self.pairs,
            self._pair_flat,
        ) = _cb.fixed_parts(robot, self.environment, srdf_path)
        gm = self.geom_model
        self._n_robot = robot.collision_model.ngeoms
        self._native: _ns.NativeSweep | None = None  # (built below, once geom_data is set)
        #: the native sweeps' calls and where they owe the pieces (placed on demand; a
        #: :class:`~packbot.native_sweep.NativeDispatch`)
        self.dispatch = _ns.NativeDispatch(self)
        # the geometry model's data and live proxies into its C++ vector of distance results
        # (valid while it lives: indexing them costs 0.1 us against 0.45 us through
        # distanceResults[k]), made on first use (a run whose sweeps are native never uses them)
        self._gd: pin.GeometryData | None = None
        self._results_list: list[Any] | None = None
        self._point_data: pin.GeometryData | None = None  # pair_contact's (made on first use)
        self._last_sweep: tuple[tuple[bytes, float], SweepResult] | None = None  # see sweep
        self._n_pairs = len(self.pairs)
        G = gm.ngeoms
        # Activation map of pin.GeometryData.setActiveCollisionPairs (upper triangle).
        self._active = np.zeros((G, G), dtype=bool)
        self._all_pairs = np.arange(len(self.pairs), dtype=np.intp)
        self._active_list: list[int] | None = None  # the pairs active in geom_data (None: other)
        self._bp_started = False  # (the broadphase's data and manager: made on first use)
        # The native sweep (None: the Python path), unless a subclass prunes with another
        # manager type (the native sweep's candidates are the SSaP manager's).
        self._native = (
            _ns.native_sweep(self)
            if self._broadphase_type is pin.BroadPhaseManager_SSaPCollisionManager
            else None
        )
        # contact_patch's Coal requests and each pair's two shapes (read-only), made once
        creq = coal.CollisionRequest()
        creq.enable_contact = True
        self._patch_requests = (creq, coal.ContactPatchRequest())
        self._patch_shapes: dict[int, tuple[Any, Any]] = {}

    # ------------------------------------------------------------------ broadphase
    #: Pinocchio's wrapper of the Coal broadphase manager the sweep prunes with: sweep and
    #: prune, chosen by measurement (benchmarks/collision.py: as fast as testing every pair of
    #: boxes for the robot and the floor, the fastest type from 100 box obstacles on).
    _broadphase_type: type = pin.BroadPhaseManager_SSaPCollisionManager

    @property
    def _bp(self) -> Any:
        """The broadphase manager, started on first use (native sweeps never need it)."""
        if not self._bp_started:
            self._start_broadphase()
        return self._bp_manager

    def _start_broadphase(self) -> None:
        """The broadphase's data, manager and pair collector on :attr:`_bp_model`."""
        self._bp_started = True
        bp_model = self._bp_model
        bp_data = bp_model.createData()
        for creq in bp_data.collisionRequests:
            creq.break_distance = 0.0  # (Coal's default 1e-3 m would inflate every box)
        self._bp_data = bp_data
        self._bp_manager = self._broadphase_type(self.robot.model, bp_model, bp_data)
        self._bp_callback = pin.CollisionCallBackCollect(bp_model, bp_data)
        # a live proxy of the callback's C++ vector of pair indices (cleared by every collide)
        self._bp_pairs = self._bp_callback.pair_indexes
        G = self.geom_model.ngeoms
        self._bp_margins = np.zeros((G, G))
        self._bp_margin = math.nan  # the margin set in bp_data's requests (nan: none yet)

    def _place_broadphase(self, margin: float) -> None:
        """Place the broadphase pieces at the last forward kinematics.

        Each piece's world box is inflated by ``margin / 2`` [m].
        """
        bp = self._bp
        pin.updateGeometryPlacements(self.robot.model, self._data, self._bp_model, self._bp_data)
        if margin != self._bp_margin:
            self._bp_margins.fill(margin)
            self._bp_data.setSecurityMargins(self._bp_model, self._bp_margins, True, False)
            self._bp_margin = margin
        bp.update(False)

    def _collect(self, margin: float) -> NDArray[np.intp]:
        """Indices (ascending) of the pairs whose boxes, inflated by ``margin`` [m], overlap.

        At the last forward kinematics; all in C++ but the read-back of the indices.
        """
        self.dispatch.place()
        self._place_broadphase(margin)
        self._bp.collide(self._bp_callback)
        pairs = self._bp_pairs
        out = np.fromiter(pairs, np.intp, len(pairs))
        out.sort()
        return out

    def world_boxes(
        self, q: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper world-box corners of every piece at q [m], shape (G, 3) each.

        The boxes the pruning uses: conservative (each contains its piece), padded by
        ``BOX_PAD``, not inflated by the margin; halfspaces' infinite sides are clipped to
        +-``HALFSPACE_BOX``.
        """
        self._fk(q)
        self._place_broadphase(0.0)
        boxes = [co.getAABB() for co in self._bp.getCollisionObjects()]
        lo = np.array([np.asarray(b.min_, dtype=float) for b in boxes])
        hi = np.array([np.asarray(b.max_, dtype=float) for b in boxes])
        return lo, hi

    # ------------------------------------------------------------------ queries
    def _query_margin(self, margin: float | None) -> float:
        """The world's margin for None; else a checked query margin [m].

        Raises:
            ConfigurationError: Not a finite number >= 0.
        """
        if margin is None:
            return self.margin
        m = float(margin)
        if not 0.0 <= m < math.inf:
            raise ConfigurationError("margin", margin, "a finite distance >= 0 [m]")
        return m

    def _place(self, q: NDArray[np.float64]) -> None:
        """Forward kinematics and piece placements (the broadphase is placed on demand)."""
        self._fk(q)

    @property
    def _geom_data(self) -> pin.GeometryData:
        """The geometry model's data as it is (made on first use; :attr:`geom_data` places it)."""
        gd = self._gd
        if gd is None:
            gd = self._gd = _cb.geometry_data(self.geom_model)
        return gd

    @property
    def _results(self) -> list[Any]:
        """Live proxies of :attr:`geom_data`'s distance results, one per pair (made once)."""
        res = self._results_list
        if res is None:
            res = self._results_list = list(self._geom_data.distanceResults)
        return res

    @property
    def geom_data(self) -> pin.GeometryData:
        """The geometry model's data (placements, distance results), at the last query's q.

        After a native sweep the pieces are placed here on first read
        (:meth:`NativeDispatch.place <packbot.native_sweep.NativeDispatch.place>`).
        """
        if self.dispatch.pending is not False:
            self.dispatch.place()
        return self._geom_data

    def _fk(self, q: NDArray[np.float64]) -> None:
        """Forward kinematics and piece placements; a wrong-size q is a ConfigurationError."""
        self.dispatch.pending = False
        try:
            pin.updateGeometryPlacements(
                self.robot.model, self._data, self.geom_model, self._geom_data, q
            )
        except (ValueError, TypeError) as exc:  # Pinocchio's own size/type check
            nq = self.robot.model.nq
            raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc

    def update(self, q: NDArray[np.float64]) -> None:
        """Place every piece at configuration q [rad] (forward kinematics)."""
        self._fk(q)

    def candidate_pairs(self, margin: float | None = None) -> NDArray[np.intp]:
        """Indices of the pairs whose piece boxes, inflated by ``margin`` [m], overlap.

        At the configuration of the last query: the pairs a :meth:`sweep` there tests.

        Raises:
            ConfigurationError: A margin that is not a finite number >= 0.
        """
        return self._collect(self._query_margin(margin))

    def sweep(
        self, q: NDArray[np.float64], margin: float | None = None, *, reuse: bool = False
    ) -> SweepResult:
        """Signed distances of the pairs that the bounding boxes leave, the smallest and its pair.

        Every pair within the margin is among them (with others whose boxes overlap). Costs
        one forward kinematics, one broadphase in C++ (Pinocchio's manager: the pieces' world
        boxes, inflated by half the margin, and their overlaps), and one C++ call
        (``pin.computeDistances``) over the candidate pairs only, which also returns the
        closest; then one read per candidate. With the compiled sweep
        (:mod:`packbot.native_sweep`, when available and enabled) all of it is one native
        call with the same candidates and distances; the pieces of ``geom_data`` are then
        placed at q only when a query that reads them (:meth:`candidate_pairs`) comes next.

        Args:
            q: Configuration [rad].
            margin: Query margin [m] (default: the world's).
            reuse: Return the last sweep's result (its arrays are read-only) when it was made
                with ``reuse`` at the same q and margin, bit for bit (the event loop sweeps
                the same state more than once). The pieces are placed at q either way (on
                first read of ``geom_data`` after a native sweep), but
                then ``geom_data``'s distance results are not recomputed: a caller that reads
                them (``contacts``) must not reuse.

        Raises:
            ConfigurationError: A wrong-size q, or a margin that is not a finite number >= 0.
        """
        m = self._query_margin(margin)
        if self._native is not None and _ns.ENABLED:
            return self.dispatch.sweep(q, m, reuse)
        self._fk(q)
        key = None
        if reuse:
            key = (np.asarray(q, dtype=np.float64).tobytes(), m)
            last = self._last_sweep
            if last is not None and last[0] == key:
                return last[1]
        cand = self._collect(m)
        n_all, n = self._n_pairs, len(cand)
        counts = SweepCounts(n_all, n_all - n, n)
        if n == 0:
            out = SweepResult(np.inf, -1, cand, np.zeros(0), counts)
        else:
            pairs = cand.tolist()
            if pairs != self._active_list:  # the set changes rarely from one step to the next
                self._activate(cand)
                self._active_list = pairs
            k = pin.computeDistances(self.geom_model, self.geom_data)
            res = self._results
            d = np.array([res[p].min_distance for p in pairs])
            out = SweepResult(res[k].min_distance, k, cand, d, counts)
        if key is not None:
            out.pairs.setflags(write=False)
            out.distances.setflags(write=False)
            self._last_sweep = (key, out)
        return out

    def _activate(self, pairs: NDArray[np.intp]) -> None:
        """Make exactly ``pairs`` the active pairs of geom_data."""
        active = self._active
        active.fill(False)
        active.put(self._pair_flat[pairs], True)
        self.geom_data.setActiveCollisionPairs(self.geom_model, active)

    def _distances_of(self, pairs: NDArray[np.intp]) -> int:
        """Compute the distances of ``pairs`` (one C++ call); returns the closest pair's index."""
        self._activate(pairs)
        self._active_list = None
        return int(pin.computeDistances(self.geom_model, self.geom_data))

    def all_distances(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distances of every tested pair [m], unpruned, in one C++ call."""
        self._place(q)
        self._distances_of(self._all_pairs)
        return np.array([r.min_distance for r in self._results])

    def _contact(self, p: int) -> Contact:
        return self._contact_of(self._results[p], p)

    def _contact_of(self, r: coal.DistanceResult, p: int) -> Contact:
        return Contact(
            self.pairs[p],
            float(r.min_distance),
            np.array(r.getNearestPoint1()),
            np.array(r.getNearestPoint2()),
            np.array(r.normal),
        )

    def contacts(self, q: NDArray[np.float64], margin: float | None = None) -> list[Contact]:
        """Every pair within ``margin`` [m] at q, with witness points and normals, closest first.

        One pruned :meth:`sweep`; witness points and normals are read back only for the pairs
        closer than the margin.
        """
        m = self.margin if margin is None else margin
        sw = self.sweep(q, m)
        if self.dispatch.pending is True:  # the witness points are the native sweep's
            out = self.dispatch.contacts(sw, m)
        else:
            close = sw.pairs[sw.distances < m]
            out = [self._contact(int(p)) for p in close]
        return sorted(out, key=lambda c: c.distance)

    def _pair_id(self, pair: int) -> int:
        """Check a pair index.

        Raises:
            ConfigurationError: Not the index of a tested pair.
        """
        k = int(pair)
        if not 0 <= k < self._n_pairs:
            raise ConfigurationError("pair", pair, f"a pair index in [0, {self._n_pairs})")
        return k

    def pair_contact(self, q: NDArray[np.float64], pair: int) -> Contact:
        """Signed distance, witness points and normal of one pair at q (no pruning).

        Raises:
            ConfigurationError: ``pair`` is not the index of a tested pair, or a wrong-size q.
        """
        k = self._pair_id(pair)
        native = self._native
        if native is not None and _ns.ENABLED and _ns.POINT_ENABLED:  # (in one native call)
            return _cq.point_contact(self, native, q, k)
        self._place(q)
        # Its own requests: Coal warm-starts GJK from a request's last answer, so the sweep's
        # distances (native or not) never depend on the point queries made between sweeps.
        data = self._point_data
        if data is None:
            data = self._point_data = _cb.geometry_data(self.geom_model)
        pin.updateGeometryPlacements(self.robot.model, self._data, self.geom_model, data)
        pin.computeDistance(self.geom_model, data, k)
        return self._contact_of(data.distanceResults[k], k)

    def closest(self, q: NDArray[np.float64]) -> Contact:
        """The closest pair at q over all tested pairs."""
        if self._n_pairs == 0:
            raise ConfigurationError("pairs", 0, "a world with at least one tested pair")
        self._place(q)
        return self._contact(self._distances_of(self._all_pairs))

    def in_collision(self, q: NDArray[np.float64], tol: float = 0.0) -> bool:
        """Whether any tested pair is closer than ``tol`` [m] at q (penetrating if tol = 0)."""
        sw = self.sweep(q, max(tol, 1e-9))
        return bool(sw.min_distance < tol)

    def pieces(self, link: str) -> tuple[str, ...]:
        """Names of the convex pieces of a link or obstacle.

        Raises:
            UnknownNameError: A link or obstacle name that the world does not have.
        """
        if link not in self.links:
            raise UnknownNameError("link or obstacle", link, self.links)
        gos = self.geom_model.geometryObjects
        return tuple(str(gos[g].name) for g, name in enumerate(self._link_of_geom) if name == link)

    def pair_index(
        self, link1: str, link2: str, piece1: str | None = None, piece2: str | None = None
    ) -> list[int]:
        """Indices of the tested pairs between two links (or obstacles), in either order.

        Args:
            link1: A link or obstacle name.
            link2: Another one.
            piece1: Only pairs with this piece of ``link1`` (default: any).
            piece2: Only pairs with this piece of ``link2`` (default: any).

        Raises:
            UnknownNameError: A link or obstacle name that the world does not have, or a piece
                name that is not one of that link's pieces (the message lists the valid ones).
        """
        for name, piece in ((link1, piece1), (link2, piece2)):
            valid = self.pieces(name)
            if piece is not None and piece not in valid:
                raise UnknownNameError(f"piece of {name}", piece, valid)
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

        Raises:
            ConfigurationError: ``pair`` is not the index of a tested pair, or a wrong-size q.
        """
        return self.contact_patches(q, [pair], tol)[0]

    def contact_patches(
        self, q: NDArray[np.float64], pairs: Sequence[int], tol: float
    ) -> list[ContactPatch | None]:
        """The contact patches of several pairs within ``tol`` [m] at q (None: farther apart).

        The same patches as :meth:`contact_patch` pair by pair, bit for bit; with the compiled
        sweep (:mod:`packbot.native_sweep`, when available and enabled) all of them in one
        native call after one forward kinematics, the pieces of ``geom_data`` then placed at q
        on first read.

        Raises:
            ConfigurationError: A pair that is not the index of a tested pair, or a wrong-size q.
        """
        ks = [self._pair_id(p) for p in pairs]
        batch = _cq.patch_batch(self, q, ks, tol)
        if batch is None:
            out: list[ContactPatch | None] = []
            for k in ks:
                found = _cq.contact_patch(self, q, k, tol)
                out.append(None if found is None else ContactPatch(self.pairs[k], *found))
            return out
        sizes, normals, depths, pts1, pts2 = batch[:5]
        out, s = [], 0
        for i, k in enumerate(ks):
            K = int(sizes[i])
            if K < 0:
                out.append(None)
                continue
            patch = ContactPatch(
                self.pairs[k],
                normals[i].copy(),
                pts1[s : s + K].copy(),
                pts2[s : s + K].copy(),
                float(depths[i]),
            )
            out.append(patch)
            s += K
        return out

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

        A capsule of ``radius`` [m] (0: the segment itself) along the segment from the frame's
        origin to the target, lying within the segment (its rounded ends included) and stopping
        1 mm short of the target, is tested (``coal.distance``) against every robot piece but
        those of the ``ignore`` links (by default the camera head itself, on whose lens the
        segment starts) and every obstacle, the floor included.

        Returns:
            The name of the blocking link or obstacle nearest to the eye, or None if the view
            is clear.

        Raises:
            UnknownNameError: An unknown frame, or an unknown link or obstacle in ``ignore``.
            ConfigurationError: A target that is not 3 finite numbers, or a negative radius.
        """
        return _cq.line_of_sight(self, q, target, frame, radius, ignore)
