"""The contact-normal mode (``contact_mode="normal"``): patches, complementarity, Coulomb friction.

**Rows.** Each touching pair is represented by its contact patch (Coal's ``computeContactPatch``:
4 points face on face, 2 edge on face, 1 vertex on face), one *normal row* per patch point. A
point is stored as two material points, p1 on body 1 and p2 on body 2 (in their joint frames),
and the normal n in body 2's frame; its gap is g = n . (p2 - p1) [m] and its normal Jacobian
J_n = n^T (J_p2 - J_p1), so g' = J_n v (n points from body 1 to body 2: g' > 0 separates). A
joint at a position limit adds a row too: gap s (limit - q_j) [rad], J = -s e_j (s = +1 upper,
-1 lower). The patches are recomputed at every restart.

**Forces.** Contact forces lambda_k >= 0 act along the normals: M a = tau - h + J_n^T lambda (+
friction). Coulomb friction (coefficient mu) acts per pair at the patch centre: a *sticking*
pair has two tangential rows (zero relative tangential acceleration, force lambda_t free,
checked against the cone |lambda_t| <= mu sum(lambda_n)); on a *slipping* pair each point's
friction force is -mu lambda_k s, s the unit sliding direction of body 2 relative to body 1.

**Modes.** Inside an integration step the modes are fixed: which normal rows are engaged
(a_n = 0, lambda free) and which pairs stick or slip; the right-hand side then solves a small
linear system (smooth, so steps stay long). A light Baumgarte term (a_n = -2 w g' - w^2 g with
w = :data:`BAUMGARTE`) holds the engaged gaps at zero against integration drift. At the end of
every step the mode conditions are checked; a violated one is an event located by root finding:

- an engaged row's force would pull (lambda < 0): ``release``;
- a free row of a pair in contact penetrates (g < -:data:`POINT_TOL`): ``impact``;
- a sticking pair's force leaves the cone: ``slip``;
- a slipping pair's sliding velocity comes back through zero by :data:`STICK_BAND` along its
  friction direction: ``stick``;
- a resting arm's accelerations leave the rest band (see below): ``slip``.

**Restart.** After every event the patches are recomputed, then:

1. *impulse*: every row touching (g <= :data:`TOUCH_GAP`) takes part in one impulse problem,
   Newton's law per row with restitution e (0 below the Zeno speed
   :attr:`SimConfig.zeno_speed`: a bounce so slow becomes resting contact); frictionless, an LCP
   on the Delassus matrix G = J M^-1 J^T (:func:`packbot.contact.lcp.solve_lcp_psd`); with
   friction, Pinocchio's ADMM on point-contact cones
   (:func:`packbot.contact.lcp.solve_ncp_admm`); residuals checked;
2. *modes*: the acceleration-level problem with the touching rows (lambda >= 0, a_n >= 0,
   complementary), sticking pairs' tangential rows eliminated, sliding friction making it
   non-symmetric (Lemke); a sticking pair whose force leaves the cone is switched to slip and
   the problem solved again. No solution (Painleve: friction making the problem inconsistent)
   is logged as an event and handled impulsively: the sliding pairs are stopped by a
   frictional impulse and the problem is solved with them sticking.

The engaged rows are the support of the solution, which both solvers return *basic* (the
engaged rows' Delassus block is non-singular even on a rank-deficient patch).

**Rest.** At a restart where every joint is slower than :data:`CAPTURE_SPEED` (and the impulse
was not a bounce), the frictional problem of every touching row is solved jointly at v = 0
(per-point cones, ADMM); if its joint accelerations are below :data:`CAPTURE_ACCEL` the
velocity is set to zero and the contacts rest (a = 0, one condition: those accelerations below
twice the band). The pair-by-pair cone check above cannot do this on a statically indeterminate
arm: it takes one force distribution of many (see :meth:`NormalContacts.capture`).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.collision import CollisionWorld, PairInfo
from packbot.contact import native
from packbot.contact.base import Active, Crossing, Key
from packbot.contact.lcp import (
    SMALL_LCP,
    lcp_residual,
    lemke,
    solve_lcp_psd,
    solve_mixed_admm,
    solve_ncp_admm,
    solve_small,
)
from packbot.contact.locks import JointLocks
from packbot.contact.pairs import PairLaw
from packbot.contact.timestep import QUIET_STEPS, MoreauJeanStepper
from packbot.ode import DenseSegment, StepKernel
from packbot.system import System

if TYPE_CHECKING:
    from typing_extensions import Self

    from packbot.config import SimConfig

__all__ = [
    "BAUMGARTE",
    "CAPTURE_ACCEL",
    "CAPTURE_SPEED",
    "CASCADE_EVENTS",
    "CASCADE_SPAN",
    "CHATTER_EVENTS",
    "CHATTER_SPAN",
    "CRAWL_STEP",
    "CRAWL_STEPS",
    "FORCE_BAND",
    "HOLD_SPEED",
    "PATCH_TOL",
    "PENETRATION_TOL",
    "POINT_TOL",
    "PROJECT_ROUNDS",
    "RELAPSE_EVENTS",
    "RELAPSE_SPAN",
    "SLIDE_TOL",
    "SPEED_BAND",
    "STICK_BAND",
    "TOUCH_GAP",
    "WINDOW_MIN",
    "ModeEvent",
    "NormalContacts",
    "NormalLaw",
    "PatchEvents",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: A row takes part in the impulse and acceleration problems when its gap is below this [m].
TOUCH_GAP = 1e-5
#: A free row of a pair in contact is an impact when its gap falls below -POINT_TOL [m].
POINT_TOL = 1e-6
#: A pair in contact whose signed distance falls below -PENETRATION_TOL [m] is re-patched (its
#: patch no longer describes the touching features).
PENETRATION_TOL = 1e-5
#: A patch whose smallest point gap is farther than this from the pair's distance [m] is not
#: used (see :meth:`NormalContacts.add_pair`).
PATCH_TOL = 1e-4
#: Hysteresis of the force conditions [N] (release, cone).
FORCE_BAND = 1e-6
#: A touching row separating slower than this takes part in the mode problem [m/s].
SPEED_BAND = 1e-6
#: Hysteresis of the stick condition [m/s]: a slipping pair sticks once its sliding velocity
#: has come back through zero by this much along its friction direction. Smaller bands let
#: a pair sliding at the cone's edge with almost no acceleration (the arm's elbow casing on the
#: chassis while link 3 slides) fire a stick event every few milliseconds, each followed by an
#: immediate slip: the restarts then keep resetting the other pair's slide (measured: a
#: stick/slip pair of events every 3.35 ms with 1e-6 m/s).
STICK_BAND = 1e-4
#: A pair may start sticking when its sliding speed is below this [m/s] (the stick mode's
#: velocity term removes the rest).
STICK_SPEED = 1e-3
#: Rest capture (:meth:`NormalContacts.capture`): at a restart, an arm slower than this
#: [rad/s] whose contacts can all stick at v = 0 with accelerations below CAPTURE_ACCEL
#: [rad/s^2] is brought to rest.
CAPTURE_SPEED = 1e-2
CAPTURE_ACCEL = 1e-2
#: A sliding pair's patch is rebuilt once its material points have slid this far apart
#: tangentially since it was built [m] (see :meth:`NormalContacts.stale`): the patch points are
#: where the contact forces act, so 0.1 mm moves a force's point of application by less than
#: 1e-3 of the arm's lever arms (0.1 to 0.5 m); the gap condition of ``stale`` catches a
#: curved body's next facet, or a point sliding off its face, much earlier.
SLIDE_TOL = 1e-4
#: Stiffness of the drift correction [rad/s] (a_n = -2 w g' - w^2 g on engaged rows).
BAUMGARTE = 20.0
#: A cascade: CASCADE_EVENTS restarts within CASCADE_SPAN [s] (a pile-up at one instant), or
#: CHATTER_EVENTS within CHATTER_SPAN [s] (a chattering slide: the drive-pose collapse with the
#: wrist free and mu = 0.8 made 10,000 a second) start a time-stepping window.
CASCADE_EVENTS = 20
CASCADE_SPAN = 1e-3
CHATTER_EVENTS = 32
CHATTER_SPAN = 0.032
#: The stepper crawls when CRAWL_STEPS accepted steps average less than CRAWL_STEP [s] (a slow
#: slide whose friction direction turns is stiff for the explicit stepper: measured 117,824
#: steps of 7 us in 0.8 s on a wrist-free start; the collapse averages 2.3 ms): a window opens.
CRAWL_STEPS = 400
CRAWL_STEP = 2.5e-5
#: A joint with Coulomb friction or a brake slower than this [rad/s] while contacts push
#: starts a window (its hold and the contact forces are one problem).
HOLD_SPEED = 1e-3
#: The shortest time-stepping window [s]; doubled when a cascade follows the previous window's
#: end within RELAPSE_SPAN [s].
WINDOW_MIN = 0.02
RELAPSE_SPAN = 0.05
#: Within RELAPSE_SPAN of a window's end, RELAPSE_EVENTS restarts within CASCADE_SPAN start the
#: next window (a relapse: the resumed state cascades at once; measured on wrist-free start 4,
#: mu 0.8: each of its six resumes was followed by 24 stick/slip restarts within 0.5 ms, a few
#: milliseconds of CPU time each, before the 20th opened the next window).
RELAPSE_EVENTS = 5
#: Largest acceptable scaled residual of a complementarity solution [-].
RESIDUAL_TOL = 1e-7
#: Rounds of the drift projection (:meth:`NormalContacts.project`): each adds to the contact set
#: the pairs that the previous one made penetrate.
PROJECT_ROUNDS = 3


@dataclass
class _Pair:
    """A pair in contact: its patch as material points and its friction mode."""

    info: PairInfo
    local1: FloatArray  # (K, 3) points on body 1, joint1 frame [m]
    local2: FloatArray  # (K, 3) points on body 2, joint2 frame [m]
    normal2: FloatArray  # (3,) normal in joint2 frame
    stick: bool = True
    slip_dir: FloatArray = field(default_factory=lambda: np.zeros(3))  # world, at onset
    # (2, K) tangential offsets (t1, t2 of the contact frame) of p2 - p1 when built [m]
    offset0: FloatArray = field(default_factory=lambda: np.zeros((2, 0)))
    # the patch centres (means of the points) in the joint frames [m] and the contact frame
    # (rows t1, t2, n) in body 2's joint frame: computed once, for the point layout
    centre1: FloatArray = field(init=False)
    centre2: FloatArray = field(init=False)
    frame2: FloatArray = field(init=False)


@dataclass
class _Layout:
    """Where the patch points of the contact set are, for the batched kinematics.

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
    normal_body: NDArray[np.intp]  # (pairs,) index into joints of body 2
    frame2: FloatArray  # (pairs, 3, 3) rows t1, t2, n in body 2's joint frame
    points: list[slice]  # per pair, its patch points among the h
    lim_joint: NDArray[np.intp]  # (limits,) velocity index of each limit row
    lim_side: FloatArray  # (limits,) +1 upper, -1 lower
    lim_value: FloatArray  # (limits,) the limit [rad]
    offset0: FloatArray  # (m_p, 2) per pair row, its tangential offset when built [m]
    no_bodies: FloatArray  # (0, 4, 4), the placements when no pair is in contact
    # (position in joints, Pinocchio's live reference to data.oMi[joint]) of the moving joints
    placements: list[tuple[int, Any]]
    H: FloatArray  # (bodies, 4, 4) buffer of the placements (the world's: identity)
    no_jacobian: FloatArray  # (6, nv) zeros, the Jacobians when no pair is in contact
    fixed: tuple[Any, ...] = ()  # body ... lim_value: the kernels' arguments after q, v


@dataclass
class ModeEvent:
    """A mode change found at a restart (for the event log).

    Attributes:
        kind: ``"stick"``, ``"slip"``, ``"release"`` or ``"painleve"``.
        pair: The pair (None for a limit row).
        detail: Extra text (a limit row's joint).
    """

    kind: str
    pair: PairInfo | None
    detail: str = ""


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


@dataclass
class _Eval:
    """The constrained dynamics at one state with the modes fixed."""

    a: FloatArray
    lam: FloatArray  # forces of the engaged normal rows then the stick rows
    gap: FloatArray  # every row
    vn: FloatArray  # every row
    vt: FloatArray  # (pairs, 3): relative tangential velocity at each patch centre (world)
    rest: tuple[FloatArray, FloatArray, FloatArray] | None = None  # (q, a_free, M^-1) at rest
    # the rows' generalized force C^T lambda [N*m] (numpy path only; None: not computed)
    qc: FloatArray | None = None
    cond: float | None = None  # the smallest mode condition (compiled path; see violated)
    slide2: FloatArray | None = None  # (pairs,) largest squared slide (compiled; see stale)


class NormalContacts:
    """The contact set of the normal mode, its modes, and the constrained dynamics.

    Args:
        model: The Pinocchio model integrated (reduced if joints are locked).
        data: Its data (shared with the system: every call recomputes what it reads).
        world: The collision world.
        mu: Coulomb friction coefficient of every pair [-].
        restitution: Coefficient of restitution e [-].
        zeno_speed: Impacts slower than this are inelastic [m/s].
        contact_tolerance: Security margin of the patch query [m].
        check_others: Whether the drift projection checks the pairs not in the contact set
            (see :meth:`project`).
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
        #: Joint Coulomb friction and brake torques F_j [N*m] (0: none) and the drive's sliding
        #: directions, for the rest capture (set by the law; None: no joint friction).
        self.joint_coulomb: FloatArray | None = None
        self.joint_fdir: FloatArray | None = None
        self.resting = False  # captured at rest (see capture)
        self.bounced = False  # the last impulse had restitution
        self._kin_cache: dict[tuple[bytes, bytes], Any] = {}  # see _kinematics
        self._planes_cache: dict[int, tuple[FloatArray, FloatArray]] = {}
        self._lay: _Layout | None = None
        self._pairs_cache: list[_Pair] | None = None
        self._version = 0  # of the contact set, see _invalidate
        # per joint: 1 on the velocities that move its body (its support), (joints, 1, nv)
        self._masks = np.zeros((model.njoints, 1, self.nv))
        for j in range(1, model.njoints):
            for s in list(model.supports[j])[1:]:
                self._masks[j, 0, model.idx_vs[s] : model.idx_vs[s] + model.nvs[s]] = 1.0
        self._joint_of = np.zeros(self.nv, dtype=np.intp)  # model joint of each velocity
        for j in range(1, model.njoints):
            self._joint_of[model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]] = j
        self._plan_key: tuple[Any, ...] | None = None
        self._plan_val: _Plan
        self._no_slip_dirs = np.zeros((0, 3))
        # the last compiled evaluation and its inputs: see evaluate_again
        self._last_eval: tuple[Any, ...] | None = None

    # ------------------------------------------------------------------ set
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
        assert self.world is not None
        patch = self.world.contact_patch(q, pair, self.tol if tol is None else tol)
        pin.forwardKinematics(self.model, self.data, q)
        if patch is None:
            return False
        from packbot.contact import kernels  # lazy: numba is imported by contact runs only

        old = self.pairs.get(pair)
        info = patch.pair
        M1 = self._placement(info.joint1)
        M2 = self._placement(info.joint2)
        R1, t1, R2, t2 = M1.rotation, M1.translation, M2.rotation, M2.translation
        gd = self.world.geom_data
        G1, G2 = gd.oMg[info.geom1], gd.oMg[info.geom2]
        N1, o1 = self._planes_of(info.geom1)
        N2, o2 = self._planes_of(info.geom2)
        n, d = patch.normal, float(patch.distance)
        ok, *made = kernels.patch_material(
            patch.points1, patch.points2, n, d, N1, o1, G1.rotation, G1.translation,
            N2, o2, G2.rotation, G2.translation, R1, t1, R2, t2, PATCH_TOL, True,
        )  # fmt: skip
        if not ok:
            # Coal's patch of a deep or grazing penetration can place its points far off the
            # pair's distance (measured: gaps of -33 mm and +12 mm for a pair 24 um deep, the
            # camera head spinning into link 1's tube): one point, the witness pair, instead.
            c = self.world.pair_contact(q, pair)
            ok, *made = kernels.patch_material(
                c.p1[None, :], c.p2[None, :], n, d, N1, o1, G1.rotation, G1.translation,
                N2, o2, G2.rotation, G2.translation, R1, t1, R2, t2, PATCH_TOL, False,
            )  # fmt: skip
            log.debug(
                "pair %s / %s: patch off its distance %.3g m: witness point used",
                info.piece1,
                info.piece2,
                patch.distance,
            )
        local1, local2, normal2, frame2, centre1, centre2, offset0 = made
        p = _Pair(info, local1, local2, normal2, offset0=offset0)
        p.frame2, p.centre1, p.centre2 = frame2, centre1, centre2
        if old is not None:
            p.stick, p.slip_dir = old.stick, old.slip_dir
        self.pairs[pair] = p
        self._invalidate()
        return True

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
        keys = list(self.limits)
        if (joint, side) not in self.limits:
            return
        row = sum(len(p.local1) for p in self.pairs.values()) + keys.index((joint, side))
        self.limits.pop((joint, side))
        self._invalidate()
        self.engaged = [r if r < row else r - 1 for r in self.engaged if r != row]

    def limit_engaged(self, joint: int, side: int) -> bool:
        """Whether a limit's row is engaged."""
        if (joint, side) not in self.limits:
            return False
        row = sum(len(p.local1) for p in self.pairs.values()) + list(self.limits).index(
            (joint, side)
        )
        return row in self.engaged

    def _placement(self, joint: int) -> pin.SE3:
        return self.data.oMi[joint] if joint > 0 else pin.SE3.Identity()

    def refresh(self, q: FloatArray) -> None:
        """Recompute every pair's patch at q (drops pairs no longer within tolerance)."""
        self.resting = False
        for k in list(self.pairs):
            if not self.add_pair(q, k):
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

    # ------------------------------------------------------------------ kinematics
    def _kinematics(
        self, q: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[dict[str, Any]]]:
        """Rows of every contact: J_n (m, nv), drift (m,), gap (m,), v_n (m,).

        And per pair the tangential rows and the velocities at the patch centre
        (:func:`packbot.contact.kernels.contact_rows`, compiled: every patch point of every
        pair at once). The result depends only on (q, v) and the contact set, so it is cached
        (a few states: the mode conditions and the restart's problems ask for the same state
        several times); the cache is emptied whenever the contact set changes. The arrays
        returned are read-only.
        """
        key = (q.tobytes(), v.tobytes())
        hit = self._kin_cache.get(key)
        if hit is not None:
            return hit
        raw = _kernels().contact_rows(*self._kernel_args(q, v))
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

    def _kernel_args(self, q: FloatArray, v: FloatArray) -> tuple[Any, ...]:
        """The arguments of :func:`packbot.contact.kernels.contact_rows` at (q, v).

        With pairs in contact, one Pinocchio call: the joint Jacobians in the world frame and
        their time variation (``data.J``, ``data.dJ``: per body, the spatial velocity J v and
        the drift acceleration J' v at the world origin).
        """
        lay = self._layout()
        return (*self._bodies(lay, q, v), lay.masks, q, v, *lay.fixed)

    def _bodies(
        self, lay: _Layout, q: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The bodies' placements H, the joint Jacobians J and their time variation dJ."""
        if not lay.joints:
            return lay.no_bodies, lay.no_jacobian, lay.no_jacobian
        model, data = self.model, self.data
        pin.computeJointJacobiansTimeVariation(model, data, q, v)
        H = lay.H  # (filled here, read by the kernel only)
        for i, M in lay.placements:
            H[i] = M.homogeneous
        nv = self.nv
        return H, data.J.reshape(6, nv), data.dJ.reshape(6, nv)  # (nv = 1: data.J is (6,))

    def _layout(self) -> _Layout:
        """The point layout of the current contact set (cached until it changes)."""
        if self._lay is not None:
            return self._lay
        pairs = list(self.pairs.values())
        joints = sorted({p.info.joint1 for p in pairs} | {p.info.joint2 for p in pairs})
        index = {j: i for i, j in enumerate(joints)}
        body1: list[int] = []
        body2: list[int] = []
        pair: list[int] = []
        rows: list[int] = []
        centre: list[int] = []
        local1: list[FloatArray] = []
        local2: list[FloatArray] = []
        points: list[slice] = []
        k = 0
        for i, p in enumerate(pairs):
            K = len(p.local1)
            local1 += [p.local1, p.centre1]
            local2 += [p.local2, p.centre2]
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
            local=np.hstack([np.vstack(local1 + local2), np.ones((2 * k, 1))])
            if pairs
            else np.zeros((0, 4)),
            pair=np.array(pair, dtype=np.intp),
            rows=np.array(rows, dtype=np.intp),
            centre=np.array(centre, dtype=np.intp),
            normal_body=np.array([index[p.info.joint2] for p in pairs], dtype=np.intp),
            frame2=np.array([p.frame2 for p in pairs]) if pairs else np.zeros((0, 3, 3)),
            points=points,
            lim_joint=np.array([j for (j, _), _ in limits], dtype=np.intp),
            lim_side=np.array([side for (_, side), _ in limits], dtype=np.float64),
            lim_value=np.array([value for _, value in limits], dtype=np.float64),
            offset0=np.ascontiguousarray(np.vstack([p.offset0.T for p in pairs]))
            if pairs
            else np.zeros((0, 2)),
            no_bodies=np.zeros((0, 4, 4)),
            no_jacobian=np.asfortranarray(np.zeros((6, self.nv))),
            placements=[(i, self.data.oMi[j]) for i, j in enumerate(joints) if j],
            H=np.array([_I4 for _ in joints]) if joints else np.zeros((0, 4, 4)),
        )
        lay = self._lay
        lay.fixed = (
            lay.body,
            lay.local,
            lay.pair,
            lay.rows,
            lay.centre,
            lay.normal_body,
            lay.frame2,
            lay.lim_joint,
            lay.lim_side,
            lay.lim_value,
        )
        return lay

    def _invalidate(self) -> None:
        """The contact set changed: forget the cached kinematics and point layout."""
        self._kin_cache.clear()
        self._last_eval = None
        self._lay = None
        self._pairs_cache = None
        self._version += 1

    @staticmethod
    def _direction_rows(ex: dict[str, Any], d: FloatArray) -> FloatArray:
        """d^T (J_p2 - J_p1) at every patch point of a pair, shape (K, nv); d (3,) world."""
        return np.asarray(d @ ex["dJ"], dtype=np.float64)

    # ------------------------------------------------------------------ dynamics
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
                s = self._slip_direction(p, ex)
                C[k : k + K] -= self.mu * self._direction_rows(ex, s)
            k += K
        return C

    def _slip_direction(self, p: _Pair, ex: dict[str, Any]) -> FloatArray:
        """The unit sliding direction of body 2 relative to body 1 at the patch centre (world).

        It follows the sliding velocity v_t inside a step (a direction frozen at the onset
        lets the friction force turn v_t sideways: an event every few degrees), blended with
        the onset direction below :data:`STICK_SPEED`: s = (v_t + STICK_SPEED s0) / |...|, so
        a slip starting from rest has the direction of its onset and a slowing slide keeps a
        smooth direction until its stick event.
        """
        w = ex["vt"] + STICK_SPEED * p.slip_dir
        nw = math.sqrt(float(w @ w))
        return np.asarray(w / nw if nw > 0.0 else p.slip_dir, dtype=np.float64)

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

    def _pair_engaged(self, p: _Pair) -> bool:
        k = 0
        for other in self.pairs.values():
            K = len(other.local1)
            if other is p:
                return any(k <= r < k + K for r in self.engaged)
            k += K
        return False

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

    @property
    def _pair_list(self) -> list[_Pair]:
        """The pairs in contact, in row order (cached while the contact set holds)."""
        if self._pairs_cache is None:
            self._pairs_cache = list(self.pairs.values())
        return self._pairs_cache

    def evaluate(self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray) -> _Eval:
        """Constrained accelerations with the modes fixed, and what the conditions need.

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            a_free: Unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.
        """
        if self.resting:  # captured: at rest while the rest condition holds
            _, _, gap, vn, extra = self._problem(q, v)
            vt = _centre_velocities(extra)
            return _Eval(np.zeros(self.nv), np.zeros(0), gap, vn, vt, (q, a_free, minv))
        plan = self._plan()
        if not len(plan.engaged):
            _, _, gap, vn, extra = self._problem(q, v)
            return _Eval(a_free, np.zeros(0), gap, vn, _centre_velocities(extra))
        if type(self)._problem is _OWN_PROBLEM:
            return self._evaluate_compiled(q, v, a_free, minv, plan)
        return self._evaluate_rows(q, v, a_free, minv, plan)

    def _evaluate_rows(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray, plan: _Plan
    ) -> _Eval:
        """:meth:`evaluate` on the rows of :meth:`_problem`, in numpy.

        The same problem as :meth:`_evaluate_compiled`, on any subclass's rows (the hand-off's
        clamps).
        """
        Jn, drift, gap, vn, extra = self._problem(q, v)
        vt = _centre_velocities(extra)
        E = plan.engaged
        A = Jn[E]  # the engaged rows, then the sticking pairs' tangential rows
        Cm = A  # their force columns (J_n - mu J_s on slipping pairs' rows)
        if plan.slips:
            Cm = A.copy()
            for i, pos, loc in plan.slips:
                ex = extra[i]
                s = self._slip_direction(self._pair_list[i], ex)
                Cm[pos] -= self.mu * (s @ ex["dJ"][loc])
        target = -2.0 * BAUMGARTE * vn[E] - BAUMGARTE**2 * gap[E]
        b = drift[E]
        if len(plan.sticks):
            JT = [extra[i]["JT"] for i in plan.sticks]
            A = np.vstack([A, *JT])
            Cm = np.vstack([Cm, *JT])
            vT = np.concatenate([extra[i]["vT"] for i in plan.sticks])
            target = np.concatenate([target, -BAUMGARTE * vT])
            b = np.concatenate([b, *(extra[i]["bT"] for i in plan.sticks)])
        b = A @ a_free + b
        MC = minv @ Cm.T
        Gm = A @ MC
        lam = solve_small(Gm, target - b)
        return _Eval(a_free + MC @ lam, lam, gap, vn, vt, qc=Cm.T @ lam)

    def _evaluate_compiled(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray, plan: _Plan
    ) -> _Eval:
        """:meth:`evaluate` in one compiled call (``kernels.constrained_accel``)."""
        kernels = _kernels()
        if plan.slips:
            slip_dir = np.array([p.slip_dir for p in self._pair_list])
        else:
            slip_dir = self._no_slip_dirs
        lay = self._layout()
        args: tuple[Any, ...] = (
            *self._bodies(lay, q, v), lay.masks, q, v, *lay.fixed,
            plan.engaged, plan.row_slip, plan.sticks, slip_dir, a_free, minv,
            self.mu, STICK_SPEED, BAUMGARTE, lay.offset0, FORCE_BAND, POINT_TOL, STICK_BAND,
        )  # fmt: skip
        a, lam, gap, vn, vt, ok, cond, slide2 = kernels.constrained_accel(*args)
        if not ok:  # a singular Delassus matrix: numpy's path (least squares)
            return self._evaluate_rows(q, v, a_free, minv, plan)
        ev = _Eval(a, lam, gap, vn, vt, cond=cond, slide2=slide2)
        # Kept for the same state asked again (the step's end: the stepper's last stage, then
        # the mode conditions and the sliding check): references, compared by value.
        self._last_eval = (q, v, a_free, minv, slip_dir, self._plan_key, ev)
        return ev

    def evaluate_again(
        self, q: FloatArray, v: FloatArray, a_free: FloatArray, minv: FloatArray
    ) -> _Eval:
        """:meth:`evaluate`, reusing the last compiled evaluation when it was at these inputs.

        The mode conditions at a step's end ask for the state of the stepper's last stage,
        which the right-hand side has just evaluated (same q, v, free accelerations, M^-1,
        modes and sliding directions: compared by value, so the result is the one
        :meth:`evaluate` would compute).
        """
        last = self._last_eval
        if last is not None and not self.resting and type(self).evaluate is _OWN_EVALUATE:
            plan = self._plan()  # (brings _plan_key up to the current modes)
            if (
                last[5] == self._plan_key
                and _same(last[0], q)
                and _same(last[1], v)
                and _same(last[2], a_free)
                and _same(last[3], minv)
                and (
                    not plan.slips
                    or _same(last[4], np.array([p.slip_dir for p in self._pair_list]))
                )
            ):
                return last[6]
        return self.evaluate(q, v, a_free, minv)

    def conditions(self, ev: _Eval) -> dict[tuple[Any, ...], tuple[str, float]]:
        """Mode conditions g >= 0 (a negative one is an event) with the event kind.

        Keys: ``("nrow", i)`` (engaged: release; free: impact), ``("nfric", k)`` (stick: slip;
        slip: stick).
        """
        out: dict[tuple[Any, ...], tuple[str, float]] = {}
        if ev.rest is not None:
            a = self._rest_accel(*ev.rest)
            margin = -1.0 if a is None else 2.0 * CAPTURE_ACCEL - float(np.abs(a).max())
            return {("nrest", 0): ("slip", margin)}
        E = self.engaged
        pos = {r: i for i, r in enumerate(E)}
        for r in range(len(ev.gap)):
            if r in pos:
                out[("nrow", r)] = ("release", float(ev.lam[pos[r]]) + FORCE_BAND)
            else:
                out[("nrow", r)] = ("impact", float(ev.gap[r]) + POINT_TOL)
        if self.mu > 0.0:
            k_row, k_t = 0, len(E)
            for (key, p), vt in zip(self.pairs.items(), ev.vt, strict=True):
                K = len(p.local1)
                rows = [pos[r] for r in range(k_row, k_row + K) if r in pos]
                k_row += K
                if not rows:
                    continue
                if p.stick:
                    lt = ev.lam[k_t : k_t + 2]
                    k_t += 2
                    g = self.mu * float(ev.lam[rows].sum()) - float(np.linalg.norm(lt))
                    out[("nfric", key)] = ("slip", g + FORCE_BAND)
                else:
                    # v_t along the friction direction (blended with the onset direction):
                    # negative once the slide has come back through zero.
                    w = vt + STICK_SPEED * p.slip_dir
                    g = float(vt @ w) / max(float(np.linalg.norm(w)), 1e-300)
                    out[("nfric", key)] = ("stick", g + STICK_BAND)
        return out

    def violated(self, ev: _Eval) -> bool:
        """Whether a mode condition of :meth:`conditions` is negative (an event).

        The same values as :meth:`conditions`, without building its dictionary (the step's
        end asks this once per step; the conditions themselves only when one is negative).
        """
        if ev.rest is not None or type(self).conditions is not _OWN_CONDITIONS:
            return any(g < 0.0 for _, g in self.conditions(ev).values())
        if ev.cond is not None:  # the kernel's smallest condition
            return ev.cond < 0.0
        plan = self._plan()
        E = plan.engaged
        ne = len(E)
        if len(ev.gap):
            g = ev.gap + POINT_TOL
            if ne:
                g[E] = ev.lam[:ne] + FORCE_BAND
            if bool((g < 0.0).any()):
                return True
        if self.mu > 0.0:
            k_t = ne
            for at in plan.stick_at:
                lt = ev.lam[k_t : k_t + 2]
                k_t += 2
                gs = self.mu * float(ev.lam[at].sum()) - float(np.linalg.norm(lt))
                if gs + FORCE_BAND < 0.0:
                    return True
            pairs = self._pair_list
            for i, _, _ in plan.slips:
                vt = ev.vt[i]
                w = vt + STICK_SPEED * pairs[i].slip_dir
                gs = float(vt @ w) / max(float(np.linalg.norm(w)), 1e-300)
                if gs + STICK_BAND < 0.0:
                    return True
        return False

    # ------------------------------------------------------------------ restart
    def restart(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """Drift correction, impulse, then modes, at a restart.

        Args:
            q: Configuration [rad].
            v: Velocity before [rad/s].
            a_free_fn: Callable (q, v) -> unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.

        Returns:
            The configuration after the drift correction, the velocity after the impulse and
            the mode changes to log.
        """
        self.refresh(q)
        events: list[ModeEvent] = []
        q_in = q
        q = self.project(q, v, minv)
        if q is not q_in and not np.array_equal(q, q_in):
            # the impulse's energy balance is exact only with M at the q it acts on
            Mi = np.asarray(pin.computeMinverse(self.model, self.data, q), dtype=np.float64)
            minv = np.triu(Mi) + np.triu(Mi, 1).T
        self.bounced = False
        v = self.impulse(q, v, minv)
        v = self.stop_slow(q, v, minv)
        captured = self.capture(q, v, a_free_fn, minv)
        if captured is not None:
            return q, np.zeros_like(v), events + captured
        events += self.select_modes(q, v, a_free_fn(q, v), minv)
        return q, v, events

    def capture(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> list[ModeEvent] | None:
        """Bring a slow arm to rest when it can stay there (rest capture).

        When every joint speed is below :data:`CAPTURE_SPEED` and, at v = 0, the frictional
        contact problem of every touching row (per-point Coulomb cones, solved jointly by
        :func:`packbot.contact.lcp.solve_ncp_admm`) has joint accelerations below
        :data:`CAPTURE_ACCEL`, the velocity is set to zero and the contacts are *resting*:
        a = 0 until the rest condition (the same accelerations below 2 CAPTURE_ACCEL) fails.
        This is a documented regularisation of the mode decision, not of the forces. The
        joint problem is needed because a statically indeterminate arm (4 dof, an edge patch
        and a second contact: 7 rows) has many force distributions; the pair-by-pair cone check
        of :meth:`select_modes` takes one of them and finds it outside the cone (measured: 1.9
        times the cone on the elbow casing) where a feasible one exists. Without the capture
        the arm rocks on its edge patch in a periodic cycle of micro-impacts (period 16.7 ms,
        joint speeds 6e-3 rad/s, forever). A bounce (an impulse with restitution) is never
        captured.

        Returns:
            The mode changes if the arm was captured (the caller sets v = 0), else None (modes
            untouched).
        """
        if self.bounced or not self.pairs or float(np.abs(v).max(initial=0.0)) > CAPTURE_SPEED:
            return None
        z = np.zeros_like(v)
        a_free = a_free_fn(q, z)
        a = self._rest_accel(q, a_free, minv)
        if a is None or float(np.abs(a).max()) > CAPTURE_ACCEL:
            return None
        events = []
        for p in self.pairs.values():
            if self.mu > 0.0 and not p.stick:
                events.append(ModeEvent("stick", p.info))
            p.stick = True
        _, _, gap, _, _ = self._problem(q, z)
        self.engaged = [int(r) for r in np.flatnonzero(gap <= TOUCH_GAP)]
        self.resting = bool(self.engaged)
        return events if self.resting else None

    def _rest_accel(self, q: FloatArray, a_free: FloatArray, minv: FloatArray) -> FloatArray | None:
        """Joint accelerations at v = 0 under the frictional contact of every touching row.

        None when no row touches or the cone problem is not solved.
        """
        z = np.zeros(self.nv)
        Jn, _, gap, _, extra = self._problem(q, z)
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        if len(touch) == 0:
            return None
        J3, mus = self._frictional_rows(touch, Jn, extra)
        coul = self.joint_coulomb
        cj = np.flatnonzero(coul > 0.0) if coul is not None else np.zeros(0, dtype=np.intp)
        if len(cj):
            # the joints' Coulomb friction and brakes hold too: boxes |tau_j| <= F_j, with
            # the sliding torque -F_j s_j the free accelerations carry taken out
            assert coul is not None and self.joint_fdir is not None
            a_free = a_free + minv @ (coul * self.joint_fdir)
            J = np.vstack([J3, np.eye(self.nv)[cj]])
            x, res = solve_mixed_admm(
                self.model, self.data, J @ minv @ J.T, J @ a_free, mus, self._joint_of[cj], coul[cj]
            )
            J3 = J
        else:
            G3 = J3 @ minv @ J3.T
            x, res = solve_ncp_admm(self.model, self.data, G3, J3 @ a_free, mus)
        if res > 1e-6:
            return None
        return np.asarray(a_free + minv @ J3.T @ x, dtype=np.float64)

    def stop_slow(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Bring the touching pairs sliding slower than :data:`STICK_SPEED` to rest.

        The least (M-weighted) velocity change that zeroes their tangential velocity at the
        patch centre and lets no touching row approach (a stick event's residual speed, like
        the joint-clamp mode's ``v_j = 0`` at a stick). Without it a slip that starts from such
        a residual speed can be against its own onset direction, and the stick condition fires
        again at once.

        The touching rows are inequalities (J_n v+ >= 0, an LCP on the Schur complement of the
        tangential equalities). A change needing a joint speed above :data:`CAPTURE_SPEED` is
        not made: the slow slide is then driven by the motion elsewhere, not a residual. In the
        arm's collapse (t = 0.508 s) the elbow casing slides on the chassis at 9e-4 m/s because
        link 3, sliding at 0.15 m/s on the shoulder casing, cams elbow1 (its casing is not
        quite round about elbow2); stopping that slide is only possible at v = 0, and the
        former version (normal velocities held as equalities, no bound) zeroed the arm's
        velocity there (elbow2 2.9 rad/s -> 0, -6.9 J).
        """
        if self.mu == 0.0 or not self.pairs:
            return v
        Jn, _, gap, vn, extra = self._problem(q, v)
        rows, target = [], []
        k = 0
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            K = len(p.local1)
            touching = bool(np.any(gap[k : k + K] <= TOUCH_GAP))
            k += K
            if touching and float(np.linalg.norm(ex["vt"])) <= STICK_SPEED:
                rows.append(ex["JT"])
                target.append(-ex["vT"])
        if not rows:
            return v
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        E, bE, In = np.vstack(rows), np.concatenate(target), Jn[touch]
        GEE_pinv = np.linalg.pinv(E @ minv @ E.T, rcond=1e-10)
        GEI = E @ minv @ In.T
        # dv = M^-1 (E^T y + I^T lam), y = GEE^+ (bE - GEI lam); w = I (v + dv) >= 0 _|_ lam >= 0
        y0 = GEE_pinv @ bE
        S = In @ minv @ In.T - GEI.T @ GEE_pinv @ GEI
        w0 = vn[touch] + GEI.T @ y0
        lam = solve_lcp_psd(S, w0)
        if lcp_residual(S, w0, lam) > RESIDUAL_TOL:
            lam2 = _lemke(S, w0)
            if lam2 is None or lcp_residual(S, w0, lam2) > RESIDUAL_TOL:
                log.debug("stop_slow: LCP unsolved, velocity kept")
                return v
            lam = lam2
        y = y0 - GEE_pinv @ (GEI @ lam)
        imp = E.T @ y + In.T @ lam  # the generalized impulse M dv [N*m*s]
        dv = minv @ imp
        if float(imp @ v) + 0.5 * float(imp @ dv) > 0.0:
            # A projection onto a cone holding 0 cannot add energy; an inexact one (rank-
            # deficient tangential rows, the LCP's residual) can: measured 2.4e-7 J.
            log.debug("stop_slow: the change would add energy: kept")
            return v
        if float(np.abs(dv).max()) > CAPTURE_SPEED:
            # The slow slide is driven by the motion elsewhere (a closed chain through two
            # contacts), not a residual: stopping it would stop the arm. Leave it.
            log.debug("stop_slow: change %.3g rad/s would stop the arm: kept", np.abs(dv).max())
            return v
        return np.asarray(v + dv, dtype=np.float64)

    def sliding(self, q: FloatArray, v: FloatArray) -> bool:
        """Whether a pair with engaged rows slides (its material points drift off the patch)."""
        if not self.engaged or not self.pairs or self.resting:
            return False
        last = self._last_eval  # the step end's mode conditions computed them (same kernel)
        if last is not None and _same(last[0], q) and _same(last[1], v):
            vts: Any = last[6].vt
        else:
            vts = _centre_velocities(self._problem(q, v)[4])
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
        in body 2; it describes the contact while (1) the points have not slid apart by more
        than :data:`SLIDE_TOL` tangentially since it was built (the forces act where the bodies
        touched, not where they touch now), and (2) the patch's smallest gap equals the pair's
        signed distance to :data:`POINT_TOL` (a curved body's next facet comes closer than the
        patch predicts, or a point slides off the edge of its face and the face's plane holds
        it where nothing does). A slide of 2e-8 m per step passes both: the patch, its drift
        projection and its modes are kept (events still watch every row and the pair's
        distance).

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
        last = self._last_eval  # the step's end: the kernel computed the slides
        slide2: Any = None
        if last is not None and _same(last[0], q) and _same(last[1], v):
            gap, slide2 = last[6].gap, last[6].slide2
        if slide2 is None:
            _, _, gap, _, extra = self._problem(q, v)
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
            if s2 > SLIDE_TOL**2:
                out.append(key)
                if engaged_only:
                    return out
        return out

    def repatch(self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray) -> FloatArray:
        """Recompute the patches of a sliding contact, correct drift and select the modes again.

        Returns:
            The corrected configuration [rad].
        """
        self.refresh(q)
        q = self.project(q, v, minv)
        self.select_modes(q, v, a_free_fn(q, v), minv, keep=True)
        return q

    def project(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Move q by the least (M-weighted) amount that closes every negative touching gap.

        The position-level LCP: dq = M^-1 J^T mu, mu >= 0, J dq + g >= 0, complementary, on
        the touching rows (g <= :data:`TOUCH_GAP`, gaps before). Removes the integration drift
        of resting gaps and the event tolerance's last micrometre at every restart. Two guards
        make it safe:

        1. *Targets clipped at the true distance*: a row's gap is measured against its patch's
           geometry (a point against a face's plane), which can read far deeper than the pair
           really is (a patch point lifted onto a face's plane beyond the face's edge, or a
           stale point). Each pair row's gap is raised to min(d, 0) - :data:`PENETRATION_TOL`
           when below it, d the pair's signed distance (Coal, one pruned sweep at q), so the
           correction never exceeds the true penetration by more than the drift it exists
           for. The band keeps the micrometre disagreements of a fresh patch corrected in
           full (the collapse, mu = 0: a lifted point reading 1.6 um deeper than the distance
           at t = 0.206 s; the elbow casing's edge patch on the chassis reading -1 um with the
           pair 10 um apart at t = 1.45 s): left below -:data:`POINT_TOL`, such a row fires
           its impact condition again at once and the restart repeats forever. Clipping
           rather than re-patching: the patches are rebuilt just before every projection
           (restart, re-patch), so a gap still off the distance is the patch's geometry,
           which a new patch reproduces.
        2. *No penetration elsewhere*: the projection moves q without looking at the pairs not
           in the contact set. After it, the pairs the sweep leaves (within the world's
           margin) are checked; one below -:data:`PENETRATION_TOL` joins the contact set (its
           patch at the projected q, as an impact would add it: it then takes part in the
           restart's impulse and modes) and the projection is made again from there, up to
           :data:`PROJECT_ROUNDS` rounds. Off with ``check_others=False`` (the hand-off,
           whose other pairs are the joint_clamp mode's).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s] (for the rows' cache key only).
            minv: M^-1 at q.

        Returns:
            The corrected configuration [rad].
        """
        for _ in range(PROJECT_ROUNDS):
            Jn, _, gap, _, _ = self._problem(q, v)
            if not bool(np.any(gap < 0.0)):
                return q
            dist = self._sweep(q)
            gap = self._clip_gaps(gap, dist)
            if not bool(np.any(gap < 0.0)):
                return q
            touch = np.flatnonzero(gap <= TOUCH_GAP)
            J = Jn[touch]
            G = J @ minv @ J.T
            mu = solve_lcp_psd(G, gap[touch])
            q = np.asarray(q + minv @ J.T @ mu, dtype=np.float64)
            if not self.check_others or self.world is None:
                return q
            dist = self._sweep(q)
            bad = [k for k, d in dist.items() if k not in self.pairs and d < -PENETRATION_TOL]
            if not bad:
                return q
            for k in bad:
                log.debug(
                    "projection: pair %s / %s at %.3g m joins the contact set",
                    self.world.pairs[k].piece1,
                    self.world.pairs[k].piece2,
                    dist[k],
                )
                self.add_pair(q, k)
        log.debug("projection: still penetrating after %d rounds", PROJECT_ROUNDS)
        return q

    def _sweep(self, q: FloatArray) -> dict[int, float]:
        """Signed distances [m] at q of the pairs within the world's margin, by pair index.

        Every pair of the contact set is included (queried alone if the sweep pruned it).
        """
        if self.world is None:
            return {}
        sw = self.world.sweep(q, reuse=True)
        dist = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
        for k in self.pairs:
            if k not in dist:
                dist[k] = self.world.pair_contact(q, k).distance
        return dist

    def _clip_gaps(self, gap: FloatArray, dist: dict[int, float]) -> FloatArray:
        """The rows' gaps [m], a pair's raised to min(d, 0) - PENETRATION_TOL (d: its distance)."""
        if not self.pairs or not dist:
            return gap
        out = gap.copy()
        k = 0
        for key, p in self.pairs.items():
            K = len(p.local1)
            d = dist.get(key)
            if d is not None:
                np.maximum(out[k : k + K], min(d, 0.0) - PENETRATION_TOL, out=out[k : k + K])
            k += K
        return out

    def impulse(self, q: FloatArray, v: FloatArray, minv: FloatArray) -> FloatArray:
        """Simultaneous impact of every touching row (Newton's law, restitution e).

        An impulse never adds kinetic energy: each candidate's change is checked exactly
        (dT = P . J v + P . J dv / 2 for the generalized impulse J^T P, no mass matrix
        needed) and the first that does not gain is applied, in this order: the frictional
        impact (ADMM), the frictionless one with restitution, the frictionless inelastic one
        (the M-projection of v onto J_n v >= 0, which cannot gain). A solver's inexact
        answer (an ADMM residual just under its bound, an NNLS solution off the LCP) could
        otherwise add energy: measured 2.5e-5 J at an impact of the camera head on link 1's
        tube (the collapse from a random start, mu = 0.5, wrist locked).
        """
        Jn, _, gap, vn, extra = self._problem(q, v)
        touch = np.flatnonzero(gap <= TOUCH_GAP)
        if len(touch) == 0 or float(vn[touch].min()) >= 0.0:
            return v
        e = self.e if float(vn[touch].min()) < -self.zeno_speed else 0.0
        self.bounced = e > 0.0
        J = Jn[touch]
        G = J @ minv @ J.T
        tried: list[str] = []
        if self.mu > 0.0:
            # Frictional impact: blocks (t1, t2, n) per touching row on Pinocchio's ADMM.
            J3, mus = self._frictional_rows(touch, Jn, extra)
            G3 = J3 @ minv @ J3.T
            g3 = J3 @ v
            g3[2::3] += e * np.minimum(g3[2::3], 0.0)
            x, res = solve_ncp_admm(self.model, self.data, G3, g3, mus)
            if res <= 1e-6:
                dv = minv @ J3.T @ x
                if _energy_change(x, J3 @ v, J3 @ dv) <= 0.0:
                    return np.asarray(v + dv, dtype=np.float64)
                tried.append("frictional (gains energy)")
            else:
                tried.append(f"frictional (residual {res:.3g})")
        for e_k in dict.fromkeys((e, 0.0)):
            target = vn[touch] + e_k * np.minimum(vn[touch], 0.0)
            P = self._normal_impulse(G, target)
            dv = minv @ J.T @ P
            if e_k == 0.0 or _energy_change(P, vn[touch], J @ dv) <= 0.0:
                if tried:
                    log.debug("impact: %s; frictionless e=%g used", ", ".join(tried), e_k)
                self.bounced = e_k > 0.0
                return np.asarray(v + dv, dtype=np.float64)
            tried.append(f"frictionless e={e_k:g} (gains energy)")
        return v  # not reached: the inelastic candidate is always taken

    @staticmethod
    def _normal_impulse(G: FloatArray, target: FloatArray) -> FloatArray:
        """The normal impulses of a frictionless impact: LCP(G, target), residual checked."""
        P = solve_lcp_psd(G, target)
        res = lcp_residual(G, target, P)
        if res > RESIDUAL_TOL:
            P2 = _lemke(G, target)
            if P2 is not None and lcp_residual(G, target, P2) < res:
                P, res = P2, lcp_residual(G, target, P2)
        if res > RESIDUAL_TOL:
            log.warning("impact LCP residual %.3g", res)
        return P

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

    def select_modes(
        self,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        keep: bool = False,
    ) -> list[ModeEvent]:
        """Solve the acceleration-level problem; set the engaged rows and stick/slip.

        With ``keep`` (a re-patch inside a mode), sticking pairs stay sticking and sliding
        pairs only update their direction.
        """
        events: list[ModeEvent] = []
        Jn, drift, gap, vn, extra = self._problem(q, v)
        touch = [int(r) for r in np.flatnonzero((gap <= TOUCH_GAP) & (vn <= SPEED_BAND))]
        self.engaged = touch
        if self.mu > 0.0:
            for p, ex in zip(self.pairs.values(), extra, strict=True):
                speed = float(np.linalg.norm(ex["vt"]))
                was = p.stick
                if keep and p.stick:
                    continue
                p.stick = speed <= STICK_SPEED and not keep
                if not p.stick:
                    p.slip_dir = ex["vt"] / speed
                if was != p.stick:
                    events.append(ModeEvent("stick" if p.stick else "slip", p.info))
        if not touch:
            self.engaged = []
            return events
        for _ in range(len(self.pairs) + 2):
            lam, ok = self._solve_modes(touch, Jn, drift, gap, vn, extra, a_free, minv)
            if not ok:
                events.append(ModeEvent("painleve", None))
                self.n_painleve += 1
                for p in self.pairs.values():
                    p.stick = True
                lam, ok = self._solve_modes(touch, Jn, drift, gap, vn, extra, a_free, minv)
                if not ok:  # give up friction for this restart
                    log.warning("contact problem unsolved even with sticking contacts")
                    self.engaged = [r for r in touch]
                    return events
            moved = self._cone_check(lam, extra)
            if not moved:
                break
            for p, s in moved:
                p.stick = False
                p.slip_dir = s
                events.append(ModeEvent("slip", p.info))
        self._consistent_directions(q, v, Jn, drift, gap, vn, extra, a_free, minv, touch)
        self._coulomb_residual_directions(extra)
        if log.isEnabledFor(logging.DEBUG):
            log.debug(
                "modes: touch %s engaged %s gaps %s vn %s",
                touch,
                self.engaged,
                np.array2string(gap, precision=8),
                np.array2string(vn, precision=6),
            )
        return events

    def _consistent_directions(
        self,
        q: FloatArray,
        v: FloatArray,
        Jn: FloatArray,
        drift: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        extra: list[dict[str, Any]],
        a_free: FloatArray,
        minv: FloatArray,
        touch: list[int],
    ) -> None:
        """Slip directions of pairs starting to slide from rest: their tangential acceleration.

        A slip onset at rest (|v_t| <= :data:`STICK_SPEED`) must slide along its direction s:
        a_t(s) . s > 0, a_t the tangential acceleration of the patch centre in the slip mode.
        From the cone check's s = -f_t / |f_t|, s is turned towards a_t (s <- s + a_t / |a_t|)
        until it is (a plain fixed point s = a_t / |a_t| can flip-flop).
        """
        if self.mu == 0.0:
            return
        starting = [
            p
            for p, ex in zip(self.pairs.values(), extra, strict=True)
            if not p.stick and float(np.linalg.norm(ex["vt"])) <= STICK_SPEED
        ]
        if not starting or not self.engaged:
            return
        for _ in range(8):
            a = self.evaluate(q, v, a_free, minv).a
            moved = False
            for p, ex in zip(self.pairs.values(), extra, strict=True):
                if p not in starting:
                    continue
                at = ex["T"].T @ (ex["JT"] @ a + ex["bT"])
                na = float(np.linalg.norm(at))
                if na <= 1e-9 or float(at @ p.slip_dir) > 0.0:
                    continue  # the slide grows along its direction: consistent
                s = p.slip_dir + at / na
                ns = float(np.linalg.norm(s))
                p.slip_dir = s / ns if ns > 1e-9 else at / na
                moved = True
            if not moved:
                return
            self._solve_modes(touch, Jn, drift, gap, vn, extra, a_free, minv)

    def _coulomb_residual_directions(self, extra: list[dict[str, Any]]) -> None:
        """A pair set to slip against its own residual slide slips along that slide.

        A slip onset inside the stick band (|v_t| <= :data:`STICK_SPEED`) takes its direction
        s from the forces (cone check, then :meth:`_consistent_directions`). When the contact
        still moves at a residual v_t that :meth:`stop_slow` could not remove (a slide driven
        through a closed chain by the motion elsewhere) and s points so far against it that
        the stick condition (the slide came back through zero) is below half of
        :data:`STICK_BAND`, that condition would fire at once and the restart repeat at the
        same instant (stick -> cone check -> slip -> stick ...; seen at mu = 0.45 in the
        collapse: link 2's casing on the chassis at 4.6e-4 m/s). Coulomb's law for a moving
        contact is friction against the motion, so such a pair slips along v_t: the slide
        slows down, passes through zero and fires the
        stick event after a finite time, where the onset is decided again.
        """
        if self.mu == 0.0:
            return
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            if p.stick:
                continue
            vt = ex["vt"]
            speed = float(np.linalg.norm(vt))
            w = vt + STICK_SPEED * p.slip_dir  # as in conditions(): g = v_t . w/|w| + band
            g = float(vt @ w) / max(float(np.linalg.norm(w)), 1e-300) + STICK_BAND
            if speed > 0.0 and g < 0.5 * STICK_BAND:
                p.slip_dir = vt / speed

    def _solve_modes(
        self,
        touch: list[int],
        Jn: FloatArray,
        drift: FloatArray,
        gap: FloatArray,
        vn: FloatArray,
        extra: list[dict[str, Any]],
        a_free: FloatArray,
        minv: FloatArray,
    ) -> tuple[dict[str, Any], bool]:
        """The mixed LCP: touching normal rows complementary, sticking rows equalities."""
        self.engaged = list(touch)
        C = self._slip_columns(Jn, extra)
        JT, bT, vT = self._stick_rows(extra)
        N = touch
        bN = Jn[N] @ a_free + drift[N] + 2.0 * BAUMGARTE * vn[N] + BAUMGARTE**2 * gap[N]
        GNN = Jn[N] @ minv @ C[N].T
        symmetric = all(p.stick for p in self.pairs.values()) or self.mu == 0.0
        if len(JT):
            bTt = JT @ a_free + bT + BAUMGARTE * vT
            GNT = Jn[N] @ minv @ JT.T
            GTN = JT @ minv @ C[N].T
            GTT = JT @ minv @ JT.T
            GTTi = np.linalg.pinv(GTT, rcond=1e-10)
            Ml = GNN - GNT @ GTTi @ GTN
            ql = bN - GNT @ GTTi @ bTt
        else:
            Ml, ql = GNN, bN
        if symmetric:
            z = solve_lcp_psd(Ml, ql)
            res = lcp_residual(Ml, ql, z)
            if res > RESIDUAL_TOL:
                z2 = _lemke(Ml, ql)
                if z2 is not None and lcp_residual(Ml, ql, z2) < res:
                    z, res = z2, lcp_residual(Ml, ql, z2)
        else:
            z2 = _lemke(Ml, ql)
            if z2 is None:
                return {}, False
            z, res = z2, lcp_residual(Ml, ql, z2)
        if res > 1e-6:
            log.debug("mode LCP residual %.3g", res)
            if not symmetric:
                return {}, False
        scale = 1e-12 * (1.0 + float(np.abs(z).max(initial=0.0)))
        self.engaged = [r for r, zr in zip(N, z.tolist(), strict=True) if zr > scale]
        lamT = -GTTi @ (GTN @ z + bTt) if len(JT) else np.zeros(0)
        return {"lamN": dict(zip(N, z.tolist(), strict=True)), "lamT": lamT}, True

    def _cone_check(
        self, lam: dict[str, Any], extra: list[dict[str, Any]]
    ) -> list[tuple[_Pair, FloatArray]]:
        """Sticking pairs whose tangential force leaves the cone, with their slip direction."""
        if self.mu == 0.0:
            return []
        out = []
        k_row, k_t = 0, 0
        lamN, lamT = lam["lamN"], lam["lamT"]
        for p, ex in zip(self.pairs.values(), extra, strict=True):
            K = len(p.local1)
            fn = sum(lamN.get(r, 0.0) for r in range(k_row, k_row + K))
            had_rows = any(k_row <= r < k_row + K for r in lamN)
            k_row += K
            if not p.stick or not had_rows:
                continue
            # tangential rows exist for this pair only if it was engaged when rows were built
            if k_t + 2 > len(lamT):
                continue
            lt = lamT[k_t : k_t + 2]
            k_t += 2
            nt = float(np.linalg.norm(lt))
            if nt > self.mu * fn + FORCE_BAND:
                f_world = ex["T"].T @ lt
                out.append((p, -f_world / nt))
        return out


#: The contact set's own rows: a subclass adding rows (the hand-off) takes the numpy path.
_OWN_PROBLEM = NormalContacts._problem
_OWN_EVALUATE = NormalContacts.evaluate
_OWN_CONDITIONS = NormalContacts.conditions


_KERNELS: list[Any] = []  # packbot.contact.kernels once imported (see _kernels)


def _kernels() -> Any:
    """:mod:`packbot.contact.kernels`, imported at the first call, then kept.

    Numba is imported by contact runs only, not by ``import packbot``; an import statement in
    the right-hand side costs a microsecond a call.
    """
    if not _KERNELS:
        from packbot.contact import kernels

        _KERNELS.append(kernels)
    return _KERNELS[0]


def _lemke(M: FloatArray, q: FloatArray) -> FloatArray | None:
    """:func:`packbot.contact.lcp.lemke`, small problems on the compiled kernel (bit for bit).

    Up to :data:`packbot.contact.lcp.SMALL_LCP` rows, ``kernels.lemke_small``: the same pivots
    and operations as the Python-float version, without its interpreter overhead.
    """
    n = len(q)
    if n == 0 or n > SMALL_LCP or bool(np.all(q >= 0.0)):
        return lemke(M, q)
    from packbot.contact import kernels  # lazy: numba is imported by contact runs only

    z, ok = kernels.lemke_small(
        np.ascontiguousarray(M, dtype=np.float64), np.asarray(q, dtype=np.float64), 200, 1e-12
    )
    return z if ok else None


def _energy_change(P: FloatArray, w: FloatArray, dw: FloatArray) -> float:
    """Kinetic energy change [J] of an impulse: P . w + P . dw / 2.

    P: the impulses on some rows J (generalized impulse J^T P = M dv); w = J v before; dw = J
    dv. Rounding below 1e-12 of the energy scale counts as no change.
    """
    gain = float(P @ w) + 0.5 * float(P @ dw)
    return gain - 1e-12 * (abs(float(P @ w)) + abs(float(P @ dw)))


def _same(a: FloatArray, b: FloatArray) -> bool:
    """Whether two float arrays are the same object or hold the same bits (same shape)."""
    return a is b or (a.shape == b.shape and a.tobytes() == b.tobytes())


def _centre_velocities(extra: list[dict[str, Any]]) -> FloatArray:
    """The pairs' tangential velocities at their patch centres, shape (pairs, 3) [m/s]."""
    if not extra:
        return np.zeros((0, 3))
    return np.array([ex["vt"] for ex in extra])


def _planes(shape: Any) -> tuple[FloatArray, FloatArray] | None:
    """Face planes (unit outward normals N, offsets o: inside <=> N x + o <= 0), local frame."""
    if isinstance(shape, coal.Halfspace):
        return np.array([shape.n]), np.array([-float(shape.d)])
    if isinstance(shape, coal.Box):
        h = np.asarray(shape.halfSide)
        N = np.vstack([np.eye(3), -np.eye(3)])
        return N, -np.concatenate([h, h])
    try:
        N = np.asarray(shape.normals(), dtype=float)
        o = np.asarray(shape.offsets(), dtype=float)
    except (AttributeError, RuntimeError):
        return None
    return (N, o) if len(N) else None


# The patch construction in numpy (the reference of kernels.patch_material: tests).
def _consistent(pts1: FloatArray, pts2: FloatArray, patch: Any) -> bool:
    """Whether a patch's points have gaps (along its normal) within PATCH_TOL of its distance.

    The smallest gap is the pair's distance; the others may exceed it (points on a tilted
    face) but not fall below it.
    """
    gaps = (pts2 - pts1) @ patch.normal
    d = float(patch.distance)
    return bool(abs(float(gaps.min()) - d) <= PATCH_TOL and float(gaps.max()) <= d + 1e-3)


def _lift(
    planes: tuple[FloatArray, FloatArray] | None,
    oMg: pin.SE3,
    mid: FloatArray,
    n: FloatArray,
    sign: float,
) -> FloatArray | None:
    """Patch points moved along n onto the shape's face most aligned with sign * n.

    Coal puts every patch point at the patch's one depth; on two faces meeting at a small angle
    the points' true gaps differ (by up to Coal's patch tolerance, 1 mm). The face whose
    outward normal is closest to sign * n carries them. ``planes``: the shape's face planes
    (:func:`_planes`), None if it has none.
    """
    if planes is None:
        return None
    N, o = planes
    R, t = oMg.rotation, oMg.translation
    nl = R.T @ n
    f = int(np.argmax(sign * (N @ nl)))
    den = float(N[f] @ nl)
    if abs(den) < 0.5:
        return None
    pl = (mid - t) @ R  # local
    s = -(pl @ N[f] + o[f]) / den
    return np.asarray(mid + s[:, None] * n, dtype=np.float64)


def _tangents(n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit tangents (t1, t2) with (t1, t2, n) right-handed."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = _cross(a, n)
    t1 /= np.linalg.norm(t1)
    return t1, _cross(n, t1)


_I4 = np.eye(4)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of 3-vectors along the last axis, broadcast.

    np.cross is slow on the small arrays of the contact rows.
    """
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


# ---------------------------------------------------------------------------------- the law
class PatchEvents(PairLaw):
    """The events of a contact-normal problem: the normal mode's, and the hand-off's.

    A pair in the problem's contact set is watched for leaving it (``release`` beyond the
    proximity tolerance) and for penetrating past :data:`PENETRATION_TOL` (``repatch``); a pair
    outside it touches at d = 0 (``impact``). The problem's own mode conditions (a row's force
    or acceleration, a friction cone, the resting arm: :meth:`NormalContacts.conditions`) are
    event functions too (keys ``("mode", kind, index)``).
    """

    def _patch_pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        """Pair events of a contact-normal pair: touch at d = 0, re-patch, leave the set."""
        cfg = self.cfg
        if key not in self.active:
            if d1 <= 0.0:
                return [self._pair_crossing("impact", key, p_idx, seg, d0, d1, lambda d: d)]
            return []
        if d1 > cfg.proximity_tolerance:
            return [
                self._pair_crossing(
                    "release", key, p_idx, seg, d0, d1, lambda d: cfg.proximity_tolerance - d
                )
            ]
        if d1 < -PENETRATION_TOL:
            return [
                self._pair_crossing(
                    "repatch", key, p_idx, seg, d0, d1, lambda d: d + PENETRATION_TOL
                )
            ]
        return []

    def _contact_eval(self, contacts: NormalContacts, t: float, y: FloatArray) -> _Eval:
        """The contact problem's evaluation at state y (the last one if it was at y)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        return contacts.evaluate_again(q, v, self.free_accel(t, y), self.sys.minv(q))

    def _contact_conditions(
        self, contacts: NormalContacts, t: float, y: FloatArray
    ) -> dict[tuple[Any, ...], tuple[str, float]]:
        """Mode conditions of a contact problem at state y."""
        return contacts.conditions(self._contact_eval(contacts, t, y))

    def _problem_crossings(
        self, contacts: NormalContacts, seg: DenseSegment, y1: FloatArray
    ) -> list[Crossing]:
        """Mode conditions of a contact problem that changed sign over the step."""
        ev1 = self._contact_eval(contacts, seg.t1, y1)
        if not contacts.violated(ev1):
            return []
        cond1 = contacts.conditions(ev1)
        bad = [k for k, (_, g) in cond1.items() if g < 0.0]
        if not bad:
            return []
        cond0 = self._contact_conditions(contacts, seg.t0, seg.y0)
        out = []
        for k in bad:

            def gn(t: float, k: tuple[Any, ...] = k) -> float:
                return self._contact_conditions(contacts, t, seg(t))[k][1]

            g0 = cond0[k][1] if k in cond0 else 1.0
            out.append(Crossing(cond1[k][0], ("mode", *k), gn, g0, cond1[k][1]))
        return out

    def _restart(
        self, contacts: NormalContacts, t: float, q: FloatArray, v: FloatArray, tail: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """A contact problem's restart at t: drift correction, impulse, modes."""

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        coul = self.drive.path.coulomb
        contacts.joint_coulomb = coul if coul.any() else None
        contacts.joint_fdir = self.drive.fdir
        return contacts.restart(q, v, a_free, self.sys.minv(q))

    def _repatch(self, contacts: NormalContacts, t: float, y: FloatArray) -> FloatArray:
        """Re-patch a contact problem's sliding pairs at (t, y); the state after."""
        n = self.n
        q, v, tail = y[:n], y[n : 2 * n], y[2 * n :]

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        q = contacts.repatch(q, v, a_free, self.sys.minv(q))
        return np.concatenate([q, v, tail])


@dataclass
class _Window:
    """A time-stepping window of the normal mode (:mod:`packbot.contact.timestep`)."""

    stepper: MoreauJeanStepper
    t_start: float
    until: float  # the earliest exit [s]
    energy_in: float  # [J]
    quiet: int = 0  # steps whose signature equalled the previous one
    last: Any = None  # the previous step's signature


class NormalLaw(PatchEvents):
    """The contact-normal mode (``contact_mode="normal"``).

    Its contacts are the patches of :class:`NormalContacts` (impulse with restitution, resting
    contact with Coulomb friction ``mu``, release when a force would pull) and its limit stops
    are rows of the same problem. Same arguments as
    :class:`~packbot.contact.stops.JointStops`.

    **Where events pile up** (:data:`CASCADE_EVENTS` restarts within :data:`CASCADE_SPAN`: a
    stick/slip or jam cascade at one instant, an accumulation of impacts; only
    :data:`RELAPSE_EVENTS` within :data:`RELAPSE_SPAN` of a window's end; or
    :data:`CHATTER_EVENTS` within :data:`CHATTER_SPAN`: a chattering slide)
    the law integrates a window with fixed time steps itself
    (:class:`~packbot.contact.timestep.MoreauJeanStepper`, through :meth:`advance`): one
    complementarity problem per step, no event location. The window lasts at least
    :data:`WINDOW_MIN` (doubled when the next cascade follows within :data:`RELAPSE_SPAN` of
    its end) and ends once the steps' decisions have held for
    :data:`~packbot.contact.timestep.QUIET_STEPS` steps; the event-driven restart then takes
    over from that state. Both ends are logged (``timestep``, ``resume``).

    Attributes:
        normal: The contact set and its modes.
        window: The time-stepping window in progress, or None.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._min_len = WINDOW_MIN
        self._last_exit = -math.inf
        super().__init__(*args, **kwargs)

    def rebuild(self, system: System) -> None:
        """A new phase: an empty contact set on the new system."""
        super().rebuild(system)
        self.normal = NormalContacts.from_config(system.model, system.data, system.world, self.cfg)
        self._native = native.native_rhs(system.model) if native.ENABLED else None
        self.window: _Window | None = None
        self._recent: deque[float] = deque(maxlen=CHATTER_EVENTS)
        self._steps: deque[float] = deque(maxlen=CRAWL_STEPS)  # the last steps' sizes [s]

    # ------------------------------------------------------------------ windows
    def advance(self, t: float, y: FloatArray, t_end: float) -> DenseSegment | None:
        """In a window, one time step from (t, y) (not past t_end); else None."""
        w = self.window
        if w is None:
            return None
        seg, info = w.stepper.step(t, y, t_end, self.energy)
        self.diag.window_steps += 1
        self.diag.sweeps += 1
        self.diag.window_energy_removed += info.removed
        self.note_min(*info.closest)  # the step's sweep at its start (the previous step's end)
        w.quiet = w.quiet + 1 if info.signature == w.last else 0
        w.last = info.signature
        return seg

    def rescue(self, t: float, y: FloatArray) -> bool:
        """A step-size underflow at (t, y) (a stiff or discontinuous stretch): a window."""
        if self.window is not None:
            return False
        self._enter(t, y, "the stepper's step size underflowed")
        return True

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """The event functions (none in a window: its steps resolve their contacts)."""
        if self.window is not None:
            return []
        self._steps.append(seg.h)
        return super().watch(seg)

    def after_step(self, t: float, y: FloatArray) -> FloatArray | None:
        """After an accepted step; in a window, its end once the contacts have settled.

        Outside a window, a stepper that crawls (:data:`CRAWL_STEPS` steps averaging less than
        :data:`CRAWL_STEP`) opens one: the stretch is stiff for an explicit stepper (a slow
        slide's friction direction turning), not for the windows' steps, whose contact forces
        are implicit.
        """
        w = self.window
        if w is None:
            steps = self._steps
            if len(steps) == CRAWL_STEPS and sum(steps) < CRAWL_STEPS * CRAWL_STEP:
                y_new = super().after_step(t, y)
                y = y if y_new is None else y_new
                self._enter(t, y, "the stepper crawled (a stiff stretch)")
                return y
            return super().after_step(t, y)
        if t < w.until or w.quiet < QUIET_STEPS:
            return None
        return self._resume(t, y)

    def settle(self, t: float, y: FloatArray) -> None:
        """The forces changed at t (in a window the next step sees them)."""
        if self.window is None:
            super().settle(t, y)

    def _enter(self, t: float, y: FloatArray, why: str) -> None:
        """Start a window at (t, y) (``why``: for the log)."""
        relapse = t - self._last_exit <= RELAPSE_SPAN
        self._min_len = 2.0 * self._min_len if relapse else WINDOW_MIN
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        self.drive.fdir[:] = 0.0  # Coulomb friction and brakes are rows of the steps
        self.locks = JointLocks()
        stepper = MoreauJeanStepper(self.sys, self.drive, self.normal, self.cfg)
        self.window = _Window(stepper, t, t + self._min_len, self.energy(q, v))
        self.diag.windows += 1
        self._steps.clear()
        self.log_event(t, "timestep", q, v, v, None)
        log.debug("t=%.6f: %s: time steps for %.3g s at least", t, why, self._min_len)

    def _resume(self, t: float, y: FloatArray) -> FloatArray:
        """End the window at (t, y): the event-driven mode restarts from that state."""
        assert self.window is not None
        n = self.n
        self._last_exit = t
        self.log_event(t, "resume", y[:n], y[n : 2 * n], y[n : 2 * n], None)
        self.rebuild(self.sys)  # every contact and mode forgotten (the window is ended)
        self._after_event(y)  # the distances at the window's end (and the deepest one)
        y_new = self.start(t, y, check=False)
        self._after_event(y_new)
        return y_new

    def accel(self, q: FloatArray, v: FloatArray, a_free: FloatArray) -> FloatArray:
        """Accelerations with the contact forces (and locks) of the current mode."""
        a = super().accel(q, v, a_free)
        if self.normal.engaged:
            a = self.normal.evaluate(q, v, a, self.sys.minv(q)).a
        return a

    def torque_accel(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """:meth:`accel` under the joint torques tau [N*m]; engaged rows: one native call.

        With engaged rows, no lock and no rest capture, the native right-hand side
        (:mod:`packbot.contact.native`: ABA, M^-1, the Jacobians, the rows and the
        constrained accelerations in one compiled call) gives the same accelerations as
        :meth:`accel` (to rounding); a singular Delassus matrix falls back to :meth:`accel`.
        """
        if self.window is not None:
            # The window's steps integrate (advance); the loop's right-hand side only gives the
            # stepper's restart value (a tick inside the window), recomputed when the window
            # ends. The window's steps re-patch pairs in the contact set, so its engaged rows
            # (the event-driven modes') may no longer index them: the free accelerations.
            return self.sys.aba(q, v, tau)
        nc = self.normal
        rhs = self._native
        if rhs is not None and nc.engaged and not nc.resting and not self.locks.any_locked:
            rhs.load(nc, nc._plan())
            a = rhs.accel(q, v, tau, True)
            if a is not None:
                return a
        return self.accel(q, v, self.sys.aba(q, v, tau))

    def step_kernel(self, t: float, y: FloatArray) -> StepKernel | None:
        """The native Dormand-Prince step of the current modes, or None (the stages call rhs).

        Offered when :meth:`torque_accel` would take the native call at every stage (engaged
        rows, no lock, no rest capture, no window) and the torques are fixed over the step (a
        held command, no motor lag: :meth:`~packbot.drive.Drive.step_torques`). The stages,
        the 5th-order solution and the error norm in one call
        (:meth:`~packbot.contact.native.NativeRhs.step`); the same numbers as the stages in
        Python around :meth:`torque_accel`, to rounding.
        """
        rhs = self._native
        nc = self.normal
        if (
            rhs is None
            or not native.STEP_ENABLED
            or not nc.engaged
            or nc.resting
            or self.locks.any_locked
            or self.window is not None
        ):
            return None
        torques = self.drive.step_torques(t, y)
        if torques is None:
            return None
        rhs.load(nc, nc._plan())
        rhs.set_torque(*torques)
        return rhs.step

    def _pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        return self._patch_pair_crossings(key, p_idx, seg, d0, d1)

    def _pairs_to_check(self, pairs: list[int], distances: list[float]) -> Iterable[int]:
        """The pairs that can have an event (see :meth:`_patch_pair_crossings`).

        A pair at 0 < d <= the proximity tolerance has none (outside the contact set: no
        impact; in it: neither release nor re-patch), nor one farther outside the set.
        """
        near = self.cfg.proximity_tolerance
        active = self.active
        return [
            i
            for i, d in enumerate(distances)
            if d <= 0.0 or (d > near and ("pair", pairs[i]) in active)
        ]

    def _mode_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        nc = self.normal
        if nc.empty:
            return []
        rhs = self._native
        if rhs is not None:  # a native step's end: its last stage evaluated the conditions
            ev = rhs.end_eval(nc, y1)
            if ev is not None and ev.cond is not None and ev.cond >= 0.0:
                return []
        return self._problem_crossings(nc, seg, y1)

    def _limit_held(self, j: int, side: int) -> bool:
        return self.normal.limit_engaged(j, side)

    def _drop_limit(self, j: int, side: int) -> None:
        self.normal.remove_limit(j, side)

    def _refresh(self, t: float, y: FloatArray) -> FloatArray | None:
        # A sliding contact's patch is rebuilt only once it is stale (slid SLIDE_TOL or its gap
        # off the pair's distance): its rows stay valid until then.
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        if self.normal.sliding(q, v) and self.normal.stale(q, v, self.last_d):
            y_new = self._repatch(self.normal, t, y)
            self._sync_pairs()
            return y_new
        return None

    def _handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Events of the normal mode: update the contact set, then impulse and modes."""
        normal, world = self.normal, self.world
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        tail = y[2 * n :]
        logged: list[tuple[str, PairInfo | None, float, tuple[str, ...]]] = []
        stick: list[int] = []
        for c in sorted(crossings, key=lambda c: c.key[0] != "mode"):
            key = c.key
            if key[0] in ("lock", "stick"):  # a joint's Coulomb friction or brake
                v = self._hold_event(t, y, q, v, c, stick)
                continue
            if key[0] == "pair":
                p_idx = key[1]
                info = world.pairs[p_idx]
                d = self.distance(p_idx, y)
                if c.kind == "release":  # left the contact set (all its rows were free)
                    self.active.pop(key, None)
                    normal.remove_pair(p_idx)
                    log.debug("t=%.6f: pair %s left the contact set", t, info.piece1)
                    continue
                if normal.add_pair(q, p_idx):
                    self.active[key] = Active(info, [])
                logged.append((c.kind, info, d, ()))
            elif key[0] == "limit":
                _, j, side = key
                lim = float(self.sys.upper[j] if side > 0 else self.sys.lower[j])
                normal.add_limit(j, side, lim)
                self.active[key] = Active(None, [])
                logged.append(("limit", None, float(side * (lim - q[j])), (self.sys.names[j],)))
            else:  # ("mode", "nrow"/"nfric"/"nrest", index)
                if key[1] == "nrest":  # the resting arm starts moving again
                    logged.append((c.kind, None, math.nan, ()))
                elif key[1] == "nrow":
                    owner, lim_key = normal.row_owner(key[2])
                    joints: tuple[str, ...] = ()
                    if lim_key is not None:
                        joints = (self.sys.names[lim_key[0]],)
                    logged.append((c.kind, owner, math.nan, joints))
                else:
                    logged.append((c.kind, normal.pairs[key[2]].info, math.nan, ()))
        q, v_new, mode_events = self._restart(normal, t, q, v, tail)
        self._sync_pairs()
        for kind, who, d, joints in logged:
            self.log_event(t, kind, q, v, v_new, who, d=d, joints=joints)
        for me in mode_events:
            if any(me.kind == k and me.pair == i for k, i, _, _ in logged):
                continue
            self.log_event(t, me.kind, q, v_new, v_new, me.pair)
        y_new = np.concatenate([q, v_new, tail])
        if self.normal.resting:  # the rest capture holds every joint (friction included)
            self.locks.set_held({})
            self.drive.fdir[:] = 0.0
        elif self.drive.path.coulomb.any():
            self.settle_modes(t, y_new, candidates=stick, log_stick=True)
        recent = self._recent
        recent.append(t)
        relapse = t - self._last_exit <= RELAPSE_SPAN
        pile = min(RELAPSE_EVENTS, CASCADE_EVENTS) if relapse else CASCADE_EVENTS
        piled = len(recent) >= pile and t - recent[-pile] <= CASCADE_SPAN
        if piled or (len(recent) == CHATTER_EVENTS and t - recent[0] <= CHATTER_SPAN):
            recent.clear()
            self._enter(t, y_new, "events piled up")
        elif self._held_with_contacts(v_new):
            self._enter(t, y_new, "joints held by friction while contacts push")
        return y_new

    def _hold_event(
        self, t: float, y: FloatArray, q: FloatArray, v: FloatArray, c: Crossing, stick: list[int]
    ) -> FloatArray:
        """A held joint slips, or a sliding one stops (Coulomb friction, brakes); new v.

        As in the other laws (:class:`~packbot.contact.stops.JointStops`): the slip takes the
        direction of the torque the hold needed; a stopped joint becomes a candidate that
        :meth:`settle_modes` holds or lets slide on.
        """
        j = c.key[1]
        fdir = self.drive.fdir
        if c.kind == "slip":
            lam = self.hold_torque(t, self.with_v(y, v), j)
            self.locks.set_held({k: b for k, b in self.locks.held.items() if k != j})
            fdir[j] = -math.copysign(1.0, lam)
            self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
        elif c.kind == "stick":
            v = v.copy()
            v[j] = 0.0
            fdir[j] = 0.0
            stick.append(j)
        return v

    def _held_with_contacts(self, v: FloatArray) -> bool:
        """Joints held (or stopped) by friction or a brake while contact rows push.

        The event-driven modes solve the holds (:class:`~packbot.contact.locks.JointLocks`)
        and the contact forces (:class:`NormalContacts`) apart, which is exact while only one
        of them acts; when both do, the joints' holding torques and the contact forces are one
        problem: a window's steps solve it (boxes and cones together). A resting arm (rest
        capture) needs neither.

        Args:
            v: Velocities [rad/s] after the restart.
        """
        if not self.normal.engaged or self.normal.resting:
            return False
        if self.locks.held:
            return True
        stopped = (self.drive.path.coulomb > 0.0) & (np.abs(v) <= HOLD_SPEED)
        return bool(stopped.any())

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m]; in a window, the last step's Coulomb and brake torques."""
        w = self.window
        if w is None:
            return super().friction(q, v, applied, friction)
        return np.asarray(friction + w.stepper.joint_torque, dtype=np.float64)

    def _sync_pairs(self) -> None:
        """Pairs that the drift projection put in the contact set become active pairs.

        :meth:`NormalContacts.project` adds a pair it made penetrate (as an impact would):
        its events are then those of a pair in contact (re-patch, release).
        """
        for k, p in self.normal.pairs.items():
            self.active.setdefault(("pair", k), Active(p.info, []))
