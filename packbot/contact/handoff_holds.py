"""The friction holds of the hand-off's mixed problem: their conditions and their settling.

While a handed-off pair is in contact, a joint held by Coulomb friction or a brake is locked in
the same problem as the contact forces (:class:`~packbot.contact.handoff.HandoffContacts`), and
its holding torque includes them (:meth:`HandoffContacts.hold_torques
<packbot.contact.handoff.HandoffContacts.hold_torques>`). :class:`MixedHolds` is the
:class:`~packbot.contact.handoff.HandoffLaw`'s part that decides which joints hold: the hold
conditions its events watch, and the choice of holds and modes together at an instant. Without
a handed-off pair the joint locks' own rules apply (:class:`~packbot.contact.holds.JointHolds`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.contact.locks import ACCEL_BAND, TORQUE_BAND
from packbot.contact.stops import STICK_SPEED

if TYPE_CHECKING:
    from packbot.contact.handoff import HandoffLaw

__all__ = ["MixedHolds"]

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)


class MixedHolds:
    """The hand-off's friction holds under a handed-off pair.

    Args:
        law: The law (its mixed problem, joint locks, drive and event log).
    """

    def __init__(self, law: HandoffLaw) -> None:
        self.law = law

    def conditions(self, t: float, y: FloatArray) -> dict[tuple[str, int], float]:
        """The holds' conditions while the mixed problem is on, with its contact forces.

        Keys ``("hold", j)``: g = F_j + TORQUE_BAND - |tau_j| with tau_j from
        :meth:`HandoffContacts.hold_torques`, or the push of the joint's one-sided clamp (as in
        :meth:`JointLocks.conditions <packbot.contact.locks.JointLocks.conditions>`); a joint
        clamped both ways never slips. Negative: a ``slip`` event.
        """
        law = self.law
        n = law.n
        q, v = y[:n], y[n : 2 * n]
        tau = law.mixed.hold_torques(q, v, law.free_accel(t, y), law.sys.minv(q))
        out: dict[tuple[str, int], float] = {}
        for j, tj in tau.items():
            signs = law.mixed.held_signs.get(j, set())
            g = law.locks.held[j] + TORQUE_BAND - abs(tj)
            if len(signs) == 1:
                (s,) = signs
                g = max(g, -s * tj + TORQUE_BAND)
            out[("hold", j)] = g if len(signs) != 2 else 1.0
        return out

    def settle(self, t: float, y: FloatArray, candidates: Sequence[int], log_stick: bool) -> None:
        """The holds (Coulomb friction, brakes) and the mixed problem's modes, together.

        The rules of :meth:`JointStops.settle_modes <packbot.contact.stops.JointStops.
        settle_modes>` with the contact forces in the holding torques
        (:meth:`HandoffContacts.hold_torques`):

        - a held joint that moves (an impulse, which a bounded torque cannot resist, set it
          moving) slides in the direction of its speed;
        - a joint with Coulomb friction at rest that is not held, and each candidate, tries to
          hold (bound F_j);
        - the modes are selected with the holds locked; the hold whose torque exceeds its bound
          the most (a one-sided clamp that pushes supplies any torque, a joint clamped both
          ways never slips) slides in the direction opposite to that torque, and the modes are
          selected again, until every hold is within its bound.

        Logs a ``slip`` for each hold lost and, with ``log_stick``, a ``stick`` for each
        candidate held.
        """
        law = self.law
        mixed, n = law.mixed, law.n
        q, v = y[:n], y[n : 2 * n]
        bound = law.drive.path.coulomb
        fdir = law.drive.fdir
        held = {j: b for j, b in law.locks.held.items() if bound[j] > 0}
        slipped: list[int] = []
        for j in list(held):
            if abs(v[j]) > STICK_SPEED:  # set moving by an impulse: it slides
                del held[j]
                fdir[j] = math.copysign(1.0, v[j])
                slipped.append(j)
        trial: list[int] = []
        for j in np.flatnonzero(bound > 0).tolist():
            if j in held:
                continue
            if abs(v[j]) > STICK_SPEED:  # sliding (a stopped candidate the impulse moved too)
                fdir[j] = math.copysign(1.0, v[j])
            elif fdir[j] == 0.0 or j in candidates:
                trial.append(j)
        for j in trial:
            fdir[j] = 0.0
            held[j] = float(bound[j])
        minv = law.sys.minv(q)
        for _ in range(len(held) + 1):
            law.locks.set_held(held)
            law.apply_clamps()
            a_free = law.free_accel(t, y)  # the sliding joints' friction as now directed
            mixed.select_modes(q, v, a_free, minv)
            tau = mixed.hold_torques(q, v, a_free, minv)
            worst, excess = -1, 0.0
            for j, tj in tau.items():
                signs = mixed.held_signs.get(j, set())
                if len(signs) == 2 or (len(signs) == 1 and -next(iter(signs)) * tj >= 0.0):
                    continue  # the contact supplies the torque
                over = abs(tj) - held[j] - 0.5 * TORQUE_BAND
                if over > excess:
                    worst, excess = j, over
            if worst < 0:
                break
            del held[worst]
            fdir[worst] = -math.copysign(1.0, tau[worst])
            slipped.append(worst)
        for j in slipped:
            if abs(v[j]) <= STICK_SPEED:
                self.slip_direction(t, y, j, minv)
        for j in slipped:
            law.log_event(t, "slip", q, v, v, None, joints=(law.sys.names[j],), joint=j)
        if log_stick:
            for j in trial:
                if j in held:
                    law.log_event(t, "stick", q, v, v, None, joints=(law.sys.names[j],), joint=j)

    def slip_direction(self, t: float, y: FloatArray, j: int, minv: FloatArray) -> None:
        """A joint slipping from rest takes a direction its acceleration follows.

        The direction opposite to the holding torque is the one its acceleration takes when
        the joint's mobility is positive, which a sliding contact's friction (not derived
        from a potential) can reverse. If joint j's acceleration does not follow ``fdir_j``
        (beyond ACCEL_BAND), the other direction is tried with the modes selected again, and
        kept if consistent (else the first stays: neither is, a Painleve-type case, logged).
        """
        law = self.law
        n, mixed, fdir = law.n, law.mixed, law.drive.fdir
        q, v = y[:n], y[n : 2 * n]
        for attempt in range(2):
            a_free = law.free_accel(t, y)
            if attempt:
                mixed.select_modes(q, v, a_free, minv)
            a = mixed.evaluate(q, v, a_free, minv).a
            if fdir[j] * a[j] >= -ACCEL_BAND:
                return
            fdir[j] = -fdir[j]
        log.debug("t=%.9f: joint %s slips inconsistently in both directions", t, j)
        mixed.select_modes(q, v, law.free_accel(t, y), minv)
