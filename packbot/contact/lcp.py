"""Small dense complementarity solvers for the contact-normal mode, with residual checks.

The linear complementarity problem LCP(G, q): find z >= 0 with w = G z + q >= 0 and z . w = 0.

- :func:`solve_lcp_psd`: G symmetric positive semi-definite (a Delassus matrix J M^-1 J^T,
  possibly rank-deficient: a contact patch has more rows than its body has freedoms). Written
  as a non-negative least-squares problem (G = A A^T by ``eigh``, q = A c, then
  min ||A^T z + c||, z >= 0 by ``scipy.optimize.nnls``); the Lawson-Hanson active set keeps the
  support's rows independent, so the solution is a *basic* one (its engaged rows have a
  non-singular Delassus block).
- :func:`lemke`: any matrix with a solution (P0, copositive-plus), e.g. the non-symmetric
  matrix of a problem with sliding friction; complementary pivoting (in the extension,
  ``src/native/lcp.hpp``).
- :func:`lcp_residual`: the true residual max(-min z, -min w, |z . w|), scaled; never trust a
  solver's own convergence flag.

And the frictional impact problem on Pinocchio's solver, :func:`solve_ncp_admm`: point-contact
constraint models whose cone axis (z of ``joint1_placement``) is the contact normal, a fresh
``DelassusOperatorDense`` per solve (ADMM leaves its damping inside the operator), and the
residual checked here.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import _native

__all__ = [
    "box_residual",
    "lcp_residual",
    "lemke",
    "ncp_residual",
    "solve_lcp_psd",
    "solve_mixed_admm",
    "solve_ncp_admm",
    "solve_small",
]

FloatArray = NDArray[np.float64]


def lcp_residual(G: FloatArray, q: FloatArray, z: FloatArray) -> float:
    """Residual of an LCP solution, relative to the problem's scale [-].

    Returns:
        max(-min z, -min w, |z . w| / s, 0) / s, w = G z + q, s = 1 + |q|_inf + |G z|_inf
        (``src/native/lcp.hpp``, its sums in index order).
    """
    if len(q) == 0:
        return 0.0
    return float(_native.lcp_residual(_reals(G), _reals(q), _reals(z)))


def _reals(x: Any) -> FloatArray:
    return np.ascontiguousarray(x, dtype=np.float64)


def solve_lcp_psd(G: FloatArray, q: FloatArray) -> FloatArray:
    """Solve LCP(G, q) for a symmetric positive semi-definite G by non-negative least squares.

    Exact when q lies in the range of G (always for a Delassus matrix and a velocity or
    acceleration that the constrained bodies can produce); otherwise the least-squares
    solution, which the caller's residual check catches.

    Args:
        G: Symmetric PSD matrix, shape (m, m).
        q: Vector, shape (m,).

    Returns:
        z, shape (m,), with a basic (independent) support.
    """
    m = len(q)
    if m == 0 or np.all(q >= 0.0):
        return np.zeros(m)
    w, V = np.linalg.eigh(0.5 * (G + G.T))
    keep = w > 1e-12 * max(float(w.max()), 1e-300)
    A = V[:, keep] * np.sqrt(w[keep])  # G = A A^T
    c = np.linalg.lstsq(A, q, rcond=None)[0]  # q = A c
    from scipy.optimize import nnls  # lazy: scipy.optimize costs ~65 ms of import

    z, _ = nnls(A.T, -c, maxiter=50 * m)
    return np.asarray(z, dtype=np.float64)


def lemke(
    M: FloatArray, q: FloatArray, max_iter: int = 200, tol: float = 1e-12
) -> FloatArray | None:
    """Lemke's complementary pivoting for LCP(M, q) (``src/native/lcp.hpp``).

    Args:
        M: Matrix, shape (m, m) (need not be symmetric).
        q: Vector, shape (m,).
        max_iter: Pivot limit.
        tol: Pivot tolerance.

    Returns:
        z, or None on ray termination or the pivot limit (no solution found: for a contact
        problem, a Painleve configuration).
    """
    n = len(q)
    if n == 0 or np.all(q >= 0.0):
        return np.zeros(n)
    z, ok = _native.lemke(_reals(M), _reals(q), max_iter, tol)
    return z if ok else None


def ncp_residual(G3: FloatArray, g3: FloatArray, x: FloatArray, mus: FloatArray) -> float:
    """Residual of a frictional contact problem's solution (blocks (t1, t2, n)), scaled [-].

    The maximum of the primal cone violation (|x_t| - mu x_n), the dual cone violation of the
    De Saxce-shifted velocity and the complementarity |x . v'|, over 1 + |g3| + |G3 x|.
    """
    if len(g3) == 0:
        return 0.0
    v = G3 @ x + g3
    X, V = x.reshape(-1, 3), v.reshape(-1, 3)
    xt = np.linalg.norm(X[:, :2], axis=1)
    vt = np.linalg.norm(V[:, :2], axis=1)
    vn_shift = V[:, 2] + mus * vt
    primal = np.maximum(xt - mus * X[:, 2], -X[:, 2]).max()
    dual = np.maximum(-vn_shift, 0.0).max()
    # dual cone of the mu-cone: mu |v_t| <= v_n' (after the shift): |v_t| mu <= vn_shift
    dual = max(dual, float(np.maximum(mus * vt - vn_shift, 0.0).max()) if np.any(mus) else dual)
    compl = abs(float((X[:, :2] * V[:, :2]).sum() + X[:, 2] @ vn_shift))
    scale = 1.0 + float(np.abs(g3).max()) + float(np.abs(G3 @ x).max())
    return float(max(primal, dual, compl / scale, 0.0)) / scale


def solve_ncp_admm(
    model: pin.Model,
    data: pin.Data,
    G3: FloatArray,
    g3: FloatArray,
    mus: FloatArray,
    *,
    tol: float = 1e-10,
    max_iterations: int = 5000,
) -> tuple[FloatArray, float]:
    """Frictional contact problem on Pinocchio's ADMM solver, with a fresh Delassus operator.

    The problem: x_k in the cone of friction mu_k (blocks (t1, t2, n), n the normal), v = G3 x +
    g3, the De Saxce-shifted v in the dual cone, complementary. The constraint models only
    supply the cones (their Jacobians are not used: G3 and g3 come from the caller); each is a
    ``PointContactConstraintModel`` of the universe on itself whose cone axis is z.

    Args:
        model: Any Pinocchio model (the constraint models need one).
        data: Its data.
        G3: Delassus matrix, shape (3K, 3K).
        g3: Free velocity (or acceleration), shape (3K,).
        mus: Friction coefficient per block, shape (K,).
        tol: Solver tolerance.
        max_iterations: Iteration limit.

    Returns:
        x (shape (3K,)) and its true residual (:func:`ncp_residual`).
    """
    none = np.zeros(0, dtype=np.intp)
    return solve_mixed_admm(
        model, data, G3, g3, mus, none, np.zeros(0), tol=tol, max_iterations=max_iterations
    )


def box_residual(G: FloatArray, g: FloatArray, x: FloatArray, bound: FloatArray) -> float:
    """Residual of box rows' solution, scaled by 1 + |g| + |G x| [-].

    The conditions: |x| <= bound; u = G x + g is 0 strictly inside the box, u <= 0 at +bound
    and u >= 0 at -bound (the impulse opposes the motion it cannot stop).
    """
    if len(g) == 0:
        return 0.0
    u = G @ x + g
    at_hi = x >= bound * (1.0 - 1e-9)
    at_lo = x <= -bound * (1.0 - 1e-9)
    viol = np.where(at_hi, np.maximum(u, 0.0), np.where(at_lo, np.maximum(-u, 0.0), np.abs(u)))
    over = np.maximum(np.abs(x) - bound, 0.0)
    scale = 1.0 + float(np.abs(g).max()) + float(np.abs(G @ x).max())
    return float(max(viol.max(), over.max(), 0.0)) / scale


def solve_mixed_admm(
    model: pin.Model,
    data: pin.Data,
    G: FloatArray,
    g: FloatArray,
    mus: FloatArray,
    box_joints: NDArray[np.intp],
    box_bound: FloatArray,
    *,
    tol: float = 1e-10,
    max_iterations: int = 5000,
    guess: FloatArray | None = None,
) -> tuple[FloatArray, float]:
    """Contact cones and joint friction boxes in one problem, on Pinocchio's ADMM solver.

    Rows: K blocks (t1, t2, n) of contact points (cone of friction ``mus[k]``; a cone of
    friction 0 is a unilateral row), then one row per box joint: the impulse x_j in
    [-box_bound_j, box_bound_j], its velocity u_j = 0 strictly inside, against x_j at a bound
    (a joint's Coulomb friction or brake: ``JointFrictionConstraintModel``). As in
    :func:`solve_ncp_admm`, the constraint models only supply the sets; G and g are the
    caller's.

    Args:
        model: The integrated Pinocchio model (the box rows name its joints).
        data: Its data.
        G: Delassus matrix, shape (3K + B, 3K + B).
        g: Free velocity of the rows, shape (3K + B,).
        mus: Friction coefficient per contact block, shape (K,).
        box_joints: Model joint index of each box row, shape (B,).
        box_bound: Bound of each box row, shape (B,) (> 0).
        tol: Solver tolerance.
        max_iterations: Iteration limit.
        guess: Impulses to start from, shape (3K + B,) (a warm start: the previous time
            step's answer on the same rows); None: from zero.

    Returns:
        x and its true residual (the larger of :func:`ncp_residual` on the cone rows and
        :func:`box_residual` on the box rows, each with the other rows' impulses applied).
    """
    K = len(mus)
    B = len(box_joints)
    cms = pin.StdVec_ConstraintModel()
    cds = pin.StdVec_ConstraintData()
    eye = pin.SE3.Identity()
    for mu in mus:
        cm = pin.PointContactConstraintModel(model, 0, eye, 0, eye)
        cm.setFriction(float(mu))
        gcm = pin.ConstraintModel(cm)
        cms.append(gcm)
        cds.append(gcm.createData())
    if B:
        order = np.argsort(box_joints, kind="stable")
        lb = np.zeros(model.nv)
        ub = np.zeros(model.nv)
        for j, bd in zip(box_joints.tolist(), box_bound.tolist(), strict=True):
            iv = model.idx_vs[j]
            lb[iv], ub[iv] = -bd, bd
        jf = pin.JointFrictionConstraintModel(
            model, pin.StdVec_Index([int(j) for j in box_joints[order]]), lb, ub
        )
        gcm = pin.ConstraintModel(jf)
        cms.append(gcm)
        cds.append(gcm.createData())
        # the solver's box rows follow the joints in model order: permute ours to match
        perm = np.concatenate([np.arange(3 * K), 3 * K + order])
        Gs, gs = G[np.ix_(perm, perm)], g[perm]
    else:
        perm = None
        Gs, gs = G, g
    D = pin.DelassusOperatorDense(np.ascontiguousarray(0.5 * (Gs + Gs.T)))
    solver = pin.ADMMConstraintSolver(len(gs))
    res = pin.ADMMSolverResult()
    if guess is not None and len(guess) == len(gs):
        res.resize(len(gs))
        res.setConstraintImpulseGuess(np.ascontiguousarray(guess if perm is None else guess[perm]))
    st = pin.ADMMSolverSettings()
    st.absolute_feasibility_tol = st.relative_feasibility_tol = tol
    st.absolute_complementarity_tol = st.relative_complementarity_tol = tol
    st.max_iterations = max_iterations
    solver.solve(D, np.ascontiguousarray(gs), cms, cds, st, res)
    xs = np.array(res.retrieveConstraintImpulses(), dtype=np.float64)
    x = xs if perm is None else np.empty_like(xs)
    if perm is not None:
        x[perm] = xs
    c = slice(0, 3 * K)
    gc = g[c] + G[c, 3 * K :] @ x[3 * K :]
    r = ncp_residual(G[c, c], gc, x[c], np.asarray(mus, dtype=float)) if K else 0.0
    if B:
        b = slice(3 * K, 3 * K + B)
        gb = g[b] + G[b, c] @ x[c]
        r = max(r, box_residual(G[b, b], gb, x[b], np.asarray(box_bound, dtype=float)))
    return x, r


def solve_small(G: FloatArray, r: FloatArray) -> FloatArray:
    """Solve G x = r (least squares if G is singular); up to 3 x 3 in closed form.

    The right-hand side's systems are this small most of the time (the locked joints of the
    report's law, the contact-normal mode's engaged rows), and numpy's solver costs several
    microseconds of call overhead on them. The closed forms (Cramer's rule) are used when the
    determinant is not lost to rounding (above 1e-12 of its terms' scale); otherwise numpy's
    LU solve, and least squares for an exactly singular G.
    """
    m = len(r)
    if m == 1 and G[0, 0] != 0.0:
        return r / G[0, 0]
    if m == 2:
        (a, b), (c, d) = G.tolist()
        det = a * d - b * c
        if abs(det) > 1e-12 * (abs(a * d) + abs(b * c)):
            r0, r1 = r.tolist()
            return np.array([(d * r0 - b * r1) / det, (a * r1 - c * r0) / det])
    if m == 3:
        (a, b, c), (d, e, f), (g, h, i) = G.tolist()
        c0, c1, c2 = e * i - f * h, f * g - d * i, d * h - e * g  # cofactors of row 0
        det = a * c0 + b * c1 + c * c2
        scale = abs(a * c0) + abs(b * c1) + abs(c * c2)
        if abs(det) > 1e-12 * scale:
            r0, r1, r2 = r.tolist()
            return np.array(
                [
                    (c0 * r0 + (c * h - b * i) * r1 + (b * f - c * e) * r2) / det,
                    (c1 * r0 + (a * i - c * g) * r1 + (c * d - a * f) * r2) / det,
                    (c2 * r0 + (b * g - a * h) * r1 + (a * e - b * d) * r2) / det,
                ]
            )
    try:
        return np.asarray(np.linalg.solve(G, r), dtype=np.float64)
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.lstsq(G, r, rcond=None)[0], dtype=np.float64)
