"""The contact set of the contact-normal mode: pairs (as patches) and joint limits in contact.

Membership (add, refresh, remove a pair; add, remove a limit), which rows are engaged, and the
caches the rows keep (emptied whenever the set changes).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import _native
from packbot.collision import CollisionWorld, PairInfo
from packbot.collision_queries import material_batch
from packbot.contact.normal_patch import _Pair, _planes
from packbot.contact.normal_tolerances import FACE_ALIGN, PATCH_TOL
from packbot.system import strict_lower

if TYPE_CHECKING:
    from typing_extensions import Self

    from packbot.config import SimConfig
    from packbot.contact.native import NativeRhs
    from packbot.contact.normal_rows import _Layout, _Plan

__all__ = ["ContactSet"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


class ContactSet:
    """The pairs and joint limits in contact, their patches and engaged rows.

    The state of the contact-normal mode's contact set; the layers above it add the rows
    (:class:`~packbot.contact.normal_rows.ContactRows`), the dynamics with the modes fixed,
    the mode selection and the restart's steps (:class:`~packbot.contact.normal.NormalContacts`
    is all of them).

    Args:
        model: The Pinocchio model integrated (reduced if joints are locked).
        data: Its data (shared with the system: every call recomputes what it reads).
        world: The collision world.
        mu: Coulomb friction coefficient of every pair [-].
        restitution: Coefficient of restitution e [-].
        zeno_speed: Impacts slower than this are inelastic [m/s].
        contact_tolerance: Security margin of the patch query [m].
        check_others: Whether the drift projection checks the pairs not in the contact set
            (see :meth:`~packbot.contact.normal_steps.RestartSteps.project`).
    """

    @classmethod
    def from_config(
        cls,
        model: pin.Model,
        data: pin.Data,
        world: CollisionWorld | None,
        config: SimConfig,
        **kwargs: Any,
    ) -> Self:
        """The contact set with ``config``'s friction, restitution, Zeno speed and tolerance."""
        return cls(
            model,
            data,
            world,
            mu=config.mu,
            restitution=config.restitution,
            zeno_speed=config.zeno_speed,
            contact_tolerance=config.contact_tolerance,
            **kwargs,
        )

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        world: CollisionWorld | None,
        *,
        mu: float,
        restitution: float,
        zeno_speed: float,
        contact_tolerance: float,
        check_others: bool = True,
    ) -> None:
        self.model, self.data, self.world = model, data, world
        self.check_others = bool(check_others)
        self.mu = float(mu)
        self.e = float(restitution)
        self.zeno_speed = float(zeno_speed)
        self.tol = float(contact_tolerance)
        self.nv = int(model.nv)
        self.pairs: dict[int, _Pair] = {}
        self.limits: dict[tuple[int, int], float] = {}  # (joint, side) -> limit [rad]
        self.engaged: list[int] = []  # row indices
        self.n_painleve = 0
        #: Energy the drift projections' velocity scaling removed [J]
        #: (``NormalContacts.neutral_velocity``).
        self.projection_energy_removed = 0.0
        #: Joint Coulomb friction and brake torques F_j [N*m] (0: none) and the drive's sliding
        #: directions, for the rest capture (set by the law; None: no joint friction).
        self.joint_coulomb: FloatArray | None = None
        self.joint_fdir: FloatArray | None = None
        self.resting = False  # captured at rest (see capture)
        self.bounced = False  # the last impulse had restitution
        #: the last impulse's touching rows and their impulses (rows, 3), blocks (t1, t2, n)
        #: [N*s, N*m*s] (:meth:`impulse`); None: it applied none
        self.impact_rows: tuple[NDArray[np.intp], FloatArray] | None = None
        #: The law's compiled right-hand side (set by the law; None: the Python path), for the
        #: restart's projection and impact (:mod:`packbot.contact.normal_steps`).
        self.native: NativeRhs | None = None
        #: The joints' position limits (upper, lower) [rad] that the drift projection keeps
        #: (set by the law where ``joint_limits``; None: it does not look at them): a stop it
        #: would move a joint past joins the set (:meth:`RestartSteps._project_round
        #: <packbot.contact.normal_steps.RestartSteps._project_round>`).
        self.stops: tuple[FloatArray, FloatArray] | None = None
        #: The extension's contact rows and constrained accelerations for this set's own calls
        #: (its layout and plan loaded there; built at the first call: see ContactRows._rows_rhs).
        self._rows_native: NativeRhs | None = None
        self._kin_cache: dict[tuple[Any, ...], Any] = {}  # see _kinematics
        self._planes_cache: dict[int, tuple[FloatArray, FloatArray]] = {}
        self._unbounded_cache: dict[int, bool] = {}
        self._built: tuple[bytes, float] = (b"", math.nan)  # (see add_pairs)
        self._lay: _Layout | None = None
        # the last layout built and its shape (see ContactRows._layout): a re-patch that keeps
        # every pair's patch size reuses all of it but the points, frames and offsets
        self._lay_prev: tuple[Any, _Layout] | None = None
        self._pairs_cache: list[_Pair] | None = None
        self._version = 0  # of the contact set, see _invalidate
        # per joint: 1 on the velocities that move its body (its support), (joints, 1, nv)
        self._masks = np.zeros((model.njoints, 1, self.nv))
        for j in range(1, model.njoints):
            for s in list(model.supports[j])[1:]:
                self._masks[j, 0, model.idx_vs[s] : model.idx_vs[s] + model.nvs[s]] = 1.0
        self._lower = strict_lower(self.nv)  # (an nv x nv matrix's strict lower part)
        self._joint_of = np.zeros(self.nv, dtype=np.intp)  # model joint of each velocity
        for j in range(1, model.njoints):
            self._joint_of[model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]] = j
        self._plan_key: tuple[Any, ...] | None = None
        self._plan_val: _Plan
        self._no_slip_dirs = np.zeros((0, 3))
        # the last compiled evaluation and its inputs: see evaluate_again
        self._last_eval: tuple[Any, ...] | None = None
        # the last rest accelerations and their inputs: see ConstrainedDynamics._rest_accel
        self._rest_cache: tuple[Any, ...] | None = None

    @property
    def empty(self) -> bool:
        """No pair and no limit in contact."""
        return not self.pairs and not self.limits

    def add_pair(self, q: FloatArray, pair: int, tol: float | None = None) -> bool:
        """Put a pair in contact (or refresh its patch); False if it is not within tolerance.

        Args:
            q: Configuration [rad].
            pair: The pair's index in the collision world.
            tol: The patch query's security margin [m] (default: the contact tolerance).
        """
        return self.add_pairs(q, [pair], tol)[0]

    def add_pairs(
        self, q: FloatArray, pairs: Sequence[int], tol: float | None = None
    ) -> list[bool]:
        """:meth:`add_pair` for several pairs at one q, in their order; whether each is in.

        The patches of all of them, made material points, come from one call of the compiled
        sweep (:meth:`_add_made`), after one forward kinematics of the model.

        Args:
            q: Configuration [rad].
            pairs: The pairs' indices in the collision world.
            tol: The patch query's security margin [m] (default: the contact tolerance).
        """
        world = self.world
        assert world is not None
        if not pairs:
            return []
        t = self.tol if tol is None else tol
        ks = [world._pair_id(k) for k in pairs]
        self._built = (q.tobytes(), t)  # (the patches are marked with it)
        made = self._add_made(q, ks, t)
        if any(made):
            self._invalidate()  # (once: the caches are not read in between)
        return made

    def _add_made(self, q: FloatArray, ks: list[int], t: float) -> list[bool]:
        """:meth:`add_pairs`'s patches made material points by the extension.

        ``Sweep.materials`` (``src/native/material.hpp``): Coal's patches
        (:func:`~packbot.collision_queries.patch_batch`'s) made material points: each body's
        points moved along the normal onto its face, in its joint's frame; a patch off its
        pair's distance is made from the witness points (:meth:`_put_witness`).
        """
        world = self.world
        assert world is not None
        batch = material_batch(world, q, ks, t, PATCH_TOL, FACE_ALIGN, self._plane_arrays)
        sizes, flags, normals, depths, rot, trans, l1, l2, off, n2, fr2, cen = batch
        pin.forwardKinematics(self.model, self.data, q)  # (the readers of data.oMi expect q)
        pairs, infos, built = self.pairs, world.pairs, self._built
        out, s = [], 0
        for i, k in enumerate(ks):
            K = int(sizes[i])
            if K == -1:
                out.append(False)
                continue
            if K < 0:  # off its distance: the witness points
                self._put_witness(
                    q, k, normals[i], float(depths[i]), rot[i, 0], trans[i, 0], rot[i, 1],
                    trans[i, 1],
                )  # fmt: skip
                out.append(True)
                continue
            flag = int(flags[i])
            p = _Pair(
                infos[k], l1[s : s + K], l2[s : s + K], n2[i], bool(flag & 1),
                offset0=off[2 * s : 2 * (s + K)].reshape(2, K),
            )  # fmt: skip
            p.frame2, p.centre1, p.centre2 = fr2[i], cen[i, 0], cen[i, 1]
            if flag & 2:
                p.slide_tol = math.inf  # (nothing lags: see _put_witness)
            old = pairs.get(k)
            if old is not None:
                p.stick, p.slip_dir = old.stick, old.slip_dir
            p.built = built
            pairs[k] = p
            s += K
            out.append(True)
        return out

    def _plane_arrays(self) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """Every piece's face planes, stacked: (N (F, 3), o (F,), start (G + 1,))."""
        assert self.world is not None
        G = int(self.world.geom_model.ngeoms)
        planes = [self._planes_of(g) for g in range(G)]
        start = np.zeros(G + 1, dtype=np.int64)
        start[1:] = np.cumsum([len(o) for _, o in planes])
        N = np.concatenate([N for N, _ in planes]) if G else np.zeros((0, 3))
        o = np.concatenate([o for _, o in planes]) if G else np.zeros(0)
        return N.reshape(-1, 3), o, start

    def _put_witness(
        self,
        q: FloatArray,
        pair: int,
        n: FloatArray,
        d: float,
        Rg1: FloatArray,
        tg1: FloatArray,
        Rg2: FloatArray,
        tg2: FloatArray,
    ) -> None:
        """Put a pair whose patch is off its distance in the contact set: its witness points.

        Coal's patch of a deep or grazing penetration can place its points far off the pair's
        distance (measured: gaps of -33 mm and +12 mm for a pair 24 um deep, the camera head
        spinning into link 1's tube): one point, the witness pair, instead, made a material
        point by ``packbot._native.patch_material`` (``src/native/material.hpp``). The
        model's kinematics at q; the caller then empties the caches (:meth:`_invalidate`).

        Args:
            q: Configuration [rad].
            pair: The pair's index.
            n: The patch normal (world, body 1 to body 2).
            d: The pair's signed distance [m].
            Rg1: Piece 1's world rotation.
            tg1: Piece 1's world translation [m].
            Rg2: Piece 2's world rotation.
            tg2: Piece 2's world translation [m].
        """
        assert self.world is not None
        old = self.pairs.get(pair)
        info = self.world.pairs[pair]
        frames: dict[int, tuple[Any, ...]] = {}
        _, R1, t1 = self._frame(frames, info.joint1)
        _, R2, t2 = self._frame(frames, info.joint2)
        N1, o1 = self._planes_of(info.geom1)
        N2, o2 = self._planes_of(info.geom2)
        c = self.world.pair_contact(q, pair)
        _, *made = _native.patch_material(
            c.p1[None, :], c.p2[None, :], n, d, N1, o1, Rg1, tg1,
            N2, o2, Rg2, tg2, R1, t1, R2, t2, PATCH_TOL, False,
        )  # fmt: skip
        log.debug(
            "pair %s / %s: patch off its distance %.3g m: witness point used",
            info.piece1,
            info.piece2,
            d,
        )
        local1, local2, normal2, frame2, centre1, centre2, offset0, on1 = made
        p = _Pair(info, local1, local2, normal2, bool(on1), offset0=offset0)
        p.frame2, p.centre1, p.centre2 = frame2, centre1, centre2
        if (len(local1) == 1 or self._unbounded(info.geom1 if on1 else info.geom2)) and _on_a_face(
            N1, Rg1, N2, Rg2, n, bool(on1)
        ):
            # a vertex on a face, or any patch on a halfspace's face (the floor: no edge to
            # slide off, its corners are the other body's material points): nothing lags
            p.slide_tol = math.inf
        if old is not None:
            p.stick, p.slip_dir = old.stick, old.slip_dir
        p.built = self._built
        self.pairs[pair] = p  # (the caller invalidates the caches)

    def _planes_of(self, geom: int) -> tuple[FloatArray, FloatArray]:
        """The face planes of a piece (see :func:`_planes`; none: 0 rows), kept per piece."""
        try:
            return self._planes_cache[geom]
        except KeyError:
            assert self.world is not None
            shape = self.world.geom_model.geometryObjects[geom].geometry
            planes = _planes(shape) or (np.zeros((0, 3)), np.zeros(0))
            self._planes_cache[geom] = planes
            return planes

    def _unbounded(self, geom: int) -> bool:
        """Whether a piece is a halfspace (its one face has no edge), kept per piece."""
        try:
            return self._unbounded_cache[geom]
        except KeyError:
            assert self.world is not None
            shape = self.world.geom_model.geometryObjects[geom].geometry
            out = self._unbounded_cache[geom] = isinstance(shape, coal.Halfspace)
            return out

    def remove_pair(self, pair: int) -> None:
        """Take a pair out of the contact set."""
        self.pairs.pop(pair, None)
        self._invalidate()
        self.engaged = []

    def add_limit(self, joint: int, side: int, limit: float) -> None:
        """Put a joint position limit in contact (side +1: upper, -1: lower)."""
        self.limits[(joint, side)] = float(limit)
        self._invalidate()

    def remove_limit(self, joint: int, side: int) -> None:
        """Take a limit out of the contact set (its row must not be engaged)."""
        if (joint, side) not in self.limits:
            return
        row = self.limit_row(joint, side)
        self.limits.pop((joint, side))
        self._invalidate()
        self.engaged = [r if r < row else r - 1 for r in self.engaged if r != row]

    def limit_row(self, joint: int, side: int) -> int:
        """The row index of a limit in the set (after every pair's rows, in the limits' order)."""
        return sum(len(p.local1) for p in self.pairs.values()) + list(self.limits).index(
            (joint, side)
        )

    def limit_engaged(self, joint: int, side: int) -> bool:
        """Whether a limit's row is engaged."""
        return (joint, side) in self.limits and self.limit_row(joint, side) in self.engaged

    def crossed_stops(self, q: FloatArray) -> list[tuple[int, int, float]]:
        """The stops of :attr:`stops` (joint, side, limit [rad]) q is past, not in the set."""
        if self.stops is None:
            return []
        upper, lower = self.stops
        out = []
        for j in np.flatnonzero((q > upper) | (q < lower)).tolist():
            side, lim = (1, upper[j]) if q[j] > upper[j] else (-1, lower[j])
            if (j, side) not in self.limits:
                out.append((j, side, float(lim)))
        return out

    def _frame(self, frames: dict[int, tuple[Any, ...]], joint: int) -> tuple[Any, ...]:
        """A joint's (placement, rotation, translation) at the last kinematics, kept in frames."""
        M = self._placement(joint)  # (kept: the arrays are views of it)
        out = frames[joint] = (M, M.rotation, M.translation)
        return out

    def _placement(self, joint: int) -> pin.SE3:
        return self.data.oMi[joint] if joint > 0 else pin.SE3.Identity()

    def refresh(self, q: FloatArray) -> None:
        """Recompute every pair's patch at q (drops pairs no longer within tolerance).

        A patch already built at this q with the contact tolerance (a pair that an impact
        has just put in the set) is kept: building it again gives the same patch.
        """
        self.resting = False
        at = (q.tobytes(), self.tol)
        ks = [k for k, p in self.pairs.items() if p.built != at]
        for k, ok in zip(ks, self.add_pairs(q, ks), strict=True):
            if not ok:
                self.pairs.pop(k)
        self._invalidate()
        self.engaged = []

    def row_owner(self, row: int) -> tuple[PairInfo | None, tuple[int, int] | None]:
        """The pair or the limit (joint, side) of a row."""
        k = 0
        for p in self.pairs.values():
            n = len(p.local1)
            if row < k + n:
                return p.info, None
            k += n
        return None, list(self.limits)[row - k]

    def clamp_of_row(self, row: int) -> tuple[int, int] | None:
        """The clamp (joint, s) of a row after the limit rows (the hand-off's only); None."""
        return None

    def row_signature(self) -> tuple[Any, ...]:
        """What the row indices mean: the pairs (index, patch size) and limits, in row order."""
        return tuple((k, len(p.local1)) for k, p in self.pairs.items()), tuple(self.limits)

    def _invalidate(self) -> None:
        """The contact set changed: forget the cached kinematics and point layout."""
        self._kin_cache.clear()
        self._last_eval = None
        self._rest_cache = None
        self._lay = None
        self._pairs_cache = None
        self._version += 1

    def _pair_engaged(self, p: _Pair) -> bool:
        k = 0
        for other in self.pairs.values():
            K = len(other.local1)
            if other is p:
                return any(k <= r < k + K for r in self.engaged)
            k += K
        return False

    @property
    def _pair_list(self) -> list[_Pair]:
        """The pairs in contact, in row order (cached while the contact set holds)."""
        if self._pairs_cache is None:
            self._pairs_cache = list(self.pairs.values())
        return self._pairs_cache


def _on_a_face(
    N1: FloatArray, Rg1: FloatArray, N2: FloatArray, Rg2: FloatArray, n: FloatArray, on1: bool
) -> bool:
    """Whether the patch normal n (world, body 1 to body 2) is a face normal of its body.

    Body 1's outward face normal is +n, body 2's -n (face planes N in each piece's frame,
    placements Rg1, Rg2); to within :data:`FACE_ALIGN` (1 - cos).
    """
    if on1:
        N, m = N1, Rg1.T @ n
    else:
        N, m = N2, -(Rg2.T @ n)
    return bool(len(N)) and float((N @ m).max()) >= 1.0 - FACE_ALIGN
