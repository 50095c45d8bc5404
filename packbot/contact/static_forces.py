"""The contact forces of a statically indeterminate rest: the analytic centre of the admissible set.

A resting arm with more contact force components than free joints (the collapse's rest: two
points, six components, four joints) is held by a whole family of force distributions: every
x with the same joint torque J^T x in the Coulomb cones holds it (the arm's motion, a = 0, is
the same for all of them). The rest capture's solver returns one of them, often on the set's
boundary (a cone saturated: the collapse's tube at 123.1 N of its admissible 83.8-123.2 N).
Rigid bodies do not say which distribution the real arm carries; a compliant contact model
would, through its stiffnesses, and that is a modelling choice.

packbot reports the *analytic centre* of the admissible set: the distribution that maximises
sum_i log(mu_i x_n,i - |x_t,i|) (for mu_i = 0: log x_n,i) over {x : J^T x = tau}, tau the
torque that holds the arm exactly still, the one deepest inside every cone at once. Where
contacts could squeeze each other without end (internal forces in every cone: a wedged or
grasping arm), the set is bounded by the ball |x| < BALL |x_ln|, x_ln the least-norm balancing
distribution, whose log barrier joins the sum. The answer is unique (a strictly concave
objective on a bounded convex set) and does not depend on the solver's answer. On the
collapse's rest it gives the tube 100.5 N and the elbow casing 1.95 N (MuJoCo 101.0 N, Drake
99.0 N: docs/contact.md). Where the set has no interior (a touching point that can carry no
force in any distribution, or friction needed at its limit), the solver's answer is kept,
moved onto the exact balance. Found in two phases: a point inside every cone (SciPy's SLSQP,
the smallest margin maximised), then damped Newton steps on the barrier.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["analytic_centre"]

FloatArray = NDArray[np.float64]

#: A distribution is interior when every margin exceeds this times the largest normal force.
INTERIOR = 1e-6
#: The tangential force's size is smoothed by this times the largest normal force under the
#: root (sqrt(|f_t|^2 + (SMOOTH f)^2)): the margins stay below the cones' own [-].
SMOOTH = 1e-4
#: The ball bounding the admissible set: this many times the least-norm distribution [-].
BALL = 3.0
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

    # the ball |x| < R bounds the set where contacts could squeeze each other without end
    # (internal forces: the barrier would have no minimum): R = BALL times the least-norm
    # balancing distribution's size, whatever the solver's answer
    least = np.zeros(3 * m)
    least[keep] = np.linalg.lstsq(A[:, keep], np.asarray(torque, dtype=np.float64), rcond=None)[0]
    radius = BALL * max(float(np.linalg.norm(least)), 1e-300)

    def margins(z: FloatArray) -> FloatArray:
        xf = x0 + basis @ z
        x = xf.reshape(m, 3)
        cone = mus * x[:, 2] - np.hypot(x[:, 0], x[:, 1])
        ball = radius - float(np.linalg.norm(xf))
        return np.append(np.where(mus > 0.0, cone, x[:, 2]), ball)

    def margins_jac(z: FloatArray) -> FloatArray:
        """The margins' derivatives in z, shape (m + 1, k)."""
        xf = x0 + basis @ z
        x = xf.reshape(m, 3)
        r = np.maximum(np.hypot(x[:, 0], x[:, 1]), 1e-300)
        grads = np.zeros((m + 1, 3 * m))
        for i in range(m):
            if mus[i] > 0.0:
                grads[i, 3 * i : 3 * i + 3] = (-x[i, 0] / r[i], -x[i, 1] / r[i], mus[i])
            else:
                grads[i, 3 * i + 2] = 1.0
        grads[m] = -xf / max(float(np.linalg.norm(xf)), 1e-300)
        return grads @ basis

    # phase 1: a point inside every cone (maximise the smallest margin, bounded moves)
    k = N.shape[1]
    bound = 10.0 * scale
    lift = np.zeros(k + 1)
    lift[-1] = -1.0
    res = scipy.optimize.minimize(
        lambda w: -w[-1],
        np.zeros(k + 1),
        jac=lambda w: lift,
        method="SLSQP",
        constraints=[
            {
                "type": "ineq",
                "fun": lambda w: margins(w[:-1]) - w[-1],
                "jac": lambda w: np.column_stack([margins_jac(w[:-1]), -np.ones(m + 1)]),
            }
        ],
        bounds=[(-bound, bound)] * k + [(None, scale)],
        options={"maxiter": 200, "ftol": 1e-12 * scale},
    )
    z = np.asarray(res.x[:-1], dtype=np.float64)
    if not float(margins(z).min()) > INTERIOR * scale:  # no interior: the balanced solver's
        return np.asarray(x0.reshape(m, 3), dtype=np.float64)

    # phase 2: the barrier's maximum from that interior point, by damped Newton steps
    zb = _newton(x0, basis, mus, z, scale, radius)
    return np.asarray((x0 + basis @ zb).reshape(m, 3), dtype=np.float64)


def _newton(
    x0: FloatArray, basis: FloatArray, mus: FloatArray, z: FloatArray, scale: float, radius: float
) -> FloatArray:
    """The minimum of -sum log s_i - log(R^2 - |x|^2) at x = x0 + basis z (damped Newton).

    s_i = mu_i x_n - |x_t| (x_n where mu_i = 0), |x_t| smoothed by (SMOOTH scale)^2 under the
    root (a point whose friction vanishes at the centre is the cone's apex: not smooth there);
    gradients and Hessians exact. From an interior z; stops when the Newton decrement is
    below 1e-20 (the barrier within rounding of its minimum) or after 100 steps.
    """
    m = len(mus)
    eps2 = (SMOOTH * scale) ** 2
    cone = mus > 0.0

    def parts(zz: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        x = (x0 + basis @ zz).reshape(m, 3)
        r = np.sqrt(x[:, 0] ** 2 + x[:, 1] ** 2 + eps2)
        s = np.where(cone, mus * x[:, 2] - r, x[:, 2])
        return x, r, s

    r2 = radius * radius

    def value(zz: FloatArray) -> float:
        x, _, s = parts(zz)
        room = r2 - float(np.sum(x * x))
        if float(s.min()) <= 0.0 or room <= 0.0:
            return math.inf
        return -float(np.log(s / scale).sum()) - math.log(room / r2)

    for _ in range(100):
        x, r, s = parts(z)
        grad_x = np.zeros((m, 3))
        hess_x = np.zeros((3 * m, 3 * m))
        for i in range(m):
            gi = np.array([0.0, 0.0, 1.0])
            Hi = np.zeros((3, 3))
            if cone[i]:
                t = x[i, :2]
                gi = np.array([-t[0] / r[i], -t[1] / r[i], mus[i]])
                Hi[:2, :2] = -(np.eye(2) - np.outer(t, t) / r[i] ** 2) / r[i]
            grad_x[i] = -gi / s[i]
            hess_x[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = np.outer(gi, gi) / s[i] ** 2 - Hi / s[i]
        xf = x.ravel()
        room = r2 - float(xf @ xf)
        grad_x = grad_x.ravel() + 2.0 * xf / room
        hess_x += 2.0 * np.eye(3 * m) / room + 4.0 * np.outer(xf, xf) / room**2
        g = basis.T @ grad_x
        H = basis.T @ hess_x @ basis
        try:
            dz = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            break
        decrement = float(-(g @ dz))
        if decrement < 1e-20:
            break
        f0, step = value(z), 1.0
        while step > 1e-12 and not value(z + step * dz) <= f0 - 0.25 * step * decrement:
            step *= 0.5
        if step <= 1e-12:
            break
        z = z + step * dz
    return z
