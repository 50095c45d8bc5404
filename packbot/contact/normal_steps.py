"""The restart's steps on positions and velocities: projection, impulse, slow stop, capture.

At a restart the contact set corrects the drift of its gaps (:meth:`RestartSteps.project`, a
position-level LCP), applies the impact (:meth:`~RestartSteps.impulse`), stops the slow
residual slides (:meth:`~RestartSteps.stop_slow`) and may bring a slow arm to rest
(:meth:`~RestartSteps.capture`).
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact.lcp import lcp_residual, solve_ncp_admm
from packbot.contact.normal_dynamics import ConstrainedDynamics
from packbot.contact.normal_modes import ModeEvent, _psd_lcp
from packbot.contact.normal_tolerances import (
    CAPTURE_ACCEL,
    CAPTURE_SPEED,
    PENETRATION_TOL,
    PROJECT_ROUNDS,
    RESIDUAL_TOL,
    SPEED_BAND,
    STICK_SPEED,
    TOUCH_GAP,
)

__all__ = ["RestartSteps"]

log = logging.getLogger(__name__)

IMPACT_ADMM_ITERATIONS = 3000
"""Iteration limit of the frictional impact's ADMM (:meth:`RestartSteps.impulse`) [-]; the
compiled conic solver tried first (:func:`_impact_cones`) has the same limit.

The solver's own tolerance (1e-10, relative) is not reached on 45 % of the impacts of the
wrist-free starts (mu = 0.5, 182 impacts of two starts replayed): those ran to the former
limit, 5,000 iterations (94 % of the ADMM's time, 24 % of those runs' CPU time), ending at true
residuals (:func:`~packbot.contact.lcp.ncp_residual`) of 4e-19 to 4.6e-8; at 3,000 they end at
2.5e-8 at most, under the 1e-6 that the impulse accepts, with the normal velocities after the
impact (G x) within 8e-7 of the problem's scale. The impacts that converge earlier are
unchanged to the bit. An answer above :data:`IMPACT_ADMM_ACCEPT` at the limit is solved again
to 5,000 iterations (the former answer). The limit is set by the golden matrix: the
contact-normal run of collapse-small with a frozen joint moves its energy change by 2.2e-7 J
at 3,000 (5.5e-7 J at 2,500, 1.3e-6 J at 2,000, 0.06 J at 1,000: another impact branch;
tolerance 1e-6 J).
"""

IMPACT_ADMM_ACCEPT = 1e-6
"""The true residual [-] under which the frictional impact's answer is used."""

IMPACT_CONIC_TOL = 1e-10
"""The compiled solver's target residual for a frictional impact [-] (Pinocchio's ADMM's)."""

DEPENDENT_ROW = 1e-12
"""A touching row of :meth:`RestartSteps.stop_slow` whose Schur complement (its diagonal in
the LCP after the tangential equalities) is below this times the largest one [-] lies in the
span of the tangential rows: rounding, not a constraint the LCP can act on."""

FloatArray = NDArray[np.float64]


class RestartSteps(ConstrainedDynamics):
    """The contact set's position and velocity steps at a restart (see the module)."""

    def capture(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> list[ModeEvent] | None:
        """Bring a slow arm to rest when it can stay there (rest capture).

        When every joint speed is below :data:`CAPTURE_SPEED` and, at v = 0, the frictional
        contact problem of every touching row (per-point Coulomb cones, solved jointly by
        :func:`packbot.contact.lcp.solve_ncp_admm`) has joint accelerations below
        :data:`CAPTURE_ACCEL`, the velocity is set to zero and the contacts are *resting*:
        a = 0 until the rest condition (the same accelerations below 2 CAPTURE_ACCEL) fails.
        This is a documented regularisation of the mode decision, not of the forces. The
        joint problem is needed because a statically indeterminate arm (4 dof, an edge patch
        and a second contact: 7 rows) has many force distributions; the pair-by-pair cone check
        of :meth:`select_modes` takes one of them and finds it outside the cone (measured: 1.9
        times the cone on the elbow casing) where a feasible one exists. Without the capture
        the arm rocks on its edge patch in a periodic cycle of micro-impacts (period 16.7 ms,
        joint speeds 6e-3 rad/s, forever). A bounce (an impulse with restitution) is never
        captured.

        Returns:
            The mode changes if the arm was captured (the caller sets v = 0), else None (modes
            untouched).
        """
        if self.bounced or not self.pairs or float(np.abs(v).max(initial=0.0)) > CAPTURE_SPEED:
            return None
        z = np.zeros_like(v)
        a_free = a_free_fn(q, z)
        a = self._rest_accel(q, a_free, minv)
        if a is None or float(np.abs(a).max()) > CAPTURE_ACCEL:
            return None
        events = []
        for p in self.pairs.values():
            if self.mu > 0.0 and not p.stick:
                events.append(ModeEvent("stick", p.info))
            p.stick = True
        _, _, gap, _, _ = self._problem(q, z)
        self.engaged = [int(r) for r in np.flatnonzero(gap <= TOUCH_GAP)]
        self.resting = bool(self.engaged)
        return events if self.resting else None

    def stop_slow(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Bring the touching pairs sliding slower than :data:`STICK_SPEED` to rest.

        The least (M-weighted) velocity change that zeroes their tangential velocity at the
        patch centre and lets no touching row approach (a stick event's residual speed, like
        the joint-clamp mode's ``v_j = 0`` at a stick). Without it a slip that starts from such
        a residual speed can be against its own onset direction, and the stick condition fires
        again at once.

        The touching rows are inequalities (J_n v+ >= 0, an LCP on the Schur complement of the
        tangential equalities). A change needing a joint speed above :data:`CAPTURE_SPEED` is
        not made: the slow slide is then driven by the motion elsewhere, not a residual. In the
        arm's collapse (t = 0.508 s) the elbow casing slides on the chassis at 9e-4 m/s because
        link 3, sliding at 0.15 m/s on the shoulder casing, cams elbow1 (its casing is not
        quite round about elbow2); stopping that slide is only possible at v = 0, and the
        former version (normal velocities held as equalities, no bound) zeroed the arm's
        velocity there (elbow2 2.9 rad/s -> 0, -6.9 J).

        A pair is stopped only where its resting rows (touching, not separating faster than
        :data:`SPEED_BAND`) keep resting: friction stops a slide through a normal force, and a
        change that lifts a resting row off (above :data:`SPEED_BAND`, out of the mode
        selection's touching rows) has no normal impulse behind its tangential one, outside
        every friction cone. Such a pair's slide is left to the modes (stick, with its
        Baumgarte term, or slip) and the others are stopped without it. Measured in the
        collapse (mu = 0.5, t = 0.333 s): the least change stopping the elbow casing's
        2e-4 m/s slide on the chassis lifted its resting point at 1.4e-4 m/s; the point fell
        back 0.53 ms later, an impact, the same stop and lift again: 33 impacts until a
        cascade window, 52 of the run's 105 events.
        """
        if self.mu == 0.0 or not self.pairs:
            return v
        native = self.native
        if native is not None:
            status, v1 = native.restart.stop_slow(
                self, q, v, minv, touch_gap=TOUCH_GAP, speed_band=SPEED_BAND,
                stick_speed=STICK_SPEED, capture_speed=CAPTURE_SPEED,
                residual_tol=RESIDUAL_TOL, dependent_row=DEPENDENT_ROW,
            )  # fmt: skip
            if status == 0:
                return v
            if status == 1:
                return v1
        Jn, _, gap, vn, extra = self._problem(q, v)
        resting = (gap <= TOUCH_GAP) & (vn <= SPEED_BAND)
        owner = np.full(len(gap), -1, dtype=np.intp)  # each row's pair (position), -1 a limit
        slow: list[int] = []
        k = 0
        for i, (p, ex) in enumerate(zip(self.pairs.values(), extra, strict=True)):
            K = len(p.local1)
            owner[k : k + K] = i
            touching = bool(np.any(gap[k : k + K] <= TOUCH_GAP))
            k += K
            if touching and float(np.linalg.norm(ex["vt"])) <= STICK_SPEED:
                slow.append(i)
        while slow:
            dv = self._stop(slow, Jn, gap, vn, extra, v, minv)
            if dv is None:
                return v
            lifted = resting & (Jn @ (v + dv) > SPEED_BAND)
            if not lifted.any():
                return np.asarray(v + dv, dtype=np.float64)
            lifting = set(owner[lifted].tolist())
            if not lifting & set(slow):  # a row of a pair not stopped (or a limit) lifts
                log.debug("stop_slow: the change would lift a resting row: kept")
                return v
            slow = [i for i in slow if i not in lifting]
        return v

    def _stop(
        self,
        slow: list[int],
        Jn: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        extra: list[dict[str, Any]],
        v: FloatArray,
        minv: FloatArray,
    ) -> FloatArray | None:
        """:meth:`stop_slow`'s velocity change [rad/s] stopping the pairs ``slow``, or None.

        None: the change is not made (unsolved, a row fixed by the slide approaching, energy
        added by an inexact solution, or a change above :data:`CAPTURE_SPEED`).
        """
        E = np.vstack([extra[i]["JT"] for i in slow])
        bE = np.concatenate([-extra[i]["vT"] for i in slow])
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        In = Jn[touch]
        GEE_pinv = np.linalg.pinv(E @ minv @ E.T, rcond=1e-10)
        GEI = E @ minv @ In.T
        # dv = M^-1 (E^T y + I^T lam), y = GEE^+ (bE - GEI lam); w = I (v + dv) >= 0 _|_ lam >= 0
        y0 = GEE_pinv @ bE
        S = In @ minv @ In.T - GEI.T @ GEE_pinv @ GEI
        w0 = vn[touch] + GEI.T @ y0
        # A touching row in the span of the tangential rows (a hand-off clamp row on the turret
        # where the slide's direction moves the turret alone) has a zero Schur complement up to
        # rounding: the equalities fix its velocity w0, which a force on it cannot change. Its
        # rounding-level diagonal made the LCP unsolvable (1e-16 against w0 = -4e-21 m/s):
        # such a row is out of the LCP, at lambda = 0, if its w0 is not negative beyond
        # RESIDUAL_TOL (otherwise the slide cannot stop without it approaching: unsolved).
        scale = float(np.abs(np.diag(S)).max(initial=0.0))
        fixed = np.diag(S) <= DEPENDENT_ROW * scale
        lam = np.zeros(len(w0))
        if fixed.any() and float(w0[fixed].min()) < -RESIDUAL_TOL:
            log.debug("stop_slow: a row fixed by the slide would approach, velocity kept")
            return None
        keep = np.flatnonzero(~fixed)
        Sk, wk = S[np.ix_(keep, keep)], w0[keep]
        lamk = _psd_lcp(Sk, wk)  # (the compiled Lemke first, else least squares)
        if lcp_residual(Sk, wk, lamk) > RESIDUAL_TOL:
            log.debug("stop_slow: LCP unsolved, velocity kept")
            return None
        lam[keep] = lamk
        y = y0 - GEE_pinv @ (GEI @ lam)
        imp = E.T @ y + In.T @ lam  # the generalized impulse M dv [N*m*s]
        dv = np.asarray(minv @ imp, dtype=np.float64)
        if float(imp @ v) + 0.5 * float(imp @ dv) > 0.0:
            # A projection onto a cone holding 0 cannot add energy; an inexact one (rank-
            # deficient tangential rows, the LCP's residual) can: measured 2.4e-7 J.
            log.debug("stop_slow: the change would add energy: kept")
            return None
        if float(np.abs(dv).max()) > CAPTURE_SPEED:
            # The slow slide is driven by the motion elsewhere (a closed chain through two
            # contacts), not a residual: stopping it would stop the arm. Leave it.
            log.debug("stop_slow: change %.3g rad/s would stop the arm: kept", np.abs(dv).max())
            return None
        return dv

    def project(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Move q by the least (M-weighted) amount that closes every negative touching gap.

        The position-level LCP: dq = M^-1 J^T mu, mu >= 0, J dq + g >= 0, complementary, on
        the touching rows (g <= :data:`TOUCH_GAP`, gaps before) and every other row the move
        would take below zero; a stop the move would pass joins the set first
        (:meth:`_project_round`). Removes the integration drift of resting gaps and the event
        tolerance's last micrometre at every restart. Two guards make it safe:

        1. *Targets clipped at the true distance*: a row's gap is measured against its patch's
           geometry (a point against a face's plane), which can read far deeper than the pair
           really is (a patch point lifted onto a face's plane beyond the face's edge, or a
           stale point). Each pair row's gap is raised to min(d, 0) - :data:`PENETRATION_TOL`
           when below it, d the pair's signed distance (Coal, one pruned sweep at q), so the
           correction never exceeds the true penetration by more than the drift it exists
           for. The band keeps the micrometre disagreements of a fresh patch corrected in
           full (the collapse, mu = 0: a lifted point reading 1.6 um deeper than the distance
           at t = 0.206 s; the elbow casing's edge patch on the chassis reading -1 um with the
           pair 10 um apart at t = 1.45 s): left below -:data:`POINT_TOL`, such a row fires
           its impact condition again at once and the restart repeats forever. Clipping
           rather than re-patching: the patches are rebuilt just before every projection
           (restart, re-patch), so a gap still off the distance is the patch's geometry,
           which a new patch reproduces.
        2. *No penetration elsewhere*: the projection moves q without looking at the pairs not
           in the contact set. After it, the pairs the sweep leaves (within the world's
           margin) are checked; one below -:data:`PENETRATION_TOL` joins the contact set (its
           patch at the projected q, as an impact would add it: it then takes part in the
           restart's impulse and modes) and the projection is made again from there, up to
           :data:`PROJECT_ROUNDS` rounds. Off with ``check_others=False`` (the hand-off,
           whose other pairs are the joint_clamp mode's).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s] (for the rows' cache key only).
            minv: M^-1 at q.

        Returns:
            The corrected configuration [rad].
        """
        for _ in range(PROJECT_ROUNDS):
            moved = self._project_round(q, v, minv)
            if moved is None:
                return q
            q = moved
            if not self.check_others or self.world is None:
                return q
            sw = self.world.sweep(q, reuse=True)
            deep = sw.distances < -PENETRATION_TOL  # (the set's own pairs are not checked)
            bad = [
                (k, d)
                for k, d in zip(sw.pairs[deep].tolist(), sw.distances[deep].tolist(), strict=True)
                if k not in self.pairs
            ]
            if not bad:
                return q
            for k, d in bad:
                log.debug(
                    "projection: pair %s / %s at %.3g m joins the contact set",
                    self.world.pairs[k].piece1,
                    self.world.pairs[k].piece2,
                    d,
                )
                self.add_pair(q, k)
        log.debug("projection: still penetrating after %d rounds", PROJECT_ROUNDS)
        return q

    def _project_round(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray | None:
        """One round of :meth:`project` up to its sweep: the moved q [rad], or None (no move).

        A round that moves a joint past one of its stops (:attr:`stops`) that is not in the
        set puts that stop in the set and is made again: the stop's row then holds the joint
        (measured before: a jaw pressed on link 1 projected 1.4e-4 rad past its lower stop,
        start 59 of the wrist-free grid, mu 0, e 0, t = 1.039 s).
        """
        for _ in range(2 * self.nv + 1):  # (each new round has one stop more)
            moved = self._project_once(q, v, minv)
            crossed = [] if moved is None else self.crossed_stops(moved)
            if not crossed:
                return moved
            for j, side, lim in crossed:
                self.add_limit(j, side, lim)
        return moved

    def _project_once(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray | None:
        """:meth:`_project_round` without its stops: the moved q [rad], or None (no move).

        Natively when the law has its compiled right-hand side (``ContactRhs.project_round``),
        except where a gap is clipped or Lemke's answer is not taken.
        """
        native = self.native
        if native is not None:
            status, q1 = native.restart.project_round(
                self, q, v, minv, TOUCH_GAP, PENETRATION_TOL, RESIDUAL_TOL
            )
            if status == 0:
                return None
            if status in (3, 4):  # (4: past a stop not in the set, which the caller adds)
                return q1
        Jn, _, gap, _, _ = self._problem(q, v)
        low = float(gap.min()) if gap.size else 0.0
        if not low < 0.0:
            return None
        if low < -PENETRATION_TOL:
            # (else the clip changes nothing: its floor min(d, 0) - PENETRATION_TOL is at
            # most -PENETRATION_TOL, below every gap; the sweep is spared)
            gap = self._clip_gaps(gap, self._sweep(q))
            if not bool(np.any(gap < 0.0)):
                return None
        # the touching rows, and every other row the move takes below zero (as the native round)
        within = gap <= TOUCH_GAP
        while True:
            J = Jn[within]
            mu = _psd_lcp(J @ minv @ J.T, gap[within])
            dq = minv @ J.T @ mu
            below = ~within & (gap + Jn @ dq < 0.0)
            if not below.any():
                return np.asarray(q + dq, dtype=np.float64)
            within |= below

    def _sweep(self, q: FloatArray) -> dict[int, float]:
        """Signed distances [m] at q of the pairs within the world's margin, by pair index.

        Every pair of the contact set is included (queried alone if the sweep pruned it).
        """
        if self.world is None:
            return {}
        sw = self.world.sweep(q, reuse=True)
        dist = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
        for k in self.pairs:
            if k not in dist:
                dist[k] = self.world.pair_contact(q, k).distance
        return dist

    def _clip_gaps(self, gap: FloatArray, dist: dict[int, float]) -> FloatArray:
        """The rows' gaps [m], a pair's raised to min(d, 0) - PENETRATION_TOL (d: its distance)."""
        if not self.pairs or not dist:
            return gap
        out = gap.copy()
        k = 0
        for key, p in self.pairs.items():
            K = len(p.local1)
            d = dist.get(key)
            if d is not None:
                np.maximum(out[k : k + K], min(d, 0.0) - PENETRATION_TOL, out=out[k : k + K])
            k += K
        return out

    def impulse(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Simultaneous impact of every touching row (Newton's law, restitution e).

        An impulse never adds kinetic energy: each candidate's change is checked exactly
        (dT = P . J v + P . J dv / 2 for the generalized impulse J^T P, no mass matrix
        needed) and the first that does not gain is applied, in this order: the frictional
        impact (:func:`_impact_cones`), the frictionless one with restitution, the
        frictionless inelastic one (the M-projection of v onto J_n v >= 0, which cannot gain).
        A solver's inexact answer (an ADMM residual just under its bound, an NNLS solution off
        the LCP) could otherwise add energy: measured 2.5e-5 J at an impact of the camera head
        on link 1's tube (the collapse from a random start, mu = 0.5, wrist locked).
        """
        self.impact_rows = None
        native = self.native
        if native is not None:  # (its frictional impact is the compiled conic solver's)
            status, v1, bounced, rows, P = native.restart.impact(
                self, q, v, minv, mu=self.mu, restitution=self.e, zeno=self.zeno_speed,
                touch_gap=TOUCH_GAP, res_tol=RESIDUAL_TOL, conic_tol=IMPACT_CONIC_TOL,
                max_iterations=IMPACT_ADMM_ITERATIONS, accept=IMPACT_ADMM_ACCEPT,
            )  # fmt: skip
            if status == 0:
                return v
            if status == 1:
                self.bounced = bounced
                self.impact_rows = (rows, P)
                return v1
        Jn, _, gap, vn, extra = self._problem(q, v)
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        if len(touch) == 0 or float(vn[touch].min()) >= 0.0:
            return v
        e = self.e if float(vn[touch].min()) < -self.zeno_speed else 0.0
        self.bounced = e > 0.0
        J = Jn[touch]
        G = J @ minv @ J.T
        tried: list[str] = []
        if self.mu > 0.0:
            # Frictional impact: blocks (t1, t2, n) per touching row on Pinocchio's ADMM.
            J3, mus = self._frictional_rows(touch, Jn, extra)
            G3 = J3 @ minv @ J3.T
            g3 = J3 @ v
            g3[2::3] += e * np.minimum(g3[2::3], 0.0)
            x, res = _impact_cones(self.model, self.data, J3, minv, G3, g3, mus)
            if res <= IMPACT_ADMM_ACCEPT:
                dv = minv @ J3.T @ x
                if _energy_change(x, J3 @ v, J3 @ dv) <= 0.0:
                    self.impact_rows = (touch, x.reshape(-1, 3))
                    return np.asarray(v + dv, dtype=np.float64)
                tried.append("frictional (gains energy)")
            else:
                tried.append(f"frictional (residual {res:.3g})")
        for e_k in dict.fromkeys((e, 0.0)):
            target = vn[touch] + e_k * np.minimum(vn[touch], 0.0)
            P = self._normal_impulse(G, target)
            dv = minv @ J.T @ P
            if e_k == 0.0 or _energy_change(P, vn[touch], J @ dv) <= 0.0:
                if tried:
                    log.debug("impact: %s; frictionless e=%g used", ", ".join(tried), e_k)
                self.bounced = e_k > 0.0
                blocks = np.zeros((len(touch), 3))
                blocks[:, 2] = P
                self.impact_rows = (touch, blocks)
                return np.asarray(v + dv, dtype=np.float64)
            tried.append(f"frictionless e={e_k:g} (gains energy)")
        return v  # not reached: the inelastic candidate is always taken

    @staticmethod
    def _normal_impulse(G: FloatArray, target: FloatArray) -> FloatArray:
        """The normal impulses of a frictionless impact: LCP(G, target), residual checked.

        Compiled Lemke first, as the projection (:func:`_psd_lcp`): the velocity change
        M^-1 J^T P is the same for every solution of this symmetric positive semi-definite
        problem (only its rounding depends on the solver).
        """
        P = _psd_lcp(G, target)
        res = lcp_residual(G, target, P)
        if res > RESIDUAL_TOL:
            log.warning("impact LCP residual %.3g", res)
        return P


def _impact_cones(
    model: Any,
    data: Any,
    J3: FloatArray,
    minv: FloatArray,
    G3: FloatArray,
    g3: FloatArray,
    mus: FloatArray,
) -> tuple[FloatArray, float]:
    """The frictional impact's impulses: the compiled conic solver first, else Pinocchio's.

    The windows' low-rank ADMM (:func:`packbot.contact.conic.solve_conic`) on the factor
    A = J3 C of G3 = J3 M^-1 J3^T (C C^T = M^-1, Cholesky), to a true residual of
    :data:`IMPACT_CONIC_TOL` within :data:`IMPACT_ADMM_ITERATIONS`; where its answer is above
    :data:`IMPACT_ADMM_ACCEPT`, or M^-1 has no Cholesky factor (singular: the hand-off's locked
    joints, where the extension's answer was not taken), Pinocchio's ADMM (:func:`_impact_admm`).

    Returns:
        The impulses (blocks (t1, t2, n) [N*s]) and their true residual.
    """
    from packbot.contact import conic  # (the windows' solver)

    try:
        C = np.linalg.cholesky(minv)
    except np.linalg.LinAlgError:  # a singular M^-1 (the hand-off's locked joints)
        return _impact_admm(model, data, G3, g3, mus)
    A = np.ascontiguousarray(J3 @ C)
    x, res, _, _ = conic.solve_conic(
        A, g3, np.asarray(mus, dtype=np.float64), np.zeros(0), np.zeros(len(g3)),
        IMPACT_CONIC_TOL, IMPACT_ADMM_ITERATIONS,
    )  # fmt: skip
    if res <= IMPACT_ADMM_ACCEPT:
        return np.asarray(x, dtype=np.float64), float(res)
    return _impact_admm(model, data, G3, g3, mus)


def _impact_admm(
    model: Any, data: Any, G3: FloatArray, g3: FloatArray, mus: FloatArray
) -> tuple[FloatArray, float]:
    """The frictional impact's impulses on Pinocchio's ADMM (:func:`_impact_cones`' fallback).

    :func:`solve_ncp_admm` stopped at :data:`IMPACT_ADMM_ITERATIONS`, and solved again to
    5,000 iterations when that answer's residual is above :data:`IMPACT_ADMM_ACCEPT`. (The
    ADMM's residual is not monotone in its iterations: the longer run is not always better.)

    Returns:
        The impulses (blocks (t1, t2, n) [N*s]) and their true residual.
    """
    x, res = solve_ncp_admm(model, data, G3, g3, mus, max_iterations=IMPACT_ADMM_ITERATIONS)
    if res > IMPACT_ADMM_ACCEPT:
        x, res = solve_ncp_admm(model, data, G3, g3, mus, max_iterations=5000)
    return x, res


def _energy_change(P: FloatArray, w: FloatArray, dw: FloatArray) -> float:
    """Kinetic energy change [J] of an impulse: P . w + P . dw / 2.

    P: the impulses on some rows J (generalized impulse J^T P = M dv); w = J v before; dw = J
    dv. Rounding below 1e-12 of the energy scale counts as no change.
    """
    gain = float(P @ w) + 0.5 * float(P @ dw)
    return gain - 1e-12 * (abs(float(P @ w)) + abs(float(P @ dw)))
