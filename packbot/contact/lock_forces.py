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
        if not self.law.locks.engaged:
            return SampleForces([], lock)
        clamp = np.zeros(len(q))
        for a in self.law.active.values():
            if a.pair is not None:  # a pair's clamps: their joints' torques are the clamps'
                for j, _ in a.clamps:
                    clamp[j], lock[j] = lock[j] + clamp[j], 0.0
        return SampleForces([], lock, clamp)

    def lock_torques(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray]
    ) -> FloatArray:
        """The engaged locks' torques [N*m] on their joints at (q, v), shape (nv,).

        Each engaged lock's torque lambda_j (:meth:`JointLocks.torques
        <packbot.contact.locks.JointLocks.torques>`, positive along +q) under the joint torques
        ``tau()`` [N*m]; where friction or a brake also holds the joint, the lock carries what
        the friction's bound does not (:func:`~packbot.contact.holds.friction_share`: the
        friction torques reported, :meth:`friction`, carry the rest). Zero off the locks. The
        arithmetic of the law's native steps (:meth:`NativeLocks.torques_at
        <packbot.contact.native.NativeLocks.torques_at>`) where their lock mode is the
        locks' current set (the last step's), else the locks' own solve.
        """
        out = np.zeros(len(q))
        law = self.law
        locks = law.locks
        if not locks.engaged:
            return out
        idx = locks.locked_index
        torque = tau()
        rhs = law._lock_step.rhs  # (the law's native steps' lock mode, where it is loaded)
        lam = None
        if rhs is not None and rhs.locks.holds(idx):
            lam = rhs.locks.torques_at(q, v, torque)
        if lam is None:
            sys = law.sys
            torques = locks.torques(sys.aba(q, v, torque), sys.minv(q))[1]
            lam = np.array([torques[j] for j in idx.tolist()], dtype=np.float64)
        out[idx] = lam
        for j, bound in locks.held.items():  # a held joint's friction carries its share
            out[j] = out[j] - friction_share(out[j], bound) if j in locks.engaged else 0.0
        return out
