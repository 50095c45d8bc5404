"""The time-stepping windows' complementarity problem: its rows, its solver (low-rank ADMM).

A window step (:mod:`packbot.contact.timestep`) solves one problem for the impulses x of its
rows: K contact blocks (t1, t2, n) with x_k in the Coulomb cone of friction mu_k and the De
Saxce-shifted velocity u_k + (0, 0, mu_k |u_kt|) in its dual cone, complementary; then B joint
rows with |x_j| <= bound_j (Coulomb friction or a brake: u_j = 0 strictly inside, u_j against
x_j at a bound). u = G x + g, with the Delassus matrix G = J M^-1 J^T.

A patch gives a contact several points and a step's contact set holds every pair within reach,
so a step's problem has many more rows than the arm has joints (measured on wrist-free random
starts: 24 to 72 rows of rank 8), and its Delassus matrix is G = A A^T with A = J C (m x nv,
C C^T = M^-1). Here the problem is solved by the ADMM of Pinocchio's ``ADMMConstraintSolver``
(which the windows called before: 0.65 ms a solve at the median on those problems, most of it
its iterations on the dense m x m factor) on that factor:

- x-update: (G + (p + rho) I) x = -(g + s) + rho z - y + p x, p = ``PROX`` (1e-6), solved by
  the Woodbury identity (G + c I)^-1 = (I - A (c I + A^T A)^-1 A^T) / c: an nv x nv Cholesky
  factor, so each iteration is O(m nv) flops (about 1.5 us for 63 rows) and a new rho costs
  nothing; over-relaxed by ``RELAX`` (1.5);
- z-update: the projection of x + y / rho onto the cones and boxes;
- y-update: y += rho (x - z), the scaled multiplier; at convergence -y = u + s lies in the
  dual cones. The De Saxce shift s = mu |u_t| on the normal rows is taken from the multiplier
  (-y, the shifted velocity's estimate), as Pinocchio does: taken from G z + g instead, the
  iteration diverged on most of the measured problems;
- rho: Pinocchio's spectral start p (L / p)^0.2 (L the largest eigenvalue of G), then its
  OSQP rule (rho times sqrt(primal / dual residual) when one exceeds the other tenfold) at
  every check;
- every ``CHECK_EVERY`` (10) iterations the *true* residual of z (the definition of
  :func:`packbot.contact.lcp.ncp_residual` and :func:`packbot.contact.lcp.box_residual`:
  the solver's own convergence measure is never trusted) decides the end; a residual stuck
  within :data:`STALL_OK` times the tolerance for ``STALL_CHECKS`` (10) checks ends it too
  (the constants: ``src/native/conic.hpp``).

Measured on 300 window problems of three wrist-free runs (cold starts, a true residual of
1e-9): median 90 to 130 iterations, 2 of 300 not converged within 3,000 (the caller then
calls Pinocchio's ADMM). Random problems of the same shape are harder: some need 15,000.

The answer z is always inside the cones and boxes (it is a projection). The solver and its
residual are the extension's (``src/native/conic.hpp``: :func:`solve_conic`,
:func:`conic_residual`), which the native window steps call too.

The window steps the native step does not take (a bounce, no converged impulses, torques that
vary over the step) build their problem here in numpy (the rows and the factor:
:func:`step_problem`); what a step's impulses decided is read by :func:`step_signature`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot import _native

__all__ = [
    "STALL_OK",
    "conic_residual",
    "solve_conic",
    "step_problem",
    "step_signature",
]

FloatArray = NDArray[np.float64]

#: A solve stops once its best residual has not dropped by 1 % for 10 checks in a row while it
#: is within STALL_OK times the tolerance (the rounding floor of the rows: measured on 3,558
#: window problems of 8 wrist-free starts, 139 ran to a 1,000-iteration limit with a residual
#: stuck at about 1.36e-9 against a tolerance of 1e-9, 42 % of the solver's time).
STALL_OK: float = float(_native.CONIC_STALL_OK)


def _reals(x: Any) -> FloatArray:
    return np.ascontiguousarray(x, dtype=np.float64)


def conic_residual(
    A: FloatArray, g: FloatArray, x: FloatArray, mus: FloatArray, bound: FloatArray
) -> float:
    """The true scaled residual of x, as :func:`packbot.contact.lcp.solve_mixed_admm` reports it.

    The larger of :func:`~packbot.contact.lcp.ncp_residual` on the cone rows and
    :func:`~packbot.contact.lcp.box_residual` on the box rows, each with the other rows'
    impulses applied (G = A A^T); inf when x is not finite.
    """
    return float(
        _native.conic_residual(_reals(A), _reals(g), _reals(x), _reals(mus), _reals(bound))
    )


def solve_conic(
    A: FloatArray,
    g: FloatArray,
    mus: FloatArray,
    bound: FloatArray,
    guess: FloatArray,
    tol: float,
    max_iterations: int,
    rho0: float = 0.0,
) -> tuple[FloatArray, float, int, float]:
    """Solve the window step's problem (see the module docstring) by low-rank ADMM.

    Args:
        A: (m, r) factor of the Delassus matrix, G = A A^T (m = 3K + B rows).
        g: (m,) the rows' free velocities (and gap terms).
        mus: (K,) friction coefficient of each contact block.
        bound: (B,) bound of each box row (> 0).
        guess: (m,) impulses to start from (zeros: a cold start).
        tol: Stop once the true scaled residual (:func:`conic_residual`) is at most this,
            or once it is stuck within :data:`STALL_OK` times this.
        max_iterations: Iteration limit.
        rho0: The ADMM's initial rho (a warm start: the previous step's last rho); 0: its
            spectral rule.

    Returns:
        x (m,) inside the cones and boxes, its true residual, the iterations taken and the
        last rho.
    """
    x, res, it, rho = _native.solve_conic(
        _reals(A), _reals(g), _reals(mus), _reals(bound), _reals(guess), float(tol),
        int(max_iterations), float(rho0),
    )  # fmt: skip
    return x, float(res), int(it), float(rho)


def step_signature(
    x: FloatArray, row_pair: NDArray[np.intp], pairs: int, limits: int, mu: float, band: float
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """What a window step's impulses decided, per pair and per limit.

    Args:
        x: The impulses: blocks (t1, t2, n) of the pairs' rows, then of the limits' rows
            (then the joint boxes, not read) [N*s].
        row_pair: (m_p,) the pair of each pair row.
        pairs: The pairs' count.
        limits: The limits' count.
        mu: Friction coefficient [-].
        band: An impulse above this pushes [N*s].

    Returns:
        (pairs,) pushing: the pair's normal impulses sum to more than ``band``; (pairs,)
        sliding: pushing, and the sum of its tangential impulses reaches the cone (within
        1e-6; never without friction); (limits,) pushing.
    """
    mp = len(row_pair)
    sums = np.zeros((pairs, 3))  # per pair: t1, t2, n impulses
    np.add.at(sums, row_pair, x[: 3 * mp].reshape(mp, 3))
    push = sums[:, 2] > band
    ft = np.sqrt(sums[:, 0] * sums[:, 0] + sums[:, 1] * sums[:, 1])
    slide = push & (mu > 0.0) & (ft >= mu * sums[:, 2] * (1 - 1e-6))
    lim = x[3 * mp + 2 : 3 * (mp + limits) : 3] > band
    return push, slide, np.asarray(lim)


def step_problem(
    Jn: FloatArray,
    T: FloatArray,
    dJp: FloatArray,
    rows: NDArray[np.intp],
    row_pair: NDArray[np.intp],
    boxes: NDArray[np.intp],
    minv: FloatArray,
    v_f: FloatArray,
    gap: FloatArray,
    h: float,
    mu: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """A window step's problem: its rows J, the factor A = J C of G = J M^-1 J^T, and u_f.

    Args:
        Jn: (m, nv) the contact rows' normals (the pairs' points, then the limits).
        T: (pairs, 2, 3) each pair's tangents (world).
        dJp: (points, 3, nv) J_p2 - J_p1 at every patch point and centre.
        rows: (m_p,) the patch point of each pair row.
        row_pair: (m_p,) the pair of each pair row.
        boxes: (B,) the velocity index of each joint box row.
        minv: (nv, nv) M^-1 (symmetric positive definite).
        v_f: (nv,) the free velocity [rad/s].
        gap: (m,) the rows' gaps [m or rad].
        h: The step [s].
        mu: The pairs' friction coefficient [-] (the limits': 0).

    Returns:
        J (3m + B, nv): per contact row the blocks (t1, t2, n), then the boxes' unit rows; A
        (3m + B, nv) = J C with C the lower Cholesky factor of M^-1 (G = A A^T); gf = J v_f
        (3m + B,); g = gf with max(gap, 0) / h added on the normal rows (an open gap may
        close within the step, not beyond); mus (m,) each block's friction.
    """
    m, nv = Jn.shape
    P = len(rows)
    B = len(boxes)
    J = np.zeros((3 * m + B, nv))
    if P:
        blocks = J[: 3 * P].reshape(P, 3, nv)  # (a view)
        blocks[:, :2] = np.einsum("rai,ric->rac", T[row_pair], dJp[rows])
    J[2 : 3 * m : 3] = Jn
    J[3 * m + np.arange(B), boxes] = 1.0
    mus = np.zeros(m)
    mus[:P] = mu
    A = np.ascontiguousarray(J @ np.linalg.cholesky(minv))
    gf = J @ v_f
    g = gf.copy()
    g[2 : 3 * m : 3] += np.maximum(gap, 0.0) / h
    return J, A, gf, g, mus
