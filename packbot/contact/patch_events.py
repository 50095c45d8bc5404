"""The events of a contact-normal problem (the normal mode's, and the hand-off's)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact.base import Crossing, Key
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_dynamics import _Eval
from packbot.contact.normal_forces import row_impulses
from packbot.contact.normal_modes import ModeEvent
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.contact.pairs import PairLaw
from packbot.contact_forces import SampleForces
from packbot.ode import DenseSegment

if TYPE_CHECKING:
    from packbot.contact.native import NativeRhs

__all__ = ["PatchEvents"]

FloatArray = NDArray[np.float64]


class PatchEvents(PairLaw):
    """The events of a contact-normal problem: the normal mode's, and the hand-off's.

    A pair in the problem's contact set is watched for leaving it (``release`` beyond the
    proximity tolerance) and for penetrating past :data:`PENETRATION_TOL` (``repatch``); a pair
    outside it touches at d = 0 (``impact``). The problem's own mode conditions (a row's force
    or acceleration, a friction cone, the resting arm: :meth:`NormalContacts.conditions`) are
    event functions too (keys ``("mode", kind, index)``).
    """

    def _patch_pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        """Pair events of a contact-normal pair: touch at d = 0, re-patch, leave the set."""
        cfg = self.cfg
        if key not in self.active:
            if d1 <= 0.0:
                return [self._pair_crossing("impact", key, p_idx, seg, d0, d1, lambda d: d)]
            return []
        if d1 > cfg.proximity_tolerance:
            return [
                self._pair_crossing(
                    "release", key, p_idx, seg, d0, d1, lambda d: cfg.proximity_tolerance - d
                )
            ]
        if d1 < -PENETRATION_TOL:
            return [
                self._pair_crossing(
                    "repatch", key, p_idx, seg, d0, d1, lambda d: d + PENETRATION_TOL
                )
            ]
        return []

    def _contact_eval(self, contacts: NormalContacts, t: float, y: FloatArray) -> _Eval:
        """The contact problem's evaluation at state y (the last one if it was at y)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        return contacts.evaluate_again(q, v, self.free_accel(t, y), self.sys.minv(q))

    def _contact_conditions(
        self, contacts: NormalContacts, t: float, y: FloatArray
    ) -> dict[tuple[Any, ...], tuple[str, float]]:
        """Mode conditions of a contact problem at state y."""
        return contacts.conditions(self._contact_eval(contacts, t, y))

    def _problem_crossings(
        self,
        contacts: NormalContacts,
        seg: DenseSegment,
        y1: FloatArray,
        native: NativeRhs | None = None,
    ) -> list[Crossing]:
        """Mode conditions of a contact problem that changed sign over the step.

        With ``native`` (the step was the native one, its modes and torques still loaded) the
        root finding evaluates the conditions inside the step in one native call each
        (:meth:`~packbot.contact.native.NativeRhs.eval_at`; a row's condition alone,
        :meth:`~packbot.contact.native.NativeWatch.row_condition_at`; in Python where it
        cannot), and a row's crossing is located in one native call
        (:meth:`~packbot.contact.native.NativeWatch.row_root`).
        """
        ev1 = self._contact_eval(contacts, seg.t1, y1)
        if not contacts.violated(ev1):
            return []
        cond1 = contacts.conditions(ev1)
        bad = [k for k, (_, g) in cond1.items() if g < 0.0]
        if not bad:
            return []
        cond0 = self._contact_conditions(contacts, seg.t0, seg.y0)
        row_at = (
            native.watch.row_condition_at
            if native is not None and contacts.rows_conditions_own()
            else None
        )
        out = []
        for k in bad:

            def gn(t: float, k: tuple[Any, ...] = k) -> float:
                y = seg(t)
                if row_at is not None and k[0] == "nrow":  # (the row's value alone, natively)
                    g = row_at(y, k[1])
                    if g is not None:
                        return g
                ev = None if native is None else native.eval_at(contacts, y)
                if ev is None:
                    ev = self._contact_eval(contacts, t, y)
                return contacts.condition(ev, k)

            g0 = cond0[k][1] if k in cond0 else 1.0
            root = None
            if native is not None and row_at is not None and k[0] == "nrow":
                root = native.watch.row_root(seg, k[1])
            out.append(Crossing(cond1[k][0], ("mode", *k), gn, g0, cond1[k][1], root))
        return out

    def _restart(
        self, contacts: NormalContacts, t: float, q: FloatArray, v: FloatArray, tail: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """A contact problem's restart at t: drift correction, impulse, modes."""

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        coul = self.drive.path.coulomb
        contacts.joint_coulomb = coul if coul.any() else None
        contacts.joint_fdir = self.drive.fdir
        removed = contacts.projection_energy_removed
        q1, v1, events = contacts.restart(q, v, a_free, self.sys.minv(q))
        self.diag.projection_energy_removed += contacts.projection_energy_removed - removed
        if contacts.impact_rows is not None:  # (its impulses, in the run's impact log)
            rows, P = contacts.impact_rows
            found = row_impulses(contacts, contacts.model.createData(), q1, rows, P)
            clamp = found.clamp_torque
            self.events.impulses.append(
                (
                    t,
                    SampleForces(
                        found.contacts,
                        self.sys.v_full(found.limit_torque),
                        None if clamp is None else self.sys.v_full(clamp),
                    ),
                )
            )
        return q1, v1, events

    def _repatch(self, contacts: NormalContacts, t: float, y: FloatArray) -> FloatArray:
        """Re-patch a contact problem's sliding pairs at (t, y); the state after."""
        n = self.n
        q, v, tail = y[:n], y[n : 2 * n], y[2 * n :]

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        removed = contacts.projection_energy_removed
        q, v = contacts.repatch(q, v, a_free, self.sys.minv(q))
        self.diag.projection_energy_removed += contacts.projection_energy_removed - removed
        return np.concatenate([q, v, tail])
