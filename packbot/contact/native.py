"""The contact-normal mode's right-hand side in one native call (``packbot._native``).

:class:`NativeRhs` wraps the compiled ``ContactRhs`` (``src/native/contact_rhs.hpp``, nanobind
against Pinocchio's headers): with the contact set's point layout and the current modes'
plan loaded, one call takes (q, v, tau) and returns the constrained accelerations, doing
what the Python path does in a right-hand-side call: Pinocchio's ``aba`` (armature included),
``computeMinverse`` and ``computeJointJacobiansTimeVariation``, then the contact rows and the
constrained accelerations (their one implementation: the contact set's own calls read them
through :meth:`NativeRhs.rows` and :meth:`NativeRhs.evaluate`).

The extension keeps its own Pinocchio model, rebuilt from the Python model's numbers (joint
types, parents, placements, inertias, armature, gravity): no object crosses between it and
the pin wheel, so the extension does not depend on the pin wheel's binary interface. Joints
other than 1-dof revolute and prismatic ones are not supported: :func:`native_rhs` then
raises :class:`~packbot.errors.ModelError`.

Conventions as :class:`packbot.contact.normal.NormalContacts` (world frame, SI units).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.normal_eval import _Eval
from packbot.contact.normal_tolerances import (
    BAUMGARTE,
    FORCE_BAND,
    NULL_GAP,
    NULL_ROW,
    PENETRATION_TOL,
    POINT_TOL,
    RESIDUAL_TOL,
    SPEED_BAND,
    STICK_BAND,
    STICK_SPEED,
    TOUCH_GAP,
)
from packbot.errors import ModelError, PackbotError
from packbot.native_joints import SUPPORTED_JOINTS
from packbot.ode import DenseSegment, HermiteSegment, StiffKernel

if TYPE_CHECKING:
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.contact.normal_rows import ContactRows

__all__ = [
    "SUPPORTED_JOINTS",
    "NativeModes",
    "NativeRhs",
    "available",
    "lock_subspace",
    "lock_torques",
    "native_rhs",
    "stop_joints",
    "stretch",
]

FloatArray = NDArray[np.float64]

_native: Any
_IMPORT_ERROR: ImportError | None = None
try:  # the compiled extension (built by `pip install .`; see CMakeLists.txt)
    from packbot import _native
except ImportError as exc:  # pragma: no cover - a build without the extension
    _native = None
    _IMPORT_ERROR = exc


#: The inputs of an evaluation that no caller passes (never equal to an array of theirs).
_NONE = np.empty(0)


def available() -> bool:
    """Whether the compiled extension ``packbot._native`` is importable."""
    return _native is not None


def _ints(x: Any) -> NDArray[np.int64]:
    return np.ascontiguousarray(x, dtype=np.int64)


@dataclass(frozen=True)
class NativeModes:
    """The modes :meth:`NativeRestart.select_modes` selected.

    Attributes:
        kept: The engaged rows given were kept (ModeSelection.repatch_modes).
        engaged: The engaged rows.
        stick: Each pair's stick flag (the contact set's order).
        slip_dir: Each pair's slip direction (pairs, 3), world.
        events: The mode changes, (kind, pair): kind 0 stick, 1 slip, 2 painleve; pair -1 none.
        painleve: The Painleve fallbacks taken.
        gave_up: Friction given up for this restart (the problem unsolved with every pair
            sticking).
    """

    kept: bool
    engaged: list[int]
    stick: NDArray[np.bool_]
    slip_dir: FloatArray
    events: list[list[int]]
    painleve: int
    gave_up: bool


def _reals(x: Any) -> FloatArray:
    return np.ascontiguousarray(x, dtype=np.float64)


class NativeRhs:
    """The compiled right-hand side of one Pinocchio model's contact-normal mode.

    Args:
        model: The Pinocchio model integrated (1-dof revolute or prismatic joints only), with
            its armature and gravity set.

    Raises:
        PackbotError: The extension is not built.
        ModelError: A joint type the extension does not rebuild.
    """

    def __init__(self, model: pin.Model) -> None:
        if _native is None:
            raise PackbotError(f"packbot._native is not built ({_IMPORT_ERROR})")
        types = [j.shortname() for j in model.joints]
        bad = sorted({t for t in types[1:] if t not in SUPPORTED_JOINTS})
        if bad:
            raise ModelError(
                f"joint types {bad} not supported by the native right-hand side "
                f"(supported: {sorted(SUPPORTED_JOINTS)})"
            )
        nj = len(types)
        axes = np.zeros((nj, 3))
        for i, j in enumerate(model.joints):
            if i and types[i].endswith("Unaligned"):
                axes[i] = np.asarray(j.extract().axis, dtype=float)
        inertias = list(model.inertias)
        self.nv = int(model.nv)
        self._rhs = _native.ContactRhs(
            types,
            _ints(list(model.parents)),
            _reals([M.homogeneous for M in model.jointPlacements]),
            _reals(axes),
            _reals([b.mass for b in inertias]),
            _reals([b.lever for b in inertias]),
            _reals([b.inertia for b in inertias]),
            _reals(model.armature),
            _reals(model.gravity.linear),
        )
        self._out = np.zeros(self.nv)  # the extension writes here
        # the torques loaded by hold_torque: (applied, viscous, coulomb_dir as a list)
        self._torques: tuple[FloatArray, FloatArray, list[float]] | None = None
        #: One native Dormand-Prince attempt (:data:`packbot.ode.StepKernel`) on the loaded
        #: modes and torques: ``step(h, Z, ay0, atol, rtol, y1, ay1) -> err`` (-1: a singular
        #: Delassus matrix at a stage, the caller takes the Python stages).
        self.step: Callable[..., float] = self._rhs.dopri
        #: The first stage of a native step after a restart (the stepper's ``first``):
        #: ``first(Z) -> ok``, ``Z[1] = (v, a)`` at ``Z[0]`` under the loaded modes and torques,
        #: the arithmetic of :meth:`accel` on ``applied + (-viscous * v - coulomb_dir)`` (False:
        #: a singular Delassus matrix).
        self.first: Callable[[FloatArray], bool] = self._rhs.first
        #: The native RODAS4 attempt for the stiff stretches (:class:`packbot.ode.StiffKernel`)
        #: on the loaded modes and torques, with the last native step's stiffness estimate and
        #: the Jacobian's spectral radius.
        self.stiff = StiffKernel(self._rhs.rosenbrock, self._rhs.stiffness, self._rhs.jac_radius)
        self._layout_id: Any = None  # the _Layout loaded
        self._plan_id: Any = None  # the _Plan loaded
        self._locked_id: Any = None  # the locked joints loaded (set_locks)
        self._screen_id: Any = None  # the lock conditions' rows loaded (set_screen)
        self._row_mode: tuple[tuple[int, ...], bool] = ((), False)  # (set_row_mode's)
        #: The lock mode (:class:`NativeLocks`), the restarts' and windows' steps
        #: (:class:`NativeRestart`) and the step's watch (:class:`NativeWatch`).
        self.locks = NativeLocks(self)
        self.restart = NativeRestart(self)
        self.watch = NativeWatch(self)

    def load(self, contacts: NormalContacts, plan: Any) -> None:
        """Load the contact set's layout and the modes' plan (only when they changed)."""
        self.load_layout(contacts)
        if plan is not self._plan_id:
            self._rhs.set_plan(
                _ints(plan.engaged),
                _ints(plan.row_slip),
                _ints(plan.sticks),
                contacts.mu,
                STICK_SPEED,
                BAUMGARTE,
            )
            self._plan_id = plan
        if plan.slips:  # the onset directions (reassigned at restarts)
            self._rhs.set_slip_dirs(_reals([p.slip_dir for p in contacts._pair_list]))

    def load_layout(self, contacts: ContactRows) -> None:
        """Load the contact set's layout, its conditions' constants and its pairs' keys.

        Only when the layout changed; the modes' plan is then loaded again by :meth:`load`. A
        layout of the loaded one's shape (a re-patch: the same index arrays) loads its patches
        alone. The layout's clamp rows (``ContactRhs.set_clamps``) and the set's row mode
        (``ContactRhs.set_row_mode``: the locked joints whose frozen rows sit apart, the clamp
        rows' velocity level; ``src/native/contact_rhs_clamps.cpp``) are loaded with it.
        """
        mode = contacts._row_mode
        if mode != self._row_mode:
            self._rhs.set_row_mode(_ints(mode[0]), mode[1], NULL_ROW, NULL_GAP)
            self._row_mode = mode
        lay = contacts._layout()
        old = self._layout_id
        if lay is old:
            return
        self._locked_id = None
        self._plan_id = None
        self._layout_id = None  # (until loaded in full: a load that raises leaves none)
        if old is not None and lay.body is old.body and lay.lim_value is old.lim_value:
            # (a re-patch of the same shape: its index arrays are the loaded layout's)
            self._rhs.set_patches(
                _reals(lay.local), _reals(lay.frame2), _reals(lay.offset0), _reals(lay.slide_tol2)
            )
        else:
            self._rhs.set_layout(
                _ints(lay.joints),
                _reals(lay.masks),
                _ints(lay.body),
                _reals(lay.local),
                _ints(lay.pair),
                _ints(lay.rows),
                _ints(lay.centre),
                _ints(lay.normal_body),
                _reals(lay.frame2),
                _ints(lay.lim_joint),
                _reals(lay.lim_side),
                _reals(lay.lim_value),
            )
            if len(lay.clamp_joint):
                self._rhs.set_clamps(_ints(lay.clamp_joint), _reals(lay.clamp_side))
            self._rhs.set_conditions(
                _reals(lay.offset0), _reals(lay.slide_tol2), FORCE_BAND, POINT_TOL, STICK_BAND
            )
            self._rhs.set_keys(_ints(list(contacts.pairs)))  # (in the layout's order)
        self._layout_id = lay

    def rows(self, contacts: ContactRows, q: FloatArray, v: FloatArray) -> tuple[Any, ...]:
        """Every contact row of the contact set at (q, v), and the pairs' tangential data.

        ``ContactRhs.rows`` (``src/native/contact_rhs_rows.cpp``) on the contact set's layout
        (loaded first): Pinocchio's joint placements, Jacobians and their time variation at
        (q, v), then the rows.

        Returns:
            Jn (m, nv) rows (pairs' points, then limits), drift (m,) = J_n' v [m/s^2], gap (m,)
            [m or rad], vn (m,) [m/s or rad/s]; per pair JT (pairs, 2, nv) tangential rows at
            the patch centre (the exact derivatives of the centres' slides t . (c2 - c1), the
            tangents turning with the frame's body), bT (pairs, 2) their drift, vT (pairs, 2)
            tangential velocities, vt (pairs, 3) the world tangential velocity where the
            bodies touch (v_rel - w x (c2 - c1)), nw (pairs, 3) the normal, T (pairs, 2, 3) the
            tangents; per point and centre dJp (h, 3, nv) = J_p2 - J_p1 and dP (h, 3) =
            p2 - p1 [m].
        """
        self.load_layout(contacts)
        Jn, drift, gap, vn, JT, bT, vT, vt, F, dJp, dP = self._rhs.rows(q, v)
        return Jn, drift, gap, vn, JT, bT, vT, vt, F[:, 2], F[:, :2], dJp, dP

    def evaluate(
        self,
        contacts: NormalContacts,
        plan: Any,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        forces: bool = False,
    ) -> _Eval | None:
        """The constrained accelerations of the plan's modes at (q, v), a_free and M^-1 given.

        ``ContactRhs.evaluate`` (``src/native/contact_rhs_dynamics.cpp``) after :meth:`load`:
        the engaged rows, the slipping pairs' force columns J_n - mu s^T (J_p2 - J_p1) (s the
        sliding direction at the patch centre, blended with the onset direction below
        ``STICK_SPEED``), the sticking pairs' tangential rows, Baumgarte's targets, the
        Delassus system and its solve; with the smallest mode condition (``cond``) and the
        patches' largest squared slides (``slide2``); with ``forces``, the rows' generalized force
        C^T lambda (``qc``) [N*m].

        Returns:
            The evaluation, or None: the Delassus matrix is singular (the caller solves by
            least squares).
        """
        self.load(contacts, plan)
        got = self._rhs.evaluate(q, v, _reals(a_free), _reals(minv), forces)
        if got is None:
            return None
        cond, a, lam, gap, vn, vt, slide2, qc = got
        return _Eval(a, lam, gap, vn, vt, qc=qc, cond=cond, slide2=slide2)

    def forces(self, lam: FloatArray, on1: NDArray[np.uint8]) -> tuple[Any, ...]:
        """The contact forces of the loaded plan's modes on the rows last computed.

        ``ContactRhs.forces`` (``src/native/contact_rhs_forces.cpp``) after :meth:`evaluate`
        (or :meth:`rows`) at the sample's state, with the multipliers ``lam`` of the plan's
        problem (engaged rows, then two per sticking pair) and each pair's ``on1`` (its normal
        carried by body 1).

        Returns:
            who (k, 2): each record's pair and row (-1: a sticking pair's centre); touch,
            point1, point2 [m], normal, force on body 2 [N], each (k, 3), world; the joint
            stops' torques (nv,) [N*m].
        """
        return tuple(self._rhs.forces(_reals(lam), np.ascontiguousarray(on1, dtype=np.uint8)))

    def forget_loaded(self) -> None:
        """Forget what is loaded: the next :meth:`load` loads the layout and plan in full.

        For a layout and plan changed elsewhere (the stretch's re-patch of a new shape).
        """
        self._layout_id = None
        self._plan_id = None

    def energies(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """Total energies [J] of several states: 0.5 v^T M(q) v plus gravity's potential.

        :meth:`System.energy <packbot.system.System.energy>` (armature included) row by
        row, in one call; the same numbers to rounding. The loaded modes are kept.

        Args:
            q: Configurations [rad], shape (k, nv).
            v: Velocities [rad/s], shape (k, nv).
        """
        out = np.empty(len(q))
        self._rhs.energies(_reals(q), _reals(v), out)
        return out

    def neutral_velocity(
        self, q0: FloatArray, q1: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, float]:
        """A drift projection q0 -> q1's velocity that adds no energy, and the energy removed.

        ``ContactRhs.neutral_velocity`` (:meth:`NormalContacts.neutral_velocity
        <packbot.contact.normal_contacts.NormalContacts.neutral_velocity>`).

        Args:
            q0: Configuration before the projection [rad].
            q1: Configuration after it [rad].
            v: Velocity [rad/s] (not modified).

        Returns:
            The velocity [rad/s] and the energy removed [J] (0 where the move adds none).
        """
        out = np.array(v, dtype=np.float64)
        removed = self._rhs.neutral_velocity(_reals(q0), _reals(q1), out)
        return out, float(removed)

    def set_torque(self, applied: FloatArray, viscous: FloatArray, coulomb_dir: FloatArray) -> None:
        """The torques of the steps to come [N*m]: ``applied + (-viscous * v - coulomb_dir)``."""
        self._rhs.set_torque(_reals(applied), _reals(viscous), _reals(coulomb_dir))

    def hold_torque(
        self, applied: FloatArray, viscous: FloatArray, coulomb_dir: FloatArray
    ) -> None:
        """:meth:`set_torque`, skipped when these torques are the ones loaded [N*m].

        A held command's arrays are never written (a new command is a new array), so the same
        ``applied`` and ``viscous`` objects are the same torques; ``coulomb_dir`` is compared
        by value (the drive rewrites it in place).
        """
        last = self._torques
        fdir = coulomb_dir.tolist()
        if last is not None and applied is last[0] and viscous is last[1] and fdir == last[2]:
            return
        self.set_torque(applied, viscous, coulomb_dir)
        self._torques = (applied, viscous, fdir)

    def accel(
        self, q: FloatArray, v: FloatArray, x: FloatArray, from_tau: bool
    ) -> FloatArray | None:
        """The accelerations [rad/s^2] at (q, v) of the loaded modes (a new array).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            x: Joint torques [N*m] (``from_tau``: the free accelerations come from ``aba``)
                or the free accelerations [rad/s^2].
            from_tau: What ``x`` is.

        Returns:
            The accelerations, or None when the Delassus matrix is singular (the Python path
            solves it by least squares).
        """
        out = self._out
        if not self._rhs.accel(q, v, x, from_tau, out):
            return None
        return out.copy()

    def end_eval(self, contacts: NormalContacts, y1: FloatArray) -> _Eval | None:
        """The evaluation at the end of the last native step, if it ended at y1.

        The step's FSAL stage is the right-hand side at y1 with the modes of ``contacts``: its
        forces, rows, centre velocities, the smallest mode condition (``cond``) and the
        patches' slides (``slide2``) are those :meth:`NormalContacts.evaluate` computes there
        (the same kernel, ported), without a call. Kept as the contact set's last evaluation
        at (q, v) (:meth:`NormalContacts.sliding` and ``stale`` read it).

        Args:
            contacts: The contact set whose modes the step had (unchanged since).
            y1: The state the step ended at, (q, v).

        Returns:
            The evaluation, or None: the last native call was not a step ending at y1.
        """
        return self._kept(contacts, y1, self._rhs.end_eval(y1))

    def eval_at(self, contacts: NormalContacts, y: FloatArray) -> _Eval | None:
        """The evaluation at state y with the loaded modes and torques (as :meth:`end_eval`).

        For an event's root finding inside a native step (the modes and torques loaded for it,
        unchanged since): the right-hand side's stage at y, then what :meth:`end_eval` reads,
        in one call instead of :meth:`NormalContacts.evaluate`'s Python and kernel (the same
        kernel, ported: the values agree to rounding). Kept as the contact set's last
        evaluation at (q, v).

        Args:
            contacts: The contact set whose modes are loaded.
            y: The state, (q, v).

        Returns:
            The evaluation, or None: the Delassus matrix is singular (the caller evaluates
            in Python).
        """
        return self._kept(contacts, y, self._rhs.eval_at(y))

    def _kept(self, contacts: NormalContacts, y: FloatArray, got: Any) -> _Eval | None:
        """The extension's evaluation tuple at y as an ``_Eval``, kept by the contact set."""
        if got is None:
            return None
        cond, a, lam, gap, vn, vt, slide2 = got
        ev = _Eval(a, lam, gap, vn, vt, cond=cond, slide2=slide2)
        nv = self.nv
        contacts._last_eval = (y[:nv], y[nv:], _NONE, _NONE, _NONE, contacts._plan_key, ev)
        return ev

    def set_reach(self, reach: FloatArray, margin: float, max_step: float) -> None:
        """Load the step bound's constants: each joint's reach [m], the margin [m], max step [s].

        After it, :attr:`step_bound` ``(y) -> [s]`` is
        ``min(max_step, margin / 2 / max(reach . |v|, 1e-9))`` (the dot product summed in
        joint order: the compiled stretch of steps bounds its steps with the same call).
        """
        self._rhs.set_reach(_reals(reach), float(margin), float(max_step))
        self.step_bound: Callable[[FloatArray], float] = self._rhs.step_bound

    def last(self) -> tuple[FloatArray, ...]:
        """The last call's (a_free, M^-1, lam, gap, v_n, v_t, G, rhs): copies, for tests."""
        return tuple(self._rhs.last())


class NativeLocks:
    """The report's law's lock mode in the extension (``NativeRhs.locks``).

    The locked joints, the step end's lock torques and conditions, a sample's lock torques.
    """

    def __init__(self, core: NativeRhs) -> None:
        self._core = core

    def set(self, locked: NDArray[np.intp]) -> None:
        """The report's law's modes instead of contact rows: these joints locked (a_j = 0).

        The joints engaged or held (:attr:`JointLocks.locked
        <packbot.contact.locks.JointLocks.locked>`, sorted): none (ABA), one (ABA and M^-1's
        rank-one correction) or all but at most 3 (the unlocked joints' block of M, from CRBA
        and the bias forces): the arithmetic of :meth:`JointStops.torque_accel
        <packbot.contact.stops.JointStops.torque_accel>`. Loaded only when the array object
        changed (the locks make a new one at every change of their set).

        Args:
            locked: The locked joints' indices, sorted.

        Raises:
            ValueError: Another number of locked joints (the extension refuses it).
        """
        if locked is not self._core._locked_id:
            self._core._rhs.set_locks(_ints(locked))
            self._core._locked_id = locked
            self._core._layout_id = None

    def holds(self, locked: NDArray[np.intp]) -> bool:
        """Whether ``locked`` (the locks' array, by identity) is the lock set loaded last."""
        return locked is self._core._locked_id

    def end(self, y1: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """The accelerations and lock torques at the end of the last native step, if at y1.

        The step's FSAL stage is the right-hand side at y1 in the loaded lock mode: its
        accelerations a [rad/s^2] and lock torques lambda_L [N*m] (M a = tau - h + S_L^T
        lambda, one per locked joint, in :meth:`set`'s order), or None: the last native
        call was not a lock-mode step ending at y1.
        """
        return self._core._rhs.end_locks(y1)

    def torques_at(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray | None:
        """The loaded lock mode's lock torques [N*m] at (q, v) under the joint torques tau.

        M a = tau - h + S_L^T lambda (:meth:`set`'s joints, in its order): the
        arithmetic of the mode's right-hand side, asked at a sample between steps (the last
        step's end, which :meth:`end` and :meth:`end_screen` read, is kept). None where
        its closed form does not hold (a singular pivot).

        Args:
            q: Configuration [rad].
            v: Velocity [rad/s].
            tau: Joint torques [N*m] (applied and friction).
        """
        out = self._core._rhs.lock_torques_at(_reals(q), _reals(v), _reals(tau))
        return None if out is None else np.asarray(out, dtype=np.float64)

    def end_screen(
        self, rows: FloatArray, y1: FloatArray, margin: float, torque_band: float, accel_band: float
    ) -> float:
        """The smallest lock condition at the end of the last native step, less its margin.

        The conditions of :meth:`JointLocks.conditions_of
        <packbot.contact.locks.JointLocks.conditions_of>` (its :meth:`screen_rows
        <packbot.contact.locks.JointLocks.screen_rows>`, loaded when the array changed) at
        the step's FSAL stage, the smallest less ``margin`` times the scale 1 + max |a| +
        max |lambda|: positive, every condition is clearly kept at y1. NaN when the last native
        call was not a lock-mode step ending at y1.

        Args:
            rows: The conditions' rows.
            y1: The state the step ended at.
            margin: The share of the scale a condition must clear [-].
            torque_band: The locks' torque band [N*m].
            accel_band: The locks' acceleration band [rad/s^2].
        """
        if rows is not self._core._screen_id:
            self._core._rhs.set_screen(rows, torque_band, accel_band)
            self._core._screen_id = rows
        return float(self._core._rhs.end_screen(y1, margin))


class NativeRestart:
    """A restart's steps and a window's step, in one native call each (``NativeRhs.restart``).

    The drift projection, the impact, the stop of slow slides, the mode selection.
    """

    def __init__(self, core: NativeRhs) -> None:
        self._core = core

    def window_step(
        self, contacts: NormalContacts, y: FloatArray, h: float, **kw: Any
    ) -> tuple[int, FloatArray | None, float, int, float, tuple[float, float, float] | None]:
        """One window step with its contact set kept, in one native call.

        The contact set's layout is loaded first, the torques by :meth:`hold_torque`. See
        :meth:`packbot.contact.timestep.MoreauJeanStepper.step`, whose arithmetic it follows,
        and the extension's ``ContactRhs.window_step`` for the arguments in ``kw``.

        Returns:
            (status, x, residual, iterations, rho, energies): status 0 the step's impulses x
            and the energies (at the start, at the end, the end's kinetic one) [J]; else why
            the caller takes the step in Python (1 the contact set changes, 2 a bounce, 3 no
            converged impulses, 4 no Cholesky factor of M^-1, 5 the impulses drive a joint
            past a stop that is not in the set: v1 and q1 written).
        """
        self._core.load_layout(contacts)
        status, x, res, it, rho, energies = self._core._rhs.window_step(y, h, **kw)
        return int(status), x, float(res), int(it), float(rho), energies

    def project_round(
        self,
        contacts: ContactRows,
        q: FloatArray,
        v: FloatArray,
        minv: FloatArray,
        touch_gap: float,
        pen_tol: float,
        res_tol: float,
    ) -> tuple[int, FloatArray]:
        """One round of the restart's drift projection, in one native call.

        See :meth:`packbot.contact.normal_steps.RestartSteps.project` and the extension's
        ``ContactRhs.project_round``. The contact set's layout is loaded first.

        Returns:
            (status, q1): 0 no gap is negative; 1 a gap is below -``pen_tol`` (the caller's
            round clips it); 2 Lemke's answer has a residual above ``res_tol`` (the caller's
            round); 3 the projected configuration q1 [rad]; 4 q1, past a stop of
            :meth:`set_limits` that is not one of the set's rows (the caller adds it and
            projects again).
        """
        self._core.load_layout(contacts)
        out = np.empty(len(q))
        status = self._core._rhs.project_round(
            _reals(q), _reals(v), _reals(minv), touch_gap, pen_tol, res_tol, out
        )
        return int(status), out

    def impact(
        self, contacts: ContactRows, q: FloatArray, v: FloatArray, minv: FloatArray, **kw: Any
    ) -> tuple[int, FloatArray, bool, NDArray[np.int64], FloatArray]:
        """The restart's impact, in one native call.

        See :meth:`packbot.contact.normal_steps.RestartSteps.impulse`, whose arithmetic it
        follows, and the extension's ``ContactRhs.impact`` for the arguments in ``kw``. The
        contact set's layout is loaded first.

        Returns:
            (status, v1, bounced, rows, P): 0 no touching row approaches (v unchanged); 1 the
            velocity after the impact v1 [rad/s], ``bounced`` whether restitution was applied,
            the touching rows and their impulses P (rows, 3), blocks (t1, t2, n) [N*s,
            N*m*s]; 2 the caller's own impulse (a frictional answer not taken, an LCP residual
            too large). Without an impact, no rows.
        """
        self._core.load_layout(contacts)
        out = np.empty(len(v))
        got = self._core._rhs.impact(_reals(q), _reals(v), _reals(minv), out_v=out, **kw)
        if int(got[0]) != 1:
            return int(got[0]), out, bool(got[1]), np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        return 1, out, bool(got[1]), np.asarray(got[2]), np.asarray(got[3])

    def stop_slow(
        self, contacts: ContactRows, q: FloatArray, v: FloatArray, minv: FloatArray, **kw: Any
    ) -> tuple[int, FloatArray]:
        """The restart's stop of the slow slides, in one native call.

        See :meth:`packbot.contact.normal_steps.RestartSteps.stop_slow`, whose arithmetic it
        follows, and the extension's ``ContactRhs.stop_slow`` (``src/native/stop_slow.hpp``)
        for the arguments in ``kw``. The contact set's layout is loaded first.

        Returns:
            (status, v1): 0 the velocity kept; 1 the velocity after the stop v1 [rad/s]; 2 the
            caller's own step (its least squares).
        """
        self._core.load_layout(contacts)
        out = np.empty(len(v))
        status = self._core._rhs.stop_slow(_reals(q), _reals(v), _reals(minv), out_v=out, **kw)
        return int(status), out

    def select_modes(
        self,
        contacts: ContactRows,
        q: FloatArray,
        v: FloatArray,
        a_free: FloatArray,
        minv: FloatArray,
        keep: bool,
        held: list[int],
    ) -> NativeModes | None:
        """A restart's or a re-patch's mode selection, in one native call.

        :meth:`ModeSelection.select_modes <packbot.contact.normal_modes.ModeSelection.
        select_modes>` (after keeping the engaged rows ``held`` when not empty, as
        :meth:`~packbot.contact.normal_modes.ModeSelection.repatch_modes` asks: that part
        exists only in the extension), whose arithmetic it follows (the
        extension's ``ContactRhs.select_modes``, ``src/native/modes.hpp``), on the contact
        set's rows at (q, v); the pairs' modes are read from ``contacts`` and returned, not
        written there. The contact set's layout is loaded first; the loaded plan is changed.

        Args:
            contacts: The contact set (its layout, pairs, stick flags and slip directions).
            q: Configuration [rad].
            v: Velocity [rad/s].
            a_free: Unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.
            keep: select_modes' ``keep`` (a re-patch inside a mode).
            held: The engaged rows to keep if they still solve the mode problem (empty: none).

        Returns:
            The modes selected, or None where the Python selection takes a branch the native
            one does not (least squares, a singular Delassus matrix, a slide of zero speed).
        """
        self._core.load_layout(contacts)
        pairs = contacts._pair_list
        stick = np.array([p.stick for p in pairs], dtype=np.uint8)
        slip = np.zeros((len(pairs), 3))
        for i, p in enumerate(pairs):
            slip[i] = p.slip_dir
        status, kept, engaged, events, painleve, gave_up = self._core._rhs.select_modes(
            _reals(q), _reals(v), _reals(a_free), _reals(minv), keep,
            np.asarray(held, dtype=np.int64), stick, slip, contacts.mu, TOUCH_GAP, SPEED_BAND,
            STICK_SPEED, FORCE_BAND, STICK_BAND, BAUMGARTE, RESIDUAL_TOL,
        )  # fmt: skip
        self._core._plan_id = None  # (the selection loaded its own plans)
        if status != 0:
            return None
        return NativeModes(
            bool(kept), engaged.tolist(), stick.astype(bool), slip, events.tolist(),
            int(painleve), bool(gave_up),
        )  # fmt: skip


class NativeWatch:
    """What the extension watches in and at the end of a native step (``NativeRhs.watch``).

    Contact rows' conditions and roots, joint limits, pairs dipping into contact, the step
    end's screen.
    """

    def __init__(self, core: NativeRhs) -> None:
        self._core = core

    def row_condition_at(self, y: FloatArray, row: int) -> float | None:
        """A contact row's mode condition at state y with the loaded modes and torques.

        What :meth:`eval_at` then :meth:`NormalContacts.condition
        <packbot.contact.normal_dynamics.ConstrainedDynamics.condition>` with the key
        ``("nrow", row)`` give (the same float: an engaged row's force plus ``FORCE_BAND``, a
        free row's gap plus ``POINT_TOL``), in one call that builds no evaluation: for the
        root finding of a row's event inside a native step, which asks for that one value
        at each point. The contact set's last evaluation is left as it was.

        Args:
            y: The state, (q, v).
            row: The contact row.

        Returns:
            The condition [N or m], or None: the Delassus matrix is singular or the mode
            conditions' constants are not loaded (the caller evaluates in Python).
        """
        g = self._core._rhs.row_condition_at(y, row)
        return None if g != g else g

    def row_root(
        self, seg: DenseSegment, row: int
    ) -> Callable[[float, float, float, float, float], float] | None:
        """A contact row's crossing inside a native step, located in one native call.

        ``root(t0, t1, g0, g1, xtol)``: :func:`packbot.ode.locate_root` on the row's condition
        (:meth:`row_condition_at`) at the step's dense output, Brent's iterates natively (the
        interpolant summed in the extension's order: the same time to rounding); NaN where a
        condition cannot be evaluated. None for a segment the extension cannot interpolate
        (with a motor lag's torques in its state).

        Args:
            seg: The native step's segment (or a truncation of it).
            row: The contact row.
        """
        Z = seg._Z
        if Z.shape[1] != 2 * self._core.nv:
            return None
        hermite = isinstance(seg, HermiteSegment)
        rhs, h, y1 = self._core._rhs, seg._hz, seg.y1

        def root(t0: float, t1: float, g0: float, g1: float, xtol: float) -> float:
            return float(rhs.row_root(Z, t0, t1, h, y1, hermite, row, g0, g1, xtol))

        return root

    def set_limits(self, upper: FloatArray, lower: FloatArray) -> None:
        """The joint limits [rad] :meth:`end_check` screens (empty arrays: none)."""
        self._core._rhs.set_limits(_reals(upper), _reals(lower))

    def limit_excursions(
        self, y0: FloatArray, y1: FloatArray, h: float, tol: float
    ) -> list[tuple[int, int, float]]:
        """Joints past a limit of :meth:`set_limits` inside a step, within it at both ends.

        The cubic Hermite of each joint's (q, v) at the step's start ``y0`` and end ``y1``
        over ``h`` [s] reaching beyond the limit by more than ``tol`` [rad] at an interior
        extreme: (joint, side (+1 upper, -1 lower), the extreme's fraction of the step).
        """
        return list(self._core._rhs.limit_excursions(_reals(y0), _reals(y1), float(h), float(tol)))

    def set_pair_joints(self, start: NDArray[np.int64], idx: NDArray[np.int64]) -> None:
        """Each world pair's joints for :meth:`pair_dips` (``pairs.pair_joints``'s CSR)."""
        self._core._rhs.set_pair_joints(
            np.ascontiguousarray(start, np.int64), np.ascontiguousarray(idx, np.int64)
        )

    def pair_dips(
        self,
        seg: DenseSegment,
        start: tuple[NDArray[np.intp], FloatArray],
        end: tuple[NDArray[np.intp], FloatArray],
        active: NDArray[np.int64],
        margin: float,
        distance: Callable[[int, FloatArray], float],
    ) -> tuple[list[tuple[int, float, float, float]], int]:
        """Pairs in contact and out again inside a step (the extension's ``pair_dips.hpp``).

        Conservative advancement on each swept pair's distance over the step ``seg``: with
        ``|d'| <= sum reach_j max |dq_j/dt|`` over the joints between its pieces (each
        joint's largest speed on the step's dense output, the path the queries follow), an
        interval whose ends' distances do not prove it clear is halved at a query on the dense
        output, level by level,
        until every part is clear (to within ``PENETRATION_TOL / 20``), or a query finds the
        pair at the level looked for: ``d <= 0`` for a pair outside the contact set apart at
        both ends, or of the set apart by more than :data:`PENETRATION_TOL` at both ends;
        ``d <= -PENETRATION_TOL`` for a pair of the set within it at the start and apart by
        more at the end (other features through its rows); a pair of the set within it at the
        end is not screened. ``start`` and ``end`` are the sweeps (pairs, distances [m]) at
        the step's ends (a pair absent from ``start`` is queried there when needed);
        ``active`` the contact set's pairs; ``distance(pair, y)`` a pair's signed distance [m]
        at state y. Returns ([(pair, s, d, level), ...]: the first query at the level, s its
        fraction of the step, d its distance [m], level 0 or -PENETRATION_TOL [m]; the number
        of queries).
        """

        def at(k: int, s: float) -> float:
            return distance(int(k), seg(seg.t0 + s * seg.h))

        Q = np.ascontiguousarray(seg._coefficients(), dtype=np.float64)
        found, evals = self._core._rhs.pair_dips(
            Q,
            float(seg.h / seg._hz),
            float(seg.h),
            np.ascontiguousarray(start[0], np.int64),
            _reals(start[1]),
            np.ascontiguousarray(end[0], np.int64),
            _reals(end[1]),
            False,
            np.ascontiguousarray(active, np.int64),
            float(margin),
            PENETRATION_TOL,
            at,
        )
        return [(int(k), float(s), float(d), float(lv)) for k, s, d, lv in found], int(evals)

    @property
    def unresolved_dips(self) -> int:
        """Pairs whose :meth:`pair_dips` screen stopped at its query cap (since the build)."""
        return int(self._core._rhs.unresolved_dips)

    def end_check(
        self,
        y1: FloatArray,
        swept: NDArray[np.int64],
        dist: FloatArray,
        active: NDArray[np.int64],
        near: float,
        pen_tol: float,
    ) -> int:
        """The step end's screen of the contact-normal mode, from the last native step's end.

        What :meth:`NormalLaw.watch <packbot.contact.normal_law.NormalLaw.watch>` and
        ``after_step`` would find at y1, in one call on the FSAL stage's evaluation (the one
        :meth:`end_eval` returns) and the step end's sweep: -1 when the last native call was
        not a step ending at y1 (nothing screened); else a bit set, 0 when there is nothing
        to do. Bit 1: a swept pair has an event (outside ``active``: ``d <= 0``; in it:
        ``d > near`` or ``d < -pen_tol``). Bit 2: a mode condition is negative (end_eval's
        ``cond < 0``). Bit 4: a pair with engaged rows slides and a sliding contact's patch
        may be stale (:meth:`NormalContacts.sliding` and ``stale`` would re-patch), or a slide
        speed is too close to the stick speed to say without numpy's rounding. Bit 8: a
        joint is at or beyond one of the limits of :meth:`set_limits`.

        Args:
            y1: The state the step ended at, (q, v).
            swept: The swept pairs' indices in the collision world.
            dist: Their signed distances at y1 [m].
            active: The active pairs' indices.
            near: The proximity tolerance [m].
            pen_tol: The penetration a contact re-patches at [m].

        Each pair's patch goes stale at its own slide (``_Layout.slide_tol2``, loaded with the
        layout by :meth:`load`).
        """
        return int(self._core._rhs.end_check(y1, swept, dist, active, near, pen_tol))


# ---- the hand-off's calls (HandoffContacts: src/native/contact_rhs_clamps.cpp) on a NativeRhs
def lock_subspace(
    rhs: NativeRhs, a_free: FloatArray, minv: FloatArray, locked: list[int]
) -> tuple[FloatArray, FloatArray]:
    """Free accelerations and M^-1 with the joints ``locked`` fixed (a_j = 0).

    ``ContactRhs.lock_subspace`` (``src/native/contact_rhs_clamps.cpp``): the Schur
    complement M^-1_c = M^-1 - M^-1 S^T (S M^-1 S^T)^-1 S M^-1 and
    a_c = a_free - M^-1 S^T (S M^-1 S^T)^-1 a_free[S], their rows and columns of S zero.

    Args:
        rhs: The contact set's native right-hand side.
        a_free: Unconstrained accelerations [rad/s^2].
        minv: M^-1.
        locked: The joints S (velocity indices).

    Returns:
        (a_c [rad/s^2], M^-1_c), new arrays.
    """
    a_c, minv_c = rhs._rhs.lock_subspace(_reals(a_free), _reals(minv), _ints(locked))
    return a_c, minv_c


def lock_torques(
    rhs: NativeRhs, a_free: FloatArray, minv: FloatArray, qc: FloatArray, locked: list[int]
) -> FloatArray:
    """The torques [N*m] holding the joints ``locked`` at rest under the rows' force ``qc``.

    ``ContactRhs.lock_torques``: tau_S = -(M^-1_SS)^-1 (a_free + M^-1 qc)_S, with qc =
    C^T lambda [N*m] (an evaluation's ``qc``), a_free [rad/s^2] and M^-1 the full arm's.

    Args:
        rhs: The contact set's native right-hand side.
        a_free: Unconstrained accelerations [rad/s^2].
        minv: M^-1.
        qc: The rows' generalized force [N*m].
        locked: The joints S (velocity indices).

    Returns:
        One torque per joint of ``locked``, in its order.
    """
    return np.asarray(
        rhs._rhs.lock_torques(_reals(a_free), _reals(minv), _reals(qc), _ints(locked))
    )


def stop_joints(
    rhs: NativeRhs, v: FloatArray, minv: FloatArray, clamps: list[tuple[int, int]], one_sided: bool
) -> tuple[int, FloatArray]:
    """The least (M-weighted) joint impulse on the clamp rows -s e_j of ``clamps`` alone.

    ``ContactRhs.stop_joints`` (``src/native/contact_rhs_clamps.cpp``): after it every
    row's velocity is >= 0 (``one_sided``: an LCP, Lemke's answer to ``RESIDUAL_TOL``;
    perfectly inelastic) or 0 (equalities; the rows' joints then exactly at rest).

    Args:
        rhs: The contact set's native right-hand side.
        v: Joint velocities [rad/s].
        minv: M^-1.
        clamps: The rows, (joint, s).
        one_sided: Inequalities (else equalities).

    Returns:
        (status, v+): 0 no row approaches (one-sided), 1 the velocity after [rad/s], 2
        unsolved (v+ = v).
    """
    status, out = rhs._rhs.stop_joints(
        _reals(v),
        _reals(minv),
        _ints([j for j, _ in clamps]),
        _reals([s for _, s in clamps]),
        one_sided,
        RESIDUAL_TOL,
    )
    return int(status), out


def stretch(rhs: NativeRhs, api: Any, **constants: Any) -> Any:
    """The compiled stretch of quiet steps on ``rhs`` and a compiled sweep's entry point ``api``.

    ``packbot._native.Stretch`` (``src/native/stretch.hpp``); ``constants`` are its keyword
    arguments (:class:`packbot.contact.stretch.QuietStretch` passes them).
    """
    assert _native is not None
    return _native.Stretch(rhs._rhs, api, **constants)


def native_rhs(model: pin.Model) -> NativeRhs:
    """The native right-hand side of ``model``.

    Raises:
        PackbotError: The extension ``packbot._native`` is not built.
        ModelError: A joint type the extension does not rebuild.
    """
    return NativeRhs(model)
