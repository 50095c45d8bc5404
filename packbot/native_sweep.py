"""The collision world's sweep: the compiled ``Sweep`` of ``packbot._native_coal``.

:class:`NativeSweep` wraps the compiled ``Sweep`` (``src/native/sweep.cpp``, nanobind against
Pinocchio's headers and Coal's library), packbot's only collision sweep: one call takes
(q, margin) and returns the pairs the broadphase boxes leave, their signed distances and the
closest pair (forward kinematics, the pieces' placements, the broadphase boxes inflated by
half the margin, their overlaps, and Coal's distance on each candidate). Its other queries
are small named calls: the broadphase candidates alone (``candidates``), the unpruned
distances of some pairs (``distances``), one pair's distance (``point_distance``) and the
contact patches of several pairs (``patches``, ``materials``).

The extension keeps its own Pinocchio model (rebuilt from the model's joint types, parents and
placements) and its own Coal shapes, built from the world's pieces' numbers: a hull's vertices
and triangles, a box's half sides, a halfspace's normal and offset.

The module links libcoal, the library the coal wheel installs. Coal's classes are used inline,
so the module serves only the coal version it was built with: :func:`require` (called when a
collision world is built) raises a :class:`~packbot.errors.PackbotError` that says how to fix
it when the module is missing or was built against another Coal (docs/collision.md, "Coal's
version").

:class:`NativeDispatch` is the world's side of it: the sweep's call (its reuse of the last
result included), where the world's pieces are owed after native queries (placed on demand) and
the witness points of the contacts the last sweep found.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
from numpy.typing import NDArray

from packbot.collision_build import GJK_TOLERANCE
from packbot.collision_records import Contact, SweepCounts, SweepResult
from packbot.errors import ConfigurationError, PackbotError
from packbot.native_joints import SUPPORTED_JOINTS

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld

__all__ = [
    "SUPPORTED_JOINTS",
    "NativeDispatch",
    "NativeSweep",
    "available",
    "native_sweep",
    "require",
    "unavailable_reason",
]

#: The extension's piece kinds.
_CONVEX, _BOX, _HALFSPACE = 0, 1, 2
#: The piece types the extension builds.
_PIECE_TYPES = ("coal.Convex", "coal.Box", "coal.Halfspace")


def _why_not(module: Any, error: ImportError | None, installed: str) -> str | None:
    """Why the compiled sweep cannot run and how to fix it (None: it can).

    Args:
        module: The imported ``packbot._native_coal`` (None: it could not be imported).
        error: Its import error (None: imported).
        installed: The installed coal module's version.
    """
    if module is None:
        return (
            f"packbot's compiled collision sweep, packbot._native_coal, cannot be imported "
            f"({error}): reinstall packbot from its source with `pip install .` (it needs a "
            "C++ compiler), which builds it"
        )
    built = str(module.COAL_VERSION)
    if built != installed:
        return (
            f"packbot._native_coal was built against Coal {built}, but the installed coal is "
            f"{installed}; Coal has no stable binary interface, so install the one it was "
            f"built with, `pip install coal=={built}`, or rebuild packbot against the installed "
            "one with `pip install .`"
        )
    return None


_native_coal: Any
try:  # the compiled extension (built by `pip install .`; see CMakeLists.txt)
    from packbot import _native_coal
except ImportError as exc:  # pragma: no cover - an install without the extension, or no libcoal
    _native_coal = None
    _WHY_NOT = _why_not(None, exc, coal.__version__)
else:
    _WHY_NOT = _why_not(_native_coal, None, coal.__version__)


def available() -> bool:
    """Whether the compiled sweep can run: the extension loads and matches the coal module."""
    return _WHY_NOT is None


def unavailable_reason() -> str | None:
    """Why the compiled sweep cannot run, and how to fix it (None: it can)."""
    return _WHY_NOT


def require() -> None:
    """Check that the compiled sweep can run.

    Raises:
        PackbotError: ``packbot._native_coal`` is missing or was built against another Coal
            version than the installed ``coal`` (the message says how to fix it).
    """
    if _WHY_NOT is not None:
        raise PackbotError(_WHY_NOT)


def _ints(x: Any) -> NDArray[np.int64]:
    return np.ascontiguousarray(x, dtype=np.int64)


def _reals(x: Any) -> NDArray[np.float64]:
    return np.ascontiguousarray(x, dtype=np.float64)


def _kinematics(model: Any) -> dict[str, Any]:
    """The extension's model arguments (joint types, parents, placements, axes).

    Built from the world's own robot model at every build: worlds that share a geometry model
    (the same pieces and joint names, :mod:`packbot.collision`) may differ in kinematics.

    Raises:
        ConfigurationError: A joint type the extension does not build.
    """
    types = [j.shortname() for j in model.joints]
    for t in types[1:]:
        if t not in SUPPORTED_JOINTS:
            raise ConfigurationError("joint type", t, sorted(SUPPORTED_JOINTS))
    axes = np.zeros((len(types), 3))
    for i, j in enumerate(model.joints):
        if i and types[i].endswith("Unaligned"):
            axes[i] = np.asarray(j.extract().axis, dtype=float)
    return {
        "types": types,
        "parents": _ints(list(model.parents)),
        "joint_placements": _reals([M.homogeneous for M in model.jointPlacements]),
        "axes": _reals(axes),
    }


def _arguments(world: CollisionWorld) -> dict[str, Any]:
    """The extension's geometry arguments for a world.

    Raises:
        ConfigurationError: A piece of a type the extension does not build, or a hull face
            that is not a triangle.
    """
    gm = world.geom_model
    kinds, joints, placements, params = [], [], [], []
    points: list[NDArray[np.float64]] = []
    triangles: list[list[int]] = []
    point_start, triangle_start = [0], [0]
    for go in gm.geometryObjects:
        g = go.geometry
        p = np.zeros(4)
        if isinstance(g, coal.Convex):
            pts = np.asarray(g.points(), dtype=float).reshape(-1, 3)
            points.append(pts)
            for i in range(g.num_polygons):
                t = g.polygons(i)
                if t.size() != 3:  # pragma: no cover - packbot's hulls are triangulated
                    raise ConfigurationError(f"piece {go.name!r} face", i, "a triangle")
                triangles.append([int(t[0]), int(t[1]), int(t[2])])
            kinds.append(_CONVEX)
        elif isinstance(g, coal.Box):
            p[:3] = np.asarray(g.halfSide, dtype=float)
            kinds.append(_BOX)
        elif isinstance(g, coal.Halfspace):
            p[:3] = np.asarray(g.n, dtype=float)
            p[3] = float(g.d)
            kinds.append(_HALFSPACE)
        else:  # pragma: no cover - packbot builds hulls, boxes and halfspaces only
            raise ConfigurationError(f"piece {go.name!r}", type(g).__name__, _PIECE_TYPES)
        point_start.append(point_start[-1] + (len(points[-1]) if kinds[-1] == _CONVEX else 0))
        triangle_start.append(len(triangles))
        joints.append(int(go.parentJoint))
        placements.append(go.placement.homogeneous)
        params.append(p)
    bp = world._bp_model.geometryObjects
    box_half = [np.asarray(b.geometry.halfSide, dtype=float) for b in bp]
    box_centre = [np.asarray(b.placement.translation, dtype=float) for b in bp]
    for b in bp:  # the broadphase boxes are axis-aligned in their frames (collision_build.py)
        assert np.array_equal(b.placement.rotation, np.eye(3))
    pairs = gm.collisionPairs
    defaults = coal.DistanceRequest()  # (Coal's iteration limits)
    return {
        "kinds": _ints(kinds),
        "joints": _ints(joints),
        "placements": _reals(placements).reshape(-1, 4, 4),
        "params": _reals(params).reshape(-1, 4),
        "points": _reals(np.concatenate(points) if points else np.zeros((0, 3))),
        "point_start": _ints(point_start),
        "triangles": _ints(triangles).reshape(-1, 3),
        "triangle_start": _ints(triangle_start),
        "box_half": _reals(box_half).reshape(-1, 3),
        "box_centre": _reals(box_centre).reshape(-1, 3),
        "first": _ints([int(c.first) for c in pairs]),
        "second": _ints([int(c.second) for c in pairs]),
        # Coal's default relative 1e-6 GJK/EPA tolerance lets one pair's distance vary by
        # ~1e-6 m between calls; absolute 1e-10 m costs nothing measurable. Each pair's GJK
        # starts from its last answer (its request's cached guess).
        "gjk_tolerance": GJK_TOLERANCE,
        "epa_tolerance": GJK_TOLERANCE,
        "gjk_max_iterations": int(defaults.gjk_max_iterations),
        "epa_max_iterations": int(defaults.epa_max_iterations),
        "absolute_criterion": True,
        "cached_guess": True,
    }


#: The geometry arguments per geometry model (the worlds of one structure share it; the
#: kinematics are not cached: :func:`_kinematics`).
_ARGS: dict[int, tuple[Any, dict[str, Any]]] = {}
_ARGS_MAX = 16
_ARGS_LOCK = threading.Lock()  # (Dask workers may build worlds in several threads)
#: A Sweep per geometry model and kinematics (never swept: Sweep.fresh's prototype), the
#: geometry model kept beside it (an id can be reused)
_PROTOTYPES: dict[tuple[object, ...], tuple[Any, Any]] = {}


class NativeSweep:
    """The compiled sweep of one collision world (its own state: one per world).

    Args:
        world: The world (its geometry model, broadphase boxes and pairs).
        sweep: The extension's ``Sweep`` of that world, new (:func:`native_sweep` makes it).
        prototype: The ``Sweep`` it is a fresh copy of (its face planes are set there too).
    """

    def __init__(self, world: CollisionWorld, sweep: Any, prototype: Any = None) -> None:
        self._sweep = sweep
        self._prototype = prototype
        #: the sweep's C entry point (a capsule; ``src/native/sweep_api.hpp``): the contact-normal
        #: mode's compiled stretch of steps calls it (:mod:`packbot.contact.stretch`)
        self.api: Any = self._sweep.api()
        #: ``sweep(q, margin) -> (pairs, distances, closest pair or -1, its distance)``.
        self.sweep = self._sweep.sweep
        #: ``candidates(q, margin) -> pairs``: the broadphase alone, the pairs (ascending)
        #: whose world boxes at q, inflated by half the margin, overlap (those ``sweep`` tests).
        self.candidates = self._sweep.candidates
        #: ``distances(q, pairs) -> (distances, points1, points2, normals)``: the unpruned
        #: signed distances [m] of several pairs at q, with witness points and normals.
        self.distances = self._sweep.distances
        #: ``last_q() -> q`` of the last sweep or candidates [rad].
        self.last_q = self._sweep.last_q
        #: ``patches(q, pairs, tol) -> (sizes, normals, depths, points1, points2, rotations,
        #: translations)``: the contact patches of several pairs at one q (see
        #: ``CollisionWorld.contact_patches``; the rotations are stored transposed).
        self.patches = self._sweep.patches
        #: ``point_distance(q, k) -> (distance, point1, point2, normal)``: one pair's query at
        #: q with its own warm starts (``CollisionWorld.pair_contact``'s).
        self.point_distance = self._sweep.point_distance
        #: ``dip_distance(q, k) -> distance``: one pair's signed distance at q with warm starts
        #: of its own (``CollisionWorld.screen_distance``'s).
        self.dip_distance = self._sweep.dip_distance
        n = len(world.pairs)
        self._n_geoms = int(world.geom_model.ngeoms)
        self._p1 = np.zeros((n, 3))
        self._p2 = np.zeros((n, 3))
        self._normal = np.zeros((n, 3))

    def materials(
        self,
        q: NDArray[np.float64],
        pairs: NDArray[np.int64],
        tol: float,
        patch_tol: float,
        face_align: float,
        planes: Callable[[], tuple[NDArray[Any], ...]],
    ) -> tuple[NDArray[Any], ...]:
        """The contact patches of several pairs at one q as material points (``Sweep.materials``).

        The pieces' face planes, ``planes() -> (N, o, start)``, are loaded at the first call
        (into the prototype too, so that its next fresh copies have them).
        """
        sweep = self._sweep
        if not sweep.has_planes:  # (a copy made before its prototype had them)
            N, o, start = planes()
            args = (_reals(N), _reals(o), _ints(start))
            sweep.set_planes(*args)
            proto = self._prototype
            if proto is not None and not proto.has_planes:
                proto.set_planes(*args)
        return tuple(sweep.materials(q, pairs, tol, patch_tol, face_align))

    def witness(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The last sweep's witness points on pieces 1 and 2 [m] and normals, per candidate.

        Arrays of shape (>= T, 3) in the candidates' order, overwritten by the next call.
        """
        self._sweep.witness(self._p1, self._p2, self._normal)
        return self._p1, self._p2, self._normal

    def boxes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The world boxes of the last sweep or candidates, inflated by half its margin [m].

        Shape (G, 3) each.
        """
        G = self._n_geoms
        lo, hi = np.zeros((G, 3)), np.zeros((G, 3))
        self._sweep.boxes(lo, hi)
        return lo, hi


def native_sweep(world: CollisionWorld) -> NativeSweep:
    """The compiled sweep of a world.

    Raises:
        PackbotError: The extension is missing or was built against another Coal version
            (:func:`require`).
        ConfigurationError: The world has a joint type or piece type the extension does not
            build.
    """
    require()
    gm = world.geom_model
    with _ARGS_LOCK:
        cached = _ARGS.get(id(gm))
    if cached is None or cached[0] is not gm:
        cached = (gm, _arguments(world))
        with _ARGS_LOCK:
            if len(_ARGS) >= _ARGS_MAX:
                del _ARGS[next(iter(_ARGS))]
            _ARGS[id(gm)] = cached
    geometry = cached[1]
    kinematics = _kinematics(world.robot.model)
    # a new Sweep: a fresh copy of the first one built for these pieces and kinematics (it
    # shares their hulls: 0.05 ms against 0.3 ms for building them again)
    key = (
        id(gm),
        tuple(kinematics["types"]),
        kinematics["parents"].tobytes(),
        kinematics["joint_placements"].tobytes(),
        kinematics["axes"].tobytes(),
    )
    with _ARGS_LOCK:
        proto = _PROTOTYPES.get(key)
    if proto is None or proto[0] is not gm:
        try:
            made = _native_coal.Sweep(**kinematics, **geometry)
        except ValueError as exc:  # the extension's own checks (e.g. a degenerate hull)
            raise ConfigurationError("collision world", str(exc), "pieces Coal can build") from exc
        proto = (gm, made)
        with _ARGS_LOCK:
            if len(_PROTOTYPES) >= _ARGS_MAX:
                del _PROTOTYPES[next(iter(_PROTOTYPES))]
            _PROTOTYPES[key] = proto
    return NativeSweep(world, proto[1].fresh(), proto[1])


_tuple_new = tuple.__new__
#: NativeDispatch's SweepCounts lists, by the world's number of pairs
_COUNTS: dict[int, list[Any]] = {}


class NativeDispatch:
    """A collision world's native sweeps: their calls, the placement they owe, their contacts.

    After a native sweep the world's own data (its Pinocchio data and ``geom_data``) are not
    placed at its q: :attr:`pending` says where they are owed, and :meth:`place` places them
    (every reader of ``geom_data`` calls it first, through the world's property).

    Args:
        world: The world (its native sweep, ``_native``, is read at every call).

    Attributes:
        pending: Where the pieces are owed: False nowhere (they are placed at the world's last
            ``_fk``), True at the compiled sweep's last q (after a sweep the witness points
            are its), bytes at that q (a reused sweep, or a query outside the sweep).
    """

    def __init__(self, world: CollisionWorld) -> None:
        self.world = world
        self.pending: bool | bytes = False
        #: a sweep kept for one reuse at its q (:meth:`keep_spare`), or None
        self.spare: tuple[tuple[bytes, float], SweepResult] | None = None
        n = len(world.pairs)
        #: SweepCounts by the number of tests (shared by the sweeps and the worlds with as
        #: many pairs, being immutable)
        counts = _COUNTS.get(n)
        if counts is None:
            counts = _COUNTS[n] = [SweepCounts(n, n - k, k) for k in range(n + 1)]
        self._counts: list[SweepCounts] = counts
        self._result = SweepResult
        self._contact: Callable[..., Contact] = Contact

    def sweep(self, q: NDArray[np.float64], m: float, reuse: bool) -> SweepResult:
        """The world's sweep in one call of its native sweep (checked margin ``m`` [m]).

        Raises:
            ConfigurationError: A wrong-size q.
        """
        world = self.world
        native = world._native
        key = None
        if reuse:
            key = (np.asarray(q, dtype=np.float64).tobytes(), m)
            last = world._last_sweep
            if last is not None and last[0] == key:
                self.pending = key[0]
                return last[1]
            spare = self.spare
            if spare is not None and spare[0] == key:  # (see keep_spare)
                self.spare = None
                world._last_sweep = spare
                self.pending = key[0]
                return spare[1]
        try:
            pairs, d, k, dmin = native.sweep(q, m)
        except (ValueError, TypeError) as exc:  # the extension's size/type check
            nq = world.robot.model.nq
            raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc
        self.pending = True
        # (tuple.__new__: a NamedTuple's own __new__ costs 0.1 us more, twice a sweep)
        out: SweepResult = _tuple_new(self._result, (dmin, k, pairs, d, self._counts[len(pairs)]))
        if key is not None:
            pairs.setflags(write=False)
            d.setflags(write=False)
            world._last_sweep = (key, out)
        return out

    def result(
        self, pairs: NDArray[np.int64], d: NDArray[np.float64], k: int, dmin: float
    ) -> SweepResult:
        """A native sweep made elsewhere as the world's sweep result.

        Args:
            pairs: Its candidates' pair indices.
            d: Their signed distances [m].
            k: The closest pair (-1: none).
            dmin: Its distance [m] (inf: none).
        """
        return _tuple_new(self._result, (float(dmin), int(k), pairs, d, self._counts[len(pairs)]))

    def adopt(
        self,
        q: NDArray[np.float64],
        pairs: NDArray[np.int64],
        d: NDArray[np.float64],
        k: int,
        dmin: float,
    ) -> None:
        """Keep a native sweep made at q elsewhere as the world's last one, for its reuse.

        The contact-normal mode's compiled stretch of steps (:mod:`packbot.contact.stretch`)
        sweeps through the compiled sweep's C entry point; the loop then watches its last step,
        whose sweep the world's ``sweep(q, reuse=True)`` returns from here (bit for bit: Coal's
        warm-started GJK would not repeat it exactly). The pieces are owed at its q.

        Args:
            q: Its configuration [rad].
            pairs: Its candidates' pair indices.
            d: Their signed distances [m].
            k: The closest pair (-1: none).
            dmin: Its distance [m] (inf: none).
        """
        self.world._last_sweep = self._kept(q, pairs, d, k, dmin)
        self.pending = True

    def keep_spare(
        self,
        q: NDArray[np.float64],
        pairs: NDArray[np.int64],
        d: NDArray[np.float64],
        k: int,
        dmin: float,
    ) -> None:
        """Keep a native sweep made at q elsewhere for a reuse at q to come (once).

        The stretch's own re-patch (:mod:`packbot.contact.stretch`) that hands its step back
        after its projection's sweep: the loop's re-patch then sweeps the same q with ``reuse``
        and finds this one (bit for bit: Coal's warm-started GJK would not repeat it exactly),
        while the world's last sweep stays the one its watch reuses first. Arguments: see
        :meth:`adopt`.
        """
        self.spare = self._kept(q, pairs, d, k, dmin)

    def _kept(
        self,
        q: NDArray[np.float64],
        pairs: NDArray[np.int64],
        d: NDArray[np.float64],
        k: int,
        dmin: float,
    ) -> tuple[tuple[bytes, float], SweepResult]:
        """A sweep made elsewhere as the world keeps one: (its reuse key, its result)."""
        pairs.setflags(write=False)
        d.setflags(write=False)
        out: SweepResult = _tuple_new(self._result, (dmin, k, pairs, d, self._counts[len(pairs)]))
        return (np.asarray(q, dtype=np.float64).tobytes(), self.world.margin), out

    def owe(self) -> None:
        """The compiled sweep swept elsewhere (its C entry point): the pieces are owed at its q.

        A reader of ``geom_data`` then finds the pieces placed at the compiled sweep's last q,
        as after this dispatch's own :meth:`sweep`.
        """
        self.pending = True

    def place(self) -> None:
        """Place the world's pieces at the last native query's q if they are not."""
        pending = self.pending
        if pending is not False:
            self.world._fk(self.last_q())

    def last_q(self) -> NDArray[np.float64]:
        """The configuration of the world's last query [rad] (a copy)."""
        pending = self.pending
        if pending is True:
            return np.asarray(self.world._native.last_q(), dtype=np.float64)
        if pending:
            return np.frombuffer(pending, dtype=np.float64).copy()
        return self.world._placed_q.copy()

    def contacts(self, sw: SweepResult, m: float) -> list[Contact]:
        """The pairs of the last native sweep ``sw`` closer than ``m`` [m], unsorted.

        With the native sweep's witness points and normals (:attr:`pending` is True).
        """
        assert self.pending is True
        p1, p2, normal = self.world._native.witness()
        rows = np.flatnonzero(sw.distances < m)
        pairs = self.world.pairs
        contact = self._contact
        return [
            contact(
                pairs[int(sw.pairs[i])],
                float(sw.distances[i]),
                p1[i].copy(),
                p2[i].copy(),
                normal[i].copy(),
            )
            for i in rows
        ]
