"""The contact forces of a statically indeterminate rest: the analytic centre of the admissible set.

A resting arm with more contact force components than free joints (the collapse's rest: two
points, six components, four joints) is held by a whole family of force distributions: every
x with the same joint torque J^T x in the Coulomb cones holds it (the arm's motion, a = 0, is
the same for all of them). The rest capture's solver returns one of them, often on the set's
boundary (a cone saturated: the collapse's tube at 123.1 N of its admissible 83.8-123.2 N).
Rigid bodies do not say which distribution the real arm carries; a compliant contact model
would, through its stiffnesses, and that is a modelling choice.

packbot reports the *analytic centre* of the admissible set: the distribution that maximises
sum_i log(mu_i x_n,i - |x_t,i|) (for mu_i = 0: log x_n,i) over {x : J^T x = J^T x_solver}, the
one deepest inside every cone at once. It is unique (a strictly concave objective on a convex
set), does not depend on the solver's starting point, and is invariant to the units of each
row. On the collapse's rest it gives the tube 100.8 N and the elbow casing 1.95 N (MuJoCo
100.1 N, Drake 99.0 N: docs/contact.md). Where the set has no interior (a touching point that
can carry no force in any distribution, or friction needed at its limit), the solver's answer
is kept.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["analytic_centre"]

FloatArray = NDArray[np.float64]

#: A distribution is interior when every margin exceeds this times the largest normal force.
INTERIOR = 1e-6
#: Null-space directions below this relative singular value are the rows' own span [-].
RANK_TOL = 1e-10


def analytic_centre(
    rows: FloatArray, forces: FloatArray, mu: FloatArray, torque: FloatArray
) -> FloatArray:
    """The admissible force distribution deepest inside the cones (see the module).

    Args:
        rows: The rows' blocks (t1, t2, n per contact), shape (3 m, nv).
        forces: A solver's distribution (t1, t2, n per contact) [N], shape (m, 3).
        mu: Each contact's friction coefficient, shape (m,).
        torque: The joint torque the distribution must exert [N*m], shape (nv,) (the one
            holding the arm exactly still).

    Returns:
        The analytic centre's distribution [N], shape (m, 3): ``rows^T x = torque``, in the
        cones; ``forces`` itself where the admissible set has no interior.
    """
    import scipy.linalg  # (a rest's forces only: not loaded with packbot)
    import scipy.optimize

    xs = np.asarray(forces, dtype=np.float64).ravel()
    m = len(mu)
    if m == 0:
        return np.asarray(forces, dtype=np.float64)
    A = np.asarray(rows, dtype=np.float64).T  # (nv, 3m): A x is the joint torque
    frictionless = np.asarray(mu, dtype=np.float64) == 0.0
    # a frictionless row carries no tangential component: those columns are fixed at 0
    keep = np.ones(3 * m, dtype=bool)
    for i in np.flatnonzero(frictionless):
        keep[3 * i : 3 * i + 2] = False
    # the solver's distribution moved (least norm) onto rows^T x = torque: a particular one
    x0 = xs.copy()
    fix = np.linalg.lstsq(A[:, keep], np.asarray(torque, dtype=np.float64) - A @ xs, rcond=None)
    x0[keep] += fix[0]
    N = scipy.linalg.null_space(A[:, keep], rcond=RANK_TOL)
    if N.shape[1] == 0:  # determinate: one distribution
        return np.asarray(x0.reshape(m, 3), dtype=np.float64)
    basis = np.zeros((3 * m, N.shape[1]))
    basis[keep] = N
    mus = np.asarray(mu, dtype=np.float64)
    scale = max(float(np.abs(xs[2::3]).max()), 1e-300)

    def margins(z: FloatArray) -> FloatArray:
        x = (x0 + basis @ z).reshape(m, 3)
        cone = mus * x[:, 2] - np.hypot(x[:, 0], x[:, 1])
        return np.asarray(np.where(mus > 0.0, cone, x[:, 2]), dtype=np.float64)

    # phase 1: a point inside every cone (maximise the smallest margin, bounded moves)
    k = N.shape[1]
    bound = 10.0 * scale
    res = scipy.optimize.minimize(
        lambda w: -w[-1],
        np.zeros(k + 1),
        method="SLSQP",
        constraints=[{"type": "ineq", "fun": lambda w: margins(w[:-1]) - w[-1]}],
        bounds=[(-bound, bound)] * k + [(None, scale)],
        options={"maxiter": 200, "ftol": 1e-12 * scale},
    )
    z = np.asarray(res.x[:-1], dtype=np.float64)
    if not float(margins(z).min()) > INTERIOR * scale:
        return np.asarray(forces, dtype=np.float64)

    # phase 2: the barrier's maximum from that interior point
    def barrier(zz: FloatArray) -> float:
        g = margins(zz)
        if float(g.min()) <= 0.0:
            return math.inf
        return -float(np.log(g / scale).sum())

    best = scipy.optimize.minimize(
        barrier,
        z,
        method="Nelder-Mead",
        options={"xatol": 1e-9 * scale, "fatol": 1e-12, "maxiter": 2000 * k},
    )
    zb = np.asarray(best.x, dtype=np.float64) if best.fun < barrier(z) else z
    return np.asarray((x0 + basis @ zb).reshape(m, 3), dtype=np.float64)
