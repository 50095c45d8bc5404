"""The contact-normal mode's law: events, restarts, and time-stepping windows.

:class:`NormalLaw` integrates the arm with the contact set of
:class:`~packbot.contact.normal.NormalContacts` between events and opens a time-stepping
window (:mod:`packbot.contact.timestep`) where events pile up; its thresholds are below.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo, SweepResult
from packbot.contact import native
from packbot.contact.base import Active, Crossing, Key
from packbot.contact.locks import JointLocks
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_forces import mode_forces
from packbot.contact.normal_tolerances import PENETRATION_TOL, POINT_TOL
from packbot.contact.pairs import pair_joints, reach_bounds
from packbot.contact.patch_events import PatchEvents
from packbot.contact.stretch import (
    LawInputs,
    QuietStretch,
    SampleClock,
    Stretched,
    adopt_repatches,
    quiet_stretch,
    repatch_modes,
)
from packbot.contact.timestep import QUIET_STEPS, MoreauJeanStepper, StepSegment
from packbot.contact.window_run import StepChain, run_native
from packbot.contact_forces import SampleForces
from packbot.ode import DenseSegment, RK45Stepper, StepKernel, StiffKernel
from packbot.system import System

__all__ = [
    "CASCADE_EVENTS",
    "CASCADE_SPAN",
    "CHATTER_EVENTS",
    "CHATTER_SPAN",
    "CRAWL_STEP",
    "CRAWL_STEPS",
    "HOLD_SPEED",
    "RELAPSE_EVENTS",
    "RELAPSE_SPAN",
    "WINDOW_MIN",
    "NormalLaw",
]

log = logging.getLogger(__name__)

#: Whether an arm captured at rest is held there in one step to the next controller tick,
#: scheduled action or the run's end (:meth:`NormalLaw.stretch`), instead of the stepper's
#: steps of ``max_step`` (tests and benchmarks switch it off to compare).
REST_HOLD = True

FloatArray = NDArray[np.float64]


#: A cascade: CASCADE_EVENTS restarts within CASCADE_SPAN [s] (a pile-up at one instant), or
#: CHATTER_EVENTS within CHATTER_SPAN [s] (a chattering slide: the drive-pose collapse with the
#: wrist free and mu = 0.8 made 10,000 a second; a jam cycling through impacts, stick/slip and
#: a joint limit every 3 ms: wrist-free start 17, mu 1.2, 3,985 events in 1.8 s) start a
#: time-stepping window. CHATTER_SPAN was 0.032 s (a restart every millisecond on average);
#: at 0.25 s (one every 7.8 ms) the 24 wrist-free starts of ``benchmarks/robustness.py``
#: take a median 0.65 -> 0.59 s (mu 0), 0.36 -> 0.33 s (mu 0.5), 0.31 -> 0.23 s (mu 1.2), the
#: worst 1.29 -> 1.15, 1.59 -> 1.50, 2.42 -> 0.83 s; the windows remove at most 0.029 J in a
#: run (0.0056 J before; frictionless); the wrist-locked starts, the collapse and the golden
#: results are unchanged (no such rate there). A chatter that comes back within CHATTER_SPAN
#: of a window's end opens the next window after RELAPSE_EVENTS restarts at the same rate, and
#: that window lasts twice the last one (a relapse): the jam above resumed into the same cycle
#: after each 20 ms window and took 32 more restarts to open the next one, 2,570 events in 3 s
#: on a rounding-level change of the dynamics; with the rule, 226 events in 7 windows.
CASCADE_EVENTS = 20
CASCADE_SPAN = 1e-3
CHATTER_EVENTS = 32
CHATTER_SPAN = 0.25
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
#: How far past a stop [rad] the cubic Hermite of a step's ends must reach for the step's dense
#: output to be asked (:meth:`NormalLaw._excursion_crossings`; a joint resting on its stop reads
#: its stop to rounding; the compiled stretch's screen uses the same 1e-9).
EXCURSION_TOL = 1e-9


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
        # Each joint's own reach (a wrist joint's 0.2 m, not REACH_BOUND's 2.2 m): the step
        # bound then follows what the moving joints can reach. (The report's law keeps
        # REACH_BOUND for every joint: its golden results are made with it.)
        self.reach = reach_bounds(system.model, system.world)
        self.normal = NormalContacts.from_config(system.model, system.data, system.world, self.cfg)
        self._native = native.native_rhs(system.model)
        self.normal.native = self._native  # (the restart's projection and impact)
        self._force_data = system.model.createData()  # (the contact forces' placements)
        self._rest_contacts: tuple[Any, SampleForces | None] = (None, None)
        if self.cfg.joint_limits:  # (the step end's screen, the drift projection)
            self._native.set_limits(system.upper, system.lower)
            self.normal.stops = (system.upper, system.lower)
        self._native.set_reach(self.reach, self.cfg.margin, self.cfg.max_step)  # (step_bound)
        self._native.set_pair_joints(*pair_joints(system.model, self.world.pairs))
        self.window: _Window | None = None
        self._recent: deque[float] = deque(maxlen=CHATTER_EVENTS)
        self._steps: deque[float] = deque(maxlen=CRAWL_STEPS)  # the last steps' sizes [s]
        self._clear: FloatArray | None = None  # a step end the screen found clear (watch)
        self._start_swept = True  # whether last_d was swept at the next step's start
        self._ready: FloatArray | None = None  # a state the native modes are loaded for
        self._offered = False  # whether step_kernel offered the native step at the loop's state
        self._stretch: QuietStretch | None = None  # (the compiled stretch of quiet steps)
        # (t, y bytes, pending step) where a native run of window steps stopped (see advance)
        self._after_run: tuple[float, bytes, Any] | None = None

    # ------------------------------------------------------------------ windows
    def advance(self, t: float, y: FloatArray, t_end: float) -> DenseSegment | None:
        """In a window, time steps from (t, y) (not past t_end); else None.

        First the steps that keep their contact set, in one native call
        (:func:`~packbot.contact.window_run.run_native`), returned as one segment
        (:class:`~packbot.contact.window_run.StepChain`); the next call then takes the step
        they stopped at (finishing it when they took it: pending), as the step-by-step loop
        would. Else one step.
        """
        w = self.window
        if w is None:
            return None
        w.stepper.forces.clear()  # (the last segment's samples are recorded)
        after, self._after_run = self._after_run, None
        if after is not None and after[0] == t and after[1] == y.tobytes():
            pending = after[2]  # (the step the run stopped at: not offered to a run again)
        else:
            run = run_native(
                w.stepper, t, y, t_end, w.until, w.quiet, w.last, self.diag.min_distance
            )
            pending = None if run is None else run.pending
            if run is not None and run.steps:
                self.diag.window_steps += run.steps
                self.diag.sweeps += run.steps
                for removed in run.removed.tolist():
                    self.diag.window_energy_removed += removed
                self.note_min(run.min_d, run.min_pair)
                w.quiet, w.last = run.quiet, run.signature
                self._after_run = (run.times[-1], run.states[-1].tobytes(), pending)
                return StepChain(run.times, list(run.states))
        seg, info = w.stepper.step(t, y, t_end, self.energy, pending=pending)
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
        self._clear = None
        if self.window is not None:
            return []
        self._steps.append(seg.h)
        y1 = seg.y1
        sw = self._end_sweep(y1)
        code = self._end_code(y1, sw)
        # (the order of JointStops.watch: limits, pairs, modes, holds)
        out = self._limit_crossings(seg, y1) if code < 0 or code & 8 else []
        out.extend(self._excursion_crossings(seg))
        out.extend(self._screened_crossings(seg, y1, sw, code))
        out.extend(self._dip_crossings(seg, sw))
        out.extend(self._hold_crossings(seg, y1))
        return out

    def _excursion_crossings(self, seg: DenseSegment) -> list[Crossing]:
        """Joints that pass a stop inside the step and are within it at both of its ends.

        A long step (35 ms with the wrists locked) can carry a joint past its stop and back
        with no event at the step's end: the candidates are the extremes of the cubic Hermite
        of the joint's (q, v) at the step's ends beyond a stop
        (``ContactRhs.limit_excursions``); an extreme the step's dense output confirms is an
        event, located before it: a stop's ``limit`` event, or for a stop in the contact set
        (a free row) its row's ``impact``. A held stop's row (engaged) is left to the modes.
        """
        if not self.cfg.joint_limits or self.normal.resting:
            return []
        found = self._native.limit_excursions(seg.y0, seg.y1, seg.h, EXCURSION_TOL)
        out: list[Crossing] = []
        normal = self.normal
        for j, side, s in found:
            lim = float(self.sys.upper[j] if side > 0 else self.sys.lower[j])
            key: Key
            if (j, side) in normal.limits:
                if normal.limit_engaged(j, side):
                    continue
                kind, key = "impact", ("mode", "nrow", normal.limit_row(j, side))
                offset = POINT_TOL
            else:
                kind, key, offset = "limit", ("limit", j, side), 0.0

            def g(
                t: float, j: int = j, side: int = side, lim: float = lim, c: float = offset
            ) -> float:
                return float(side * (lim - seg(t)[j])) + c  # [rad]

            t_m = seg.t0 + s * seg.h
            g_m, g0 = g(t_m), g(seg.t0)
            if not (g_m < 0.0 < g0):
                continue  # (the dense output stays within the stop there)

            def early(t: float, g: Callable[[float], float] = g, t_m: float = t_m) -> float:
                return g(min(t, t_m))

            out.append(Crossing(kind, key, early, g0, g_m))
        return out

    def _dip_crossings(self, seg: DenseSegment, sw: SweepResult) -> list[Crossing]:
        """Pairs that touch inside the step and are apart at both of its ends.

        A fast, grazing pass (the camera head through a flipper's corner within one step)
        starts and ends the step apart: each swept pair is screened over the step by
        conservative advancement on its distance
        (:meth:`~packbot.contact.native.NativeRhs.pair_dips`); a query on the dense output
        that finds it touching is an ``impact`` (a pair of the contact set: its patch rebuilt
        there), one that finds a pair of the set leaving from contact below
        -:data:`PENETRATION_TOL` a ``repatch``, each located before that query.
        """
        active = np.array([k[1] for k in self.active if k[0] == "pair"], dtype=np.int64)
        # the kept distances are the step start's, unless a re-patch's projection moved it
        # since they were swept (then each pair is queried at the start when needed)
        last = self.last_d if self._start_swept else {}
        self._start_swept = True
        start = (
            np.fromiter(last.keys(), np.int64, len(last)),
            np.fromiter(last.values(), float, len(last)),
        )
        n = self.n

        def distance(pair: int, y: FloatArray) -> float:
            self.diag.distance_queries += 1
            return self.world.screen_distance(y[:n], pair)

        found, _ = self._native.pair_dips(
            seg, start, (sw.pairs, sw.distances), active, self.cfg.margin, distance
        )
        out: list[Crossing] = []
        for p_idx, s, _, level in found:
            t_m = seg.t0 + s * seg.h

            def g(t: float, p_idx: int = p_idx, level: float = level) -> float:
                return self.distance(p_idx, seg(t)) - level  # [m]

            g0 = last.get(p_idx, math.nan) - level
            if not g0 > 0.0:
                g0 = g(seg.t0)
            g_m = g(t_m)  # (the located function's own value there: a bracket it agrees with)
            if not g_m <= 0.0 < g0:
                continue

            def early(t: float, g: Callable[[float], float] = g, t_m: float = t_m) -> float:
                return g(min(t, t_m))

            kind = "impact" if level == 0.0 else "repatch"
            out.append(Crossing(kind, ("pair", p_idx), early, g0, g_m))
        return out

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
                if self.window is None:  # (the re-patch's Painleve fallback may have opened one)
                    self._enter(t, y, "the stepper crawled (a stiff stretch)")
                return y
            n_active = len(self.active)
            y_new = super().after_step(t, y)
            if y_new is None and y is self._clear and len(self.active) == n_active:
                self._ready = y  # no mode changed since the step: its loaded modes hold
            return y_new
        if t < w.until or w.quiet < QUIET_STEPS:
            return None
        return self._resume(t, y)

    def settle(self, t: float, y: FloatArray) -> None:
        """The forces changed at t (in a window the next step sees them)."""
        self._ready = None
        if self.window is None:
            super().settle(t, y)

    def _enter(self, t: float, y: FloatArray, why: str, relapse_span: float = RELAPSE_SPAN) -> None:
        """Start a window at (t, y) (``why``: for the log).

        It lasts twice as long as the last one when the last one ended within
        ``relapse_span`` [s] (a relapse), else :data:`WINDOW_MIN` at least.
        """
        self._keep_end_eval()
        self._ready = None
        relapse = t - self._last_exit <= relapse_span
        self._min_len = 2.0 * self._min_len if relapse else WINDOW_MIN
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        self.drive.fdir[:] = 0.0  # Coulomb friction and brakes are rows of the steps
        self.locks = JointLocks()
        stepper = MoreauJeanStepper(
            self.sys, self.drive, self.normal, self.cfg, reach=self.reach, native=self._native
        )
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
        if nc.engaged and not nc.resting and not self.locks.any_locked:
            rhs.load(nc, nc._plan())
            a = rhs.accel(q, v, tau, True)
            if a is not None:
                return a
        return self.accel(q, v, self.sys.aba(q, v, tau))

    @property
    def first_stage(self) -> Callable[[FloatArray], bool] | None:
        """The native step's first stage after a restart.

        Where :meth:`step_kernel` offers the native step, :meth:`torque_accel` at its start
        would take the native call on the same modes and torques: the same numbers (the
        stepper's deferred derivative, :meth:`RK45Stepper.reset
        <packbot.ode.RK45Stepper.reset>`'s ``defer``).
        """
        return self._native.first

    @property
    def stiff_kernel(self) -> StiffKernel | None:
        """The native RODAS4 attempt on the modes :meth:`step_kernel` loaded.

        For the stepper's stiff stretches (a slow slide whose friction direction decays
        sideways fast: :attr:`NativeRhs.stiff <packbot.contact.native.NativeRhs.stiff>`).
        """
        return self._native.stiff

    def step_kernel(self, t: float, y: FloatArray) -> StepKernel | None:
        """The native Dormand-Prince step of the current modes, or None (the stages call rhs).

        Offered when :meth:`torque_accel` would take the native call at every stage (engaged
        rows, no lock, no rest capture, no window) and the torques are fixed over the step (a
        held command, no motor lag: :meth:`~packbot.drive.Drive.step_torques`). The stages,
        the 5th-order solution and the error norm in one call
        (:meth:`~packbot.contact.native.NativeRhs.step`). Elsewhere the stepper's stages call
        :meth:`torque_accel`.
        """
        rhs = self._native
        nc = self.normal
        self._offered = False
        if not nc.engaged or nc.resting or self.locks.any_locked or self.window is not None:
            return None
        torques = self.drive.step_torques(t, y)
        if torques is None:
            return None
        if y is not self._ready:  # (else no mode changed since the last load)
            rhs.load(nc, nc._plan())
        self._ready = None
        rhs.hold_torque(*torques)
        self._offered = True
        return rhs.step

    def step_bound(self, y: FloatArray) -> float:
        """Largest step keeping every point's motion within half the query margin [s].

        :meth:`PairLaw.step_bound <packbot.contact.pairs.PairLaw.step_bound>`'s bound, its dot
        product summed in joint order, computed by the native right-hand side with the
        arithmetic of the compiled stretch's steps (:meth:`stretch`).
        """
        return self._native.step_bound(y)

    def stretch(
        self,
        stepper: RK45Stepper,
        t_end: float,
        t_last: float,
        t_sched: float,
        clock: SampleClock,
    ) -> Stretched | None:
        """The quiet steps from the stepper's state in one native call (:mod:`.stretch`).

        Offered right after :meth:`step_kernel` offered the native step (its modes and torques
        loaded), outside a window, with no conditional lock or Coulomb-sliding joint (their
        conditions are watched in Python) and with the compiled sweep; else None. An arm
        captured at rest is held there instead (:meth:`_hold_at_rest`).
        """
        if self.normal.resting:
            return self._hold_at_rest(stepper, t_end)
        if (
            not self._offered
            or self.window is not None
            or self.locks.conditional
            or self.drive.fdir.any()
        ):
            return None
        crawl = (CRAWL_STEPS, CRAWL_STEP)
        st = self._stretch = quiet_stretch(self, stepper, clock, self._stretch, crawl)
        stops = [(k[1], k[2]) for k in self.active if k[0] == "limit"]
        upper, lower = self.sys.upper, self.sys.lower
        inputs = LawInputs(
            active=np.array([k[1] for k in self.active if k[0] == "pair"], dtype=np.int64),
            limits=np.array(
                [(j, side, self._limit_held(j, side)) for j, side in stops], dtype=np.int64
            ).reshape(-1, 3),
            lim_value=np.array([upper[j] if side > 0 else lower[j] for j, side in stops]),
            crawl=np.array(self._steps, dtype=np.float64),
            min_d=self.diag.min_distance,
            # (a subclass's hooks: its re-patches are the loop's)
            modes=repatch_modes(self) if type(self) is NormalLaw else None,
        )
        self.world.dispatch.spare = None
        done, out = st.run(stepper, t_end, t_last, t_sched, clock, inputs)
        k = out["samples_before"]
        if out["repatches"] and k > 0:
            # the samples before its first re-patch, their forces read from the contact set as
            # the stretch found it (those after, from the set its last re-patch leaves)
            clock.record_states(done.samples[:k])
            done = dataclasses.replace(done, samples=done.samples[k:])
        adopt_repatches(self, out)
        if done.steps:
            self._stretched(stepper.y if done.pending is None else done.pending.y0, out)
            if out["repatches"]:
                self._ready = None  # (the modes and patches loaded again from the set's)
        if done.pending is not None:
            # its sweep, for the watch to reuse (the same numbers: Coal's warm-started GJK
            # would not give them bit for bit a second time)
            self.world.dispatch.adopt(
                done.pending.y1[: self.n],
                out["pending_pairs"][0],
                out["pending_dist"][0],
                out["pending_best"],
                out["pending_best_d"],
            )
        return done

    def _hold_at_rest(self, stepper: RK45Stepper, t_end: float) -> Stretched | None:
        """The arm captured at rest, held there to t_end in one step (pending), or None.

        The rest capture (:meth:`NormalContacts.capture
        <packbot.contact.normal_steps.RestartSteps.capture>`) stops every joint and holds it
        until a mode condition says otherwise (``nrest``: the accelerations the arm would
        have without the hold). With the torques fixed (a held command, or none, and no motor
        lag: :meth:`~packbot.drive.Drive.step_torques`) nothing changes until the next
        controller tick or scheduled action: the stepper's steps from such a state keep it
        bit for bit, each one a right-hand side, a sweep and the checks at its end. One step
        to t_end does the same once; the loop watches it as any step (its end's sweep and
        conditions: the state's) and records its samples (the state). The stepper restarts at
        its end.

        Args:
            stepper: The loop's stepper, at the loop's state.
            t_end: The step's end [s] (no controller tick before it).
        """
        t, y = stepper.t, stepper.y
        n = self.n
        if (
            not REST_HOLD
            or t_end <= t
            or len(y) != 2 * n
            or y[n:].any()
            or self.locks.conditional
            or self.drive.fdir.any()
            or self.drive.step_torques(t, y) is None
        ):
            return None
        seg = StepSegment(t, t_end, y, y.copy())
        stepper.reset(t_end, seg.y1, h=stepper.h, defer=True)
        return Stretched(0, np.zeros((0, len(y))), seg)

    def _stretched(self, y: FloatArray, out: dict[str, Any]) -> None:
        """Past a stretch's kept steps, ending at y: what watch and after_step keep.

        Args:
            y: The last kept step's end (its modes still loaded: the native step's next start).
            out: The native call's results (:meth:`QuietStretch.run
                <packbot.contact.stretch.QuietStretch.run>`).
        """
        self._steps.extend(out["hs"][0].tolist())
        self.diag.sweeps += out["steps"]
        self.note_min(out["min_d"], out["min_pair"])
        pairs, distances = out["last_pairs"][0], out["last_dist"][0]
        pairs.setflags(write=False)
        distances.setflags(write=False)
        self._pending_arr = self._last_arr = (pairs, distances)
        self._pending_d = self._last_d = None
        self._start_swept = out["repatches"] == 0  # (a re-patch's projection moves q)
        self._clear = self._ready = y
        self.world.dispatch.owe()  # (its pieces are owed at the last compiled sweep's q)

    def _pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        return self._patch_pair_crossings(key, p_idx, seg, d0, d1)

    def _contact_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        sw = self._end_sweep(y1)
        return self._screened_crossings(seg, y1, sw, self._end_code(y1, sw))

    def _end_code(self, y1: FloatArray, sw: SweepResult) -> int:
        """The step end's screen (:meth:`~packbot.contact.native.NativeRhs.end_check`).

        After a native step (:meth:`step_kernel`), one call on its last stage's evaluation and
        the end's sweep says which checks of :meth:`watch` and :meth:`after_step` can find
        something: the limits' (bit 8), the pairs' (an impact, a release, a re-patch: 1), the
        modes' (a negative condition: 2) and :meth:`_refresh`'s (a sliding contact's stale
        patch: 4). -1: not a native step's end (every check runs).
        """
        rhs = self._native
        if self.normal.empty:
            return -1
        active = np.array([k[1] for k in self.active if k[0] == "pair"], dtype=np.int64)
        return rhs.end_check(
            y1,
            sw.pairs,
            sw.distances,
            active,
            self.cfg.proximity_tolerance,
            PENETRATION_TOL,
        )

    def _screened_crossings(
        self, seg: DenseSegment, y1: FloatArray, sw: SweepResult, code: int
    ) -> list[Crossing]:
        """The pairs' and modes' events over the step: the checks the screen's code asks for.

        As without the screen; a step end it finds clear of pair, mode and refresh checks
        (the common case) is marked for :meth:`_refresh` (nothing to re-patch there).
        """
        if code < 0:  # not a native step's end: every check
            out = self._swept_crossings(seg, sw)
            out.extend(self._mode_crossings(seg, y1))
            return out
        out = self._swept_crossings(seg, sw) if code & 1 else []
        if code & 2:
            out.extend(self._mode_crossings(seg, y1))
        elif code & 4:  # the evaluation the refresh reads (end_eval's, as without the screen)
            self._native.end_eval(self.normal, y1)
        else:
            self._clear = y1
        return out

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
        ev = rhs.end_eval(nc, y1)  # a native step's end: its last stage evaluated the conditions
        if ev is not None and ev.cond is not None and ev.cond >= 0.0:
            return []
        # (ev None: not a native step, its modes are not the loaded ones)
        return self._problem_crossings(nc, seg, y1, None if ev is None else rhs)

    def _limit_held(self, j: int, side: int) -> bool:
        return self.normal.limit_engaged(j, side)

    def _drop_limit(self, j: int, side: int) -> None:
        self.normal.remove_limit(j, side)

    def _keep_end_eval(self) -> None:
        """The last step end's evaluation kept by the contact set, as without the screen.

        A step end the screen found clear (:meth:`_screened_crossings`) did not hand its
        evaluation to the contact set; before events or a window, which may read it, it does.
        """
        if self._clear is not None:
            self._native.end_eval(self.normal, self._clear)

    def _refresh(self, t: float, y: FloatArray) -> FloatArray | None:
        # A sliding contact's patch is rebuilt only once it is stale (slid SLIDE_TOL or its gap
        # off the pair's distance): its rows stay valid until then.
        if y is self._clear:  # the step end's screen found no sliding contact's stale patch
            return None
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        if self.normal.sliding(q, v) and self.normal.stale(q, v, self.last_d):
            painleve = self.normal.n_painleve
            y_new = self._repatch(self.normal, t, y)
            self._sync_pairs()
            self._start_swept = False  # (the projection moved q after the step end's sweep)
            if self.normal.n_painleve > painleve:
                v_new = y_new[n : 2 * n]
                self.log_event(t, "painleve", y_new[:n], v_new, v_new, None)
                self._enter(t, y_new, "no contact mode is consistent (Painleve)")
            return y_new
        return None

    def _handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Events of the normal mode: update the contact set, then impulse and modes."""
        self._keep_end_eval()
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
        # a chatter: CHATTER_EVENTS within CHATTER_SPAN; within CHATTER_SPAN of the last
        # window's end, RELAPSE_EVENTS at the same rate (the chatter came back)
        again = t - self._last_exit <= CHATTER_SPAN
        chat = RELAPSE_EVENTS if again else CHATTER_EVENTS
        span = CHATTER_SPAN * chat / CHATTER_EVENTS
        chatter = len(recent) >= chat and t - recent[-chat] <= span
        if piled or chatter:
            recent.clear()
            # (a chatter that came back within its own span of the last window's end is a
            # relapse too: the window doubles)
            self._enter(t, y_new, "events piled up", CHATTER_SPAN if chatter else RELAPSE_SPAN)
        elif self._held_with_contacts(v_new):
            self._enter(t, y_new, "joints held by friction while contacts push")
        elif any(me.kind == "painleve" for me in mode_events):
            self._enter(t, y_new, "no contact mode is consistent (Painleve)")
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

    def contact_forces(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """The current mode's contact forces and stop torques at (q, v) (``mode_forces``).

        Inside a time-stepping window, the mean forces of the step that holds the sample's time
        t [s] (:class:`~packbot.contact.window_forces.WindowForces`); None if no step kept
        holds t.
        """
        nc = self.normal
        if self.window is not None:
            return self.window.stepper.forces.at(t)
        if not nc.engaged:
            return SampleForces([], np.zeros(self.sys.nv))
        # a resting arm's samples under one torque are one state: its contacts are found once
        torque = tau()
        key = (nc._version, q.tobytes(), torque.tobytes()) if nc.resting and not v.any() else None
        if key is not None and self._rest_contacts[0] == key:
            return self._rest_contacts[1]
        # (not the compiled right-hand side's call: a call there would forget the step end it
        # keeps for the step end's checks)
        a_free = super().accel(q, v, self.sys.aba(q, v, torque))
        kept = nc._last_eval  # (the step end's evaluation, kept for its own state)
        try:
            found = mode_forces(nc, self._force_data, q, v, a_free, self.sys.minv(q))
        finally:
            nc._last_eval = kept
        if key is not None:
            self._rest_contacts = (key, found)
        return found

    def _sync_pairs(self) -> None:
        """Pairs and stops that the drift projection put in the contact set become active.

        :meth:`NormalContacts.project` adds a pair it made penetrate (as an impact would) and
        a stop it would move a joint past: their events are then those of a pair in contact
        (re-patch, release) and of a stop reached (release).
        """
        for k, p in self.normal.pairs.items():
            self.active.setdefault(("pair", k), Active(p.info, []))
        for j, side in self.normal.limits:
            self.active.setdefault(("limit", j, side), Active(None, []))
