"""Time-stepping windows of the contact-normal mode: Moreau-Jean steps where events pile up.

Event-driven integration resolves every contact event exactly while events are few. Where they
pile up, it breaks down: an impulsive stick/slip or jam cascade that cycles through its modes at
one instant, an accumulation of impacts, a chattering slide (with the light wrist and camera
joints free, most random starts did, at the ``max_events`` guard). The event-driven literature's
answer (Acary & Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*, Springer 2008,
ch. 10 and 12) is to switch locally to time-stepping: integrate the window where events
accumulate with fixed steps, one complementarity problem per step and no event location, then
return to exact event-driven integration once the contacts have settled.

One step of :class:`MoreauJeanStepper` from (t, q, v) over h (the Moreau-Jean scheme with
theta = 1, i.e. symplectic Euler with impulses):

1. **Contact set**: every collision pair within ``d_act`` of touching (its patch: one row per
   point, as the event-driven mode builds them) and, with joint limits on, every joint within
   ``h |v_j| +`` :data:`LIMIT_GAP` of a limit. ``d_act`` = :data:`ACTIVE_GAP` plus twice the
   distance any point can travel in the step, h sum_j r_j |v_j| with r_j the joint's reach
   bound (:func:`reach_bounds`). A pair's patch is kept while it describes the contact (the
   event-driven mode's rule: :meth:`NormalContacts.stale_pairs`): :mod:`.window_set`.
2. **Free velocity**: v_f = v + h a_free(t + h/2, q_m, v_m) (applied torques, gravity,
   Coriolis, viscous joint friction), at the explicit midpoint q_m = q (+) (h/2) v,
   v_m = v + (h/2) a_free(t, q, v): an Euler step v + h a_free(t, q, v) gains energy where a
   light joint spins (its gyroscopic terms; measured in docs/contact.md). Joint Coulomb
   friction and brakes are not in a_free: they are rows of the problem below.
3. **One complementarity problem** for the impulses x [N*s, N*m*s] (Pinocchio's ADMM,
   :func:`packbot.contact.lcp.solve_mixed_admm`), with u = J v+ the rows' velocities after the
   step and v+ = v_f + M^-1 J^T x:

   - per contact point, blocks (t1, t2, n): x in the Coulomb cone of friction mu, the De
     Saxce-shifted u + b in the dual cone, complementary. b_n = max(g, 0) / h lets an open gap
     g close within the step but not beyond; a touching point approaching faster than the Zeno
     speed gets Newton's law, b_n = e min(u_n-, 0) (u_n- its normal velocity before), unless
     that impulse would add kinetic energy (then the inelastic one);
   - per limit row: x >= 0 (a cone of friction 0), the same b;
   - per joint with Coulomb friction or a brake (holding torque F_j [N*m]): |x_j| <= h F_j;
     v_j+ = 0 strictly inside (the joint sticks), v_j+ against x_j at the bound (it slips).

4. **Positions**: q+ = q (+) h v+; a pair left deeper than :data:`PROJECT_DEPTH` is projected
   out (the contact set's position-level LCP, :meth:`NormalContacts.project`).
5. **Energy**: the discrete step can add energy (symplectic Euler's energy error oscillates
   with the step, O(h)); a step whose energy change exceeds the work of the applied motor
   torques is scaled back, v+ <- s v+ with 0 <= s < 1 so that it does not (scaling keeps every
   row's sign: a stuck point stays stuck, a separating one separates). The energy removed this
   way is counted (:attr:`StepInfo.removed`, ``Diagnostics.window_energy_removed``): a
   modelling choice of the window, measured in docs/contact.md.

A step is the extension's (:meth:`NativeRestart.window_step
<packbot.contact.native.NativeRestart.window_step>`, ``src/native/contact_rhs_window.cpp``): the
free velocity, M^-1, the rows, the patch rule, the problem and its impulses by the low-rank
ADMM (:mod:`packbot.contact.conic`), v1, q1 and the guard's energies, in one call, where the
torques are fixed over the step and the contact set stays as it is
(:meth:`MoreauJeanStepper._native_step`). Where the set changes, Python updates it (the sweep,
the patches, the limits) and the same call, its set checks off, takes the impulses. The
extension does not cover a touching row that bounces (restitution), impulses that do not
converge (the fallbacks of :meth:`WindowImpulses._solve
<packbot.contact.window_impulses.WindowImpulses._solve>`), torques that vary over the step
(a torque function, a motor lag) or a set of limits alone: those steps' problems are assembled
in numpy (:func:`packbot.contact.conic.step_problem`) and solved in Python
(:mod:`packbot.contact.window_impulses`). The sweep at a step's end serves the next step's
contact set, and the energy at its end the next step's guard. What a step costs, and where:
docs/performance.md, "Window steps".

A step's *signature* is what the solution decided: the pairs and limits pushing, the pairs
sliding, the joints slipping. The law (:class:`~packbot.contact.normal.NormalLaw`) leaves the
window when the signature has held for :data:`QUIET_STEPS` steps (or the arm is free of
contacts, or at rest), and the event-driven restart takes over from that state.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from itertools import compress
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact import conic
from packbot.contact import window_impulses as wi
from packbot.contact.pairs import reach_bounds
from packbot.contact.window_forces import WindowForces
from packbot.contact.window_impulses import WindowImpulses
from packbot.contact.window_set import WindowSet
from packbot.errors import PackbotError
from packbot.ode import DenseSegment

if TYPE_CHECKING:
    from packbot.config import SimConfig
    from packbot.contact.native import NativeRhs
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.drive import Drive
    from packbot.system import System

__all__ = [
    "ACTIVE_GAP",
    "LIMIT_GAP",
    "PROJECT_DEPTH",
    "QUIET_STEPS",
    "STEP_ANGLE",
    "WINDOW_STEP",
    "MoreauJeanStepper",
    "StepInfo",
    "StepSegment",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
_NONE = np.zeros(0)  # (an empty argument of the native step: no guess, no limits)
_NO_PAIRS = np.zeros(0, dtype=np.int64)  # (its sweep after a set update: none, unchecked)


class _PythonStep(NamedTuple):
    """A window step's impulses taken in Python (:meth:`MoreauJeanStepper._python_step`)."""

    v_f: FloatArray
    v1: FloatArray
    x: FloatArray
    residual: float
    closest: tuple[float, int]
    cj: NDArray[np.intp]
    lay: Any
    m: int


#: Time step of a window [s].
WINDOW_STEP = 5e-4
#: No body turns more than this in a step [rad] (a step is shortened below WINDOW_STEP when the
#: joints' speeds sum to more than STEP_ANGLE / WINDOW_STEP = 10 rad/s): the scheme moves points
#: along straight lines, off their arcs by about r (STEP_ANGLE)^2 / 2 = 1.25e-6 m at r = 0.1 m.
#: Measured without it: 21 um of penetration with the wrist spinning at 36 rad/s.
STEP_ANGLE = 5e-3
#: Pairs closer than this (plus the step's travel) take part in a step's problem [m].
ACTIVE_GAP = 1e-4
#: Joints closer than this (plus the step's travel) to a limit take part [rad].
LIMIT_GAP = 1e-4
#: The sweep at a step's end, which the next step's contact set reuses, has the margin of that
#: step's reach at this many times the current speeds (the next step's free velocity adds
#: h a_free; a reach beyond the margin sweeps again).
SWEEP_SLACK = 1.5
#: A step that leaves a pair deeper than this is projected out [m], in up to PROJECT_PASSES
#: passes (each from patches at the corrected q: a curved piece's contact point moves).
PROJECT_DEPTH = 5e-6
PROJECT_PASSES = 3
#: The law leaves a window once a step's signature has held this many steps.
QUIET_STEPS = 20
#: A contact point pushes when its normal impulse exceeds this [N*s] (signatures).
IMPULSE_BAND = 1e-9


class StepSegment(DenseSegment):
    """One time step [t0, t1] of a window: q linear (its slope is v+), v linear between ends.

    The recorder samples it like an integrator step; q(t) is the scheme's own (q moves with
    the step's end velocity), v(t) a linear blend for the samples.
    """

    __slots__ = ()

    def __init__(self, t0: float, t1: float, y0: FloatArray, y1: FloatArray) -> None:
        """A step from (t0, y0) to (t1, y1)."""
        super().__init__(t0, t1, t1 - t0, y0, y1, np.zeros((8, len(y0))))

    def __call__(self, t: float) -> FloatArray:
        """y(t) by linear interpolation, exactly y0 at t0 and y1 at t1."""
        if t == self.t1:
            return self.y1.copy()
        if t == self.t0 or self.h <= 0.0:
            return self.y0.copy()
        th = (t - self.t0) / self.h
        return np.asarray(self.y0 + th * (self.y1 - self.y0), dtype=np.float64)

    def derivative(self, t: float) -> FloatArray:
        """The step's mean slope [units of y per s]."""
        return np.asarray((self.y1 - self.y0) / self.h, dtype=np.float64)


@dataclass
class StepInfo:
    """What one window step decided and did.

    Attributes:
        signature: The pairs pushing, the pairs sliding, the limits pushing and the joints
            slipping (a hashable summary; the window is quiet while it holds).
        rows: Contact rows (points and limits) in the step's problem.
        residual: The complementarity solution's scaled residual [-].
        removed: Energy the step's guard removed [J] (0 when the step did not gain).
        projected: Whether a penetrating pair was projected out.
        closest: The smallest signed distance [m] of the step's sweep (at its start) and its
            pair (-1: none within reach).
    """

    signature: tuple[frozenset[int], frozenset[int], frozenset[tuple[int, int]], frozenset[int]]
    rows: int
    residual: float
    removed: float
    projected: bool
    closest: tuple[float, int] = (math.inf, -1)


class MoreauJeanStepper:
    """Fixed time steps with one complementarity problem each (see the module docstring).

    Args:
        system: The phase's integrated system (model, mass matrix, energy, collision world).
        drive: The run's torques (its ``fdir`` must be zero: Coulomb friction is a row here).
        contacts: The contact set whose patches and rows the steps use (the law's own).
        config: Simulation settings (mu, restitution, zeno_speed, joint_limits, motor_lag).
        h: Time step [s].
        reach: Per velocity index, the bound [m] :func:`reach_bounds` gives for this model and
            world, if the caller holds it (None: computed here).
        native: The law's compiled right-hand side of this model (required: the steps are its
            ``window_step``).

    Raises:
        PackbotError: ``native`` is None (no compiled right-hand side for this model).
    """

    def __init__(
        self,
        system: System,
        drive: Drive,
        contacts: NormalContacts,
        config: SimConfig,
        h: float = WINDOW_STEP,
        reach: FloatArray | None = None,
        native: NativeRhs | None = None,
    ) -> None:
        self.sys, self.drive, self.contacts, self.cfg = system, drive, contacts, config
        if native is None:
            raise PackbotError(
                "the time-stepping window needs the compiled right-hand side of this model "
                "(packbot._native, with the model's joints supported)"
            )
        #: The law's compiled right-hand side: its ``window_step`` takes the steps.
        self.native: NativeRhs = native
        #: Steps taken in one native call, and those it handed back to Python by why (1 the
        #: contact set changes, 2 a bounce, 3 no converged impulses, 4 no factor of M^-1, 5
        #: its impulses drive a joint past a stop that is not in the set).
        self.native_steps = 0
        self.native_misses: dict[int, int] = {}
        #: Of those handed back because the set changes: the steps whose impulses the native
        #: call then took on the updated set (:meth:`_python_step`).
        self.native_solves = 0
        #: why the last native step handed back and its torques (None: it did not)
        self._miss: tuple[int, tuple[FloatArray, ...]] | None = None
        #: the velocity [rad/s] of a native step handed back because its impulses drive a
        #: joint past a stop not in the set (status 5), else None
        self._miss_v1: FloatArray | None = None
        #: the step a native run of steps (window_run.run_native) handed back: (the state's
        #: bytes, the step's size [s], why, its free velocity [rad/s]); None: none
        self._handed: tuple[bytes, float, int, FloatArray] | None = None
        self.h = float(h)
        self.n = system.nv
        #: The last step's Coulomb and brake torques [N*m] (its box impulses / h).
        self.joint_torque = np.zeros(self.n)
        #: The Python problem and solvers of the steps the extension does not take, and
        #: every step's warm start.
        self.impulses = WindowImpulses(system, drive, contacts, config)
        #: The steps' impulses as their samples' contact forces (cleared by the law once a
        #: segment's samples are recorded).
        self.forces = WindowForces(contacts, system.model.createData())
        # the last step's sweep at its end: (q bytes, margin [m], result), or None
        self._next_sweep: tuple[bytes, float, Any] | None = None
        # the last step's end state (q, v bytes) and its energy [J], or None
        self._end_energy: tuple[bytes, float] | None = None
        self._lay: _PairLayout | None = None  # see _layout
        #: Per velocity index, a bound on the distance [m] from the joint's axis to any point
        #: it moves: a point's speed is at most reach . |v| (see reach_bounds; ``reach``: the
        #: caller's, for the same model and world).
        self.reach = reach_bounds(system.model, contacts.world) if reach is None else reach
        #: The contact set's updates at each step (the pairs and limits within its reach).
        self.set = WindowSet(system, contacts, self.reach, config.joint_limits)

    def step(
        self,
        t: float,
        y: FloatArray,
        t_end: float,
        energy: Callable[[FloatArray, FloatArray], float],
        pending: tuple[tuple[Any, ...], tuple[float, Any]] | None = None,
    ) -> tuple[StepSegment, StepInfo]:
        """One step from (t, y), not past t_end; the step and what it decided.

        Args:
            t: Time [s].
            y: State (q, v[, tau_m]).
            t_end: The step ends at min(t + h, t_end) [s].
            energy: Total mechanical energy [J] of (q, v).
            pending: The step already taken natively, and the sweep at its end (its margin
                [m], the result), by :func:`packbot.contact.window_run.run_native`: it is
                finished here (``_native_step``'s result and ``_finish``'s first sweep).
        """
        sys, n = self.sys, self.n
        q, v, tail = y[:n], y[n : 2 * n], y[2 * n :]
        # no body turns more than STEP_ANGLE in a step (the scheme is first order in it)
        h = min(self.h, STEP_ANGLE / max(float(np.abs(v).sum()), 1e-300), t_end - t)
        _, target, applied, _ = self.drive.torques(t, y)
        fast: Any = pending[0] if pending is not None else self._native_step(t, y, h)
        if isinstance(fast, np.ndarray):  # handed back, with its free velocity
            fast = self._python_step(t, y, h, fast)
        if isinstance(fast, _PythonStep):
            v_f, v1, x, residual, closest, cj, lay, m = fast
            q1 = np.asarray(pin.integrate(sys.model, q, h * v1), dtype=np.float64)
            energies = None
        elif fast is not None:
            v_f, v1, q1, x, residual, closest, cj, lay, energies = fast
            m = (len(x) - len(cj)) // 3  # (the contact rows' blocks, then the joint boxes)
        else:
            v_f, v1, x, residual, closest, cj, lay, m = self._python_step(t, y, h)
            q1 = np.asarray(pin.integrate(sys.model, q, h * v1), dtype=np.float64)
            energies = None
        # what the step decided, on the rows it solved (the projection below may change the set)
        c = self.contacts
        sig = lay.signature(x, list(c.limits), c.mu, self.h * self.drive.path.coulomb[cj], cj)
        self.joint_torque = np.zeros(n)
        self.joint_torque[cj] = x[3 * m :] / h
        self.forces.keep(t, t + h, q, x)  # (on the rows solved: the projection may change them)
        end = (v_f, v1, q1, energies)
        first = None if pending is None else pending[1]
        return self._finish(
            t, y, h, tail, target, applied, end, sig, m, residual, closest, energy, first
        )

    def _native_step(
        self, t: float, y: FloatArray, h: float
    ) -> tuple[Any, ...] | FloatArray | None:
        """The step's impulses in one native call, or None: the step is Python's.

        The compiled right-hand side's ``window_step`` (:meth:`NativeRestart.window_step
        <packbot.contact.native.NativeRestart.window_step>`) takes the step's free velocity, M^-1,
        rows, problem and impulses with the arithmetic of :meth:`_python_step`, when the torques
        are fixed over the step (a held command or none, no motor lag, no Coulomb direction
        outside the problem's boxes: :meth:`Drive.step_torques`) and the contact set stays as
        it is: the last step's sweep at its end, at this q, covers the step's reach and holds
        exactly the set's pairs within it, the set's limits are the joints' near limits, and
        no patch is stale. It hands the step back where the set changes (this method's caller
        then updates it), with a bounce or with no converged impulses (the fallbacks of
        :meth:`WindowImpulses._solve <packbot.contact.window_impulses.WindowImpulses._solve>`),
        and where its impulses drive a joint past a stop not in the set (:meth:`_python_step`
        adds the stops within h |v1| and solves again).

        Returns:
            None when not attempted; the free velocity v_f [rad/s] when handed back (the
            caller's Python step reuses it); else (v_f, v1, q1, x, residual, closest, cj, lay,
            energies): as :meth:`_python_step`
            (without m), with q1 = q (+) h v1 and the energies at the step's start and end and
            the end's kinetic energy [J] (the guard's, the sums of ``NativeRhs.energies``).
        """
        contacts, n = self.contacts, self.n
        cached = self._next_sweep
        if len(y) != 2 * n or not contacts.pairs or cached is None or cached[0] != y[:n].tobytes():
            return None
        torques = self.drive.step_torques(t, y)
        if torques is None or torques[2].any():
            return None
        handed, self._handed = self._handed, None
        if handed is not None and handed[0] == y.tobytes() and handed[1] == h:
            # (the window's native run stopped at this step: handed back, with its v_f)
            self._miss = (handed[2], torques)
            self.native_misses[handed[2]] = self.native_misses.get(handed[2], 0) + 1
            return np.asarray(handed[3], dtype=np.float64)
        sw = cached[2]
        closest = (float(sw.min_distance), int(sw.min_pair))
        return self._native_call(y, h, torques, closest, (sw.pairs, sw.distances, cached[1]))

    def _native_call(
        self,
        y: FloatArray,
        h: float,
        torques: tuple[FloatArray, ...],
        closest: tuple[float, int],
        sweep: tuple[NDArray[np.int64], FloatArray, float] | None,
    ) -> tuple[Any, ...] | FloatArray:
        """The native window step: :meth:`_native_step`'s results.

        ``sweep``: the last sweep's pairs, distances and margin [m] that check the set; None:
        the set was just updated for this step (:meth:`_python_step`), not checked.
        """
        contacts, n = self.contacts, self.n
        rhs = self.native
        rhs.hold_torque(*torques)
        coul = self.drive.path.coulomb
        cj = np.flatnonzero(coul > 0.0)
        lay = self._layout()
        rows = (lay.key, len(cj))
        guess, rho0 = self.impulses.guess(rows)
        cfg = self.cfg
        limits = (self.sys.upper, self.sys.lower) if cfg.joint_limits else (_NONE, _NONE)
        pairs, dist, margin = (_NO_PAIRS, _NONE, 0.0) if sweep is None else sweep
        v_f, v1, q1 = np.empty(n), np.empty(n), np.empty(n)
        status, x, residual, _, rho, energies = rhs.restart.window_step(
            contacts, y, h, swept=pairs, dist=dist, sweep_margin=margin,
            reach=self.reach, active_gap=ACTIVE_GAP, upper=limits[0], lower=limits[1],
            limit_gap=LIMIT_GAP, mu=contacts.mu, restitution=cfg.restitution,
            zeno=cfg.zeno_speed, touch_gap=wi.TOUCH_GAP, boxes=cj, bound=h * coul[cj],
            guess=_NONE if guess is None else guess, rho0=rho0, tol=wi.CONIC_TOL,
            max_iterations=wi.CONIC_ITERATIONS, ok=wi.RESIDUAL_OK, out_vf=v_f, out_v1=v1,
            out_q1=q1, checked=sweep is not None,
        )  # fmt: skip
        if status != 0:
            self._miss = (status, torques)
            self._miss_v1 = v1 if status == 5 else None
            self.native_misses[status] = self.native_misses.get(status, 0) + 1
            return v_f  # (its free velocity: the midpoint rule's, as Python's)
        assert x is not None  # (status 0: the impulses)
        if sweep is not None:
            self.native_steps += 1
        else:
            self.native_solves += 1
        self.impulses.keep(rows, x, rho)
        return v_f, v1, q1, x, residual, closest, cj, lay, energies

    def _python_step(
        self, t: float, y: FloatArray, h: float, v_free: FloatArray | None = None
    ) -> _PythonStep | tuple[Any, ...]:
        """The step's impulses in Python: (v_f, v1, x, residual, closest, cj, lay, m).

        ``v_free``: the free velocity, already computed (by a native step handed back). A
        native step handed back because the contact set changes: the set is updated here,
        then the step's impulses are the native call's (:meth:`_native_step`'s results; the
        same arithmetic as below) unless it hands the step back again (a bounce, no
        converged impulses: the fallbacks below).
        """
        sys, contacts, n = self.sys, self.contacts, self.n
        q, v = y[:n], y[n : 2 * n]
        # (a native step handed back because the set changes: its torques, else None)
        miss, self._miss = self._miss, None
        crossed_v1, self._miss_v1 = self._miss_v1, None
        torques = miss[1] if v_free is not None and miss is not None and miss[0] in (1, 5) else None
        # the free accelerations at the step's midpoint (explicit midpoint rule): an Euler step
        # v + h a_free(q, v) gains energy where a light joint spins (its gyroscopic terms)
        if v_free is not None:
            v_f = v_free
        else:
            a0 = self.drive.free_accel(t, y)
            y_mid = y.copy()
            y_mid[:n] = pin.integrate(sys.model, q, 0.5 * h * v)
            y_mid[n : 2 * n] = v + 0.5 * h * a0
            v_f = v + h * self.drive.free_accel(t + 0.5 * h, y_mid)

        # the set, the impulses, and again with the stops they drive a joint past (each round
        # adds one stop at least: its limit rows then hold it)
        reach = LIMIT_GAP + h * np.maximum(np.abs(v), np.abs(v_f))
        closest = self.set.update(q, v, v_f, h, ACTIVE_GAP, reach, self._next_sweep)
        while True:
            if crossed_v1 is None and torques is not None and contacts.pairs:
                fast = self._native_call(y, h, torques, closest, None)
                if not isinstance(fast, np.ndarray):
                    return fast
                crossed_v1, self._miss_v1, self._miss = self._miss_v1, None, None
            if crossed_v1 is None:
                lay = self._layout()
                v1, x, residual, cj, m = self.impulses.solve(q, v, v_f, h, lay)
                if not self._crosses(q, v1, h):
                    return _PythonStep(v_f, v1, x, residual, closest, cj, lay, m)
                crossed_v1 = v1
            before = len(contacts.limits)
            np.maximum(reach, LIMIT_GAP + h * np.abs(crossed_v1), out=reach)
            self.set.update_limits(q, reach)
            if len(contacts.limits) <= before:
                # (not reached: a crossed stop is within h |v1| of q, so it joins the set)
                raise RuntimeError("the stops the impulses cross did not join the set")
            crossed_v1 = None

    def _crosses(self, q: FloatArray, v1: FloatArray, h: float) -> bool:
        """Whether q (+) h v1 is past a joint limit that is not one of the set's rows."""
        if self.contacts.stops is None:  # (no joint limits)
            return False
        q1 = np.asarray(pin.integrate(self.sys.model, q, h * v1), dtype=np.float64)
        return bool(self.contacts.crossed_stops(q1))

    def _finish(
        self,
        t: float,
        y: FloatArray,
        h: float,
        tail: FloatArray,
        target: FloatArray,
        applied: FloatArray,
        end: tuple[FloatArray, FloatArray, FloatArray, tuple[float, float, float] | None],
        sig: Any,
        m: int,
        residual: float,
        closest: tuple[float, int],
        energy: Callable[[FloatArray, FloatArray], float],
        first: tuple[float, Any] | None = None,
    ) -> tuple[StepSegment, StepInfo]:
        """The step's end, and the step and what it decided.

        The sweep at q1 (a deep pair projected out), the energy guard, the motor lag's
        torques. ``end``: the free velocity v_f, v1 and q1 [rad/s, rad], and the native step's
        energies (at the start, at the end, the end's kinetic one [J]; None: computed here).
        ``first``: the first pass's sweep at q1, already made (its margin [m], the result).

        The speeds and the applied torques' work are numpy's sums of products (not ``@``,
        BLAS's order): ``ContactRhs.window_run`` sums them in the same order, to the bit.
        """
        sys, cfg, contacts, n = self.sys, self.cfg, self.contacts, self.n
        q, v = y[:n], y[n : 2 * n]
        v_f, v1, q1, energies = end
        projected = False
        world = contacts.world
        # the first pass's sweep at q1 also serves the next step's contact set (it starts at
        # q1 unless a pass moves it): its margin covers that step's reach at the speeds now
        # and at its free velocity, predicted with this step's change v_f - v (an arm at
        # rest has v1 = 0 and the next step's reach h |a_free|)
        r = self.reach
        speed = max(float((r * np.abs(v1)).sum()), float((r * np.abs(v1 + (v_f - v))).sum()))
        reach = ACTIVE_GAP + 2.0 * self.h * SWEEP_SLACK * speed
        self._next_sweep = None
        for npass in range(PROJECT_PASSES if world is not None else 0):
            assert world is not None
            if npass == 0 and first is not None:
                reach, sw = first
            else:
                sw = world.sweep(q1, margin=reach if npass == 0 else PROJECT_DEPTH)
            if npass == 0:
                self._next_sweep = (q1.tobytes(), reach, sw)
            deep = sw.pairs[sw.distances < -PROJECT_DEPTH].tolist()
            if not deep:
                break
            # patches at q1 (a curved piece's contact moves): a pass corrects to first order
            contacts.refresh(q1)
            contacts.add_pairs(q1, deep)
            q1 = contacts.project(q1, v1, sys.minv(q1))
            projected = True
            self._next_sweep = None

        # the energy guard (the energy at the step's start: the last step's at its end when
        # this step starts there, bit for bit)
        last = self._end_energy
        kept = last[1] if last is not None and last[0] == y[: 2 * n].tobytes() else None
        if energies is not None and not projected:  # (the native step's, at its q1)
            e0 = energies[0] if kept is None else kept
            e1, kin = energies[1], energies[2]
        else:
            e0 = energy(q, v) if kept is None else kept
            e1, kin = energy(q1, v1), math.nan
        work = h * float((applied * (0.5 * (v + v1))).sum())
        removed = 0.0
        excess = e1 - e0 - work
        if excess > 0.0:
            if math.isnan(kin):
                kin = 0.5 * float(v1 @ sys.mass_matrix(q1) @ v1)
            s = math.sqrt(max(0.0, kin - excess) / kin) if kin > 0.0 else 0.0
            v1 = s * v1
            removed = kin * (1.0 - s * s)
            self._end_energy = None
        else:
            self._end_energy = (q1.tobytes() + v1.tobytes(), e1)

        if len(tail):
            lag = cfg.motor_lag
            tail = target + (tail - target) * math.exp(-h / lag) if lag > 0.0 else tail
        y1 = np.concatenate([q1, v1, tail])
        info = StepInfo(sig, m, residual, removed, projected, closest)
        return StepSegment(t, t + h, y, y1), info

    def _layout(self) -> _PairLayout:
        """The layout of the contact set's rows (kept while the set's own layout is)."""
        lay = self.contacts._layout()
        mine = self._lay
        if mine is None or mine.of is not lay:
            mine = self._lay = _PairLayout.build(self.contacts, lay)
        return mine


@dataclass
class _PairLayout:
    """The pairs of a contact set in its order, and where their points' rows are.

    Attributes:
        of: The contact set's own point layout (``NormalContacts._layout``) this one extends.
        keys: The pairs' indices in the collision world.
        rows: (m_p,) the patch point of each pair row (the limits' rows follow them).
        row_pair: (m_p,) the pair (position in the set) of each pair row.
        key: What makes two steps' rows the same rows (the pairs and their point counts, the
            limits; a warm start's condition): the points themselves move from step to step.
    """

    of: Any
    keys: list[int]
    rows: NDArray[np.intp]
    row_pair: NDArray[np.intp]
    key: tuple[Any, ...]

    @classmethod
    def build(cls, contacts: NormalContacts, lay: Any) -> _PairLayout:
        """The layout of the set as it is now (``lay``: its own point layout)."""
        keys = list(contacts.pairs)
        counts = [len(p.local1) for p in contacts.pairs.values()]
        key = (tuple(zip(keys, counts, strict=True)), tuple(contacts.limits))
        rows = np.asarray(lay.rows, dtype=np.intp)
        pair = np.asarray(lay.pair, dtype=np.intp)
        return cls(lay, keys, rows, pair[rows], key)

    def signature(
        self,
        x: FloatArray,
        limits: list[tuple[int, int]],
        mu: float,
        bound: FloatArray,
        cj: NDArray[np.intp],
    ) -> tuple[frozenset[int], frozenset[int], frozenset[tuple[int, int]], frozenset[int]]:
        """What a step's impulses x on these rows decided (:attr:`StepInfo.signature`).

        Pairs pushing, pairs sliding, limits pushing, joints slipping.

        A pair pushes when its points' normal impulses sum to more than
        :data:`IMPULSE_BAND`; it slides when their tangential impulses' sum reaches the cone of
        friction ``mu`` (within 1e-6: :func:`packbot.contact.conic.step_signature`); a joint
        (velocity indices ``cj``) slips when its box impulse is at its ``bound`` [N*m*s]
        (within 1e-6). ``limits``: the contact set's limits, in its order.
        """
        push, slide, lim = conic.step_signature(
            x, self.row_pair, len(self.keys), len(limits), mu, IMPULSE_BAND
        )
        slipping: frozenset[int] = frozenset()
        if len(cj):
            slip = np.abs(x[len(x) - len(cj) :]) >= bound * (1 - 1e-6)
            slipping = frozenset(cj[slip].tolist())
        return (
            frozenset(compress(self.keys, push.tolist())),
            frozenset(compress(self.keys, slide.tolist())),
            frozenset(compress(limits, lim.tolist())),
            slipping,
        )
