"""Mode selection at a restart: engaged rows, stick or slip, consistent slip directions.

The acceleration-level problem with the touching rows (a mixed LCP: complementary normal rows,
sticking pairs' tangential rows as equalities; compiled Lemke, with non-negative least squares
as the fallback of the symmetric problems), the cone check switching a sticking pair to slip,
the Painleve fallback, and the slip directions of pairs starting to slide.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact.lcp import lcp_residual, lemke, solve_lcp_psd
from packbot.contact.normal_dynamics import (
    _OWN_CONDITIONS,
    _OWN_EVALUATE,
    _OWN_VIOLATED,
    ConstrainedDynamics,
)
from packbot.contact.normal_patch import _Pair
from packbot.contact.normal_tolerances import (
    BAUMGARTE,
    FORCE_BAND,
    RESIDUAL_TOL,
    SPEED_BAND,
    STICK_BAND,
    STICK_SPEED,
    TOUCH_GAP,
)

__all__ = ["ModeEvent", "ModeSelection"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


_KINDS = ("stick", "slip", "painleve")  # (the native selection's event kinds, by code)


@dataclass
class ModeEvent:
    """A mode change found at a restart (for the event log).

    Attributes:
        kind: ``"stick"``, ``"slip"``, ``"release"`` or ``"painleve"``.
        pair: The pair (None for a limit row).
        detail: Extra text (a limit row's joint).
    """

    kind: str
    pair: PairInfo | None
    detail: str = ""


class ModeSelection(ConstrainedDynamics):
    """The contact set's mode selection (see the module)."""

    def select_modes(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        keep: bool = False,
    ) -> list[ModeEvent]:
        """Solve the acceleration-level problem; set the engaged rows and stick/slip.

        With ``keep`` (a re-patch inside a mode), sticking pairs stay sticking and sliding
        pairs only update their direction.
        """
        native = self._native_modes(q, v, a_free, minv, keep, [])
        if native is not None:
            return native
        events: list[ModeEvent] = []
        Jn, drift, gap, vn, extra = self._problem(q, v)
        touch = [int(r) for r in np.flatnonzero((gap <= TOUCH_GAP) & (np.abs(vn) <= SPEED_BAND))]
        self.engaged = touch
        if self.mu > 0.0:
            for p, ex in zip(self.pairs.values(), extra, strict=True):
                speed = _norm(ex["vt"])
                was = p.stick
                if keep and p.stick:
                    continue
                p.stick = speed <= STICK_SPEED and not keep
                if not p.stick and speed > 0.0:  # (re-patched at zero speed: kept)
                    p.slip_dir = ex["vt"] / speed
                if was != p.stick:
                    events.append(ModeEvent("stick" if p.stick else "slip", p.info))
        if not touch:
            self.engaged = []
            return events
        base = _ModeBase(touch, Jn, drift, gap, vn, a_free, minv)
        args = (touch, Jn, drift, gap, vn, extra, a_free, minv, base)
        if not self._mode_loop(args, events):
            return events
        self._consistent_directions(q, v, Jn, drift, gap, vn, extra, a_free, minv, touch, base)
        # The engaged rows were solved with the former directions: with a sliding pair's
        # friction turned, a row's force can change sign (measured: a hand-off clamp row
        # engaged at +0.6 N*m read -0.11 N*m in the new direction, a 'disengage' at once,
        # repeated at that instant until max_events). Solve again with the new ones.
        if self._coulomb_residual_directions(extra) and not self._mode_loop(args, events):
            return events
        if log.isEnabledFor(logging.DEBUG):
            log.debug(
                "modes: touch %s engaged %s gaps %s vn %s",
                touch,
                self.engaged,
                np.array2string(gap, precision=8),
                np.array2string(vn, precision=6),
            )
        return events

    def _mode_loop(self, args: tuple[Any, ...], events: list[ModeEvent]) -> bool:
        """The mode problem solved with the cone check until no sticking pair leaves its cone.

        ``args``: the arguments of :meth:`_solve_modes`. A problem Lemke cannot solve (sliding
        friction: non-symmetric) is solved again with every pair sticking (a ``painleve``
        event); if that fails too, every touching row stays engaged and False is returned (the
        selection gives up friction for this restart, logged).
        """
        touch, *_, extra, _a_free, _minv, _base = args
        for _ in range(len(self.pairs) + 2):
            lam, ok = self._solve_modes(*args)
            if not ok:
                events.append(ModeEvent("painleve", None))
                self.n_painleve += 1
                for p in self.pairs.values():
                    p.stick = True
                lam, ok = self._solve_modes(*args)
                if not ok:  # give up friction for this restart
                    log.warning("contact problem unsolved even with sticking contacts")
                    self.engaged = [r for r in touch]
                    return False
            moved = self._cone_check(lam, extra)
            if not moved:
                break
            for p, s in moved:
                p.stick = False
                p.slip_dir = s
                events.append(ModeEvent("slip", p.info))
        return True

    def repatch_modes(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        signature: tuple[Any, ...],
        engaged: list[int],
    ) -> None:
        """The modes after a re-patch: the rows engaged before kept, else a new selection.

        The extension's selection keeps the engaged rows of before the re-patch (``held``)
        where the rows mean what they meant (``signature``, :meth:`~packbot.contact.
        normal_set.ContactSet.row_signature`), every one still touches, no sliding pair is
        slower than :data:`STICK_SPEED` and one solve with them solves the mode problem of
        :meth:`select_modes` (positive forces, no touching free row accelerating into contact,
        every mode condition satisfied): sticking pairs stay sticking, sliding pairs take the
        direction of their sliding velocity. Otherwise, and under a subclass's dynamics, the
        modes are selected again (``select_modes(keep=True)``), which gives the same modes
        wherever that problem has one solution.

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            a_free: Unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.
            signature: The row signature before the re-patch.
            engaged: The engaged rows before the re-patch.
        """
        if (
            engaged
            and self._keeps_own_rows(signature)
            and self._native_modes(q, v, a_free, minv, True, engaged) is not None
        ):
            return
        self.select_modes(q, v, a_free, minv, keep=True)

    def _keeps_own_rows(self, signature: tuple[Any, ...]) -> bool:
        """Whether the engaged rows of before a re-patch may be kept (:meth:`repatch_modes`)."""
        return (
            type(self).evaluate is _OWN_EVALUATE
            and type(self).violated is _OWN_VIOLATED
            and signature == self.row_signature()
        )

    def _native_modes(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        keep: bool,
        held: list[int],
    ) -> list[ModeEvent] | None:
        """:meth:`select_modes` in one native call, first keeping the rows ``held``.

        (:meth:`repatch_modes`.) None where it does not run (no compiled right-hand side, a
        resting contact set, rows ``held`` to keep under a subclass's dynamics or conditions)
        or hands back; else the modes are set and the mode changes returned.
        """
        native = self.native
        own = type(self).evaluate is _OWN_EVALUATE and type(self).conditions is _OWN_CONDITIONS
        if native is None or self.resting or (held and not own):
            return None
        out = native.restart.select_modes(self, q, v, a_free, minv, keep, held)
        if out is None:
            return None
        pairs = self._pair_list
        for p, st, sd in zip(pairs, out.stick.tolist(), out.slip_dir, strict=True):
            p.stick = st
            if not np.array_equal(sd, p.slip_dir):
                p.slip_dir = sd.copy()
        self.engaged = out.engaged
        self.n_painleve += out.painleve
        if out.gave_up:
            log.warning("contact problem unsolved even with sticking contacts")
        return [
            ModeEvent(_KINDS[kind], pairs[i].info if i >= 0 else None) for kind, i in out.events
        ]

    def _consistent_directions(
        self,
        q: FloatArray,
        v: FloatArray,
        Jn: FloatArray,
        drift: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        extra: list[dict[str, Any]],
        a_free: FloatArray,
        minv: FloatArray,
        touch: list[int],
        base: _ModeBase | None = None,
    ) -> None:
        """Slip directions of pairs starting to slide from rest: their tangential acceleration.

        A slip onset at rest (|v_t| <= :data:`STICK_SPEED`) must slide along its direction s:
        a_t(s) . s > 0, a_t the tangential acceleration of the patch centre in the slip mode.
        From the cone check's s = -f_t / |f_t|, s is turned towards a_t (s <- s + a_t / |a_t|)
        until it is (a plain fixed point s = a_t / |a_t| can flip-flop).
        """
        if self.mu == 0.0:
            return
        starting = [
            (p, ex)
            for p, ex in zip(self.pairs.values(), extra, strict=True)
            if not p.stick and _norm(ex["vt"]) <= STICK_SPEED
        ]
        if not starting or not self.engaged:
            return
        if base is None:
            base = _ModeBase(touch, Jn, drift, gap, vn, a_free, minv)
        for _ in range(8):
            a = self.evaluate(q, v, a_free, minv).a
            moved = False
            for p, ex in starting:
                at = ex["T"].T @ (ex["JT"] @ a + ex["bT"])
                na = _norm(at)
                if na <= 1e-9 or float(at @ p.slip_dir) > 0.0:
                    continue  # the slide grows along its direction: consistent
                s = p.slip_dir + at / na
                ns = _norm(s)
                p.slip_dir = s / ns if ns > 1e-9 else at / na
                moved = True
            if not moved:
                return
            self._solve_modes(touch, Jn, drift, gap, vn, extra, a_free, minv, base)

    def _coulomb_residual_directions(self, extra: list[dict[str, Any]]) -> bool:
        """A pair set to slip against its own residual slide slips along that slide.

        A slip onset inside the stick band (|v_t| <= :data:`STICK_SPEED`) takes its direction
        s from the forces (cone check, then :meth:`_consistent_directions`). When the contact
        still moves at a residual v_t that :meth:`stop_slow` could not remove (a slide driven
        through a closed chain by the motion elsewhere) and s points so far against it that
        the stick condition (the slide came back through zero) is below half of
        :data:`STICK_BAND`, that condition would fire at once and the restart repeat at the
        same instant (stick -> cone check -> slip -> stick ...; seen at mu = 0.45 in the
        collapse: link 2's casing on the chassis at 4.6e-4 m/s). Coulomb's law for a moving
        contact is friction against the motion, so such a pair slips along v_t: the slide
        slows down, passes through zero and fires the
        stick event after a finite time, where the onset is decided again.

        Returns:
            Whether a direction was turned (the caller then solves the modes again: the
            engaged rows were chosen with the former direction's friction).
        """
        if self.mu == 0.0:
            return False
        turned = False
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            if p.stick:
                continue
            vt = ex["vt"]
            speed = _norm(vt)
            w = vt + STICK_SPEED * p.slip_dir  # as in conditions(): g = v_t . w/|w| + band
            g = float(vt @ w) / max(_norm(w), 1e-300) + STICK_BAND
            if speed > 0.0 and g < 0.5 * STICK_BAND:
                p.slip_dir = vt / speed
                turned = True
        return turned

    def _solve_modes(
        self,
        touch: list[int],
        Jn: FloatArray,
        drift: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        extra: list[dict[str, Any]],
        a_free: FloatArray,
        minv: FloatArray,
        base: _ModeBase | None = None,
    ) -> tuple[dict[str, Any], bool]:
        """The mixed LCP: touching normal rows complementary, sticking rows equalities.

        ``base``: the parts independent of the modes (built from these arguments when None).
        """
        self.engaged = list(touch)
        C = self._slip_columns(Jn, extra)
        N = touch
        if base is None:
            base = _ModeBase(touch, Jn, drift, gap, vn, a_free, minv)
        bN, JnM = base.bN, base.JnM
        sticks = tuple([p.stick for p in self.pairs.values()])
        rows = base.stick_rows.get(sticks)
        if rows is None:  # the sticking rows' blocks: they follow the stick flags alone
            JT, bT, vT = self._stick_rows(extra)
            if len(JT):
                bTt = JT @ a_free + bT + BAUMGARTE * vT
                JTM = JT @ minv
                GTTi = np.linalg.pinv(JTM @ JT.T, rcond=1e-10)
                rows = (JT, bTt, JTM, GTTi)
            else:
                rows = (JT, bT, JT, JT)
            base.stick_rows[sticks] = rows
        JT, bTt, JTM, GTTi = rows
        CNt = C[N].T
        GNN = JnM @ CNt
        symmetric = all(sticks) or self.mu == 0.0
        if len(JT):
            GNT = JnM @ JT.T
            GTN = JTM @ CNt
            GNTi = GNT @ GTTi
            Ml = GNN - GNTi @ GTN
            ql = bN - GNTi @ bTt
        else:
            Ml, ql = GNN, bN
        if symmetric:
            z = _psd_lcp(Ml, ql)
            res = lcp_residual(Ml, ql, z)
        else:
            z2 = lemke(Ml, ql)
            if z2 is None:
                return {}, False
            z, res = z2, lcp_residual(Ml, ql, z2)
        if res > 1e-6:
            log.debug("mode LCP residual %.3g", res)
            if not symmetric:
                return {}, False
        scale = 1e-12 * (1.0 + float(np.abs(z).max(initial=0.0)))
        self.engaged = [r for r, zr in zip(N, z.tolist(), strict=True) if zr > scale]
        lamT = -GTTi @ (GTN @ z + bTt) if len(JT) else np.zeros(0)
        return {"lamN": dict(zip(N, z.tolist(), strict=True)), "lamT": lamT}, True

    def _cone_check(
        self, lam: dict[str, Any], extra: list[dict[str, Any]]
    ) -> list[tuple[_Pair, FloatArray]]:
        """Sticking pairs whose tangential force leaves the cone, with their slip direction."""
        if self.mu == 0.0:
            return []
        out = []
        k_row, k_t = 0, 0
        lamN, lamT = lam["lamN"], lam["lamT"]
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            K = len(p.local1)
            fn = sum(lamN.get(r, 0.0) for r in range(k_row, k_row + K))
            had_rows = any(k_row <= r < k_row + K for r in lamN)
            k_row += K
            if not p.stick or not had_rows:
                continue
            # tangential rows exist for this pair only if it was engaged when rows were built
            if k_t + 2 > len(lamT):
                continue
            lt = lamT[k_t : k_t + 2]
            k_t += 2
            nt = _norm(lt)
            if nt > self.mu * fn + FORCE_BAND:
                f_world = ex["T"].T @ lt
                out.append((p, -f_world / nt))
        return out


class _ModeBase:
    """The parts of :meth:`ModeSelection._solve_modes` that the modes do not change.

    Built once per restart from the touching rows ``touch`` (N) and the row data: J_n[N] M^-1
    and the right-hand side b_N = J_n[N] a_free + drift[N] + 2 BAUMGARTE v_n[N] +
    BAUMGARTE^2 gap[N] [m/s^2], the same operations in the same order as the solve made them
    each time (so the same bits); the mode loop and :meth:`ModeSelection._consistent_directions`
    reuse it while their arguments are the ones it was built from. ``stick_rows`` caches, by
    the pairs' stick flags (all the sticking rows depend on with these arguments: the engaged
    rows are the touching ones during a solve), the sticking rows J_T, their right-hand side,
    J_T M^-1 and the pseudo-inverse of G_TT = J_T M^-1 J_T^T: the direction iteration changes
    only the sliding directions, so its solves reuse them.
    """

    __slots__ = ("JnM", "bN", "stick_rows")

    def __init__(
        self,
        touch: list[int],
        Jn: FloatArray,
        drift: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
    ) -> None:
        N = touch
        JnN = Jn[N]
        self.bN: FloatArray = (
            JnN @ a_free + drift[N] + 2.0 * BAUMGARTE * vn[N] + BAUMGARTE**2 * gap[N]
        )
        self.JnM: FloatArray = JnN @ minv
        self.stick_rows: dict[
            tuple[bool, ...], tuple[FloatArray, FloatArray, FloatArray, FloatArray]
        ] = {}


def _norm(x: FloatArray) -> float:
    """``float(np.linalg.norm(x))`` of a real vector, bit for bit: sqrt(x . x) [its unit]."""
    return math.sqrt(float(x.dot(x)))


def _psd_lcp(G: FloatArray, g: FloatArray) -> FloatArray:
    """LCP(G, g) of a Delassus matrix G = J M^-1 J^T: compiled Lemke, else least squares.

    For the projection (dq = M^-1 J^T mu [rad]), a frictionless impact (dv = M^-1 J^T P
    [rad/s]) and the symmetric mode problems (the constrained acceleration M^-1 J^T lambda
    [rad/s^2]). Every solution z of this symmetric positive semi-definite problem minimises
    the convex 1/2 z.G z + g.z over z >= 0 and has the same M^-1/2 J^T z (the objective is
    strictly convex in it), so the step is the same whichever solution a solver returns: the
    solver only changes it by rounding. Which rows carry the force can differ where the rows
    are dependent; Lemke's solution is basic, as the least-squares one (the Delassus block of
    its support is non-singular: its final basis holds those columns). Lemke's pivots
    (:func:`~packbot.contact.lcp.lemke`) replace :func:`~packbot.contact.lcp.solve_lcp_psd`
    (``eigh``, ``lstsq`` and scipy's NNLS) whenever their residual passes; otherwise the
    least-squares solution, or Lemke's if its residual is the smaller (the caller checks and
    reports it).
    """
    n = len(g)
    if n == 0 or bool(np.all(g >= 0.0)):
        return np.zeros(n)
    z = lemke(G, g)
    res = lcp_residual(G, g, z) if z is not None else math.inf
    if z is not None and res <= RESIDUAL_TOL:
        return z
    z2 = solve_lcp_psd(G, g)
    if z is not None and res < lcp_residual(G, g, z2):
        return z
    return z2
