"""The joint_clamp -> normal hand-off (``SimConfig.handoff``): the mixed contact problem.

In ``contact_mode="joint_clamp"`` with ``handoff=True``, a pair whose signed distance falls below
zero although its joints are clamped (a ``secondary_intersection``, the report's self-diagnosis)
is handed to the contact-normal machinery of :mod:`packbot.contact.normal`: its clamps are
released and it becomes a patch contact (impulse with restitution, resting contact with Coulomb
friction, release when its force would pull). The other contacts keep the report's law.

While a handed-off pair is in contact the two laws are solved as one problem. The remaining
clamps (joint j, direction s: "joint j may not accelerate in direction s", s a_j <= 0, see
:mod:`packbot.contact.locks`) are one-sided joint-space constraints, exactly like a limit row of
the normal mode: each is a *clamp row* J = -s e_j appended after the patch (and limit) rows of
the same complementarity problems. The row's meaning is the report's, which constrains
accelerations, not positions:

- acceleration level (the mode problem and the right-hand side): a_n = -s a_j >= 0, its force
  lambda >= 0 (a torque -s lambda on joint j, pushing away from the contact), complementary;
  the row always takes part (gap and velocity reported as zero: no drift correction), so an
  engaged row is exactly an engaged lock (a_j = 0) and a free row a free clamped joint;
- velocity level (the impulse): J v+ >= 0 with the row's true velocity, no restitution: the
  impulse may not set a clamped joint moving toward its contact (the report's law widens its
  reset to such joints for the same reason), it may move it away. In two stages: a clamped
  joint already moving toward its contact is first stopped by the least (M-weighted) joint
  impulse on the clamp rows alone, perfectly inelastic (:meth:`HandoffContacts.stop_clamped`);
  then the normal mode's impulse problem (restitution e on the patch rows) runs with the clamp
  rows as constraints, all at v_n >= 0 (so e does not act on them);
- conditions (events): an engaged row whose torque would pull (lambda < -TORQUE_BAND) is a
  ``disengage``; a free row accelerating toward its contact (-s a_j < -ACCEL_BAND) an
  ``engage``: the two sign conditions of :class:`packbot.contact.locks.JointLocks`.

A joint clamped in both directions (two contacts) is *bilateral*: it may move neither way. Two
opposite unilateral rows would make every problem degenerate (a singular Delassus matrix, on
which Lemke fails once sliding friction makes it non-symmetric), so a bilateral joint is not a
row: it is stopped at each restart (the first stage above, which it always fails unless at
rest) and then eliminated exactly, every problem being solved in the subspace a_j = 0 (M^-1
and the free accelerations replaced by their constrained versions, the Schur complement of the
locked joints: M^-1_c = M^-1 - M^-1 S^T (S M^-1 S^T)^-1 S M^-1).

Joints *held* by Coulomb friction or a brake (:class:`~packbot.contact.locks.JointLocks`'s
``held``) are locked the same way while a handed-off pair is in contact: they join the
eliminated set S (a_S = 0), so the contact forces and the holding torques are one problem. At
the solution, M a = M a_free + Q_c + S^T tau_S with Q_c = C^T lambda the rows' generalized force
(C their force columns), so the holding torque is

    tau_S = -(M^-1_SS)^-1 (a_free + M^-1 Q_c)_S          (:meth:`HandoffContacts.hold_torques`)

and the hold lasts while |tau_j| <= F_j (or a one-sided clamp on the joint pushes). A held
joint's clamps are not rows (the joint is locked anyway): its hold condition takes them in, as
:class:`~packbot.contact.locks.JointLocks` does. A bounded torque does nothing in an instant: at
an impulse the held joints are free (an impact may set a braked joint moving; it then slides,
its friction opposing; one it would set moving slower than ``HOLD_KICK`` stays held), and the
holds are chosen again after it (:meth:`MixedHolds.settle
<packbot.contact.handoff_holds.MixedHolds.settle>`).

When the last handed-off pair leaves the contact set (its distance beyond the proximity
tolerance) the clamps go back to :class:`~packbot.contact.locks.JointLocks` and that pair's next
impact is a ``joint_clamp`` impact again.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact import native
from packbot.contact.base import Active, Crossing, ForceReport, Key
from packbot.contact.handoff_forces import HandoffReport
from packbot.contact.handoff_holds import MixedHolds
from packbot.contact.joint_clamp import JointClampLaw
from packbot.contact.locks import ACCEL_BAND, TORQUE_BAND
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_dynamics import _Eval
from packbot.contact.normal_modes import ModeEvent
from packbot.contact.patch_events import PatchEvents
from packbot.contact.stops import HOLD_KICK, RECEDE_SPEED
from packbot.ode import DenseSegment
from packbot.system import System

__all__ = ["HandoffContacts", "HandoffLaw"]

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)

#: An engaged clamp row whose joint the restart's impulse leaves receding slower than this
#: [rad/s] stays engaged, its joint stopped (:meth:`HandoffLaw._stop_creeping_clamps`): the
#: Zeno end of a clamp's release and return at one instant, as ``SimConfig.zeno_speed`` ends a
#: contact's bounces. Faster, the clamp is released (it would do positive work).
CLAMP_ZENO = 1e-6


class HandoffContacts(NormalContacts):
    """Handed-off pairs (patch rows) plus the joint_clamp clamps as one-sided joint rows.

    Same arguments as :class:`~packbot.contact.normal.NormalContacts`.

    The clamp rows and the locked joints are the extension's (``src/native/
    contact_rhs_clamps.cpp``): the rows come with the patch and limit rows from every native
    call, and the locked subspace's M^-1 and free accelerations from
    :func:`~packbot.contact.native.lock_subspace`.

    Attributes:
        clamps: The one-sided clamps in force, (joint index, forbidden acceleration direction
            s = +1 or -1), sorted; their rows follow the patch and limit rows in this order.
        bilateral: Joints clamped in both directions (locked: eliminated, not rows), sorted.
        held: Joints held by Coulomb friction or a brake (locked like the bilateral ones while
            a handed-off pair is in contact), sorted; set by :class:`HandoffLaw`.
        held_signs: Held joint -> the directions s of its clamps (its hold condition's).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.clamps: list[tuple[int, int]] = []
        self.bilateral: list[int] = []
        self.held: list[int] = []
        self.held_signs: dict[int, set[int]] = {}
        self.native = self._rows_rhs()  # (the restart's native steps on this set's rows)

    @property
    def constrained(self) -> bool:
        """Whether the dynamics differ from the free ones (engaged rows or locked joints)."""
        return bool(self.engaged) or bool(self.bilateral) or bool(self.held)

    @property
    def locked_joints(self) -> list[int]:
        """The eliminated joints S: the bilateral and the held ones, sorted."""
        if not self.held:
            return self.bilateral
        return sorted(set(self.bilateral) | set(self.held))

    def set_held(self, held: Iterable[int], signs: dict[int, set[int]]) -> None:
        """Replace the held joints and their clamps' directions (see ``held_signs``)."""
        self.held = sorted(int(j) for j in held)
        self.held_signs = {j: set(signs.get(j, set())) for j in self.held}

    # ------------------------------------------------------------------ clamp rows
    def _base_rows(self) -> int:
        """Number of patch and limit rows (the first clamp row's index)."""
        return sum(len(p.local1) for p in self.pairs.values()) + len(self.limits)

    def set_clamps(self, clamps: Iterable[tuple[int, int]]) -> None:
        """Replace the clamps (the union over the joint_clamp contacts); engaged rows kept."""
        signs: dict[int, set[int]] = {}
        for j, s in clamps:
            signs.setdefault(int(j), set()).add(int(s))
        new = sorted((j, next(iter(ss))) for j, ss in signs.items() if len(ss) == 1)
        base = self._base_rows()
        old = {base + i: c for i, c in enumerate(self.clamps)}
        index = {c: base + i for i, c in enumerate(new)}
        self.engaged = [
            r if r < base else index[old[r]]
            for r in self.engaged
            if r < base or (r in old and old[r] in index)
        ]
        if new != self.clamps:  # (the rows' layout)
            self.clamps = new
            self._invalidate()
        self.bilateral = sorted(j for j, ss in signs.items() if len(ss) == 2)

    def clamp_of_row(self, row: int) -> tuple[int, int] | None:
        """The clamp (joint, s) of a row, or None for a patch or limit row."""
        k = row - self._base_rows()
        return self.clamps[k] if 0 <= k < len(self.clamps) else None

    def row_owner(self, row: int) -> tuple[PairInfo | None, tuple[int, int] | None]:
        """The pair or the limit of a row; (None, None) for a clamp row."""
        if self.clamp_of_row(row) is not None:
            return None, None
        return super().row_owner(row)

    # ------------------------------------------------------------------ locked joints
    def _lock(self, a_free: FloatArray, minv: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Free accelerations and M^-1 with the locked joints S fixed (a_j = 0)."""
        return native.lock_subspace(self._rows_rhs(), a_free, minv, self.locked_joints)

    @contextmanager
    def _row_level(self, locked: tuple[int, ...], velocity: bool) -> Iterator[None]:
        """The rows reported with these locked joints' frozen rows apart, at this level."""
        mode = self._row_mode
        self._row_mode = (locked, velocity)
        try:
            yield
        finally:
            self._row_mode = mode

    def _locked(self) -> AbstractContextManager[None]:
        """Inside: the calls work in the locked subspace (the rows it freezes apart).

        A pair whose bodies the locked joints join rigidly (the arm's link 3 on link 1 with
        both elbows locked) has rows with no component on the free joints: their gaps cannot
        change, their forces do nothing, and in the problems they would be zero rows of the
        Delassus matrix (with a Baumgarte term on a micrometre gap, an infeasible LCP). The
        extension reports such a row apart (gap ``NULL_GAP``, v_n 0: not touching, no event;
        :data:`~packbot.contact.normal_tolerances.NULL_ROW`) while the joints stay locked.
        """
        return self._row_level(tuple(self.locked_joints), self._row_mode[1])

    def _velocity(self) -> AbstractContextManager[None]:
        """Inside: the clamp rows carry their true velocity (the impulse's level)."""
        return self._row_level(self._row_mode[0], True)

    def _bypass(self) -> bool:
        """No locked joint, or already in the locked subspace: call the base method."""
        return bool(self._row_mode[0]) or not self.locked_joints

    def evaluate(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        forces: bool = False,
    ) -> _Eval:
        """The normal mode's constrained dynamics, the locked joints fixed."""
        if self._bypass():
            return super().evaluate(q, v, a_free, minv, forces)
        a_c, minv_c = self._lock(a_free, minv)
        with self._locked():
            return super().evaluate(q, v, a_c, minv_c, forces)

    def select_modes(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        keep: bool = False,
    ) -> list[ModeEvent]:
        """The normal mode's mode selection, bilateral joints locked."""
        if self._bypass():
            return super().select_modes(q, v, a_free, minv, keep=keep)
        a_c, minv_c = self._lock(a_free, minv)
        with self._locked():
            return super().select_modes(q, v, a_c, minv_c, keep=keep)

    def repatch(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The normal mode's re-patch, bilateral joints locked."""
        if self._bypass():
            return super().repatch(q, v, a_free_fn, minv)
        minv_c = self._lock(np.zeros(self.nv), minv)[1]
        with self._locked():
            return super().repatch(q, v, self._locked_fn(a_free_fn, minv), minv_c)

    def restart(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """The normal mode's restart, after stopping every clamped joint that approaches.

        Bilateral joints are stopped here (with the full M^-1) and locked from then on. The
        held joints are not held through it (a bounded friction or brake torque does nothing
        in an instant): the caller chooses the holds again after it. A held joint that it would
        set moving slower than :data:`~packbot.contact.stops.HOLD_KICK` stays held: the
        restart is solved again with it locked (as a stop's impulse under the report's law:
        :meth:`~packbot.contact.stops.JointStops.reset`); without that, each restart's impulse
        kicks a light held joint (the wrist's) at rounding-level speeds, it slides, sticks
        nanoseconds later, and the next restart kicks it again.
        """
        held, signs = self.held, self.held_signs
        self.held, self.held_signs = [], {}
        removed = self.projection_energy_removed  # (a restart solved again counts once)
        try:
            out = self._restart_with_locks(q, v, a_free_fn, minv)
            kicked = [j for j in held if 0.0 < abs(out[1][j]) <= HOLD_KICK]
            if kicked:
                self.held = sorted(j for j in held if abs(out[1][j]) <= HOLD_KICK)
                self.held_signs = {j: signs.get(j, set()) for j in self.held}
                self.projection_energy_removed = removed
                out = self._restart_with_locks(q, v, a_free_fn, minv)
            return out
        finally:
            self.held, self.held_signs = held, signs

    def _restart_with_locks(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """:meth:`restart` with the current locked joints (bilateral, and ``held``)."""
        both = [(j, s) for j in self.bilateral for s in (-1, 1)]
        v = self.stop_clamped(v, minv, sorted(set(self.clamps) | set(both)))
        if self._bypass():
            return super().restart(q, v, a_free_fn, minv)
        v = v.copy()
        v[self.locked_joints] = 0.0  # stopped (bilateral) or held: exactly at rest
        minv_c = self._lock(np.zeros(self.nv), minv)[1]
        with self._locked():
            return super().restart(q, v, self._locked_fn(a_free_fn, minv), minv_c)

    def hold_torques(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> dict[int, float]:
        """The torques [N*m] holding the held joints, with the contact forces of the modes.

        tau_S = -(M^-1_SS)^-1 (a_free + M^-1 Q_c)_S on the locked joints S (module docstring;
        the extension's :func:`~packbot.contact.native.lock_torques`, Q_c from the
        evaluation's ``qc``), the same sign convention as
        :meth:`JointLocks.torques <packbot.contact.locks.JointLocks.torques>` (a torque added on
        the joint).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            a_free: Unconstrained accelerations [rad/s^2] (the full arm's).
            minv: M^-1 at q (the full arm's).

        Returns:
            Held joint -> its holding torque; empty when nothing is held or the arm rests.
        """
        if not self.held or self.resting:
            return {}
        qc = self.evaluate(q, v, a_free, minv, forces=True).qc
        assert qc is not None  # (not resting)
        locked = self.locked_joints
        tau = native.lock_torques(self._rows_rhs(), a_free, minv, qc, locked)
        pos = {j: k for k, j in enumerate(locked)}
        return {j: float(tau[pos[j]]) for j in self.held}

    def _locked_fn(self, a_free_fn: Any, minv: FloatArray) -> Any:
        def fn(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self._lock(a_free_fn(qq, vv), minv)[0]

        return fn

    # ------------------------------------------------------------------ velocity level
    def impulse(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """The normal mode's impulse, the clamp rows at their true velocity (J v+ >= 0).

        Clamped joints moving toward their contact are stopped first (:meth:`stop_clamped`:
        a velocity reset of the report's law, in the event's velocities, not an impulse of the
        run's impact log). The second stage's impulses are recorded (``impact_rows``): the
        patch rows' as contact impulses, the clamp rows' as the clamps' joint impulses.
        """
        v = self.stop_clamped(v, minv, self.clamps)
        with self._velocity():
            return super().impulse(q, v, minv)

    def stop_slow(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """The normal mode's stop of slow slides, the clamp rows at their true velocity."""
        with self._velocity():
            return super().stop_slow(q, v, minv)

    def stop_clamped(
        self, v: FloatArray, minv: FloatArray, clamps: list[tuple[int, int]]
    ) -> FloatArray:
        """The least (M-weighted) joint impulse making every given clamp row's velocity >= 0.

        The LCP w = G P + J v >= 0, P >= 0, complementary, on the clamp rows J alone
        (G = J M^-1 J^T); P [N*m*s] pushes each approaching clamped joint to a stop (both rows
        of a bilateral joint: it stops). Perfectly inelastic: never adds energy. The
        extension's :func:`~packbot.contact.native.stop_joints` (Lemke).

        Args:
            v: Joint velocities [rad/s].
            minv: M^-1 at the current configuration.
            clamps: The (joint, s) rows to enforce.

        Returns:
            The joint velocities after [rad/s] (v itself when no row approaches).
        """
        if not clamps:
            return v
        status, out = native.stop_joints(self._rows_rhs(), v, minv, clamps, one_sided=True)
        if status == 2:
            log.warning("clamped joints' stop unsolved (LCP on %s): velocity kept", clamps)
        return out if status == 1 else v

    # ------------------------------------------------------------------ conditions
    def conditions(self, ev: _Eval) -> dict[tuple[Any, ...], tuple[str, float]]:
        """The normal mode's conditions; a clamp row's are the lock sign conditions.

        Keys ``("nrow", r)`` of clamp rows: engaged, ``("disengage", lambda + TORQUE_BAND)``;
        free, ``("engage", -s a_j + ACCEL_BAND)``.
        """
        out = super().conditions(ev)
        if ev.rest is not None or not self.clamps:
            return out
        base = self._base_rows()
        pos = {r: i for i, r in enumerate(self.engaged)}
        for i, (j, s) in enumerate(self.clamps):
            r = base + i
            if r in pos:
                out[("nrow", r)] = ("disengage", float(ev.lam[pos[r]]) + TORQUE_BAND)
            else:
                out[("nrow", r)] = ("engage", -s * float(ev.a[j]) + ACCEL_BAND)
        return out


# ---------------------------------------------------------------------------------- the law
class HandoffLaw(JointClampLaw, PatchEvents):
    """The report's law with ``SimConfig.handoff``: a secondary intersection hands its pair over.

    The handed-off pairs follow the normal mode (re-patch, leave the set beyond the proximity
    tolerance, row and friction mode changes); the other pairs and the limit stops follow the
    report's law (impact, limit, release: their clamps). While a handed-off pair is in contact,
    the clamps are rows of its problem (:class:`HandoffContacts`); otherwise the joint locks
    take them and the law is the report's alone. Same arguments as
    :class:`~packbot.contact.stops.JointStops`.

    Attributes:
        mixed: The handed-off pairs and the clamp rows.
        report: The forces at the samples (:class:`~packbot.contact.handoff_forces.
            HandoffReport`).
        holds_mixed: The friction holds under a handed-off pair (:class:`~packbot.contact.
            handoff_holds.MixedHolds`).
    """

    def rebuild(self, system: System) -> None:
        """A new phase: no pair handed off."""
        super().rebuild(system)
        self.mixed = HandoffContacts.from_config(
            system.model,
            system.data,
            system.world,
            self.cfg,
            check_others=False,  # its other pairs are the joint_clamp mode's
        )
        self.report = HandoffReport(self)
        self.holds_mixed = MixedHolds(self)

    def forces(self) -> ForceReport:
        """The current mode's forces at the samples (its :class:`HandoffReport`)."""
        return self.report

    @property
    def mixed_on(self) -> bool:
        """Whether a handed-off pair is in contact (the clamps are then rows of its problem)."""
        return bool(self.mixed.pairs)

    def accel(self, q: FloatArray, v: FloatArray, a_free: FloatArray) -> FloatArray:
        """Accelerations of the current mode: the mixed problem's while it has a pair.

        The mixed problem holds the clamps (rows or bilateral joints) and the held joints
        itself; otherwise the joint locks do.
        """
        if self.mixed_on:
            if self.mixed.constrained:
                return self.mixed.evaluate(q, v, a_free, self.sys.minv(q)).a
            return a_free
        return super().accel(q, v, a_free)

    def _locks_now(self) -> bool:
        """The locks' accelerations alone while no handed-off pair is in contact.

        Then :meth:`accel` is the report's law's, computed the same way (the flag changes
        nothing before its first use); while a pair is, the mixed problem holds the joints.
        """
        return not self.mixed_on

    def lock_conditions(self, t: float, y: FloatArray) -> dict[tuple[str, int], float]:
        """The holds' conditions; while the mixed problem is on, with its contact forces.

        :meth:`MixedHolds.conditions <packbot.contact.handoff_holds.MixedHolds.conditions>`.
        """
        if not self.mixed_on:
            return super().lock_conditions(t, y)
        return self.holds_mixed.conditions(t, y)

    def _pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        if p_idx in self.mixed.pairs:  # a handed-off pair
            return self._patch_pair_crossings(key, p_idx, seg, d0, d1)
        return super()._pair_crossings(key, p_idx, seg, d0, d1)

    def _mode_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        if not self.mixed_on:
            return []
        return self._problem_crossings(self.mixed, seg, y1)

    def _refresh(self, t: float, y: FloatArray) -> FloatArray | None:
        """Re-patch sliding handed-off pairs after an accepted step (not logged)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        if self.mixed_on and self.mixed.sliding(q, v) and self.mixed.stale(q, v, self.last_d):
            return self._repatch(self.mixed, t, y)
        return None

    def apply_clamps(self) -> None:
        """Give the clamps of the active contacts to the hand-off rows or to the joint locks."""
        clamps = [cl for a in self.active.values() for cl in a.clamps]
        if self.mixed_on:  # a held joint is locked: its clamps are in its hold condition
            held = self.locks.held
            signs: dict[int, set[int]] = {}
            for j, s in clamps:
                if j in held:
                    signs.setdefault(j, set()).add(s)
            self.mixed.set_clamps(cl for cl in clamps if cl[0] not in held)
            self.mixed.set_held(held, signs)
            self.locks.set_clamps(())
        else:
            self.mixed.set_clamps(())
            self.mixed.set_held((), {})
            self.locks.set_clamps(clamps)

    def settle_modes(
        self,
        t: float,
        y: FloatArray,
        *,
        flip: int | None = None,
        candidates: Sequence[int] = (),
        log_stick: bool = False,
    ) -> None:
        """The locks' modes (the report's law), or the mixed problem's while it has a pair."""
        if self.mixed_on:  # the clamps are rows of the hand-off problem
            self.settle_mixed(t, y, candidates=candidates, log_stick=log_stick)
            return
        super().settle_modes(t, y, flip=flip, candidates=candidates, log_stick=log_stick)

    def settle_mixed(
        self, t: float, y: FloatArray, *, candidates: Sequence[int] = (), log_stick: bool = False
    ) -> None:
        """The modes of the mixed problem at (t, y) (no impulse: v is kept), holds included.

        Args:
            t: Time [s].
            y: State.
            candidates: Joints with Coulomb friction that just stopped (see
                :meth:`MixedHolds.settle <packbot.contact.handoff_holds.MixedHolds.settle>`).
            log_stick: Log a ``stick`` event for each candidate that sticks.
        """
        mixed = self.mixed
        n, tail = self.n, y[2 * self.n :]
        q, v = y[:n], y[n : 2 * n]
        coul = self.drive.path.coulomb  # a failure may have changed the bounds (a brake)
        mixed.joint_coulomb = coul if coul.any() else None
        mixed.joint_fdir = self.drive.fdir
        if mixed.resting:  # the rest capture holds every joint; its rest condition is watched
            self.locks.set_held({})
            self.drive.fdir[:] = 0.0
            self.apply_clamps()
            return
        self.apply_clamps()
        mixed.refresh(q)
        if coul.any():
            self.holds_mixed.settle(t, y, candidates, log_stick)
        else:
            mixed.select_modes(q, v, self.free_accel(t, y), self.sys.minv(q))
        if not mixed.pairs:  # the refresh dropped the last pair: the locks take the clamps
            self.apply_clamps()
            y_new = np.concatenate([q, v, tail])
            self.settle_modes(t, y_new, candidates=candidates, log_stick=log_stick)
            return
        self._release_receding_rows(t, y)

    def _release_receding_rows(self, t: float, y: FloatArray) -> None:
        """Engaged clamp rows on receding joints released, the modes selected again (logged).

        The rule of the report's law (:mod:`packbot.contact.joint_clamp`: a clamp never does
        positive work) on the clamp rows of the mixed problem: an engaged row holds its joint at
        a_j = 0, so on a joint moving away from its contact (s v_j < -RECEDE_SPEED) its torque
        would do positive work. Such a clamp is released (a ``release`` naming the pair and the
        joint) until its joint turns.
        """
        n, mixed = self.n, self.mixed
        q, v = y[:n], y[n : 2 * n]
        for _ in range(n + 1):
            engaged = {cl for r in mixed.engaged if (cl := mixed.clamp_of_row(r)) is not None}
            away = [
                (key, cl)
                for key, act in self.active.items()
                for cl in act.clamps
                if cl in engaged and cl[1] * v[cl[0]] < -RECEDE_SPEED
            ]
            if not away:
                return
            for key, cl in away:
                self._let_go(t, y, key, cl)
            self.apply_clamps()
            mixed.select_modes(q, v, self.free_accel(t, y), self.sys.minv(q))

    def _handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Events with a handed-off pair in contact, or at a secondary intersection.

        The handed-off pairs follow the normal mode, the others and the stops the report's
        law; then, while a handed-off pair is in contact, one restart of the mixed problem
        (drift correction, impulse, modes) with the clamps as rows; otherwise the joint locks
        take the clamps. Without either, the report's handling.
        """
        if not (self.mixed_on or any(c.kind == "secondary_intersection" for c in crossings)):
            return super()._handle(t, y, crossings)
        mixed, world = self.mixed, self.world
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        tail = y[2 * n :]
        handed: list[tuple[PairInfo, float]] = []
        logged: list[tuple[str, PairInfo | None, float, tuple[str, ...], int | None]] = []
        stick: list[int] = []
        order = {"release": 0, "secondary_intersection": 1}
        for c in sorted(crossings, key=lambda c: order.get(c.kind, 2)):
            key = c.key
            if key[0] == "pair":
                p_idx = key[1]
                info = world.pairs[p_idx]
                d = self.distance(p_idx, y)
                if p_idx in mixed.pairs:  # a handed-off pair
                    if c.kind == "release":
                        self.active.pop(key, None)
                        mixed.remove_pair(p_idx)
                        logged.append(("release", info, d, (), None))
                    else:  # repatch
                        mixed.add_pair(q, p_idx)
                        logged.append((c.kind, info, d, (), None))
                elif c.kind == "release":
                    act = self.active.pop(key, None)
                    if act is not None:
                        self.log_event(t, "release", q, v, v, info, d=d)
                elif c.kind == "secondary_intersection" and mixed.add_pair(q, p_idx):
                    self.active[key] = Active(info, [])  # its clamps are released
                    handed.append((info, d))
                else:  # an impact (or a secondary intersection without a patch): the law
                    v = self.impact(t, q, v, p_idx, c.kind)
            elif key[0] == "limit":
                v = self.limit(t, q, v, key[1], key[2])
            elif key[0] == "mode":
                if key[1] == "nrow" and (cl := mixed.clamp_of_row(key[2])) is not None:
                    j = cl[0]
                    logged.append((c.kind, None, math.nan, (self.sys.names[j],), j))
                elif key[1] == "nrow":
                    owner, _ = mixed.row_owner(key[2])
                    logged.append((c.kind, owner, math.nan, (), None))
                elif key[1] == "nfric":
                    logged.append((c.kind, mixed.pairs[key[2]].info, math.nan, (), None))
                else:  # nrest: the resting arm starts moving again
                    logged.append((c.kind, None, math.nan, (), None))
            elif key[0] == "stick":  # a sliding joint stopped: it holds or slides on (below)
                j = key[1]
                v[j] = 0.0
                self.drive.fdir[j] = 0.0
                stick.append(j)
            elif c.kind == "slip":  # a held joint's torque beyond its bound
                self._slip(t, self.with_v(y, v), key[1])
            else:  # a lock's engage/disengage at the instant of a hand-off: re-solved below
                j = key[1]
                logged.append((c.kind, None, math.nan, (self.sys.names[j],), j))
        self.apply_clamps()
        if not self.mixed_on:  # the last handed-off pair left: the report's law alone
            for kind, who, d, joints, jnt in logged:
                self.log_event(t, kind, q, v, v, who, d=d, joints=joints, joint=jnt)
            y_new = self.with_v(y, v)
            self.settle_modes(t, y_new, candidates=stick, log_stick=True)
            return y_new
        before = {k: p.stick for k, p in mixed.pairs.items()}
        q, v_new, mode_events = self._restart(mixed, t, q, v, tail)
        v_new = self._stop_creeping_clamps(q, v_new)
        y_new = np.concatenate([q, v_new, tail])
        for pair, d in handed:
            joints = tuple(self.sys.names[i] for i in np.flatnonzero(v_new != v))
            self.log_event(t, "handoff", q, v, v_new, pair, d=d, joints=joints)
        for kind, who, d, joints, jnt in logged:
            self.log_event(t, kind, q, v, v_new, who, d=d, joints=joints, joint=jnt)
        if mixed.resting:  # the rest capture holds every joint (friction included)
            self.locks.set_held({})
            self.drive.fdir[:] = 0.0
            self.apply_clamps()
        elif self.drive.path.coulomb.any():  # the holds chosen with the modes: the net change
            self.holds_mixed.settle(t, y_new, stick, True)
            for j in self.locks.held:  # held: at rest (the impulse's rounding residue dropped)
                y_new[n + j] = 0.0
            mode_events = [me for me in mode_events if me.kind not in ("stick", "slip")]
            mode_events += [
                ModeEvent("stick" if p.stick else "slip", p.info)
                for k, p in mixed.pairs.items()
                if p.stick != before.get(k, True)
            ]
        for me in mode_events:
            if any(me.kind == k and me.pair == i for k, i, _, _, _ in logged):
                continue
            self.log_event(t, me.kind, q, v_new, v_new, me.pair)
        self._release_receding_rows(t, y_new)
        return y_new

    def _stop_creeping_clamps(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """Engaged clamp rows that the restart's impulse left receding slower than CLAMP_ZENO.

        Their joints are stopped by the least (M-weighted) joint impulse on those rows (a
        projection: it only takes energy out), so the clamp stays engaged. Without it, a light
        joint (the wrist's) that the impulse sets receding at rounding-level speeds (1e-9 to
        1e-8 rad/s, within the impulse solver's tolerance) has its clamp released, turns at
        once, is clamped again, and so on at one instant (measured on random wrist-free starts).

        Args:
            q: Configuration [rad].
            v: Velocities after the restart [rad/s].

        Returns:
            The velocities [rad/s] (v itself when no engaged clamp creeps away).
        """
        mixed = self.mixed
        creep = [
            cl
            for r in mixed.engaged
            if (cl := mixed.clamp_of_row(r)) is not None
            and -CLAMP_ZENO <= cl[1] * v[cl[0]] < -RECEDE_SPEED
        ]
        if not creep:
            return v
        rhs = mixed._rows_rhs()
        status, out = native.stop_joints(rhs, v, self.sys.minv(q), creep, one_sided=False)
        return out if status == 1 else v

    def _slip(self, t: float, y: FloatArray, j: int) -> None:
        """Held joint j slips: it slides against the torque its hold needed (logged)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        if self.mixed_on:
            tau = self.mixed.hold_torques(q, v, self.free_accel(t, y), self.sys.minv(q))
            lam = tau.get(j, 0.0)
        else:
            lam = self.hold_torque(t, y, j)
        self.locks.set_held({k: b for k, b in self.locks.held.items() if k != j})
        self.drive.fdir[j] = -math.copysign(1.0, lam)
        self.apply_clamps()
        self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
