"""The constrained dynamics with the modes fixed, and the mode conditions.

:meth:`ConstrainedDynamics.evaluate` solves the engaged rows' accelerations (in the
extension: :meth:`NativeRhs.evaluate <packbot.contact.native.NativeRhs.evaluate>`; numpy's
least squares where its Delassus matrix is singular); :meth:`~ConstrainedDynamics.
conditions` and :meth:`~ConstrainedDynamics.violated` give the mode conditions whose sign
changes are the events (release, impact, slip, stick, the resting arm's slip).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.lcp import solve_mixed_admm, solve_ncp_admm, solve_small
from packbot.contact.normal_eval import _Eval
from packbot.contact.normal_rows import ContactRows, _centre_velocities, _Plan, _same
from packbot.contact.normal_tolerances import (
    BAUMGARTE,
    CAPTURE_ACCEL,
    FORCE_BAND,
    POINT_TOL,
    STICK_BAND,
    STICK_SPEED,
    TOUCH_GAP,
)

__all__ = ["ConstrainedDynamics", "RestSolution"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RestSolution:
    """The frictional contact problem of a resting arm (v = 0), as the rest capture solved it.

    Attributes:
        a: The joint accelerations under its forces [rad/s^2] (below the capture bound).
        touch: The touching rows (patch points, then limits), shape (m,).
        forces: Per touching row its force (t1, t2, n) [N] in the row's contact frame (a limit
            row: n only), shape (m, 3): the solver's answer, one of the statically admissible
            distributions.
        rows: The rows' blocks (t1, t2, n per row), shape (3 m, nv): J^T of ``forces``
            (flattened) is their joint torque.
        mu: Each row's friction coefficient (0 for a limit row), shape (m,).
        torque: The rows' joint torque that holds the arm exactly still [N*m], shape (nv,):
            J^T of ``forces`` less M a (the solver leaves a within its tolerance of 0).
        friction: The joints' Coulomb friction and brake torques holding them [N*m], shape
            (nv,) (each within its bound; 0 on joints without): the problem's joint boxes.
    """

    a: FloatArray
    touch: NDArray[np.intp]
    forces: FloatArray
    rows: FloatArray
    mu: FloatArray
    torque: FloatArray
    friction: FloatArray


class ConstrainedDynamics(ContactRows):
    """The contact set's accelerations and mode conditions with the modes fixed."""

    def evaluate(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        forces: bool = False,
    ) -> _Eval:
        """Constrained accelerations with the modes fixed, and what the conditions need.

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            a_free: Unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.
            forces: Also the engaged rows' generalized force (``qc``; zero without one).
        """
        if self.resting:  # captured: at rest while the rest condition holds
            _, _, gap, vn, extra = self._problem(q, v)
            vt = _centre_velocities(extra)
            return _Eval(np.zeros(self.nv), np.zeros(0), gap, vn, vt, (q, a_free, minv))
        plan = self._plan()
        if not len(plan.engaged):
            _, _, gap, vn, extra = self._problem(q, v)
            qc = np.zeros(self.nv) if forces else None
            return _Eval(a_free, np.zeros(0), gap, vn, _centre_velocities(extra), qc=qc)
        return self._evaluate_compiled(q, v, a_free, minv, plan, forces)

    def _evaluate_rows(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray, plan: _Plan
    ) -> _Eval:
        """:meth:`evaluate` in numpy, by least squares where the Delassus matrix is singular.

        :meth:`_evaluate_compiled`'s fallback, where the extension's solve finds it singular.
        """
        Jn, drift, gap, vn, extra = self._problem(q, v)
        vt = _centre_velocities(extra)
        E = plan.engaged
        A = Jn[E]  # the engaged rows, then the sticking pairs' tangential rows
        Cm = A  # their force columns (J_n - mu J_s on slipping pairs' rows)
        if plan.slips:
            Cm = A.copy()
            for i, pos, loc in plan.slips:
                ex = extra[i]
                s = self.slip_directions(self._pair_list[i], ex)[loc]
                Cm[pos] -= self.mu * np.einsum("...i,...ic->...c", s, ex["dJ"][loc])
        target = -2.0 * BAUMGARTE * vn[E] - BAUMGARTE**2 * gap[E]
        b = drift[E]
        if len(plan.sticks):
            JT = [extra[i]["JT"] for i in plan.sticks]
            A = np.vstack([A, *JT])
            Cm = np.vstack([Cm, *JT])
            vT = np.concatenate([extra[i]["vT"] for i in plan.sticks])
            target = np.concatenate([target, -BAUMGARTE * vT])
            b = np.concatenate([b, *(extra[i]["bT"] for i in plan.sticks)])
        b = A @ a_free + b
        MC = minv @ Cm.T
        Gm = A @ MC
        lam = solve_small(Gm, target - b)
        return _Eval(a_free + MC @ lam, lam, gap, vn, vt, qc=Cm.T @ lam)

    def _evaluate_compiled(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        plan: _Plan,
        forces: bool = False,
    ) -> _Eval:
        """:meth:`evaluate` in one call of the extension.

        :meth:`NativeRhs.evaluate <packbot.contact.native.NativeRhs.evaluate>`.
        """
        if plan.slips:
            slip_dir = np.array([p.slip_dir for p in self._pair_list])
        else:
            slip_dir = self._no_slip_dirs
        ev = self._rows_rhs().evaluate(self, plan, q, v, a_free, minv, forces)  # type: ignore[arg-type]
        if ev is None:  # a singular Delassus matrix: numpy's path (least squares)
            return self._evaluate_rows(q, v, a_free, minv, plan)
        # Kept for the same state asked again (the step's end: the stepper's last stage, then
        # the mode conditions and the sliding check): references, compared by value.
        self._last_eval = (q, v, a_free, minv, slip_dir, self._plan_key, ev)
        return ev

    def evaluate_again(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> _Eval:
        """:meth:`evaluate`, reusing the last compiled evaluation when it was at these inputs.

        The mode conditions at a step's end ask for the state of the stepper's last stage,
        which the right-hand side has just evaluated (same q, v, free accelerations, M^-1,
        modes and sliding directions: compared by value, so the result is the one
        :meth:`evaluate` would compute).
        """
        last = self._last_eval
        if last is not None and not self.resting and type(self).evaluate is _OWN_EVALUATE:
            plan = self._plan()  # (brings _plan_key up to the current modes)
            if (
                last[5] == self._plan_key
                and _same(last[0], q)
                and _same(last[1], v)
                and _same(last[2], a_free)
                and _same(last[3], minv)
                and (
                    not plan.slips
                    or _same(last[4], np.array([p.slip_dir for p in self._pair_list]))
                )
            ):
                return last[6]
        return self.evaluate(q, v, a_free, minv)

    def conditions(self, ev: _Eval) -> dict[tuple[Any, ...], tuple[str, float]]:
        """Mode conditions g >= 0 (a negative one is an event) with the event kind.

        Keys: ``("nrow", i)`` (engaged: release; free: impact), ``("nfric", k)`` (stick: slip;
        slip: stick).
        """
        out: dict[tuple[Any, ...], tuple[str, float]] = {}
        if ev.rest is not None:
            a = self._rest_accel(*ev.rest)
            margin = -1.0 if a is None else 2.0 * CAPTURE_ACCEL - float(np.abs(a).max())
            return {("nrest", 0): ("slip", margin)}
        E = self.engaged
        pos = {r: i for i, r in enumerate(E)}
        for r in range(len(ev.gap)):
            if r in pos:
                out[("nrow", r)] = ("release", float(ev.lam[pos[r]]) + FORCE_BAND)
            else:
                out[("nrow", r)] = ("impact", float(ev.gap[r]) + POINT_TOL)
        if self.mu > 0.0:
            k_row, k_t = 0, len(E)
            for (key, p), vt in zip(self.pairs.items(), ev.vt, strict=True):
                K = len(p.local1)
                rows = [pos[r] for r in range(k_row, k_row + K) if r in pos]
                k_row += K
                if not rows:
                    continue
                if p.stick:
                    lt = ev.lam[k_t : k_t + 2]
                    k_t += 2
                    g = self.mu * float(ev.lam[rows].sum()) - float(np.linalg.norm(lt))
                    out[("nfric", key)] = ("slip", g + FORCE_BAND)
                else:
                    # v_t along the friction direction (blended with the onset direction):
                    # negative once the slide has come back through zero.
                    w = vt + STICK_SPEED * p.slip_dir
                    g = float(vt @ w) / max(float(np.linalg.norm(w)), 1e-300)
                    out[("nfric", key)] = ("stick", g + STICK_BAND)
        return out

    def condition(self, ev: _Eval, key: tuple[Any, ...]) -> float:
        """The value of one mode condition of :meth:`conditions` (the same float).

        An event function on the step's dense output asks for one condition at each point;
        a row's (``("nrow", r)``) is read without building the dictionary of all of them.
        """
        if key[0] == "nrow" and ev.rest is None and type(self).conditions is _OWN_CONDITIONS:
            r = key[1]
            E = self.engaged
            if r in E:
                return float(ev.lam[E.index(r)]) + FORCE_BAND
            return float(ev.gap[r]) + POINT_TOL
        return self.conditions(ev)[key][1]

    def rows_conditions_own(self) -> bool:
        """Whether a row's condition is the row's own force or gap (:meth:`condition`'s rule).

        True unless a subclass redefines :meth:`conditions`; the native root finding of a
        row's event (:meth:`NativeWatch.row_condition_at
        <packbot.contact.native.NativeWatch.row_condition_at>`) computes that rule.
        """
        return type(self).conditions is _OWN_CONDITIONS

    def violated(self, ev: _Eval) -> bool:
        """Whether a mode condition of :meth:`conditions` is negative (an event).

        The same values as :meth:`conditions`, without building its dictionary (the step's
        end asks this once per step; the conditions themselves only when one is negative).
        """
        if ev.rest is not None or type(self).conditions is not _OWN_CONDITIONS:
            return any(g < 0.0 for _, g in self.conditions(ev).values())
        if ev.cond is not None:  # the extension's smallest condition
            return ev.cond < 0.0
        plan = self._plan()
        E = plan.engaged
        ne = len(E)
        if len(ev.gap):
            g = ev.gap + POINT_TOL
            if ne:
                g[E] = ev.lam[:ne] + FORCE_BAND
            if bool((g < 0.0).any()):
                return True
        if self.mu > 0.0:
            k_t = ne
            for at in plan.stick_at:
                lt = ev.lam[k_t : k_t + 2]
                k_t += 2
                gs = self.mu * float(ev.lam[at].sum()) - float(np.linalg.norm(lt))
                if gs + FORCE_BAND < 0.0:
                    return True
            pairs = self._pair_list
            for i, _, _ in plan.slips:
                vt = ev.vt[i]
                w = vt + STICK_SPEED * pairs[i].slip_dir
                gs = float(vt @ w) / max(float(np.linalg.norm(w)), 1e-300)
                if gs + STICK_BAND < 0.0:
                    return True
        return False

    def _rest_accel(self, q: FloatArray, a_free: FloatArray, minv: FloatArray) -> FloatArray | None:
        """Joint accelerations at v = 0 under the frictional contact of every touching row.

        None when no row touches or the cone problem is not solved (:meth:`rest_solution`).
        """
        sol = self.rest_solution(q, a_free, minv)
        return None if sol is None else sol.a.copy()

    def rest_solution(
        self, q: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> RestSolution | None:
        """The frictional contact problem at v = 0 (:class:`RestSolution`), or None.

        None when no row touches or the cone problem is not solved. A resting arm's state does
        not move: the step ends' rest condition asks this again with the same q, a_free and
        M^-1, whose answer (a cone problem solved from scratch: a function of its inputs) is
        kept while the contact set and the joints' Coulomb friction are unchanged too. The
        arrays returned are the kept ones (read only).
        """
        coul, fdir = self.joint_coulomb, self.joint_fdir
        key = (
            self._version,
            self.mu,
            q.tobytes(),
            a_free.tobytes(),
            minv.tobytes(),
            None if coul is None else coul.tobytes(),
            None if fdir is None else fdir.tobytes(),
            self._row_mode,
        )
        got = self._rest_cache
        if got is not None and got[0] == key:
            return got[1]
        sol = self._rest_solve(q, a_free, minv)
        self._rest_cache = (key, sol)
        return sol

    def _rest_accel_solve(
        self, q: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> FloatArray | None:
        """:meth:`_rest_accel`, solved from scratch (the kept answer not used)."""
        sol = self._rest_solve(q, a_free, minv)
        return None if sol is None else sol.a.copy()

    def _rest_solve(
        self, q: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> RestSolution | None:
        """:meth:`rest_solution`, solved."""
        z = np.zeros(self.nv)
        Jn, _, gap, _, extra = self._problem(q, z)
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        if len(touch) == 0:
            return None
        J3, mus = self._frictional_rows(touch, Jn, extra)
        m3 = len(J3)
        coul = self.joint_coulomb
        cj = np.flatnonzero(coul > 0.0) if coul is not None else np.zeros(0, dtype=np.intp)
        if len(cj):
            # the joints' Coulomb friction and brakes hold too: boxes |tau_j| <= F_j, with
            # the sliding torque -F_j s_j the free accelerations carry taken out
            assert coul is not None and self.joint_fdir is not None
            a_free = a_free + minv @ (coul * self.joint_fdir)
            J = np.vstack([J3, np.eye(self.nv)[cj]])
            x, res = solve_mixed_admm(
                self.model, self.data, J @ minv @ J.T, J @ a_free, mus, self._joint_of[cj], coul[cj]
            )
            J3 = J
            friction = np.zeros(self.nv)
            friction[cj] = x[len(x) - len(cj) :]
        else:
            friction = np.zeros(self.nv)
            G3 = J3 @ minv @ J3.T
            x, res = solve_ncp_admm(self.model, self.data, G3, J3 @ a_free, mus)
        if res > 1e-6:
            return None
        a = np.asarray(a_free + minv @ J3.T @ x, dtype=np.float64)
        forces = np.asarray(x[:m3], dtype=np.float64).reshape(-1, 3)
        rows = np.asarray(J3[:m3], dtype=np.float64)
        if not bool(np.all(np.diag(minv) > 0.0)):  # the hand-off's locked subspace's M^-1_c
            M = pin.crba(self.model, self.data, q)
            Ma = (np.triu(M) + np.triu(M, 1).T) @ a
        else:
            Ma = np.linalg.solve(minv, a)
        torque = rows.T @ forces.ravel() - Ma
        for arr in (a, touch, forces, rows, mus, torque, friction):
            arr.setflags(write=False)
        return RestSolution(a, touch, forces, rows, mus, torque, friction)


_OWN_EVALUATE = ConstrainedDynamics.evaluate
_OWN_CONDITIONS = ConstrainedDynamics.conditions
_OWN_VIOLATED = ConstrainedDynamics.violated
