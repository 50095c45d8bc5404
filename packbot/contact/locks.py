"""Unilateral joint locks: the clamps of the report's law and of joint-limit stops.

A clamp on joint j with direction s_j = +1 or -1 forbids the joint to accelerate in direction
s_j ("toward the contact"): s_j a_j <= 0. A clamped joint is either

- *engaged*: locked, a_j = 0, held by a constraint torque lambda_j that must push away from the
  contact, s_j lambda_j <= 0; or
- *free*: it moves with the dynamics and does not accelerate toward the contact, s_j a_j <= 0.

A joint clamped in both directions (two contacts) is locked bilaterally. The accelerations obey
M a = tau - h + S^T lambda with S the rows of the engaged joints, so the lock torques act through
the whole arm (unlike zeroing one acceleration after the fact). Which clamped joints are engaged
is the solution of a small linear complementarity problem (unique: its matrix (M^-1)_CC is
positive definite), solved at every restart; inside an integration step the engaged set is
fixed, and the step's end checks the two sign conditions, whose change is an event.

*Held* joints are locked by a bounded torque instead: static joint friction or a brake
(:mod:`packbot.actuators`). A held joint j has a_j = 0 while its holding torque stays within its
bound, |lambda_j| <= F_j; it slips when the holding torque would exceed the bound (an event). A
held joint that is also clamped by a contact slips only if the contact cannot supply the torque
(the contact may push, -s lambda >= 0, whatever the bound).
"""

from __future__ import annotations

from collections.abc import Iterable
from itertools import combinations
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact.lcp import solve_small

_gesv: Any = None
try:  # numpy's LU solver itself (LAPACK gesv), without np.linalg.solve's checks (~6 us a call)
    from numpy.linalg import _umath_linalg

    _gesv = _umath_linalg.solve1
except (ImportError, AttributeError):  # pragma: no cover - another numpy layout
    pass

__all__ = ["ACCEL_BAND", "TORQUE_BAND", "JointLocks"]

#: Hysteresis of the sign conditions: a free clamped joint engages only once it accelerates
#: toward its contact by more than ACCEL_BAND [rad/s^2]; an engaged lock lets go only once its
#: torque would pull by more than TORQUE_BAND [N*m]. Without a band, a joint whose acceleration
#: is exactly zero (the turret under gravity) would switch at every numerical whisper.
ACCEL_BAND = 1e-6
TORQUE_BAND = 1e-6

FloatArray = NDArray[np.float64]
_EMPTY = np.zeros(0)


class JointLocks:
    """The clamps in force and which of them are engaged.

    Args:
        n: The number of joints (None: not known; then :attr:`unlocked` is None).

    Attributes:
        signs: Joint index -> set of forbidden acceleration directions (+1, -1).
        engaged: Joint indices currently locked by their clamps (a_j = 0).
        held: Joint index -> holding-torque bound F_j [N*m] of the joints held by friction or a
            brake (a_j = 0 while |lambda_j| <= F_j).
    """

    def __init__(self, n: int | None = None) -> None:
        self.n = n
        self.signs: dict[int, set[int]] = {}
        self.held: dict[int, float] = {}
        self._locked: list[int] | None = None  # the locked set the arrays below are of
        self._set_engaged(())

    @property
    def any_locked(self) -> bool:
        """Whether some joint is engaged or held (the right-hand side's cheap test)."""
        return bool(self._idx.size)

    @property
    def n_locked(self) -> int:
        """The number of joints engaged or held."""
        return len(self._idx)

    @property
    def locked_index(self) -> NDArray[np.intp]:
        """The joints with a_j = 0 (engaged or held), sorted: a new array when the set changes."""
        return self._idx

    @property
    def locked(self) -> tuple[int, ...]:
        """Every joint with a_j = 0 in the current mode (engaged or held), sorted."""
        return tuple(int(j) for j in self._idx)

    def set_held(self, held: dict[int, float]) -> None:
        """Replace the held joints (joint -> bound [N*m])."""
        self.held = {int(j): float(f) for j, f in held.items()}
        self._set_engaged(self.engaged)

    def set_clamps(self, clamps: Iterable[tuple[int, int]]) -> None:
        """Replace the clamps by (joint, sign) pairs (the union over active contacts)."""
        signs: dict[int, set[int]] = {}
        for j, s in clamps:
            signs.setdefault(int(j), set()).add(int(s))
        self.signs = signs
        self._set_engaged(tuple(j for j in self.engaged if j in signs))

    def _set_engaged(self, engaged: tuple[int, ...]) -> None:
        self.engaged = engaged
        self._screen: FloatArray | None = None  # the conditions' rows (screen_rows)
        #: Whether the current mode has sign conditions: a held joint or a one-sided clamp.
        self.conditional = bool(self.held) or any(len(s) == 1 for s in self.signs.values())
        locked = sorted(set(engaged) | set(self.held))
        if locked == self._locked:
            return  # the same locked set: its arrays (and their identity) kept
        self._locked = locked
        self._idx = np.array(locked, dtype=int)
        self._grid = np.ix_(self._idx, self._idx)
        self._all = -1  # the number of joints if every joint is locked (set at the first use)
        #: The joints not locked (None: n unknown) and their block's index grid.
        self.unlocked: NDArray[np.intp] | None = None
        if self.n is not None:
            kept = set(locked)
            u = np.array([j for j in range(self.n) if j not in kept], dtype=np.intp)
            self.unlocked = u
            # M_UU's entries in the upper triangle of M, flat: M_ij at min(i,j) n + max(i,j)
            lo, hi = np.minimum.outer(u, u), np.maximum.outer(u, u)
            self._uflat = (lo * self.n + hi).ravel()
        self._pos = {int(j): k for k, j in enumerate(self._idx)}

    def accelerations(self, a_free: FloatArray, minv: FloatArray | None) -> FloatArray:
        """Accelerations with the engaged joints locked, from the unconstrained ones.

        This is the right-hand side's hot path: the engaged set's index grid is cached; with
        every joint locked (an arm at rest, each joint held by its static friction) the blocks
        of M^-1 are M^-1 itself (the same numbers, no copy by fancy indexing).

        Args:
            a_free: Accelerations of the unconstrained arm [rad/s^2].
            minv: M^-1 (needed only when some joint is engaged).
        """
        idx = self._idx
        if len(idx) == 0 or minv is None:
            return a_free
        if len(idx) == 1:
            j = int(idx[0])
            return a_free - minv[:, j] * (a_free[j] / minv[j, j])
        return self._solve_locked(a_free, minv)[0]

    def reduced_accelerations(self, mass: FloatArray, force: FloatArray) -> FloatArray:
        """Accelerations of the current mode from the unlocked joints' own equations.

        With the locked set fixed, a_j = 0 on the locked joints and M_UU a_U = f_U on the others
        (U: :attr:`unlocked`; the lock torques act on the locked joints' rows only): the same
        accelerations as :meth:`accelerations` (the Schur complement of M^-1's locked block is
        M_UU^-1), from one solve of the unlocked block, in closed form up to 3 x 3.

        Args:
            mass: The joint-space mass matrix M (armature included); only its upper triangle
                is read (Pinocchio's CRBA fills that one).
            force: tau - C(q, v) v - g(q): the torques besides the locks [N*m].
        """
        assert self.unlocked is not None
        a = np.zeros(len(force))
        u = self.unlocked
        k = len(u)
        if k:
            a[u] = solve_small(mass.take(self._uflat).reshape(k, k), force[u])
        return a

    def _current(
        self, a_free: FloatArray, minv: FloatArray | None
    ) -> tuple[FloatArray, FloatArray]:
        """(accelerations, lock torques) of the current locked set (none: a_free)."""
        if minv is None or not len(self._idx):
            return a_free, _EMPTY
        return self._solve_locked(a_free, minv)

    def _solve_locked(self, a_free: FloatArray, minv: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(accelerations, lock torques) of the current locked set (at least one joint)."""
        idx = self._idx
        if self._all < 0:
            self._all = len(idx) if len(idx) == len(a_free) else 0
        if self._all:
            # minv.T: minv is exactly symmetric, and minv[:, idx] is the Fortran-ordered copy
            # of it, whose product BLAS sums in another order than minv's: minv.T is that layout.
            lam = _solve(minv, -a_free)
            return a_free + minv.T @ lam, lam
        lam = _solve(minv[self._grid], -a_free[idx])
        return a_free + minv[:, idx] @ lam, lam

    @staticmethod
    def _solve(
        a_free: FloatArray, minv: FloatArray | None, idx: NDArray[np.intp]
    ) -> tuple[FloatArray, FloatArray]:
        if len(idx) == 0 or minv is None:
            return a_free, np.zeros(0)
        lam = _solve(minv[idx[:, None], idx], -a_free[idx])  # (np.ix_'s block, without its checks)
        return a_free + minv[:, idx] @ lam, lam

    def conditions(
        self, a_free: FloatArray, minv: FloatArray | None
    ) -> dict[tuple[str, int], float]:
        """Conditions g >= 0 of the current mode, with the locked set fixed.

        Keys ``("clamp", j)``: engaged joint: g = -s lambda (its lock must push away); free
        clamped joint: g = -s a (it must not accelerate toward the contact). Keys
        ``("hold", j)``: g = F_j - |lambda_j| (or the contact pushes). A g below zero is a mode
        change (an event).
        """
        a, lam_arr = self._current(a_free, minv)
        return self.conditions_of(a, lam_arr)

    def conditions_of(self, a: FloatArray, lam_arr: FloatArray) -> dict[tuple[str, int], float]:
        """:meth:`conditions` from the current mode's accelerations and lock torques.

        Args:
            a: Accelerations of the current locked set [rad/s^2].
            lam_arr: The lock torques [N*m] of :attr:`locked`, in its order.
        """
        lam = lam_arr.tolist()  # (Python floats: the same numbers, faster to index)
        out: dict[tuple[str, int], float] = {}
        pos = self._pos
        for j, bound in self.held.items():
            lj = lam[pos[j]]
            g = bound + TORQUE_BAND - abs(lj)
            signs = self.signs.get(j, set())
            if len(signs) == 1:
                (s,) = signs
                g = max(g, -s * lj + TORQUE_BAND)
            out[("hold", j)] = g if len(signs) != 2 else 1.0
        for j, signs in self.signs.items():
            if len(signs) != 1 or j in self.held:
                continue  # bilateral: always engaged; held: its hold condition covers it
            (s,) = signs
            out[("clamp", j)] = (
                -s * lam[pos[j]] + TORQUE_BAND if j in pos else -s * a[j] + ACCEL_BAND
            )
        return out

    def screen_rows(self) -> FloatArray:
        """The conditions of :meth:`conditions_of` as rows (kind, index, s, bound).

        For the native step's screen (:meth:`NativeLocks.end_screen
        <packbot.contact.native.NativeLocks.end_screen>`), in :meth:`conditions_of`'s order:
        kind 0 a held joint (index: its position in :attr:`locked`; s: the sign of its
        one-sided clamp, or 0; its bound [N*m]); 1 an engaged clamp (its position, s); 2 a free
        clamped joint (the joint, s); 3 a constant condition (the bound: a held joint clamped
        both ways, 1). Built once per change of the clamps, holds or engaged set (a new array).
        """
        rows = self._screen
        if rows is None:
            out: list[tuple[float, float, float, float]] = []
            pos = self._pos
            for j, bound in self.held.items():
                signs = self.signs.get(j, set())
                if len(signs) == 2:
                    out.append((3, j, 0, 1.0))
                else:
                    s = next(iter(signs)) if signs else 0
                    out.append((0, pos[j], s, bound))
            for j, signs in self.signs.items():
                if len(signs) != 1 or j in self.held:
                    continue
                (s,) = signs
                out.append((1, pos[j], s, 0.0) if j in pos else (2, j, s, 0.0))
            rows = self._screen = np.array(out, dtype=np.float64).reshape(-1, 4)
        return rows

    def torques(
        self, a_free: FloatArray, minv: FloatArray | None
    ) -> tuple[FloatArray, dict[int, float]]:
        """Accelerations [rad/s^2] and the lock torques lambda_j [N*m] of the locked joints."""
        a, lam = self._current(a_free, minv)
        return a, dict(zip(self._idx.tolist(), lam.tolist(), strict=True))

    def solve_engaged(
        self, a_free: FloatArray, minv: FloatArray, flip: int | None = None, eps: float = 1e-12
    ) -> tuple[int, ...]:
        """Find and set the engaged set (the complementarity problem), by enumeration.

        Args:
            a_free: Unconstrained accelerations [rad/s^2].
            minv: M^-1.
            flip: A joint whose mode an event just changed: among consistent sets, prefer the
                one that toggles it (resolves ties at the exact switching instant).
            eps: Tolerance of the sign conditions (scaled by the acceleration magnitude).
        """
        bilateral = [j for j, s in self.signs.items() if len(s) == 2]
        one_sided = sorted(j for j, s in self.signs.items() if len(s) == 1 and j not in self.held)
        bilateral = sorted(set(bilateral) | set(self.held))
        tol_a = 0.5 * ACCEL_BAND + eps * float(np.abs(a_free).max(initial=0.0))
        tol_t = 0.5 * TORQUE_BAND
        candidates: list[tuple[int, ...]] = []
        for k in range(len(one_sided) + 1):
            for subset in combinations(one_sided, k):
                eng = tuple(sorted((*bilateral, *subset)))
                a, lam = self._solve(a_free, minv, np.array(eng, dtype=int))
                pos = {j: i for i, j in enumerate(eng)}
                ok = True
                for j in one_sided:
                    (s,) = self.signs[j]
                    g = -s * lam[pos[j]] + tol_t if j in pos else -s * a[j] + tol_a
                    if g < 0.0:
                        ok = False
                        break
                if ok:
                    candidates.append(eng)
        if not candidates:  # cannot happen for a positive definite M; be safe: lock them all
            candidates = [tuple(sorted(set(self.signs) | set(self.held)))]
        choice = candidates[0]
        if flip is not None:
            was = flip in self.engaged
            for eng in candidates:
                if (flip in eng) != was:
                    choice = eng
                    break
        engaged = tuple(j for j in choice if j in self.signs)
        self._set_engaged(engaged)
        return engaged


def _solve(G: FloatArray, r: FloatArray) -> FloatArray:
    """:func:`~packbot.contact.lcp.solve_small`, with numpy's LU solve called directly above 3 x 3.

    The same LAPACK routine as ``np.linalg.solve`` (the same numbers), without its argument
    checks and its error-state context (most of its cost on 4 x 4 to 8 x 8 systems: an arm at
    rest locks every joint). An exactly singular matrix (a principal block of M^-1 is positive
    definite: it cannot be, short of a broken model) gives non-finite numbers there (numpy warns
    of an invalid value), and :func:`solve_small` takes over (numpy's solve, least squares).
    """
    if len(r) > 3 and _gesv is not None:
        x = _gesv(G, r, signature="dd->d")
        if np.isfinite(x @ x):
            return x
    return solve_small(G, r)
