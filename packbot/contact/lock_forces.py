"""The forces of the joint-lock laws at a sample: no Cartesian force, the locks' joint torques.

Under the report's law (``contact_mode="joint_clamp"``) a pair in contact acts on the arm only
through its clamps, a lock on each joint between its bodies, and a joint on its position stop is
a lock too (as in ``contact_mode="none"``, which has no pairs): :class:`LockReport` reports each
engaged lock's torque on its joint, the stop's where only a position stop holds the joint, the
clamp's where a pair's clamp does (one lock cannot be split between a stop and a pair on the
same joint: the pair's clamp takes it). Conventions of the records: :mod:`packbot.contact_forces`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.contact.holds import friction_share
from packbot.contact_forces import SampleForces

if TYPE_CHECKING:
    from packbot.contact.stops import JointStops

__all__ = ["LockReport"]

FloatArray = NDArray[np.float64]


class LockReport:
    """The joint-lock laws' forces at the samples: a :class:`~packbot.contact.base.ForceReport`.

    Args:
        law: The law (its joint locks, holds, active contacts and system).
    """

    def __init__(self, law: JointStops) -> None:
        self.law = law

    def held(self) -> tuple[int, ...]:
        """The joints held still (engaged and held locks), sorted."""
        return self.law.held()

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m], each held joint's holding torque in place."""
        return self.law.friction(q, v, applied, friction)

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """No Cartesian contact force; the stops' and the clamps' torques [N*m] at (q, v).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            tau: The joint torques [N*m] (applied and friction), called only with a lock
                engaged.
            t: The sample's time [s] (unused).
        """
        lock = self.lock_torques(q, v, tau)
        law = self.law
        pairs = {j for a in law.active.values() if a.pair is not None for j, _ in a.clamps}
        on_pairs = np.zeros(len(q), dtype=bool)
        on_pairs[sorted(pairs)] = True
        return SampleForces([], np.where(on_pairs, 0.0, lock), np.where(on_pairs, lock, 0.0))

    def lock_torques(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray]
    ) -> FloatArray:
        """The engaged locks' torques [N*m] on their joints at (q, v), shape (nv,).

        Each engaged lock's torque lambda_j (:meth:`JointLocks.torques
        <packbot.contact.locks.JointLocks.torques>`, positive along +q) under the joint torques
        ``tau()`` [N*m]; where friction or a brake also holds the joint, the lock carries what
        the friction's bound does not (:func:`~packbot.contact.holds.friction_share`: the
        friction torques reported, :meth:`friction`, carry the rest). Zero off the locks.
        """
        out = np.zeros(len(q))
        locks = self.law.locks
        if not locks.engaged:
            return out
        sys = self.law.sys
        _, lam = locks.torques(sys.aba(q, v, tau()), sys.minv(q))
        for j in locks.engaged:
            bound = locks.held.get(j)
            out[j] = lam[j] - (0.0 if bound is None else friction_share(lam[j], bound))
        return out
