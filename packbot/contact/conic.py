"""Compiled solver of the time-stepping windows' complementarity problem (low-rank ADMM).

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

- x-update: (G + (p + rho) I) x = -(g + s) + rho z - y + p x, p = :data:`PROX`, solved by
  the Woodbury identity (G + c I)^-1 = (I - A (c I + A^T A)^-1 A^T) / c: an nv x nv Cholesky
  factor, so each iteration is O(m nv) flops (about 1.5 us for 63 rows) and a new rho costs
  nothing; over-relaxed by :data:`RELAX`;
- z-update: the projection of x + y / rho onto the cones and boxes;
- y-update: y += rho (x - z), the scaled multiplier; at convergence -y = u + s lies in the
  dual cones. The De Saxce shift s = mu |u_t| on the normal rows is taken from the multiplier
  (-y, the shifted velocity's estimate), as Pinocchio does: taken from G z + g instead, the
  iteration diverged on most of the measured problems;
- rho: Pinocchio's spectral start p (L / p)^0.2 (L the largest eigenvalue of G), then its
  OSQP rule (rho times sqrt(primal / dual residual) when one exceeds the other tenfold) at
  every check;
- every :data:`CHECK_EVERY` iterations the *true* residual of z (the definition of
  :func:`packbot.contact.lcp.ncp_residual` and :func:`packbot.contact.lcp.box_residual`:
  the solver's own convergence measure is never trusted) decides the end; a residual stuck
  within :data:`STALL_OK` times the tolerance for :data:`STALL_CHECKS` checks ends it too.

Measured on 300 window problems of three wrist-free runs (cold starts, a true residual of
1e-9): median 90 to 130 iterations, 2 of 300 not converged within 3,000 (the caller then
calls Pinocchio's ADMM). Random problems of the same shape are harder: some need 15,000.

The answer z is always inside the cones and boxes (it is a projection). Compiled with numba
(``@njit(cache=True)``, cached beside this file), imported by a window's first stepper only.

The window step's other small dense algebra is compiled here too, each piece one call instead
of a numpy call per pair or per row: the problem's rows and factor (:func:`step_problem`), the
patch rule over every pair at once (:func:`stale_pairs`) and what the impulses decided
(:func:`step_signature`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "CHECK_EVERY",
    "conic_residual",
    "solve_conic",
    "stale_pairs",
    "step_problem",
    "step_signature",
]

#: The true residual is evaluated (and rho adapted) every this many iterations.
CHECK_EVERY = 10
#: The proximal term of the x-update (Pinocchio's ``mu_prox``) [-].
PROX = 1e-6
#: The initial rho's power (Pinocchio's spectral rule: PROX (L / PROX)^RHO_POWER).
RHO_POWER = 0.2
#: rho adapts when one residual exceeds the other by this factor.
RATIO = 10.0
#: rho's range, relative to G's largest eigenvalue.
RHO_MIN = 1e-9
RHO_MAX = 1e3
#: Power iterations for G's largest eigenvalue.
POWER_ITERATIONS = 20
#: Over-relaxation of the x-update.
RELAX = 1.5
#: A solve stops once its best residual has not dropped below STALL_GAIN times itself for
#: STALL_CHECKS checks in a row while it is within STALL_OK times the tolerance: measured on
#: 3,558 window problems of 8 wrist-free starts (mu 0.5), 139 ran to the 1,000-iteration limit
#: with a residual stuck at about 1.36e-9 against a tolerance of 1e-9 (its rounding floor on
#: those rows), 42 % of the solver's time (with STALL_OK = 2: 40 % fewer iterations in all, the
#: same answers but for the 64 stuck ones).
STALL_CHECKS = 10
STALL_GAIN = 0.99
STALL_OK = 2.0


@njit(cache=True)
def _factor(AtA: Any, rho: float) -> Any:  # pragma: no cover - compiled
    """Lower Cholesky factor of rho I + A^T A (r x r, positive definite for rho > 0)."""
    r = AtA.shape[0]
    L = np.zeros((r, r))
    for i in range(r):
        for j in range(i + 1):
            s = AtA[i, j] + (rho if i == j else 0.0)
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = math.sqrt(max(s, 1e-300))
            else:
                L[i, j] = s / L[j, j]
    return L


@njit(cache=True)
def _transposed_apply(A: Any, b: Any, w: Any) -> None:  # pragma: no cover - compiled
    """The product A^T b into w."""
    m, r = A.shape
    for k in range(r):
        s = 0.0
        for i in range(m):
            s += A[i, k] * b[i]
        w[k] = s


@njit(cache=True)
def _inverse_apply(  # pragma: no cover - compiled
    A: Any, L: Any, rho: float, b: Any, out: Any, w: Any
) -> None:
    """The product (A A^T + rho I)^-1 b into out, by the Woodbury identity (L: rho I + A^T A).

    w: a work vector of A's column count (overwritten).
    """
    m, r = A.shape
    _transposed_apply(A, b, w)
    # (rho I + A^T A)^-1 w: forward then backward substitution
    for i in range(r):
        s = w[i]
        for k in range(i):
            s -= L[i, k] * w[k]
        w[i] = s / L[i, i]
    for i in range(r - 1, -1, -1):
        s = w[i]
        for k in range(i + 1, r):
            s -= L[k, i] * w[k]
        w[i] = s / L[i, i]
    for i in range(m):
        s = b[i]
        for k in range(r):
            s -= A[i, k] * w[k]
        out[i] = s / rho


@njit(cache=True)
def _velocity(A: Any, x: Any, g: Any, out: Any, w: Any) -> None:  # pragma: no cover - compiled
    """The rows' velocities u = G x + g = A A^T x + g, into out (w: a work vector, as above)."""
    m, r = A.shape
    _transposed_apply(A, x, w)
    for i in range(m):
        s = g[i]
        for k in range(r):
            s += A[i, k] * w[k]
        out[i] = s


@njit(cache=True)
def _project(x: Any, mus: Any, bound: Any) -> None:  # pragma: no cover - compiled
    """Project x in place onto the cones (blocks t1, t2, n) and then the boxes."""
    K = mus.shape[0]
    for k in range(K):
        mu = mus[k]
        a, b, n = x[3 * k], x[3 * k + 1], x[3 * k + 2]
        t = math.sqrt(a * a + b * b)
        if n >= 0.0 and t <= mu * n:  # inside
            continue
        if mu * t <= -n:  # in the polar cone (t = 0 < n was inside)
            x[3 * k] = 0.0
            x[3 * k + 1] = 0.0
            x[3 * k + 2] = 0.0
            continue
        al = (mu * t + n) / (mu * mu + 1.0)
        f = mu * al / t
        x[3 * k] = a * f
        x[3 * k + 1] = b * f
        x[3 * k + 2] = al
    for j in range(bound.shape[0]):
        i = 3 * K + j
        bd = bound[j]
        if x[i] > bd:
            x[i] = bd
        elif x[i] < -bd:
            x[i] = -bd


@njit(cache=True)
def conic_residual(A: Any, g: Any, x: Any, mus: Any, bound: Any) -> float:  # pragma: no cover
    """The true scaled residual of x, as :func:`packbot.contact.lcp.solve_mixed_admm` reports it.

    The larger of :func:`~packbot.contact.lcp.ncp_residual` on the cone rows and
    :func:`~packbot.contact.lcp.box_residual` on the box rows, each with the other rows'
    impulses applied (G = A A^T).
    """
    m, r = A.shape
    K = mus.shape[0]
    c = 3 * K
    for i in range(m):
        if not math.isfinite(x[i]):
            return math.inf
    wc = np.zeros(r)  # A_c^T x_c
    wb = np.zeros(r)  # A_b^T x_b
    for k in range(r):
        s = 0.0
        for i in range(c):
            s += A[i, k] * x[i]
        wc[k] = s
        s = 0.0
        for i in range(c, m):
            s += A[i, k] * x[i]
        wb[k] = s
    res = 0.0
    if K:
        g3max = 0.0
        G3xmax = 0.0
        V = np.empty(c)
        for i in range(c):
            sc = 0.0
            sb = 0.0
            for k in range(r):
                sc += A[i, k] * wc[k]
                sb += A[i, k] * wb[k]
            gc = g[i] + sb
            V[i] = sc + gc
            g3max = max(g3max, abs(gc))
            G3xmax = max(G3xmax, abs(sc))
        scale = 1.0 + g3max + G3xmax
        primal = -math.inf
        dual = 0.0
        compl = 0.0
        anymu = False
        for k in range(K):
            mu = mus[k]
            if mu != 0.0:
                anymu = True
        for k in range(K):
            mu = mus[k]
            x1, x2, xn = x[3 * k], x[3 * k + 1], x[3 * k + 2]
            v1, v2, vn = V[3 * k], V[3 * k + 1], V[3 * k + 2]
            xt = math.sqrt(x1 * x1 + x2 * x2)
            vt = math.sqrt(v1 * v1 + v2 * v2)
            vs = vn + mu * vt
            primal = max(primal, max(xt - mu * xn, -xn))
            dual = max(dual, -vs)
            if anymu:
                dual = max(dual, mu * vt - vs)
            compl += x1 * v1 + x2 * v2 + xn * vs
        res = max(primal, dual, abs(compl) / scale, 0.0) / scale
    B = m - c
    if B:
        gmax = 0.0
        Gxmax = 0.0
        worst = 0.0
        for j in range(B):
            i = c + j
            sc = 0.0
            sb = 0.0
            for k in range(r):
                sc += A[i, k] * wc[k]
                sb += A[i, k] * wb[k]
            gb = g[i] + sc
            u = sb + gb
            gmax = max(gmax, abs(gb))
            Gxmax = max(Gxmax, abs(sb))
            bd = bound[j]
            if x[i] >= bd * (1.0 - 1e-9):
                viol = max(u, 0.0)
            elif x[i] <= -bd * (1.0 - 1e-9):
                viol = max(-u, 0.0)
            else:
                viol = abs(u)
            worst = max(worst, viol, abs(x[i]) - bd)
        res = max(res, worst / (1.0 + gmax + Gxmax))
    return res


@njit(cache=True)
def solve_conic(  # pragma: no cover - compiled
    A: Any,
    g: Any,
    mus: Any,
    bound: Any,
    guess: Any,
    tol: float,
    max_iterations: int,
    rho0: float = 0.0,
) -> Any:
    """Solve the window step's problem (see the module docstring) by low-rank ADMM.

    Args:
        A: (m, r) factor of the Delassus matrix, G = A A^T (m = 3K + B rows).
        g: (m,) the rows' free velocities (and gap terms).
        mus: (K,) friction coefficient of each contact block.
        bound: (B,) bound of each box row (> 0).
        guess: (m,) impulses to start from (zeros: a cold start).
        tol: Stop once the true scaled residual (:func:`conic_residual`) is at most this,
            or once it is stuck within :data:`STALL_OK` times this (:data:`STALL_CHECKS`).
        max_iterations: Iteration limit.
        rho0: The ADMM's initial rho (a warm start: the previous step's last rho); 0: its
            spectral rule.

    Returns:
        x (m,) inside the cones and boxes, its true residual, the iterations taken and the
        last rho.
    """
    m, r = A.shape
    K = mus.shape[0]
    z = guess.copy()
    _project(z, mus, bound)
    best = z.copy()
    best_res = conic_residual(A, g, z, mus, bound)
    if best_res <= tol and rho0 > 0.0:  # a warm start already converged: nothing to set up
        return best, best_res, 0, rho0
    AtA = np.zeros((r, r))
    for a in range(r):
        for b in range(a + 1):
            sacc = 0.0
            for i in range(m):
                sacc += A[i, a] * A[i, b]
            AtA[a, b] = sacc
            AtA[b, a] = sacc
    # the largest eigenvalue of G (that of A^T A), by power iteration
    w = np.ones(r)
    lam = 0.0
    for _ in range(POWER_ITERATIONS):
        w2 = AtA @ w
        lam = math.sqrt(float(w2 @ w2))
        if lam <= 0.0:
            break
        w = w2 / lam
    lam = max(lam, 1e-300)
    # the spectral rule of the initial rho (Pinocchio's ADMM: mu_prox (L / mu_prox)^0.2)
    rho = PROX * (lam / PROX) ** RHO_POWER if rho0 <= 0.0 else rho0
    if best_res <= tol:
        return best, best_res, 0, rho
    L = _factor(AtA, PROX + rho)
    u = np.empty(m)
    work = np.empty(r)  # A^T times a vector, for the Woodbury products (no allocation a step)
    _velocity(A, z, g, u, work)
    # the multiplier of the guess: y = -(u + s), its shifted velocity negated
    y = np.empty(m)
    for i in range(m):
        y[i] = -u[i]
    for k in range(K):
        y[3 * k + 2] -= mus[k] * math.sqrt(u[3 * k] ** 2 + u[3 * k + 1] ** 2)
    x = z.copy()
    xp = np.empty(m)
    zp = np.empty(m)
    rhs = np.empty(m)
    it = 0
    stall_ref = best_res  # the best residual when it last dropped by a 1 - STALL_GAIN share
    stalled = 0  # checks since
    while it < max_iterations:
        it += 1
        for i in range(m):
            xp[i] = x[i]
            zp[i] = z[i]
        # the De Saxce shift from the multiplier (-y: the shifted velocity's estimate)
        for i in range(m):
            rhs[i] = -g[i] + rho * z[i] - y[i] + PROX * x[i]
        for k in range(K):
            rhs[3 * k + 2] -= mus[k] * math.sqrt(y[3 * k] ** 2 + y[3 * k + 1] ** 2)
        _inverse_apply(A, L, PROX + rho, rhs, x, work)
        for i in range(m):
            x[i] = RELAX * x[i] + (1.0 - RELAX) * zp[i]
            z[i] = x[i] + y[i] / rho
        _project(z, mus, bound)
        prim = 0.0
        dual = 0.0
        for i in range(m):
            d = x[i] - z[i]
            y[i] += rho * d
            prim = max(prim, abs(d))
            dual = max(dual, abs(rho * (z[i] - zp[i]) + PROX * (x[i] - xp[i])))
        if it % CHECK_EVERY == 0:
            res = conic_residual(A, g, z, mus, bound)
            if res < best_res:
                best_res = res
                for i in range(m):
                    best[i] = z[i]
            if res <= tol or not math.isfinite(res):
                break
            if best_res < STALL_GAIN * stall_ref:
                stall_ref = best_res
                stalled = 0
            else:
                stalled += 1
                if stalled >= STALL_CHECKS and best_res <= STALL_OK * tol:
                    break  # stuck just above the tolerance (its rounding floor)
            # rho from the residuals' balance (the OSQP rule of Pinocchio's ADMM)
            if (prim > RATIO * dual or dual > RATIO * prim) and prim > 0.0 and dual > 0.0:
                rho = min(max(rho * math.sqrt(prim / dual), RHO_MIN * lam), RHO_MAX * lam)
                L = _factor(AtA, PROX + rho)
    return best, best_res, it, rho


@njit(cache=True)
def stale_pairs(  # pragma: no cover - compiled
    gap: Any,
    T: Any,
    dP: Any,
    rows: Any,
    pair: Any,
    offset0: Any,
    distance: Any,
    point_tol: float,
    slide_tol2: Any,
) -> Any:
    """Which pairs' patches no longer describe their contact (the window step's contact set).

    The rule of :meth:`packbot.contact.normal.NormalContacts.stale_pairs` on every pair at
    once, from the contact set's kinematics (:func:`packbot.contact.kernels.contact_rows`):
    a pair is stale when its smallest patch gap is off its distance by more than
    ``point_tol`` (or it has no distance: NaN), or a point slid by more than its ``slide_tol2``
    tangentially since the patch was built.

    Args:
        gap: (m,) the rows' gaps [m] (the pairs' rows first).
        T: (pairs, 2, 3) each pair's tangents (world).
        dP: (points, 3) p2 - p1 at every patch point and centre [m].
        rows: (m_p,) the patch point of each pair row.
        pair: (points,) the pair of each point.
        offset0: (m_p, 2) each pair row's tangential offset when its patch was built [m].
        distance: (pairs,) each pair's signed distance [m] (NaN: none).
        point_tol: Gap tolerance [m].
        slide_tol2: (pairs,) the square of the slide each pair goes stale at [m^2].

    Returns:
        (pairs,) True where the pair is stale.
    """
    n = T.shape[0]
    gmin = np.full(n, np.inf)
    slide2 = np.zeros(n)
    for r in range(rows.shape[0]):
        k = rows[r]
        p = pair[k]
        if gap[r] < gmin[p]:
            gmin[p] = gap[r]
        a = T[p, 0, 0] * dP[k, 0] + T[p, 0, 1] * dP[k, 1] + T[p, 0, 2] * dP[k, 2] - offset0[r, 0]
        b = T[p, 1, 0] * dP[k, 0] + T[p, 1, 1] * dP[k, 1] + T[p, 1, 2] * dP[k, 2] - offset0[r, 1]
        s2 = a * a + b * b
        if s2 > slide2[p]:
            slide2[p] = s2
    out = np.empty(n, dtype=np.bool_)
    for p in range(n):
        out[p] = not abs(gmin[p] - distance[p]) <= point_tol or slide2[p] > slide_tol2[p]
    return out


@njit(cache=True)
def step_signature(  # pragma: no cover - compiled
    x: Any, row_pair: Any, pairs: int, limits: int, mu: float, band: float
) -> Any:
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
    xn = np.zeros(pairs)
    t1 = np.zeros(pairs)
    t2 = np.zeros(pairs)
    mp = row_pair.shape[0]
    for r in range(mp):
        p = row_pair[r]
        t1[p] += x[3 * r]
        t2[p] += x[3 * r + 1]
        xn[p] += x[3 * r + 2]
    push = np.empty(pairs, dtype=np.bool_)
    slide = np.empty(pairs, dtype=np.bool_)
    for p in range(pairs):
        push[p] = xn[p] > band
        ft = math.sqrt(t1[p] * t1[p] + t2[p] * t2[p])
        slide[p] = push[p] and mu > 0.0 and ft >= mu * xn[p] * (1 - 1e-6)
    lim = np.empty(limits, dtype=np.bool_)
    for i in range(limits):
        lim[i] = x[3 * (mp + i) + 2] > band
    return push, slide, lim


@njit(cache=True)
def step_problem(  # pragma: no cover - compiled
    Jn: Any,
    T: Any,
    dJp: Any,
    rows: Any,
    row_pair: Any,
    boxes: Any,
    minv: Any,
    v_f: Any,
    gap: Any,
    h: float,
    mu: float,
) -> Any:
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
    P = rows.shape[0]
    B = boxes.shape[0]
    J = np.zeros((3 * m + B, nv))
    for r in range(P):
        k = rows[r]
        p = row_pair[r]
        for a in range(2):
            for c in range(nv):
                J[3 * r + a, c] = (
                    T[p, a, 0] * dJp[k, 0, c]
                    + T[p, a, 1] * dJp[k, 1, c]
                    + T[p, a, 2] * dJp[k, 2, c]
                )
    for r in range(m):
        for c in range(nv):
            J[3 * r + 2, c] = Jn[r, c]
    for i in range(B):
        J[3 * m + i, boxes[i]] = 1.0
    mus = np.zeros(m)
    for r in range(P):
        mus[r] = mu
    C = _factor(minv, 0.0)  # lower Cholesky factor of M^-1
    rt = 3 * m + B
    A = np.zeros((rt, nv))
    gf = np.zeros(rt)
    for i in range(rt):
        sv = 0.0
        for k in range(nv):
            Jik = J[i, k]
            if Jik != 0.0:
                sv += Jik * v_f[k]
                for c in range(k + 1):
                    A[i, c] += Jik * C[k, c]
        gf[i] = sv
    g = gf.copy()
    for r in range(m):
        g[3 * r + 2] += max(gap[r], 0.0) / h
    return J, A, gf, g, mus
