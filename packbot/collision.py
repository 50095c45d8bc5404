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

Pruning and distances: the compiled sweep (``packbot._native_coal``, :mod:`packbot.native_sweep`)
keeps, in one native call, the pairs whose world boxes, each inflated by half the query margin,
overlap, and runs Coal's GJK/EPA on those pairs only.

The world's fixed parts (pieces, pairs, broadphase boxes) are built in
``packbot.collision_build``, once per robot, environment and SRDF; one pair's distance, the
contact patches and the line of sight are in ``packbot.collision_queries``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

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
        srdf: An SRDF file of link pairs not to test; None means the robot's
            (:attr:`Robot.srdf_path <packbot.model.Robot.srdf_path>`: PackBot's shipped one), True
            the shipped one, False none.
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
        if srdf is None:
            srdf_path = robot.srdf_path
        elif srdf is not False:
            srdf_path = data_dir("urdf") / SRDF_NAME if srdf is True else Path(str(srdf))
        if srdf_path is not None and not srdf_path.is_file():
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
        ) = _cb.fixed_parts(robot, self.environment, srdf_path)
        self._n_robot = robot.collision_model.ngeoms
        self._n_pairs = len(self.pairs)
        self._all_pairs = np.arange(self._n_pairs, dtype=np.int64)
        # the geometry model's data, for its placements only (made on first use)
        self._gd: pin.GeometryData | None = None
        self._placed_q = pin.neutral(model)  # (where _fk last placed the pieces)
        self._last_sweep: tuple[tuple[bytes, float], SweepResult] | None = None  # see sweep
        #: the compiled sweep (raises a PackbotError when the extension is missing or was
        #: built against another Coal)
        self._native: _ns.NativeSweep = _ns.native_sweep(self)
        #: the native sweeps' calls and where they owe the pieces (placed on demand; a
        #: :class:`~packbot.native_sweep.NativeDispatch`)
        self.dispatch = _ns.NativeDispatch(self)

    def world_boxes(
        self, q: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper world-box corners of every piece at q [m], shape (G, 3) each.

        The boxes the pruning uses: conservative (each contains its piece), padded by
        ``BOX_PAD``, not inflated by the margin; halfspaces' infinite sides are clipped to
        +-``HALFSPACE_BOX``.

        Raises:
            ConfigurationError: A wrong-size q.
        """
        self._candidates(q, 0.0)
        return self._native.boxes()

    def _candidates(self, q: NDArray[np.float64], margin: float) -> NDArray[np.intp]:
        """The compiled sweep's broadphase at q with checked margin [m] (its candidates).

        Raises:
            ConfigurationError: A wrong-size q.
        """
        qa = np.ascontiguousarray(q, dtype=np.float64)
        try:
            out = self._native.candidates(qa, margin)
        except (ValueError, TypeError) as exc:  # the extension's size/type check
            nq = self.robot.model.nq
            raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc
        self.dispatch.pending = True  # (the pieces owed at its q)
        return out.astype(np.intp, copy=False)

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
            gd = self._gd = self.geom_model.createData()
        return gd

    @property
    def geom_data(self) -> pin.GeometryData:
        """The geometry model's data, its pieces placed at the last query's q.

        After a compiled query the pieces are placed here on first read
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
        self._placed_q = np.array(q, dtype=np.float64)

    def update(self, q: NDArray[np.float64]) -> None:
        """Place every piece at configuration q [rad] (forward kinematics)."""
        self._fk(q)

    def candidate_pairs(self, margin: float | None = None) -> NDArray[np.intp]:
        """Indices of the pairs whose piece boxes, inflated by ``margin`` [m], overlap.

        At the configuration of the last query: the pairs a :meth:`sweep` there tests.

        Raises:
            ConfigurationError: A margin that is not a finite number >= 0.
        """
        m = self._query_margin(margin)
        return self._candidates(self.dispatch.last_q(), m)

    def sweep(
        self, q: NDArray[np.float64], margin: float | None = None, *, reuse: bool = False
    ) -> SweepResult:
        """Signed distances of the pairs that the bounding boxes leave, the smallest and its pair.

        Every pair within the margin is among them (with others whose boxes overlap). One call
        of the compiled sweep (:mod:`packbot.native_sweep`): forward kinematics, the pieces'
        world boxes inflated by half the margin, their overlaps, and Coal's distance on each
        candidate; the pieces of ``geom_data`` are then placed at q only when a reader comes.

        Args:
            q: Configuration [rad].
            margin: Query margin [m] (default: the world's).
            reuse: Return the last sweep's result (its arrays are read-only) when it was made
                with ``reuse`` at the same q and margin, bit for bit (the event loop sweeps
                the same state more than once).

        Raises:
            ConfigurationError: A wrong-size q, or a margin that is not a finite number >= 0.
        """
        return self.dispatch.sweep(q, self._query_margin(margin), reuse)

    def _distances(self, q: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Every tested pair's distance, witness points and normal at q (``Sweep.distances``).

        Raises:
            ConfigurationError: A wrong-size q.
        """
        qa = np.ascontiguousarray(q, dtype=np.float64)
        try:
            out = self._native.distances(qa, self._all_pairs)
        except (ValueError, TypeError) as exc:  # the extension's size/type check
            nq = self.robot.model.nq
            raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc
        self.dispatch.pending = qa.tobytes()  # (the pieces owed at q)
        return tuple(out)

    def all_distances(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distances of every tested pair [m], unpruned, in one native call."""
        return self._distances(q)[0]

    def contacts(self, q: NDArray[np.float64], margin: float | None = None) -> list[Contact]:
        """Every pair within ``margin`` [m] at q, with witness points and normals, closest first.

        One pruned :meth:`sweep`; witness points and normals are read back only for the pairs
        closer than the margin.
        """
        m = self.margin if margin is None else margin
        sw = self.sweep(q, m)
        return sorted(self.dispatch.contacts(sw, m), key=lambda c: c.distance)

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
        return _cq.point_contact(self, q, self._pair_id(pair))

    def screen_distance(self, q: NDArray[np.float64], pair: int) -> float:
        """Signed distance [m] of one pair at q by GJK requests of its own (no pruning).

        The query of the contact-normal mode's screen of contacts between step ends (the
        compiled stretch's too): its warm starts are not :meth:`pair_contact`'s, so event
        location does not depend on the screen.

        Raises:
            ConfigurationError: ``pair`` is not the index of a tested pair, or a wrong-size q.
        """
        k = self._pair_id(pair)
        qa = np.ascontiguousarray(q, dtype=np.float64)
        try:
            return float(self._native.dip_distance(qa, k))
        except (ValueError, TypeError) as exc:  # the extension's size/type check
            nq = self.robot.model.nq
            raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc

    def closest(self, q: NDArray[np.float64]) -> Contact:
        """The closest pair at q over all tested pairs (the first of equally close ones)."""
        if self._n_pairs == 0:
            raise ConfigurationError("pairs", 0, "a world with at least one tested pair")
        d, p1, p2, normal = self._distances(q)
        k = int(np.argmin(d))
        return Contact(self.pairs[k], float(d[k]), p1[k], p2[k], normal[k])

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

        All of them in one call of the compiled sweep after one forward kinematics, the pieces
        of ``geom_data`` then placed at q on first read.

        Raises:
            ConfigurationError: A pair that is not the index of a tested pair, or a wrong-size q.
        """
        ks = [self._pair_id(p) for p in pairs]
        sizes, normals, depths, pts1, pts2 = _cq.patch_batch(self, q, ks, tol)[:5]
        out: list[ContactPatch | None] = []
        s = 0
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
