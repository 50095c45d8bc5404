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

When the last handed-off pair leaves the contact set (its distance beyond the proximity
tolerance) the clamps go back to :class:`~packbot.contact.locks.JointLocks` and that pair's next
impact is a ``joint_clamp`` impact again.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact.base import Active, Crossing, Key
from packbot.contact.joint_clamp import JointClampLaw
from packbot.contact.lcp import lcp_residual, lemke, solve_lcp_psd
from packbot.contact.locks import ACCEL_BAND, TORQUE_BAND
from packbot.contact.normal import (
    RESIDUAL_TOL,
    ModeEvent,
    NormalContacts,
    PatchEvents,
    _Eval,
)
from packbot.contact.stops import RECEDE_SPEED
from packbot.ode import DenseSegment
from packbot.system import System

__all__ = ["HandoffContacts", "HandoffLaw"]

FloatArray = NDArray[np.float64]

#: A row is frozen by the bilateral joints when its largest entry on the other joints is below
#: NULL_ROW times its largest entry [-] (rounding: the two bodies' Jacobians cancel there).
NULL_ROW = 1e-9
#: The gap reported for such a row [m]: far from touching.
NULL_GAP = 1.0


class HandoffContacts(NormalContacts):
    """Handed-off pairs (patch rows) plus the joint_clamp clamps as one-sided joint rows.

    Same arguments as :class:`~packbot.contact.normal.NormalContacts`.

    Attributes:
        clamps: The one-sided clamps in force, (joint index, forbidden acceleration direction
            s = +1 or -1), sorted; their rows follow the patch and limit rows in this order.
        bilateral: Joints clamped in both directions (locked: eliminated, not rows), sorted.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.clamps: list[tuple[int, int]] = []
        self.bilateral: list[int] = []
        self._velocity_level = False  # clamp rows report their true velocity (impulse level)
        self._reduced = False  # inside a call already working in the bilateral-locked subspace

    @property
    def constrained(self) -> bool:
        """Whether the dynamics differ from the free ones (engaged rows or bilateral joints)."""
        return bool(self.engaged) or bool(self.bilateral)

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
        self.clamps = new
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

    def _rows(self, clamps: list[tuple[int, int]]) -> FloatArray:
        """Rows J = -s e_j of the given clamps, shape (len(clamps), nv)."""
        m = len(clamps)
        rows = np.zeros((m, self.nv))
        joints = np.array([j for j, _ in clamps], dtype=np.intp)
        signs = np.array([s for _, s in clamps], dtype=float)
        rows[np.arange(m), joints] = -signs
        return rows

    def _problem(
        self, q: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[dict[str, Any]]]:
        Jn, drift, gap, vn, extra = super()._problem(q, v)
        if self._reduced and len(gap):
            gap, vn = self._null_rows_apart(Jn, gap, vn)
        m = len(self.clamps)
        if m == 0:
            return Jn, drift, gap, vn, extra
        rows = self._rows(self.clamps)
        vc = rows @ v if self._velocity_level else np.zeros(m)
        z = np.zeros(m)
        return (
            np.vstack([Jn, rows]),
            np.concatenate([drift, z]),
            np.concatenate([gap, z]),
            np.concatenate([vn, vc]),
            extra,
        )

    # ------------------------------------------------------------------ bilateral joints
    def _null_rows_apart(
        self, Jn: FloatArray, gap: FloatArray, vn: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Rows that the locked joints freeze, reported apart (gap NULL_GAP, v_n 0).

        A pair whose bodies the bilateral joints join rigidly (the arm's link 3 on link 1 with
        both elbows locked) has a row with no component on the free joints: its gap cannot
        change, its force does nothing, and in the problems it would be a zero row of the
        Delassus matrix (with a Baumgarte term on a micrometre gap, an infeasible LCP). Such a
        row sits out of every problem (not touching, no event) while the joints stay locked.
        """
        free = np.ones(self.nv, dtype=bool)
        free[self.bilateral] = False
        scale = np.abs(Jn).max(axis=1, initial=0.0)
        null = np.abs(Jn[:, free]).max(axis=1, initial=0.0) <= NULL_ROW * scale
        if not null.any():
            return gap, vn
        gap, vn = gap.copy(), vn.copy()
        gap[null] = NULL_GAP
        vn[null] = 0.0
        return gap, vn

    def _lock(self, a_free: FloatArray, minv: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Free accelerations and M^-1 with the bilateral joints locked (a_j = 0)."""
        idx = np.array(self.bilateral, dtype=np.intp)
        K = minv[:, idx]
        W = minv[np.ix_(idx, idx)]
        minv_c = minv - K @ np.linalg.solve(W, K.T)
        a_c = a_free - K @ np.linalg.solve(W, a_free[idx])
        minv_c[idx, :] = 0.0
        minv_c[:, idx] = 0.0
        a_c[idx] = 0.0
        return np.asarray(a_c, dtype=np.float64), np.asarray(minv_c, dtype=np.float64)

    @contextmanager
    def _locked(self) -> Iterator[None]:
        self._reduced = True
        try:
            yield
        finally:
            self._reduced = False

    def _bypass(self) -> bool:
        """No bilateral joint, or already in the locked subspace: call the base method."""
        return self._reduced or not self.bilateral

    def evaluate(self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray) -> _Eval:
        """The normal mode's constrained dynamics, bilateral joints locked."""
        if self._bypass():
            return super().evaluate(q, v, a_free, minv)
        a_c, minv_c = self._lock(a_free, minv)
        with self._locked():
            return super().evaluate(q, v, a_c, minv_c)

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

    def repatch(self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray) -> FloatArray:
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

        Bilateral joints are stopped here (with the full M^-1) and locked from then on.
        """
        both = [(j, s) for j in self.bilateral for s in (-1, 1)]
        v = self.stop_clamped(v, minv, sorted(set(self.clamps) | set(both)))
        if self._bypass():
            return super().restart(q, v, a_free_fn, minv)
        v = v.copy()
        v[self.bilateral] = 0.0  # stopped to rounding: exactly
        minv_c = self._lock(np.zeros(self.nv), minv)[1]
        with self._locked():
            return super().restart(q, v, self._locked_fn(a_free_fn, minv), minv_c)

    def _locked_fn(self, a_free_fn: Any, minv: FloatArray) -> Any:
        def fn(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self._lock(a_free_fn(qq, vv), minv)[0]

        return fn

    # ------------------------------------------------------------------ velocity level
    def impulse(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """The normal mode's impulse, the clamp rows at their true velocity (J v+ >= 0).

        Clamped joints moving toward their contact are stopped first (:meth:`stop_clamped`).
        """
        v = self.stop_clamped(v, minv, self.clamps)
        self._velocity_level = True
        try:
            return super().impulse(q, v, minv)
        finally:
            self._velocity_level = False

    def stop_slow(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """The normal mode's stop of slow slides, the clamp rows at their true velocity."""
        self._velocity_level = True
        try:
            return super().stop_slow(q, v, minv)
        finally:
            self._velocity_level = False

    def stop_clamped(
        self, v: FloatArray, minv: FloatArray, clamps: list[tuple[int, int]]
    ) -> FloatArray:
        """The least (M-weighted) joint impulse making every given clamp row's velocity >= 0.

        The LCP w = G P + J v >= 0, P >= 0, complementary, on the clamp rows J alone
        (G = J M^-1 J^T); P [N*m*s] pushes each approaching clamped joint to a stop (both rows
        of a bilateral joint: it stops). Perfectly inelastic: never adds energy.

        Args:
            v: Joint velocities [rad/s].
            minv: M^-1 at the current configuration.
            clamps: The (joint, s) rows to enforce.

        Returns:
            The joint velocities after [rad/s] (v itself when no row approaches).
        """
        if not clamps:
            return v
        J = self._rows(clamps)
        w = J @ v
        if float(w.min()) >= 0.0:
            return v
        G = J @ minv @ J.T
        P = solve_lcp_psd(G, w)
        res = lcp_residual(G, w, P)
        if res > RESIDUAL_TOL:
            P2 = lemke(G, w)
            if P2 is not None and lcp_residual(G, w, P2) < res:
                P = P2
        return np.asarray(v + minv @ J.T @ P, dtype=np.float64)

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

    @property
    def mixed_on(self) -> bool:
        """Whether a handed-off pair is in contact (the clamps are then rows of its problem)."""
        return bool(self.mixed.pairs)

    def accel(self, q: FloatArray, v: FloatArray, a_free: FloatArray) -> FloatArray:
        """Accelerations with the locks, then the mixed problem's rows, of the current mode."""
        a = super().accel(q, v, a_free)
        if self.mixed.constrained:
            a = self.mixed.evaluate(q, v, a, self.sys.minv(q)).a
        return a

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
        if self.mixed_on:
            self.mixed.set_clamps(clamps)
            self.locks.set_clamps(())
        else:
            self.mixed.set_clamps(())
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
            self.settle_mixed(t, y)
            return
        super().settle_modes(t, y, flip=flip, candidates=candidates, log_stick=log_stick)

    def settle_mixed(self, t: float, y: FloatArray) -> None:
        """The modes of the mixed problem at (t, y) (no impulse: v is kept)."""
        mixed = self.mixed
        n, tail = self.n, y[2 * self.n :]
        q, v = y[:n], y[n : 2 * n]
        self.apply_clamps()
        mixed.refresh(q)
        mixed.select_modes(q, v, self.free_accel(t, y), self.sys.minv(q))
        if not mixed.pairs:  # the refresh dropped the last pair: the locks take the clamps
            self.apply_clamps()
            self.settle_modes(t, np.concatenate([q, v, tail]))
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
            else:  # a lock's engage/disengage at the instant of a hand-off: re-solved below
                j = key[1]
                logged.append((c.kind, None, math.nan, (self.sys.names[j],), j))
        self.apply_clamps()
        if not self.mixed_on:  # the last handed-off pair left: the report's law alone
            for kind, who, d, joints, jnt in logged:
                self.log_event(t, kind, q, v, v, who, d=d, joints=joints, joint=jnt)
            y_new = self.with_v(y, v)
            self.settle_modes(t, y_new)
            return y_new
        q, v_new, mode_events = self._restart(mixed, t, q, v, tail)
        for pair, d in handed:
            joints = tuple(self.sys.names[i] for i in np.flatnonzero(v_new != v))
            self.log_event(t, "handoff", q, v, v_new, pair, d=d, joints=joints)
        for kind, who, d, joints, jnt in logged:
            self.log_event(t, kind, q, v, v_new, who, d=d, joints=joints, joint=jnt)
        for me in mode_events:
            if any(me.kind == k and me.pair == i for k, i, _, _, _ in logged):
                continue
            self.log_event(t, me.kind, q, v_new, v_new, me.pair)
        y_new = np.concatenate([q, v_new, tail])
        self._release_receding_rows(t, y_new)
        return y_new
