"""The hand-off's forces at a sample (``SimConfig.handoff``): its :class:`HandoffReport`.

While no handed-off pair is in contact the law is the report's alone: no Cartesian contact
force, the clamps' torques on their joints (:class:`~packbot.contact.lock_forces.LockReport`).
While one is, the mixed problem
(:class:`~packbot.contact.handoff.HandoffContacts`) holds the handed-off pairs' patch rows,
the remaining clamps as one-sided joint rows and the locked joints (clamped both ways, or held
by friction or a brake), and its multipliers are the sample's forces:

* each handed-off pair's contact forces, read off its patch rows as in the contact-normal mode
  (:func:`~packbot.contact.normal_forces.row_forces`; at rest the frictional problem's);
* a clamp row J = -s e_j with multiplier lambda >= 0: the torque -s lambda on joint j;
* a locked joint's torque tau_S = -(M^-1_SS)^-1 (a_free + M^-1 Q_c)_S with Q_c the rows'
  generalized force (:func:`~packbot.contact.native.lock_torques`, the holding torques of
  :meth:`HandoffContacts.hold_torques <packbot.contact.handoff.HandoffContacts.hold_torques>`):
  a held joint's share within its friction's bound is its friction torque (what
  :meth:`HandoffLaw.friction <packbot.contact.handoff.HandoffLaw.friction>` reports), the rest
  its clamp's.

The clamps' torques are the sample's ``clamp_torque``: with the contacts' J^T f and the stops'
torques they close the equations of motion (M a + C v + g = tau + tau_friction + J^T f +
limit_torque + clamp_torque).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.contact import native
from packbot.contact.holds import friction_share
from packbot.contact.normal_forces import RowForces, rest_friction, row_forces
from packbot.contact_forces import SampleForces

if TYPE_CHECKING:
    from packbot.contact.handoff import HandoffLaw

__all__ = ["HandoffReport"]

FloatArray = NDArray[np.float64]


class HandoffReport:
    """The hand-off's forces at the samples: its :class:`~packbot.contact.base.ForceReport`.

    One per phase of the law (built with its mixed problem).

    Args:
        law: The law (its mixed problem, its joint locks and holds).
    """

    def __init__(self, law: HandoffLaw) -> None:
        self.law = law
        self._data = law.sys.model.createData()  # (the contact forces' placements)

    def held(self) -> tuple[int, ...]:
        """The joints held still (engaged and held locks), sorted."""
        return self.law.held()

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m], each held joint's holding torque in place.

        While the mixed problem is on, the holding torques with its contact forces
        (:meth:`HandoffContacts.hold_torques <packbot.contact.handoff.HandoffContacts.
        hold_torques>`, the part within the bound: :func:`~packbot.contact.holds.
        friction_share`), at rest the rest problem's friction boxes
        (:func:`~packbot.contact.normal_forces.rest_friction`); otherwise the joint locks'
        (:meth:`JointStops.friction <packbot.contact.stops.JointStops.friction>`).
        """
        law = self.law
        mixed, sys = law.mixed, law.sys
        if not (law.mixed_on and (law.locks.held or mixed.resting)):
            return law.friction(q, v, applied, friction)
        a_free, minv = sys.aba(q, v, applied + friction), sys.minv(q)
        if mixed.resting:
            if mixed.joint_coulomb is None:
                return friction
            if mixed.locked_joints:
                a_c, minv_c = mixed._lock(a_free, minv)
                with mixed._locked():
                    found = rest_friction(mixed, q, a_c, minv_c, friction)
            else:
                found = rest_friction(mixed, q, a_free, minv, friction)
            return friction if found is None else found
        friction = friction.copy()
        for j, tj in mixed.hold_torques(q, v, a_free, minv).items():
            friction[j] = friction_share(tj, law.locks.held[j])
        return friction

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """The handed-off pairs' contacts, the stops' and the clamps' torques at (q, v).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            tau: The joint torques [N*m] (applied and friction), called once.
            t: The sample's time [s] (unused: the hand-off has no time-stepping window).
        """
        law = self.law
        if not law.mixed_on:
            return law.lock_report.contacts(q, v, tau, t)
        mixed, sys = law.mixed, law.sys
        a_free = sys.aba(q, v, tau())
        minv = sys.minv(q)
        locked = mixed.locked_joints
        kept = mixed._last_eval  # (the step end's evaluation, kept for its own state)
        try:
            if locked:
                a_c, minv_c = mixed._lock(a_free, minv)
                with mixed._locked():
                    rows = row_forces(mixed, self._data, q, v, a_c, minv_c)
            else:
                rows = row_forces(mixed, self._data, q, v, a_free, minv)
        finally:
            mixed._last_eval = kept
        return SampleForces(
            rows.found.contacts,
            rows.found.limit_torque,
            self._clamp_torque(rows, a_free, minv, locked),
        )

    def _clamp_torque(
        self, rows: RowForces, a_free: FloatArray, minv: FloatArray, locked: list[int]
    ) -> FloatArray:
        """The clamp rows' and the locked joints' torques [N*m], (nv,) (see the module).

        Args:
            rows: The mixed problem's forces at the state.
            a_free: Unconstrained accelerations [rad/s^2] (the full arm's).
            minv: M^-1 (the full arm's).
            locked: The locked joints S.
        """
        mixed = self.law.mixed
        out = np.zeros(len(a_free))
        for r, lam in rows.beyond.items():
            clamp = mixed.clamp_of_row(r)
            assert clamp is not None  # (the rows beyond the patch and limit rows)
            j, s = clamp
            out[j] -= s * lam
        if not locked:
            return out
        tau = native.lock_torques(mixed._rows_rhs(), a_free, minv, rows.qc, locked)
        bounds = self.law.locks.held
        for k, j in enumerate(locked):
            tj = float(tau[k])
            # a held joint's friction carries its share (HandoffLaw.friction's, not at rest)
            share = 0.0 if j not in bounds or mixed.resting else friction_share(tj, bounds[j])
            out[j] += tj - share
        return out
