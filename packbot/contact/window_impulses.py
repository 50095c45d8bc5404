"""The impulses of the window steps the extension does not take, and the steps' warm start.

A window step (:mod:`packbot.contact.timestep`) is the extension's ``ContactRhs.window_step``
where it covers the step. It does not cover a touching row that bounces (Newton's law row by
row, with the check that the impulse adds no kinetic energy), impulses that do not converge to
:data:`RESIDUAL_OK` (Pinocchio's ADMM, the frictionless LCP of the normal rows, the primal
projection), or torques that vary over the step (a torque function, a motor lag). Those steps'
problems are assembled here in numpy (:func:`packbot.contact.conic.step_problem`) and solved
by :meth:`WindowImpulses._solve`'s chain. Every step, native or not, starts its solver from the
last accepted answer on the same rows (:meth:`WindowImpulses.guess`).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact import conic
from packbot.contact.lcp import lcp_residual, lemke, solve_lcp_psd, solve_mixed_admm

if TYPE_CHECKING:
    from packbot.config import SimConfig
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.drive import Drive
    from packbot.system import System

__all__ = [
    "CONIC_ITERATIONS",
    "CONIC_TOL",
    "RESIDUAL_OK",
    "TOUCH_GAP",
    "WindowImpulses",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: The steps' solver tolerance and iteration limit (Pinocchio's ADMM): a step's impulses need
#: no more (measured on the collapse with joint friction: median 0.4 ms a step; with 1e-10 and
#: 5,000 iterations, a few degenerate problems took 250 ms each for no visible difference).
ADMM_TOL = 1e-9
ADMM_ITERATIONS = 1000
#: The compiled solver's tolerance (the true scaled residual) and iteration limit: measured
#: in two wrist-free runs (mu 0.8, starts 4 and 5: 4,565 problems of 24 to 72 rows of rank 7
#: or 8, warm-started from the previous step's impulses and rho on the same rows): median 30
#: and 50 iterations, none left above RESIDUAL_OK; on start 5's problems 0.14 ms a solve
#: against Pinocchio's 0.87 ms. Frictionless (2,098
#: problems of start 4, mu 0): median 30 iterations, 0.04 ms a solve against 0.34 ms for the
#: LCP of the normal rows (eigh, NNLS, Lemke), the same velocities to 4e-7 at the median.
CONIC_TOL = 1e-9
CONIC_ITERATIONS = 1000
#: A solution with a larger scaled residual is not used (see :meth:`WindowImpulses._solve`);
#: the retry's iteration limit.
RESIDUAL_OK = 1e-6
ADMM_RETRY_ITERATIONS = 4000
#: Touching rows (gap below this [m]) approaching faster than the Zeno speed get restitution.
TOUCH_GAP = 1e-5


class WindowImpulses:
    """The Python problem and solvers of a window's steps, and their shared warm start.

    Args:
        system: The phase's integrated system (model, M^-1, mass matrix).
        drive: The run's torques (the joints' Coulomb friction and brake bounds).
        contacts: The window's contact set.
        config: Simulation settings (restitution, zeno_speed).
    """

    def __init__(
        self, system: System, drive: Drive, contacts: NormalContacts, config: SimConfig
    ) -> None:
        self.sys, self.drive, self.contacts, self.cfg = system, drive, contacts, config
        self.joint_of = contacts._joint_of  # model joint of each velocity index
        #: Steps whose combined problem fell back to the frictionless normal rows.
        self.fallbacks = 0
        #: Problems the compiled solver left above RESIDUAL_OK (Pinocchio's ADMM then).
        self.conic_fallbacks = 0
        # the last accepted answer, its rows' key and the compiled ADMM's last rho (0: its
        # spectral rule): the next step's warm start on the same rows
        self._rows: tuple[Any, ...] | None = None
        self._x: FloatArray | None = None
        self._rho = 0.0

    def guess(self, rows: tuple[Any, ...]) -> tuple[FloatArray | None, float]:
        """The warm start of a problem on ``rows``: the last accepted impulses and rho there.

        ``rows``: the layout's key and the boxes' count; (None, 0) on other rows.
        """
        if rows == self._rows:
            return self._x, self._rho
        return None, 0.0

    def keep(self, rows: tuple[Any, ...], x: FloatArray, rho: float) -> None:
        """An accepted answer on ``rows``, and its solver's rho (0: not the compiled one's)."""
        self._rows, self._x, self._rho = rows, x, rho

    def solve(
        self, q: FloatArray, v: FloatArray, v_f: FloatArray, h: float, lay: Any
    ) -> tuple[FloatArray, FloatArray, float, NDArray[np.intp], int]:
        """The impulses of a step from (q, v) over h, its free velocity v_f given.

        The contact set is updated for the step; ``lay`` is the stepper's layout of it.

        Returns:
            v1 [rad/s], the impulses x (blocks t1, t2, n per contact row, then the joint
            boxes) [N*s, N*m*s], the residual of the solution used, the velocity indices of
            the joint boxes and the contact rows' count.
        """
        sys, cfg, contacts = self.sys, self.cfg, self.contacts
        minv = sys.minv(q)
        raw = contacts.rows_raw(q, v)
        Jn, gap, vn = raw[0], raw[2], raw[3]
        m = len(gap)
        coul = self.drive.path.coulomb
        cj = np.flatnonzero(coul > 0.0)
        # the rows (blocks t1, t2, n; the boxes), G = A A^T with A = J C, C C^T = M^-1 (the
        # compiled solver works on the factor; G itself is formed only where a fallback or
        # the restitution check needs it), u_f = J v_f and the gaps' terms, in one call
        J, A, gf, g, mus = conic.step_problem(
            Jn, raw[9], raw[10], lay.rows, lay.row_pair, cj, minv, v_f, gap, h, contacts.mu
        )
        x = np.zeros(len(J))
        residual = 0.0
        if len(J):
            bounce = (gap <= TOUCH_GAP) & (vn < -cfg.zeno_speed) if cfg.restitution > 0.0 else None
            if bounce is not None and bool(bounce.any()):
                # Newton's law row by row over a patch can add energy (as at an event): the
                # impulse's kinetic energy change x . J v_f + x . G x / 2 is checked, and an
                # impulse that gains is replaced by the inelastic one (which cannot, up to its
                # residual: with e = 0 every row's x . u = 0 and b >= 0).
                G = A @ A.T
                gb = g.copy()
                gb[2 : 3 * m : 3] += np.where(bounce, cfg.restitution * np.minimum(vn, 0.0), 0.0)
                x, residual = self._solve(A, G, gb, mus, cj, h * coul[cj], m, lay.key)
                if float(x @ gf) + 0.5 * float(x @ (G @ x)) > 0.0:
                    x, residual = self._solve(A, G, g, mus, cj, h * coul[cj], m, lay.key)
            else:
                x, residual = self._solve(A, None, g, mus, cj, h * coul[cj], m, lay.key)
        v1 = v_f + minv @ (J.T @ x) if len(J) else v_f
        if residual > RESIDUAL_OK:  # no dual solution to trust: the primal problem instead
            v1 = self._project(v_f, Jn, np.maximum(gap, 0.0) / h, sys.mass_matrix(q))
        return v1, x, residual, cj, m

    def _solve(
        self,
        A: FloatArray,
        G: FloatArray | None,
        g: FloatArray,
        mus: FloatArray,
        cj: NDArray[np.intp],
        bound: FloatArray,
        m: int,
        rows: tuple[Any, ...],
    ) -> tuple[FloatArray, float]:
        """The step's impulses: the combined problem, with a fallback that cannot misbehave.

        First the compiled low-rank ADMM (:func:`packbot.contact.conic.solve_conic`, on the
        factor A of G = A A^T, to a true residual of :data:`CONIC_TOL`, from the previous
        step's impulses and rho on the same rows). If its residual is above
        :data:`RESIDUAL_OK`: frictionless without joint boxes (mu = 0), the LCP of the normal
        rows (NNLS, then Lemke; Pinocchio's ADMM on cones of friction 0 converged slowly:
        28 ms a step against 0.5); otherwise Pinocchio's ADMM at :data:`ADMM_TOL`, then again
        with
        :data:`ADMM_RETRY_ITERATIONS` at a tighter tolerance; if still above, the
        frictionless problem of the normal rows alone (an LCP on their Delassus block, solved
        exactly by :func:`~packbot.contact.lcp.solve_lcp_psd`; friction and the joints' boxes
        left out of that step, which can only drop dissipation). An unconverged ADMM answer
        is not used: measured once on a frictionless start with the wrist free (27 rows of
        three nearly parallel patches), a residual of 5e-3 turned 11 rad/s into 30 rad/s.

        G (m x m, A A^T) is formed here only if a fallback needs it (None: not yet formed);
        ``rows`` is the step's rows' key (:meth:`_PairLayout.key`, the warm start's condition).

        Returns:
            The impulses and the residual of the solution used.
        """
        sys = self.sys
        joints = self.joint_of[cj]
        rows = (rows, len(cj))
        guess, rho0 = self.guess(rows)
        x, res, _, rho = conic.solve_conic(
            A, g, np.asarray(mus, dtype=np.float64), np.asarray(bound, dtype=np.float64),
            np.zeros(len(g)) if guess is None else guess, CONIC_TOL, CONIC_ITERATIONS,
            rho0,
        )  # fmt: skip
        if res <= RESIDUAL_OK:
            self.keep(rows, x, rho)
            return x, res
        self.conic_fallbacks += 1
        G = A @ A.T if G is None else G
        if not len(cj) and not np.any(mus):  # frictionless, no joint boxes: an LCP
            return self._frictionless(G, g, m)
        x, res = solve_mixed_admm(
            sys.model, sys.data, G, g, mus, joints, bound,
            tol=ADMM_TOL, max_iterations=ADMM_ITERATIONS, guess=guess,
        )  # fmt: skip
        if res <= RESIDUAL_OK:
            self.keep(rows, x, 0.0)
            return x, res
        x2, res2 = solve_mixed_admm(
            sys.model, sys.data, G, g, mus, joints, bound,
            tol=0.1 * ADMM_TOL, max_iterations=ADMM_RETRY_ITERATIONS,
        )  # fmt: skip
        if res2 <= RESIDUAL_OK:
            self.keep(rows, x2, 0.0)
            return x2, res2
        self.fallbacks += 1
        log.debug("window step: ADMM residual %.3g; frictionless normal rows used", res2)
        return self._frictionless(G, g, m)

    @staticmethod
    def _frictionless(G: FloatArray, g: FloatArray, m: int) -> tuple[FloatArray, float]:
        """Impulses on the normal rows alone: LCP(G_nn, g_n) (NNLS, then Lemke), residual."""
        rows = np.arange(2, 3 * m, 3)
        Gn, gn = G[np.ix_(rows, rows)], g[rows]
        x = np.zeros(len(g))
        z = solve_lcp_psd(Gn, gn)
        r = lcp_residual(Gn, gn, z)
        if r > RESIDUAL_OK:
            z2 = lemke(Gn, gn)
            if z2 is not None and lcp_residual(Gn, gn, z2) < r:
                z, r = z2, lcp_residual(Gn, gn, z2)
        x[rows] = z
        return x, r

    @staticmethod
    def _project(v_f: FloatArray, Jn: FloatArray, b: FloatArray, M: FloatArray) -> FloatArray:
        """The velocity nearest v_f (M-norm) that closes no gap beyond the step: J_n v + b >= 0.

        The frictionless inelastic step as a small quadratic programme in the joint
        velocities (always feasible: v = 0 satisfies it, b >= 0), for the rare step whose
        complementarity problem no solver answers (its dual, the LCP, is then degenerate).
        """
        from scipy.optimize import minimize  # lazy: scipy.optimize costs ~65 ms of import

        def cost(v: FloatArray) -> tuple[float, FloatArray]:
            d = v - v_f
            Md = M @ d
            return 0.5 * float(d @ Md), Md

        res = minimize(
            cost,
            np.zeros_like(v_f) if np.any(Jn @ v_f + b < 0.0) else v_f,
            jac=True,
            method="SLSQP",
            constraints=[{"type": "ineq", "fun": lambda v: Jn @ v + b, "jac": lambda v: Jn}],
            options={"ftol": 1e-14, "maxiter": 200},
        )
        v = np.asarray(res.x, dtype=np.float64)
        if float((Jn @ v + b).min(initial=0.0)) < -1e-9:
            log.debug("window step: the projection left a row at %.3g", (Jn @ v + b).min())
        return v
