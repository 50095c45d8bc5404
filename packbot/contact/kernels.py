"""Compiled kernels of the contact-normal mode: contact rows and constrained accelerations.

The right-hand side of the contact-normal mode with its modes fixed is a few Pinocchio calls
(free accelerations, M^-1, the joint Jacobians and their time variation) and small dense
algebra on a few contact points: the rows J_n, their drift, gaps and normal velocities, the
tangential rows of the sticking pairs, then the Delassus system of the engaged rows. That
algebra works on arrays of 2 to 20 rows, where numpy's per-call overhead (a few microseconds
per operation, some 40 operations) would cost most of a run. Here it is one
compiled function per purpose, with plain loops:

- :func:`contact_rows`: every contact row of the contact set (patch points of the pairs, then
  the joint limits) and the pairs' tangential data, from Pinocchio's world-frame Jacobians;
- :func:`constrained_accel`: the accelerations of the current modes (engaged rows, slipping
  pairs' force columns J_n - mu J_s, sticking pairs' tangential rows, Baumgarte
  stabilisation), calling :func:`contact_rows` itself.

Compiled with numba (``@njit(cache=True)``): the machine code is cached beside this file
(``__pycache__``), so only the first run on a machine pays the compilation (measured in
``benchmarks/peers.py``). This module is imported only when a contact-normal run evaluates its
first contact, so ``import packbot`` does not import numba.

Conventions (as :class:`packbot.contact.normal.NormalContacts`): world frame, SI; a row's
gap and normal velocity are body 2 minus body 1 along the normal carried by body 2; the
tangential rows are (t1, t2) of the contact frame at the pair's patch centre.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "constrained_accel",
    "contact_rows",
    "lemke_checked",
    "lemke_small",
    "normal_owner",
    "patch_material",
]


@njit(cache=True)
def _cross(a: Any, b: Any) -> Any:  # pragma: no cover - compiled
    """The cross product a x b of 3-vectors."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def contact_rows(  # pragma: no cover - compiled
    H: Any,
    J: Any,
    dJ: Any,
    masks: Any,
    q: Any,
    v: Any,
    body: Any,
    local: Any,
    pair: Any,
    rows: Any,
    centre: Any,
    normal_body: Any,
    frame2: Any,
    lim_joint: Any,
    lim_side: Any,
    lim_value: Any,
) -> Any:
    """Every contact row of a contact set at (q, v), and the pairs' tangential data.

    Args:
        H: (bodies, 4, 4) world placements of the bodies' joints (homogeneous).
        J: (6, nv) Pinocchio's joint Jacobians in the world frame (``data.J``), at the world
            origin, linear over angular.
        dJ: (6, nv) their time variation (``data.dJ``).
        masks: (bodies, nv) 1 on the velocities that move each body.
        q: (nv,) configuration [rad].
        v: (nv,) velocity [rad/s].
        body: (2h,) body of each point (first h on body 1, then h on body 2).
        local: (2h, 4) the points in their joints' frames, homogeneous [m].
        pair: (h,) pair of each point.
        rows: (m_p,) the patch points (point index) of the pair rows, in row order.
        centre: (pairs,) the patch centres (point index).
        normal_body: (pairs,) body carrying each pair's normal (its body 2, or body 1: see
            :func:`normal_owner`).
        frame2: (pairs, 3, 3) rows t1, t2, n of each pair's contact frame in that body's frame.
        lim_joint: (m_l,) joint (velocity index) of each limit row.
        lim_side: (m_l,) +1 upper limit, -1 lower limit.
        lim_value: (m_l,) the limit [rad].

    Returns:
        Jn (m, nv) rows (pairs' points, then limits), drift (m,) = J_n' v [m/s^2], gap (m,)
        [m or rad], vn (m,) [m/s or rad/s]; per pair JT (pairs, 2, nv) tangential rows at the
        centre (the exact derivatives of the centres' slides t . (c2 - c1), the tangents
        turning with the frame's body), bT (pairs, 2) their drift, vT (pairs, 2) tangential
        velocities, vt (pairs, 3) the world tangential velocity where the bodies touch
        (v_rel - w x (c2 - c1)), nw (pairs, 3) the normal, T (pairs, 2, 3) the tangents;
        per point dJp (h, 3, nv) = J_p2 - J_p1 and dP (h, 3) = p2 - p1 [m].
    """
    nv = v.shape[0]
    nb = H.shape[0]
    n2h = body.shape[0]
    h = n2h // 2
    npairs = centre.shape[0]
    mp = rows.shape[0]
    ml = lim_joint.shape[0]
    # per body: spatial velocity and drift acceleration at the world origin
    Vb = np.zeros((nb, 6))
    Ab = np.zeros((nb, 6))
    for b in range(nb):
        for r in range(6):
            sv = 0.0
            sa = 0.0
            for c in range(nv):
                if masks[b, c] != 0.0:
                    sv += J[r, c] * v[c]
                    sa += dJ[r, c] * v[c]
            Vb[b, r] = sv
            Ab[b, r] = sa
    # per point: position, Jacobian, velocity, drift acceleration
    P = np.empty((n2h, 3))
    Jp = np.empty((n2h, 3, nv))
    vp = np.empty((n2h, 3))
    ap = np.empty((n2h, 3))
    for i in range(n2h):
        b = body[i]
        for r in range(3):
            P[i, r] = (
                H[b, r, 0] * local[i, 0]
                + H[b, r, 1] * local[i, 1]
                + H[b, r, 2] * local[i, 2]
                + H[b, r, 3]
            )
        px, py, pz = P[i, 0], P[i, 1], P[i, 2]
        for c in range(nv):
            m = masks[b, c]
            wx, wy, wz = J[3, c] * m, J[4, c] * m, J[5, c] * m
            # J_p = J_v - skew(P) J_w = J_v - P x J_w
            Jp[i, 0, c] = J[0, c] * m - (py * wz - pz * wy)
            Jp[i, 1, c] = J[1, c] * m - (pz * wx - px * wz)
            Jp[i, 2, c] = J[2, c] * m - (px * wy - py * wx)
        for r in range(3):
            s = 0.0
            for c in range(nv):
                s += Jp[i, r, c] * v[c]
            vp[i, r] = s
        al = Ab[b, 3:6]
        w = Vb[b, 3:6]
        pa = _cross(P[i], al)
        wv = _cross(w, vp[i])
        for r in range(3):
            ap[i, r] = Ab[b, r] - pa[r] + wv[r]
    dJp = np.empty((h, 3, nv))
    vrel = np.empty((h, 3))
    arel = np.empty((h, 3))
    dP = np.empty((h, 3))
    for k in range(h):
        for r in range(3):
            for c in range(nv):
                dJp[k, r, c] = Jp[h + k, r, c] - Jp[k, r, c]
            vrel[k, r] = vp[h + k, r] - vp[k, r]
            arel[k, r] = ap[h + k, r] - ap[k, r]
            dP[k, r] = P[h + k, r] - P[k, r]
    # contact frames in the world: F = frame2 R^T (rows t1, t2, n)
    F = np.empty((npairs, 3, 3))
    for p in range(npairs):
        b = normal_body[p]
        for r in range(3):
            for c in range(3):
                F[p, r, c] = (
                    frame2[p, r, 0] * H[b, c, 0]
                    + frame2[p, r, 1] * H[b, c, 1]
                    + frame2[p, r, 2] * H[b, c, 2]
                )
    m = mp + ml
    Jn = np.zeros((m, nv))
    drift = np.zeros(m)
    gap = np.empty(m)
    vn = np.empty(m)
    for r in range(mp):
        k = rows[r]
        p = pair[k]
        n = F[p, 2]
        # The gap n . (p2 - p1), its normal n turning with the body b carrying it (angular
        # velocity w, drift acceleration al): J_n = n . (J_p2 - J_p1) + (n x dP) . J_w(b),
        # v_n = J_n v, drift = n . (a_p2 - a_p1) + 2 (w x n) . v_rel + (n x dP) . al
        # + (w x (w x n)) . dP, dP = p2 - p1: its exact derivatives (the terms in dP act on
        # body b at the other body's point, where the bodies touch, not at b's material point,
        # which slides away from it; all zero when b is the world)
        b = normal_body[p]
        w = Vb[b, 3:6]
        wxn = _cross(w, n)
        wwxn = _cross(w, wxn)
        nxd = _cross(n, dP[k])
        for c in range(nv):
            Jn[r, c] = n[0] * dJp[k, 0, c] + n[1] * dJp[k, 1, c] + n[2] * dJp[k, 2, c]
            if masks[b, c] != 0.0:
                Jn[r, c] += nxd[0] * J[3, c] + nxd[1] * J[4, c] + nxd[2] * J[5, c]
        g = 0.0
        vv = 0.0
        dd = 0.0
        for i in range(3):
            g += dP[k, i] * n[i]
            vv += vrel[k, i] * n[i]
            dd += arel[k, i] * n[i] + 2.0 * vrel[k, i] * wxn[i]
        for i in range(3):
            vv += wxn[i] * dP[k, i]
            dd += nxd[i] * Ab[b, 3 + i] + wwxn[i] * dP[k, i]
        gap[r] = g
        vn[r] = vv
        drift[r] = dd
    for i in range(ml):
        j = lim_joint[i]
        s = lim_side[i]
        Jn[mp + i, j] = -s
        gap[mp + i] = s * (lim_value[i] - q[j])
        vn[mp + i] = -s * v[j]
    JT = np.empty((npairs, 2, nv))
    bT = np.empty((npairs, 2))
    vT = np.empty((npairs, 2))
    vt = np.empty((npairs, 3))
    nw = np.empty((npairs, 3))
    T = np.empty((npairs, 2, 3))
    for p in range(npairs):
        # The tangential slides t . (c2 - c1) of the patch centres, the tangents turning with
        # the body b carrying the frame: their exact derivatives, as the normal rows' (the
        # terms in dP = c2 - c1 act on body b at the other body's centre, where the bodies
        # touch). The sliding velocity is the relative velocity there, v_rel - w x dP.
        c0 = centre[p]
        b = normal_body[p]
        w = Vb[b, 3:6]
        d = dP[c0]
        wxd = _cross(w, d)
        for r in range(2):
            t = F[p, r]
            wxt = _cross(w, t)
            wwxt = _cross(w, wxt)
            txd = _cross(t, d)
            for c in range(nv):
                JT[p, r, c] = t[0] * dJp[c0, 0, c] + t[1] * dJp[c0, 1, c] + t[2] * dJp[c0, 2, c]
                if masks[b, c] != 0.0:
                    JT[p, r, c] += txd[0] * J[3, c] + txd[1] * J[4, c] + txd[2] * J[5, c]
            bb = 0.0
            vv = 0.0
            for i in range(3):
                bb += t[i] * arel[c0, i] + 2.0 * wxt[i] * vrel[c0, i]
                vv += t[i] * vrel[c0, i]
            for i in range(3):
                bb += txd[i] * Ab[b, 3 + i] + wwxt[i] * d[i]
                vv += wxt[i] * d[i]
            bT[p, r] = bb
            vT[p, r] = vv
            for i in range(3):
                T[p, r, i] = t[i]
        vnc = 0.0
        for i in range(3):
            vnc += F[p, 2, i] * (vrel[c0, i] - wxd[i])
        for i in range(3):
            nw[p, i] = F[p, 2, i]
            vt[p, i] = vrel[c0, i] - wxd[i] - F[p, 2, i] * vnc
    return Jn, drift, gap, vn, JT, bT, vT, vt, nw, T, dJp, dP


@njit(cache=True)
def _solve_small(G: Any, r: Any) -> Any:  # pragma: no cover - compiled
    """Solve G x = r: 1 x 1 and 2 x 2 in closed form, else Gaussian elimination.

    Returns:
        (x, ok); ok is False when G is singular (a zero pivot, or a 2 x 2 whose determinant
        vanishes to rounding), for the caller's least-squares fallback.
    """
    m = r.shape[0]
    x = np.zeros(m)
    if m == 1 and G[0, 0] != 0.0:
        x[0] = r[0] / G[0, 0]
        return x, True
    if m == 2:
        a, b, c, d = G[0, 0], G[0, 1], G[1, 0], G[1, 1]
        det = a * d - b * c
        if abs(det) > 1e-12 * (abs(a * d) + abs(b * c)):
            x[0] = (d * r[0] - b * r[1]) / det
            x[1] = (a * r[1] - c * r[0]) / det
            return x, True
    A = G.copy()
    y = r.copy()
    for k in range(m):
        piv = k
        best = abs(A[k, k])
        for i in range(k + 1, m):
            if abs(A[i, k]) > best:
                best = abs(A[i, k])
                piv = i
        if best == 0.0 or not math.isfinite(best):
            return x, False
        if piv != k:
            for c in range(m):
                A[k, c], A[piv, c] = A[piv, c], A[k, c]
            y[k], y[piv] = y[piv], y[k]
        for i in range(k + 1, m):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for c in range(k, m):
                    A[i, c] -= f * A[k, c]
                y[i] -= f * y[k]
    for k in range(m - 1, -1, -1):
        s = y[k]
        for c in range(k + 1, m):
            s -= A[k, c] * x[c]
        x[k] = s / A[k, k]
    return x, True


@njit(cache=True)
def constrained_accel(  # noqa: D417 (contact_rows documents H ... lim_value)  # pragma: no cover
    H: Any,
    J: Any,
    dJ: Any,
    masks: Any,
    q: Any,
    v: Any,
    body: Any,
    local: Any,
    pair: Any,
    rows: Any,
    centre: Any,
    normal_body: Any,
    frame2: Any,
    lim_joint: Any,
    lim_side: Any,
    lim_value: Any,
    engaged: Any,
    row_slip: Any,
    sticks: Any,
    slip_dir: Any,
    a_free: Any,
    minv: Any,
    mu: float,
    stick_speed: float,
    baumgarte: float,
    offset0: Any,
    force_band: float,
    point_tol: float,
    stick_band: float,
) -> Any:
    """Accelerations of the current contact modes, with the rows the mode conditions need.

    The problem (see ``NormalContacts.evaluate``): engaged rows A = J_n[E] with force columns
    C = J_n - mu s^T (J_p2 - J_p1) on slipping pairs' rows (s the unit sliding direction at the
    row's point, blended with the onset direction below ``stick_speed``), then two
    tangential rows per sticking pair (force columns = rows); target accelerations
    -2 B v_n - B^2 gap (normal rows) and -B v_T (tangential rows); forces from
    (A M^-1 C^T) lambda = target - (A a_free + drift), accelerations a_free + M^-1 C^T lambda.

    Args:
        H: As :func:`contact_rows` (and J, dJ, masks, q, v, body, local, pair, rows, centre,
            normal_body, frame2, lim_joint, lim_side, lim_value).
        engaged: (e,) the engaged rows (row indices).
        row_slip: (e,) the slipping pair of each engaged row, or -1.
        sticks: (s,) the sticking pairs with engaged rows.
        slip_dir: (pairs, 3) each pair's sliding direction at onset (world).
        a_free: (nv,) accelerations without contact forces [rad/s^2].
        minv: (nv, nv) M^-1 (symmetric).
        mu: Coulomb friction coefficient [-].
        stick_speed: Below this sliding speed the direction blends with the onset's [m/s].
        baumgarte: Stabilisation rate B [1/s].
        offset0: (m_p, 2) per pair row, the tangential offset (t1, t2) of its points p2 - p1
            when the patch was built [m].
        force_band: Hysteresis of the force conditions [N].
        point_tol: A free row is an impact below -point_tol [m].
        stick_band: Hysteresis of the stick condition [m/s].

    Returns:
        (a, lam, gap, vn, vt, ok, cond, slide2): ok is False when the Delassus matrix is
        singular (a and lam are then unset: the caller solves the problem otherwise). cond is
        the smallest mode condition of ``NormalContacts.conditions`` (an event when
        negative): per row lam + force_band (engaged) or gap + point_tol (free); per sticking
        pair with engaged rows mu sum(lam_n) - |lam_t| + force_band; per slipping one
        v_t . w / |w| + stick_band (w = v_t + stick_speed s0). slide2 (pairs,): the largest
        squared tangential slide [m^2] of a pair's points since its patch was built,
        |T (p2 - p1) - offset0|^2.
    """
    Jn, drift, gap, vn, JT, bT, vT, vt, nw, T, dJp, dP = contact_rows(
        H, J, dJ, masks, q, v, body, local, pair, rows, centre, normal_body, frame2,
        lim_joint, lim_side, lim_value,
    )  # fmt: skip
    nv = v.shape[0]
    ne = engaged.shape[0]
    ns = sticks.shape[0]
    n = ne + 2 * ns
    A = np.empty((n, nv))
    C = np.empty((n, nv))
    target = np.empty(n)
    b = np.empty(n)
    for e in range(ne):
        r = engaged[e]
        for c in range(nv):
            A[e, c] = Jn[r, c]
            C[e, c] = Jn[r, c]
        p = row_slip[e]
        if p >= 0:
            # the point's own sliding direction (ContactRows.slip_directions)
            k = rows[r]
            vr0 = 0.0
            vr1 = 0.0
            vr2 = 0.0
            for c in range(nv):
                vr0 += dJp[k, 0, c] * v[c]
                vr1 += dJp[k, 1, c] * v[c]
                vr2 += dJp[k, 2, c] * v[c]
            vrn = vr0 * nw[p, 0] + vr1 * nw[p, 1] + vr2 * nw[p, 2]
            w0 = vr0 - vrn * nw[p, 0] + stick_speed * slip_dir[p, 0]
            w1 = vr1 - vrn * nw[p, 1] + stick_speed * slip_dir[p, 1]
            w2 = vr2 - vrn * nw[p, 2] + stick_speed * slip_dir[p, 2]
            nrm = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if nrm > 0.0:
                s0, s1, s2 = w0 / nrm, w1 / nrm, w2 / nrm
            else:
                s0, s1, s2 = slip_dir[p, 0], slip_dir[p, 1], slip_dir[p, 2]
            for c in range(nv):
                C[e, c] -= mu * (s0 * dJp[k, 0, c] + s1 * dJp[k, 1, c] + s2 * dJp[k, 2, c])
        target[e] = -2.0 * baumgarte * vn[r] - baumgarte * baumgarte * gap[r]
        b[e] = drift[r]
    for i in range(ns):
        p = sticks[i]
        for j in range(2):
            e = ne + 2 * i + j
            for c in range(nv):
                A[e, c] = JT[p, j, c]
                C[e, c] = JT[p, j, c]
            target[e] = -baumgarte * vT[p, j]
            b[e] = bT[p, j]
    MC = np.zeros((nv, n))  # M^-1 C^T
    for i in range(nv):
        for e in range(n):
            s = 0.0
            for c in range(nv):
                s += minv[i, c] * C[e, c]
            MC[i, e] = s
    G = np.empty((n, n))
    rhs = np.empty(n)
    for e in range(n):
        s = b[e]
        for c in range(nv):
            s += A[e, c] * a_free[c]
        rhs[e] = target[e] - s
        for f in range(n):
            s = 0.0
            for c in range(nv):
                s += A[e, c] * MC[c, f]
            G[e, f] = s
    lam, ok = _solve_small(G, rhs)
    a = a_free.copy()
    if ok:
        for i in range(nv):
            s = 0.0
            for e in range(n):
                s += MC[i, e] * lam[e]
            a[i] += s
    # the mode conditions' smallest value
    m = gap.shape[0]
    mp = rows.shape[0]
    npairs = centre.shape[0]
    pos = np.full(m, -1)
    for e in range(ne):
        pos[engaged[e]] = e
    cond = math.inf
    for r in range(m):
        g = lam[pos[r]] + force_band if pos[r] >= 0 else gap[r] + point_tol
        if g < cond:
            cond = g
    if mu > 0.0:
        for i in range(ns):
            p = sticks[i]
            fn = 0.0
            for r in range(mp):
                if pos[r] >= 0 and pair[rows[r]] == p:
                    fn += lam[pos[r]]
            l0 = lam[ne + 2 * i]
            l1 = lam[ne + 2 * i + 1]
            g = mu * fn - math.sqrt(l0 * l0 + l1 * l1) + force_band
            if g < cond:
                cond = g
        slipping = np.zeros(npairs, dtype=np.bool_)
        for e in range(ne):
            if row_slip[e] >= 0:
                slipping[row_slip[e]] = True
        for p in range(npairs):
            if slipping[p]:
                w0 = vt[p, 0] + stick_speed * slip_dir[p, 0]
                w1 = vt[p, 1] + stick_speed * slip_dir[p, 1]
                w2 = vt[p, 2] + stick_speed * slip_dir[p, 2]
                nw = max(math.sqrt(w0 * w0 + w1 * w1 + w2 * w2), 1e-300)
                g = (vt[p, 0] * w0 + vt[p, 1] * w1 + vt[p, 2] * w2) / nw + stick_band
                if g < cond:
                    cond = g
    # the patches' slides
    slide2 = np.zeros(npairs)
    for r in range(mp):
        k = rows[r]
        p = pair[k]
        s2 = 0.0
        for j in range(2):
            d = T[p, j, 0] * dP[k, 0] + T[p, j, 1] * dP[k, 1] + T[p, j, 2] * dP[k, 2]
            d -= offset0[r, j]
            s2 += d * d
        if s2 > slide2[p]:
            slide2[p] = s2
    return a, lam, gap, vn, vt, ok, cond, slide2


@njit(cache=True)
def _lift_points(  # pragma: no cover - compiled
    N: Any, o: Any, R: Any, t: Any, mid: Any, n: Any, sign: float
) -> Any:
    """Points ``mid`` moved along n onto the face most aligned with sign * n.

    The faces: planes N x + o = 0 in the piece's frame (placement R, t). Returns (points, ok),
    ok False when that face is too oblique (|N_f . n| < 0.5).
    """
    K = mid.shape[0]
    nl = np.empty(3)
    for i in range(3):
        nl[i] = R[0, i] * n[0] + R[1, i] * n[1] + R[2, i] * n[2]
    f = 0
    best = -math.inf
    for j in range(N.shape[0]):
        s = sign * (N[j, 0] * nl[0] + N[j, 1] * nl[1] + N[j, 2] * nl[2])
        if s > best:
            best = s
            f = j
    den = N[f, 0] * nl[0] + N[f, 1] * nl[1] + N[f, 2] * nl[2]
    out = np.empty((K, 3))
    if abs(den) < 0.5:
        return out, False
    for k in range(K):
        s = o[f]
        for i in range(3):
            pl = (
                (mid[k, 0] - t[0]) * R[0, i]
                + (mid[k, 1] - t[1]) * R[1, i]
                + (mid[k, 2] - t[2]) * R[2, i]
            )
            s += pl * N[f, i]
        s = -s / den
        for i in range(3):
            out[k, i] = mid[k, i] + s * n[i]
    return out, True


@njit(cache=True)
def _consistent_points(  # pragma: no cover - compiled
    p1: Any, p2: Any, n: Any, distance: float, patch_tol: float
) -> bool:
    """Whether the points' gaps along n are consistent with the pair's distance.

    The smallest within patch_tol of the distance, none beyond distance + 1 mm.
    """
    lo = math.inf
    hi = -math.inf
    for k in range(p1.shape[0]):
        g = (p2[k, 0] - p1[k, 0]) * n[0] + (p2[k, 1] - p1[k, 1]) * n[1]
        g += (p2[k, 2] - p1[k, 2]) * n[2]
        lo = min(lo, g)
        hi = max(hi, g)
    return abs(lo - distance) <= patch_tol and hi <= distance + 1e-3


@njit(cache=True)
def patch_material(  # noqa: D417 (pairs of arguments documented together)  # pragma: no cover
    p1: Any,
    p2: Any,
    n: Any,
    distance: float,
    N1: Any,
    o1: Any,
    Rg1: Any,
    tg1: Any,
    N2: Any,
    o2: Any,
    Rg2: Any,
    tg2: Any,
    RM1: Any,
    tM1: Any,
    RM2: Any,
    tM2: Any,
    patch_tol: float,
    check: bool,
) -> Any:
    """A contact patch as material points: its points on each body, in the joints' frames.

    Coal puts every patch point at the patch's one depth; each body's points are moved along
    the normal onto that body's face most aligned with the normal (planes N x + o = 0 in the
    piece's frame; none: zero rows), unless a face is too oblique or the lifted points' gaps
    are off the pair's distance (then Coal's points are kept).

    Args:
        p1: (K, 3) Coal's patch points on body 1, world [m] (p2: on body 2).
        n: (3,) the patch normal, world, from body 1 to body 2.
        distance: The pair's signed distance [m].
        N1: (F, 3) face normals of piece 1 (its frame), o1 (F,) their offsets; Rg1, tg1 the
            piece's world placement (N2, o2, Rg2, tg2: piece 2).
        RM1: (3, 3) world rotation of body 1's joint, tM1 (3,) its translation (RM2, tM2:
            body 2).
        patch_tol: Largest distance of the smallest gap from the pair's distance [m].
        check: Lift and check the points (False: take p1, p2 as they are).

    The normal is fixed in the body whose face it is (:func:`normal_owner`): body 2, unless
    a face of body 1 is the better aligned with it.

    Returns:
        (ok, local1, local2, normal2, frame2, centre1, centre2, offset0, on1): ok False when
        even Coal's points are off the distance (the caller takes the witness points); local1
        and local2 (K, 3) the points in their joints' frames, normal2 (3,) the normal in the
        frame of the joint carrying it (body 2's, body 1's when on1), frame2 (3, 3) rows t1,
        t2, n2 of the contact frame there, centre1 and centre2 (1, 3) the points' means,
        offset0 (2, K) the tangential offsets (t1, t2) of the points p2 - p1 in that frame, on1
        whether the normal is fixed in body 1.
    """
    K = p1.shape[0]
    pts1 = p1
    pts2 = p2
    ok = True
    if check:
        mid = 0.5 * (p1 + p2)
        lifted = N1.shape[0] > 0 and N2.shape[0] > 0
        if lifted:
            l1, ok1 = _lift_points(N1, o1, Rg1, tg1, mid, n, 1.0)
            l2, ok2 = _lift_points(N2, o2, Rg2, tg2, mid, n, -1.0)
            lifted = ok1 and ok2 and _consistent_points(l1, l2, n, distance, patch_tol)
            if lifted:
                pts1 = l1
                pts2 = l2
        if not lifted:
            ok = _consistent_points(p1, p2, n, distance, patch_tol)
    on1 = normal_owner(N1, Rg1, N2, Rg2, n)
    RMn = RM1 if on1 else RM2
    local1 = np.empty((K, 3))
    local2 = np.empty((K, 3))
    centre1 = np.zeros((1, 3))
    centre2 = np.zeros((1, 3))
    for k in range(K):
        for i in range(3):
            a = 0.0
            b = 0.0
            for j in range(3):
                a += (pts1[k, j] - tM1[j]) * RM1[j, i]
                b += (pts2[k, j] - tM2[j]) * RM2[j, i]
            local1[k, i] = a
            local2[k, i] = b
            centre1[0, i] += a
            centre2[0, i] += b
    for i in range(3):
        centre1[0, i] /= K
        centre2[0, i] /= K
    n2 = np.empty(3)
    for i in range(3):
        n2[i] = RMn[0, i] * n[0] + RMn[1, i] * n[1] + RMn[2, i] * n[2]
    # tangents: t1 = a x n2 / |a x n2|, t2 = n2 x t1 (a: the x axis unless n2 is near it)
    ax = np.zeros(3)
    if abs(n2[0]) < 0.9:
        ax[0] = 1.0
    else:
        ax[1] = 1.0
    t1 = _cross(ax, n2)
    nt = math.sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2])
    for i in range(3):
        t1[i] /= nt
    t2 = _cross(n2, t1)
    frame2 = np.empty((3, 3))
    for i in range(3):
        frame2[0, i] = t1[i]
        frame2[1, i] = t2[i]
        frame2[2, i] = n2[i]
    offset0 = np.empty((2, K))
    for k in range(K):
        d = np.empty(3)
        for i in range(3):
            d[i] = (
                RMn[0, i] * (pts2[k, 0] - pts1[k, 0])
                + RMn[1, i] * (pts2[k, 1] - pts1[k, 1])
                + RMn[2, i] * (pts2[k, 2] - pts1[k, 2])
            )
        for r in range(2):
            offset0[r, k] = frame2[r, 0] * d[0] + frame2[r, 1] * d[1] + frame2[r, 2] * d[2]
    return ok, local1, local2, n2, frame2, centre1, centre2, offset0, on1


@njit(cache=True)
def normal_owner(N1: Any, Rg1: Any, N2: Any, Rg2: Any, n: Any) -> bool:  # pragma: no cover
    """Whether a patch normal n is a face normal of body 1 rather than of body 2.

    The contact of a vertex or an edge of one body with a face of the other has the face's
    normal: fixed in the face's body, it stays the normal while the other body turns and slides
    on the face; fixed in the other body it turns with that body, and the gap n . (p2 - p1)
    measured along it departs from the distance as the material points slide apart (by
    about the turn times the slide: the camera head spinning at 2.6 rad/s on the palm's face,
    its normal in the head, read 0.07 um of penetration where the pair was 0.33 um apart after
    a 2 ms step, and its normal velocity 1.8 mm/s where the distance changed by -0.1 mm/s).
    The face is the one whose outward normal is best aligned with the patch's (+n for body 1,
    -n for body 2; face planes N in each piece's frame, placements Rg1, Rg2); a body without
    face planes (a sphere, a cylinder) has none. On a tie (two faces flat on each other, where
    either is the normal) body 2.
    """
    best1 = -math.inf
    for j in range(N1.shape[0]):
        s = 0.0
        for i in range(3):
            s += N1[j, i] * (Rg1[0, i] * n[0] + Rg1[1, i] * n[1] + Rg1[2, i] * n[2])
        best1 = max(best1, s)
    best2 = -math.inf
    for j in range(N2.shape[0]):
        s = 0.0
        for i in range(3):
            s -= N2[j, i] * (Rg2[0, i] * n[0] + Rg2[1, i] * n[1] + Rg2[2, i] * n[2])
        best2 = max(best2, s)
    return best1 > best2


@njit(cache=True)
def lemke_small(  # pragma: no cover - compiled
    M: Any, q: Any, max_iter: int, tol: float
) -> Any:
    """:func:`packbot.contact.lcp.lemke` compiled: the same pivots and floating-point operations.

    Line for line the Python-float version of ``lcp._lemke_small`` (same tableau, same order of
    operations, no fused multiply-adds), so the same result to the last bit.

    Returns:
        (z, ok): ok False on ray termination or the pivot limit.
    """
    n = q.shape[0]
    w = 2 * n + 2
    T = np.zeros((n, w))
    for i in range(n):
        T[i, i] = 1.0
        for j in range(n):
            T[i, n + j] = -M[i, j]
        T[i, 2 * n] = -1.0
        T[i, 2 * n + 1] = q[i]
    basis = np.arange(n)
    r = 0
    for i in range(1, n):
        if q[i] < q[r]:
            r = i
    entering = 2 * n
    Tr = np.empty(w)
    ratios = np.empty(n)
    for _ in range(max_iter):
        piv = T[r, entering]
        for j in range(w):
            Tr[j] = T[r, j] / piv
        for i in range(n):
            c = 0.0 if i == r else T[i, entering]
            if i == r:
                for j in range(w):
                    T[i, j] = Tr[j] - c * Tr[j]
            else:
                for j in range(w):
                    T[i, j] = T[i, j] - c * Tr[j]
        leaving = basis[r]
        basis[r] = entering
        if leaving == 2 * n:
            z = np.zeros(2 * n + 1)
            for i in range(n):
                z[basis[i]] = T[i, w - 1]
            out = np.empty(n)
            for i in range(n):
                out[i] = max(z[n + i], 0.0)
            return out, True
        entering = leaving + n if leaving < n else leaving - n
        blocked = True
        for i in range(n):
            if T[i, entering] > tol:
                ratios[i] = T[i, w - 1] / T[i, entering]
                blocked = False
            else:
                ratios[i] = math.inf
        if blocked:
            return np.zeros(n), False
        rmin = ratios[0]
        for i in range(1, n):
            rmin = min(rmin, ratios[i])
        bound = rmin + 1e-12 * (1.0 + abs(rmin))
        first = -1
        r = -1
        for i in range(n):
            if ratios[i] <= bound:
                if first < 0:
                    first = i
                if basis[i] == 2 * n and r < 0:
                    r = i
        if r < 0:
            r = first
    return np.zeros(n), False


@njit(cache=True)
def lemke_checked(  # pragma: no cover - compiled
    M: Any, q: Any, max_iter: int, tol: float
) -> Any:
    """:func:`lemke_small` and the solution's :func:`packbot.contact.lcp.lcp_residual` in one call.

    The residual is summed in index order (numpy's ``G @ z`` may sum in another order: the two
    differ by rounding, a few ulps of the problem's scale).

    Returns:
        (z, residual, ok): ok False on ray termination or the pivot limit (z zeros, residual
        inf).
    """
    n = q.shape[0]
    z, ok = lemke_small(M, q, max_iter, tol)
    if not ok:
        return z, math.inf, False
    if n == 0:
        return z, 0.0, True
    qmax = 0.0
    gzmax = 0.0
    zmin = math.inf
    wmin = math.inf
    zw = 0.0
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += M[i, j] * z[j]
        w = s + q[i]
        qmax = max(qmax, abs(q[i]))
        gzmax = max(gzmax, abs(s))
        zmin = min(zmin, z[i])
        wmin = min(wmin, w)
        zw += z[i] * w
    scale = 1.0 + qmax + gzmax
    res = max(-zmin, -wmin, abs(zw) / scale, 0.0)
    return z, res / scale, True
