"""The collision world's answers: its pairs, their signed distances, patches and sweeps.

Plain records, made by :class:`packbot.collision.CollisionWorld` and the modules it is built
from (``collision_build``, ``collision_queries``, ``native_sweep``); they know nothing of how
they were computed. The conventions (pair order, signs, normals) are
:mod:`packbot.collision`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from packbot.keywords import checked_arguments

__all__ = ["Contact", "ContactPatch", "PairInfo", "SweepCounts", "SweepResult"]


@checked_arguments
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


@checked_arguments
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


@checked_arguments
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
        min_distance: Smallest signed distance among the pairs the pruning left [m] (``inf``
            if it left none). It may exceed the margin: a pair whose inflated boxes overlap
            can be farther apart than the margin.
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
