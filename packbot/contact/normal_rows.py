"""The rows of the contact set: kinematics, point layout, the modes' plan, patch staleness.

Every patch point's normal row (gap, J_n, drift, v_n) and every pair's tangential rows at its
patch centre come from one call of the extension (:meth:`NativeRhs.rows
<packbot.contact.native.NativeRhs.rows>`) over the point layout (:class:`_Layout`);
:class:`_Plan` lists the rows of the constrained problem for the current modes. A sliding
patch is rebuilt once stale (:meth:`ContactRows.stale`).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact.native import NativeRhs
from packbot.contact.normal_patch import _Pair
from packbot.contact.normal_set import ContactSet
from packbot.contact.normal_tolerances import POINT_TOL, STICK_SPEED

__all__ = ["ContactRows"]

FloatArray = NDArray[np.float64]


@dataclass
class _Layout:
    """Where the patch points of the contact set are, for the rows (the extension's layout).

    Every pair contributes its K points and its centre (their mean), on body 1 then on
    body 2: point i of the h = sum(K + 1) points is row i on body 1 and row h + i on body 2.
    """

    joints: list[int]  # the joints of the bodies involved
    masks: FloatArray  # (bodies, nv) 1 on the velocities moving each body
    body: NDArray[np.intp]  # (2h,) index into joints of each point's body
    local: FloatArray  # (2h, 4) point in its joint frame, homogeneous [m]
    pair: NDArray[np.intp]  # (h,) pair of each point (position in the contact set)
    rows: NDArray[np.intp]  # (m,) the patch points (not the centres), in row order
    centre: NDArray[np.intp]  # (pairs,) the centres
    normal_body: NDArray[np.intp]  # (pairs,) index into joints of the body carrying the normal
    frame2: FloatArray  # (pairs, 3, 3) rows t1, t2, n in that body's joint frame
    points: list[slice]  # per pair, its patch points among the h
    lim_joint: NDArray[np.intp]  # (limits,) velocity index of each limit row
    lim_side: FloatArray  # (limits,) +1 upper, -1 lower
    lim_value: FloatArray  # (limits,) the limit [rad]
    clamp_joint: NDArray[np.intp]  # (clamps,) velocity index of each clamp row
    clamp_side: FloatArray  # (clamps,) its forbidden direction s (+1 or -1): the row -s e_j
    offset0: FloatArray  # (m_p, 2) per pair row, its tangential offset when built [m]
    slide_tol2: FloatArray  # (pairs,) the square of the slide each patch goes stale at [m^2]


@dataclass
class _Plan:
    """The constrained problem's rows for the current modes (see ``NormalContacts._plan``)."""

    engaged: NDArray[np.intp]  # (e,) the engaged rows E
    # per slipping pair with engaged rows: its position in the contact set, the positions of
    # its rows in E, their points in its patch
    slips: list[tuple[int, Any, Any]]
    sticks: NDArray[np.intp]  # the positions of the sticking pairs with engaged rows
    row_slip: NDArray[np.intp]  # (e,) the slipping pair of each engaged row, or -1
    # per sticking pair with engaged rows (as sticks): the positions of its rows in E
    stick_at: list[NDArray[np.intp]] = field(default_factory=list)


class ContactRows(ContactSet):
    """The contact set with its rows (see the module)."""

    #: One-sided joint rows (joint, s) after the limit rows, J = -s e_j: the hand-off's clamps
    #: (:class:`~packbot.contact.handoff.HandoffContacts` sets them; none in the normal mode).
    clamps: Sequence[tuple[int, int]] = ()
    #: How the rows are reported (:meth:`NativeRhs.load_layout
    #: <packbot.contact.native.NativeRhs.load_layout>`): the locked joints whose frozen rows
    #: sit apart (none: no row does), and whether the clamp rows carry their true velocity
    #: (velocity level) or 0 (acceleration level).
    _row_mode: tuple[tuple[int, ...], bool] = ((), False)

    def _kinematics(
        self, q: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[dict[str, Any]]]:
        """Rows of every contact: J_n (m, nv), drift (m,), gap (m,), v_n (m,).

        And per pair the tangential rows and the velocities at the patch centre
        (:meth:`NativeRhs.rows <packbot.contact.native.NativeRhs.rows>`: every patch point of
        every pair at once; the hand-off's clamp rows after the limit rows). The result depends only
        on (q, v), the contact set and its row mode (``_row_mode``), so it is cached
        (a few states: the mode conditions and the restart's problems ask for the same state
        several times); the cache is emptied whenever the contact set changes. The arrays
        returned are read-only.
        """
        key = (q.tobytes(), v.tobytes(), self._row_mode)
        hit = self._kin_cache.get(key)
        if hit is not None:
            return hit
        raw = self.rows_raw(q, v)
        rows, drift, gap, vn, JT, bT, vT, vt, nw, T, dJp, dP = raw
        extra = [
            {
                "n": nw[i],
                "T": T[i],
                "JT": JT[i],
                "bT": bT[i],
                "vT": vT[i],
                "vt": vt[i],
                "dJ": dJp[sl],
                "vr": dJp[sl] @ v,  # (K, 3) the points' relative velocities p2' - p1' [m/s]
                "dp": dP[sl],
            }
            for i, sl in enumerate(self._layout().points)
        ]
        out = (rows, drift, gap, vn, extra)
        for arr in out[:4]:
            arr.setflags(write=False)
        if len(self._kin_cache) >= 8:
            self._kin_cache.clear()
        self._kin_cache[key] = out
        return out

    def rows_raw(self, q: FloatArray, v: FloatArray) -> tuple[Any, ...]:
        """The contact set's rows at (q, v), uncached.

        :meth:`NativeRhs.rows <packbot.contact.native.NativeRhs.rows>`'s tuple.
        """
        return self._rows_rhs().rows(self, q, v)

    def _rows_rhs(self) -> NativeRhs:
        """The extension's object computing this set's rows (built at the first call)."""
        rhs = self._rows_native
        if rhs is None:
            rhs = self._rows_native = NativeRhs(self.model)
        return rhs

    def _layout(self) -> _Layout:
        """The point layout of the current contact set (cached until it changes)."""
        if self._lay is not None:
            return self._lay
        pairs = list(self.pairs.values())
        shape = (
            tuple([(k, len(p.local1), p.on1) for k, p in self.pairs.items()]),
            tuple(self.limits.items()),
            tuple(self.clamps),
        )
        prev = self._lay_prev
        if prev is not None and prev[0] == shape:
            # the same pairs with the same patch sizes, normals on the same bodies and the same
            # limits (a re-patch): only the points, the frames and the offsets change
            self._lay = lay = _replace_patches(prev[1], pairs)
            self._lay_prev = (shape, lay)
            return lay
        joints = sorted({p.info.joint1 for p in pairs} | {p.info.joint2 for p in pairs})
        index = {j: i for i, j in enumerate(joints)}
        body1: list[int] = []
        body2: list[int] = []
        pair: list[int] = []
        rows: list[int] = []
        centre: list[int] = []
        points: list[slice] = []
        k = 0
        for i, p in enumerate(pairs):
            K = len(p.local1)
            body1 += [index[p.info.joint1]] * (K + 1)
            body2 += [index[p.info.joint2]] * (K + 1)
            pair += [i] * (K + 1)
            rows += range(k, k + K)
            points.append(slice(k, k + K))
            centre.append(k + K)
            k += K + 1
        limits = list(self.limits.items())
        self._lay = _Layout(
            joints=joints,
            masks=np.ascontiguousarray(self._masks[joints][:, 0, :]),
            body=np.array(body1 + body2, dtype=np.intp),
            local=_local(pairs, k),
            pair=np.array(pair, dtype=np.intp),
            rows=np.array(rows, dtype=np.intp),
            centre=np.array(centre, dtype=np.intp),
            normal_body=np.array(
                [index[p.info.joint1 if p.on1 else p.info.joint2] for p in pairs], dtype=np.intp
            ),
            frame2=_frame2(pairs),
            points=points,
            lim_joint=np.array([j for (j, _), _ in limits], dtype=np.intp),
            lim_side=np.array([side for (_, side), _ in limits], dtype=np.float64),
            lim_value=np.array([value for _, value in limits], dtype=np.float64),
            clamp_joint=np.array([j for j, _ in self.clamps], dtype=np.intp),
            clamp_side=np.array([s for _, s in self.clamps], dtype=np.float64),
            offset0=_offset0(pairs),
            slide_tol2=np.array([p.slide_tol**2 for p in pairs], dtype=np.float64),
        )
        lay = self._lay
        self._lay_prev = (shape, lay)
        return lay

    @staticmethod
    def _direction_rows(ex: dict[str, Any], d: FloatArray) -> FloatArray:
        """d^T (J_p2 - J_p1) at every patch point of a pair, shape (K, nv); d (3,) world."""
        return np.asarray(d @ ex["dJ"], dtype=np.float64)

    def _problem(
        self, q: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[dict[str, Any]]]:
        return self._kinematics(q, v)

    def _slip_columns(self, Jn: FloatArray, extra: list[dict[str, Any]]) -> FloatArray:
        """Force columns of the normal rows: J_n - mu J_s on the rows of slipping pairs."""
        if self.mu == 0.0:
            return Jn
        C = Jn.copy()
        k = 0
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            K = len(p.local1)
            if not p.stick:
                s = self.slip_directions(p, ex)
                C[k : k + K] -= self.mu * np.einsum("ki,kic->kc", s, ex["dJ"])
            k += K
        return C

    @staticmethod
    def slip_directions(p: _Pair, ex: dict[str, Any]) -> FloatArray:
        """The unit sliding direction of body 2 relative to body 1 at each patch point (world).

        Each point's own: the tangential part v_t of its relative velocity (J_p2 - J_p1) v
        (``ex["vr"]``), blended with the tangential part s0_t of the pair's onset direction s0
        below :data:`STICK_SPEED`, s = (v_t + STICK_SPEED s0_t) / |...| (s0 where that is
        zero), so a slip starting from rest has the direction of its onset and a slowing slide
        keeps a smooth direction until its stick event. The friction force -mu lambda s then
        does work -mu lambda s . v_t <= 0 at every point (to the blend's STICK_SPEED): a patch
        spinning about its normal slides its points in different directions, and the
        direction of the patch centre for all of them made friction push some points along
        their slide (energy gained; measured 0.95 J on a random start). s0 is fixed in the
        world at the onset and the normal turns with its body: s0 itself gave s a normal part
        (0.17 on wrist-locked start 26 at mu 1.2, 0.4 s after the onset), a force along n at
        the material points 2.2 cm apart, which did +0.6 W of work. The same rule as the
        compiled engine's ``point_slip_direction`` (src/native/rows.hpp).

        Returns:
            (K, 3): one direction per patch point of the pair, in the pair's row order.
        """
        vr = ex["vr"]  # (K, 3) the points' relative velocities p2' - p1' [m/s]
        n = ex["n"]
        s0 = p.slip_dir
        w = vr - np.outer(vr @ n, n) + STICK_SPEED * (s0 - (s0 @ n) * n)
        nw = np.sqrt(np.einsum("ki,ki->k", w, w))
        out = np.empty_like(w)
        for j in range(len(w)):
            out[j] = w[j] / nw[j] if nw[j] > 0.0 else p.slip_dir
        return out

    def _stick_rows(self, extra: list[dict[str, Any]]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Tangential rows (2 per sticking pair), their drift and velocities."""
        if self.mu == 0.0:
            z = np.zeros(0)
            return np.zeros((0, self.nv)), z, z
        JT, bT, vT = [], [], []
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            if p.stick and self._pair_engaged(p):
                JT.append(ex["JT"])
                bT.append(ex["bT"])
                vT.append(ex["vT"])
        if not JT:
            z = np.zeros(0)
            return np.zeros((0, self.nv)), z, z
        return np.vstack(JT), np.concatenate(bT), np.concatenate(vT)

    def _plan(self) -> _Plan:
        """The rows of the constrained problem for the current modes (cached while they hold)."""
        pairs = self._pair_list
        key = (self._version, tuple(self.engaged), tuple([p.stick for p in pairs]))
        if self._plan_key == key:
            return self._plan_val
        pos = {r: i for i, r in enumerate(self.engaged)}
        slips: list[tuple[int, Any, Any]] = []
        sticks: list[int] = []
        stick_at: list[NDArray[np.intp]] = []
        row_slip = np.full(len(self.engaged), -1, dtype=np.intp)
        k = 0
        for i, p in enumerate(pairs):
            K = len(p.local1)
            mine = [(pos[r], r - k) for r in range(k, k + K) if r in pos]
            k += K
            if not mine or self.mu == 0.0:
                continue
            if p.stick:
                sticks.append(i)
                stick_at.append(np.array([m[0] for m in mine], dtype=np.intp))
            else:
                at = np.array([m[0] for m in mine], dtype=np.intp)
                slips.append((i, at, np.array([m[1] for m in mine], dtype=np.intp)))
                row_slip[at] = i
        self._plan_key = key
        self._plan_val = _Plan(
            np.array(self.engaged, dtype=np.intp),
            slips,
            np.array(sticks, dtype=np.intp),
            row_slip,
            stick_at,
        )
        return self._plan_val

    def _frictional_rows(
        self, rows: NDArray[np.intp], Jn: FloatArray, extra: list[dict[str, Any]]
    ) -> tuple[FloatArray, FloatArray]:
        """Blocks (t1, t2, n) of the given normal rows (limit rows: no tangential part)."""
        per_row: list[tuple[FloatArray, float]] = []
        k = 0
        lookup: dict[int, tuple[FloatArray, float]] = {}
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            K = len(p.local1)
            t1 = self._direction_rows(ex, ex["T"][0])
            t2 = self._direction_rows(ex, ex["T"][1])
            for i in range(K):
                lookup[k + i] = (np.vstack([t1[i], t2[i], Jn[k + i]]), self.mu)
            k += K
        for r in rows.tolist():
            if r in lookup:
                per_row.append(lookup[r])
            else:
                blk = np.zeros((3, self.nv))
                blk[2] = Jn[r]
                per_row.append((blk, 0.0))
        return np.vstack([b for b, _ in per_row]), np.array([m for _, m in per_row])

    def sliding(self, q: FloatArray, v: FloatArray) -> bool:
        """Whether a pair with engaged rows slides (its material points drift off the patch)."""
        if not self.engaged or not self.pairs or self.resting:
            return False
        last = self._last_eval  # the step end's mode conditions computed them (the same rows)
        if last is not None and _same(last[0], q) and _same(last[1], v):
            vts: Any = last[6].vt
        else:
            vts = _centre_velocities(self._problem(q, v)[4])
        if self.mu > 0.0:  # the plan's slipping pairs: those with engaged rows not sticking
            for i, _, _ in self._plan().slips:
                vt = vts[i]
                if math.sqrt(float(vt @ vt)) > STICK_SPEED:
                    return True
            return False
        for p, vt in zip(self.pairs.values(), vts, strict=True):
            if (
                not (self.mu > 0.0 and p.stick)
                and math.sqrt(float(vt @ vt)) > STICK_SPEED  # (np.linalg.norm's own formula)
                and self._pair_engaged(p)
            ):
                return True
        return False

    def stale(self, q: FloatArray, v: FloatArray, distance: dict[int, float]) -> bool:
        """Whether a pair with engaged rows no longer has a valid patch (it must be rebuilt).

        A patch is a set of material point pairs (p1 on body 1, p2 on body 2) and a normal fixed
        in the body whose face it is; it describes the contact while (1) the points have not
        slid apart by more than the pair's ``slide_tol`` (normally
        :data:`~packbot.contact.normal_tolerances.SLIDE_TOL`) tangentially since it was built
        (the rows act where the bodies touch, but a face-on-face patch's corners on the other
        face's edges stay where they were; a vertex on a face has no such corner and never goes
        stale by its slide: :data:`~packbot.contact.normal_tolerances.FACE_ALIGN`), and (2) the
        patch's smallest gap equals the pair's signed distance to :data:`POINT_TOL` (a curved body's
        next facet comes closer than the patch predicts, or a point slides off the edge of its
        face and the face's plane holds it where nothing does). A slide of 2e-8 m per step
        passes both: the patch, its drift projection and its modes are kept (events still
        watch every row and the pair's distance).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            distance: Signed distance [m] of the pairs in contact at q (Coal, by pair index);
                a pair missing from it counts as stale.
        """
        return bool(self.stale_pairs(q, v, distance, engaged_only=True))

    def stale_pairs(
        self, q: FloatArray, v: FloatArray, distance: dict[int, float], engaged_only: bool = False
    ) -> list[int]:
        """The pairs whose patch no longer describes the contact (see :meth:`stale`).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            distance: Signed distance [m] of the pairs at q, by pair index.
            engaged_only: Only the pairs with engaged rows.
        """
        if not self.pairs:
            return []
        last = self._last_eval  # the step's end: its evaluation computed the slides
        slide2: Any = None
        if last is not None and _same(last[0], q) and _same(last[1], v):
            gap, slide2 = last[6].gap, last[6].slide2
        if slide2 is None:
            _, _, gap, _, extra = self._problem(q, v)
        elif engaged_only and self.mu > 0.0:
            return self._stale_engaged(gap, slide2, distance)
        out: list[int] = []
        k = 0
        for i, (key, p) in enumerate(self.pairs.items()):
            K = len(p.local1)
            g = gap[k : k + K]
            k += K
            if engaged_only and not self._pair_engaged(p):
                continue
            d = distance.get(key)
            if d is None or abs(float(g.min()) - d) > POINT_TOL:
                out.append(key)
                if engaged_only:
                    return out
                continue
            if slide2 is not None:
                s2 = float(slide2[i])
            else:
                ex = extra[i]
                slide = ex["T"] @ ex["dp"].T - p.offset0  # (2, K)
                s2 = float(np.max(slide[0] ** 2 + slide[1] ** 2))
            if s2 > p.slide_tol**2:
                out.append(key)
                if engaged_only:
                    return out
        return out

    def _stale_engaged(self, gap: Any, slide2: Any, distance: dict[int, float]) -> list[int]:
        """:meth:`stale_pairs` with ``engaged_only`` from the compiled evaluation's slides.

        The pairs with engaged rows are the modes' plan's (with friction: its slipping and
        sticking pairs), in the contact set's order; the first stale one is returned.
        """
        plan = self._plan()
        engaged = [s[0] for s in plan.slips] + plan.sticks.tolist()
        if not engaged:
            return []
        engaged.sort()
        keys = list(self.pairs)
        points = self._layout().points
        for i in engaged:
            sl = points[i]  # (among the points and centres: i centres before it)
            key = keys[i]
            d = distance.get(key)
            if d is None or abs(float(gap[sl.start - i : sl.stop - i].min()) - d) > POINT_TOL:
                return [key]
            if float(slide2[i]) > self._pair_list[i].slide_tol ** 2:
                return [key]
        return []


def _local(pairs: list[_Pair], h: int) -> FloatArray:
    """(2h, 4) every patch point and centre, on body 1 then body 2, homogeneous [m]."""
    if not pairs:
        return np.zeros((0, 4))
    local1: list[FloatArray] = []
    local2: list[FloatArray] = []
    for p in pairs:
        local1 += [p.local1, p.centre1]
        local2 += [p.local2, p.centre2]
    out = np.ones((2 * h, 4))  # (the points and centres are (K, 3) and (1, 3): one copy)
    np.concatenate(local1 + local2, out=out[:, :3])
    return out


def _frame2(pairs: list[_Pair]) -> FloatArray:
    """(pairs, 3, 3) each pair's rows t1, t2, n in the joint frame of the body carrying n."""
    return np.array([p.frame2 for p in pairs]) if pairs else np.zeros((0, 3, 3))


def _offset0(pairs: list[_Pair]) -> FloatArray:
    """(m_p, 2) each pair row's tangential offset when its patch was built [m]."""
    if not pairs:
        return np.zeros((0, 2))
    return np.ascontiguousarray(np.concatenate([p.offset0.T for p in pairs]))


def _replace_patches(lay: _Layout, pairs: list[_Pair]) -> _Layout:
    """A new layout of the same shape as ``lay`` with the patches of ``pairs``.

    The pairs, their patch sizes and the limits are those of ``lay``; its index arrays and
    masks are shared (none is written after it is built); the points, frames, offsets and
    slides allowed are the new patches'.
    """
    h = len(lay.pair)
    new = copy.copy(lay)  # (dataclasses.replace, without its field-by-field __init__)
    new.local, new.frame2, new.offset0 = _local(pairs, h), _frame2(pairs), _offset0(pairs)
    # (a new patch of the same size may slide further or less: a vertex on a face, the floor)
    new.slide_tol2 = np.array([p.slide_tol**2 for p in pairs], dtype=np.float64)
    return new


def _same(a: FloatArray, b: FloatArray) -> bool:
    """Whether two float arrays are the same object or hold the same bits (same shape)."""
    return a is b or (a.shape == b.shape and a.tobytes() == b.tobytes())


def _centre_velocities(extra: list[dict[str, Any]]) -> FloatArray:
    """The pairs' tangential velocities at their patch centres, shape (pairs, 3) [m/s]."""
    if not extra:
        return np.zeros((0, 3))
    return np.array([ex["vt"] for ex in extra])
