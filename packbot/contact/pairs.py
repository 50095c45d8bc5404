"""Pairs of bodies: what every law with a collision world does with its signed distances.

:class:`PairLaw` extends :class:`~packbot.contact.stops.JointStops` with the phase's
:class:`~packbot.collision.CollisionWorld`: one pruned sweep of the signed distances at each
step's end (the pair events of a law are sign changes against the distances kept at the step's
start), one after the events of an instant, one at a phase's start (a penetrating start is
refused; pairs within the contact tolerance are contacts at once); root finding on one pair's
distance along the step's dense output; the smallest distance over the kept states
(``Diagnostics.min_distance``); and the step bound that keeps every pair from passing through
contact within one step unseen. A law says what the distances mean: its ``_pair_crossings``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo, SweepResult
from packbot.contact.base import Crossing, Key
from packbot.contact.stops import JointStops
from packbot.errors import InitialCollisionError
from packbot.ode import DenseSegment
from packbot.system import System

if TYPE_CHECKING:
    import pinocchio as pin

    from packbot.collision import CollisionWorld

__all__ = ["REACH_BOUND", "REVOLUTE", "PairLaw", "reach_bounds"]

FloatArray = NDArray[np.float64]
#: Bound on the distance from any joint axis to any point of the arm [m] (reach is ~2 m).
REACH_BOUND = 2.2
#: The joint types whose reach :func:`reach_bounds` bounds (one rotation about an axis through
#: the joint's origin); a model with another type uses REACH_BOUND for every joint.
REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")


def _distances(pairs: NDArray[np.intp], dist: FloatArray) -> dict[int, float]:
    """Pair -> signed distance [m], from a sweep's arrays."""
    return dict(zip(pairs.tolist(), dist.tolist(), strict=True))


class PairLaw(JointStops):
    """The base of the laws with collisions: distances tracked, pair events located.

    Same arguments as :class:`~packbot.contact.stops.JointStops`; the system must have a
    collision world.

    Attributes:
        world: The phase's collision world.
        last_d: Pair -> signed distance at the last kept state [m].
    """

    # The kept distances are made a dict only when read: a step end keeps its sweep's arrays
    # (a new pair of arrays at every sweep, never written); None: the dict is still to make.
    _last_d: dict[int, float] | None
    _last_arr: tuple[NDArray[np.intp], FloatArray]
    _pending_d: dict[int, float] | None
    _pending_arr: tuple[NDArray[np.intp], FloatArray]

    def rebuild(self, system: System) -> None:
        """A new phase: the pairs' kept distances forgotten."""
        super().rebuild(system)
        assert system.world is not None
        self.world = system.world
        #: Per velocity index, a bound [m] on the distance from the joint's axis to the pieces
        #: it moves: a point's speed is at most ``reach . |v|``. Here REACH_BOUND for every
        #: joint; the contact-normal mode takes each joint's own (:func:`reach_bounds`).
        self.reach = np.full(system.nv, REACH_BOUND)
        self.last_d = {}
        self.pending_d = {}  # the same at the end of the step being checked
        self.pending_min: tuple[float, int] = (math.inf, -1)

    @property
    def last_d(self) -> dict[int, float]:
        """Pair -> signed distance at the last kept state [m]."""
        d = self._last_d
        if d is None:
            d = self._last_d = _distances(*self._last_arr)
        return d

    @last_d.setter
    def last_d(self, d: dict[int, float]) -> None:
        self._last_d = d

    @property
    def pending_d(self) -> dict[int, float]:
        """Pair -> signed distance at the end of the step being checked [m]."""
        d = self._pending_d
        if d is None:
            d = self._pending_d = _distances(*self._pending_arr)
        return d

    @pending_d.setter
    def pending_d(self, d: dict[int, float]) -> None:
        self._pending_d = d

    def step_bound(self, y: FloatArray) -> float:
        """Largest step keeping every point's motion within half the query margin [s].

        A point's speed is bounded by ``reach . |v|`` at the step's start (:attr:`reach`), so
        a pair beyond the margin cannot pass through contact within the step unseen.
        """
        return self._bound(float(self.reach @ np.abs(y[self.n : 2 * self.n])))

    def _bound(self, speed: float) -> float:
        """The step bound [s] for a bound ``speed`` [m/s] on every point's speed."""
        return min(self.cfg.max_step, 0.5 * self.cfg.margin / max(speed, 1e-9))

    def distance(self, pair: int, y: FloatArray) -> float:
        """Signed distance [m] of one pair at state y."""
        self.diag.distance_queries += 1
        return self.world.pair_contact(y[: self.n], pair).distance

    def note_min(self, d: float, pair: int) -> None:
        """Track the smallest signed distance of the states the run keeps."""
        if pair >= 0 and d < self.diag.min_distance:
            p = self.world.pairs[pair]
            self.diag.min_distance = d
            self.diag.min_distance_pair = f"{p.piece1} - {p.piece2}"

    # ------------------------------------------------------------------ hooks
    def _pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        """A pair's events over the step, from its distances at the start (d0) and end (d1)."""
        raise NotImplementedError

    def _pairs_to_check(self, pairs: list[int], distances: list[float]) -> Iterable[int]:
        """Positions (ascending) of the swept pairs whose events ``_pair_crossings`` checks.

        All of them; a law whose pairs have no event in some band of distances skips those.

        Args:
            pairs: The swept pairs' indices.
            distances: Their signed distances at the step's end [m].
        """
        return range(len(pairs))

    def _mode_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        """The law's contact modes that changed over the step (after the pairs')."""
        return []

    def _initial_pairs(self, y: FloatArray, check: bool) -> list[Crossing]:
        world, cfg, n = self.world, self.cfg, self.n
        crossings: list[Crossing] = []
        sw = world.sweep(y[:n])
        self.diag.sweeps += 1
        self.note_min(sw.min_distance, sw.min_pair)
        bad = [(world.pairs[p], d) for p, d in zip(sw.pairs, sw.distances, strict=True) if d < 0]
        if bad and check:
            raise InitialCollisionError([(p.piece1, p.piece2, d) for p, d in bad])
        self.last_d = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
        for p, d in self.last_d.items():
            if d <= cfg.contact_tolerance:
                crossings.append(Crossing("impact", ("pair", p), lambda t: 0.0, 0.0, 0.0))
        return crossings

    def _contact_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        sw = self._end_sweep(y1)
        out = self._swept_crossings(seg, sw)
        out.extend(self._mode_crossings(seg, y1))
        return out

    def _end_sweep(self, y1: FloatArray) -> SweepResult:
        """The sweep at a step's end y1: its distances become the pending ones."""
        sw = self.world.sweep(y1[: self.n], reuse=True)
        self.diag.sweeps += 1
        self.pending_min = (sw.min_distance, sw.min_pair)
        self._pending_arr = (sw.pairs, sw.distances)
        self._pending_d = None
        return sw

    def _swept_crossings(self, seg: DenseSegment, sw: SweepResult) -> list[Crossing]:
        """The pair events over the step whose end's sweep is sw."""
        out: list[Crossing] = []
        pairs, dist = sw.pairs.tolist(), sw.distances.tolist()
        last_d = self.last_d
        for i in self._pairs_to_check(pairs, dist):
            p_idx, d1 = pairs[i], dist[i]
            d0 = last_d.get(p_idx, math.inf)
            out.extend(self._pair_crossings(("pair", p_idx), p_idx, seg, d0, d1))
        return out

    def _after_event(self, y: FloatArray) -> None:
        sw = self.world.sweep(y[: self.n], reuse=True)
        self.diag.sweeps += 1
        self.last_d = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
        self.note_min(sw.min_distance, sw.min_pair)

    def _accept(self) -> None:
        self._last_d = self._pending_d
        if self._pending_d is None:
            self._last_arr = self._pending_arr
        self.note_min(*self.pending_min)

    def _pair_crossing(
        self,
        kind: str,
        key: Key,
        p_idx: int,
        seg: DenseSegment,
        d0: float,
        d1: float,
        fn: Callable[[float], float],
    ) -> Crossing:
        """The crossing of fn(distance) of one pair, located on the step's dense output."""

        def g(t: float) -> float:
            return fn(self.distance(p_idx, seg(t)))

        g0 = fn(d0) if math.isfinite(d0) else 1.0
        if g0 <= 0.0:  # not a clean crossing (e.g. just restarted on it): take the step start
            g0 = g(seg.t0)
        return Crossing(kind, key, g, g0, fn(d1))


def pair_joints(
    model: pin.Model, pairs: Sequence[PairInfo]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Per pair, the velocity indices of the joints that move one piece relative to the other.

    The joints in the chain of one body and not of the other (the ones both hang from move
    the two rigidly together, so the pair's distance does not change with them). As a CSR:
    pair k's indices are ``idx[start[k]:start[k + 1]]``, ``pairs[k].index == k`` in turn.

    Returns:
        (start (len(pairs) + 1,), idx).
    """
    start = [0]
    idx: list[int] = []
    for k, p in enumerate(pairs):
        if p.index != k:
            raise ValueError(f"pairs[{k}].index is {p.index}: the world's pairs in order expected")
        between = set(model.supports[p.joint1]) ^ set(model.supports[p.joint2])
        for j in sorted(between - {0}):
            joint = model.joints[j]
            idx.extend(range(joint.idx_v, joint.idx_v + joint.nv))
        start.append(len(idx))
    return np.array(start, dtype=np.int64), np.array(idx, dtype=np.int64)


def reach_bounds(model: pin.Model, world: CollisionWorld | None) -> FloatArray:
    """Per velocity index, a bound [m] on the distance from the joint's axis to its pieces.

    Any point of the collision pieces the joint moves, over every configuration. A point p of
    a piece moves at dp/dt = sum over the joints s carrying it of w_s x (p - o_s) (revolute
    joints: |w_s| = |v_s|, o_s on the axis), so its speed is at most sum_s r_s |v_s| with
    r_s the largest |p - o_s|. By the triangle inequality r_s is at most the lengths of the
    joint placements from s down to the piece's joint, plus the piece's own radius about
    that joint's origin (its placement's offset, its bounding box's centre and half
    diagonal). Joints that move no piece get 0. For the arm's wrist joints this is about
    0.2 m instead of :data:`REACH_BOUND` (2.2 m): a step's contact set
    holds the pairs it can reach, not every pair within a spinning gripper's worst-case
    travel. A model with a joint that is not revolute (or no collision world): REACH_BOUND
    for every joint; no joint gets more.

    Args:
        model: The integrated model (its joints are the velocity indices).
        world: The collision world on that model (its pieces' parent joints).
    """
    nv = int(model.nv)
    flat = np.full(nv, REACH_BOUND)
    names = tuple(j.shortname() for j in list(model.joints)[1:])
    if world is None or any(n not in REVOLUTE for n in names):  # (one velocity per joint)
        return flat
    offset = [
        float(np.linalg.norm(model.jointPlacements[j].translation)) for j in range(model.njoints)
    ]
    # (the worlds of one robot share their geometry model: the bounds of the last few kept)
    gm = world.geom_model
    key = (id(gm), names, tuple(offset), tuple(model.parents), tuple(model.idx_vs))
    kept = _REACH.get(key)
    if kept is not None and kept[0] is gm:
        return kept[1].copy()
    r = _reach(model, world, nv, offset)
    if len(_REACH) >= 16:
        del _REACH[next(iter(_REACH))]
    _REACH[key] = (gm, r)
    return r.copy()


#: reach_bounds' results by model and geometry model (the geometry model kept: ids are reused)
_REACH: dict[tuple[object, ...], tuple[object, FloatArray]] = {}


def _reach(model: pin.Model, world: CollisionWorld, nv: int, offset: list[float]) -> FloatArray:
    """:func:`reach_bounds` of a model with revolute joints only."""
    r = np.zeros(nv)
    for go in world.geom_model.geometryObjects:
        j = int(go.parentJoint)
        if j == 0:
            continue
        shape = go.geometry
        shape.computeLocalAABB()
        radius = (
            float(np.linalg.norm(go.placement.translation))
            + float(np.linalg.norm(shape.aabb_center))
            + float(shape.aabb_radius)
        )
        # from the piece's joint up its chain: each joint's distance to the piece grows by the
        # placement of the joint below it
        k = j
        while k > 0:
            iv = int(model.idx_vs[k])
            r[iv] = max(r[iv], radius)
            radius += offset[k]
            k = int(model.parents[k])
    return np.minimum(r, REACH_BOUND)  # (both are bounds; an unbounded piece: REACH_BOUND)
