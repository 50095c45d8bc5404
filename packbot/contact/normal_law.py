"""The contact-normal mode's law: events, restarts, and time-stepping windows.

:class:`NormalLaw` integrates the arm with the contact set of
:class:`~packbot.contact.normal.NormalContacts` between events and opens a time-stepping
window (:mod:`packbot.contact.timestep`) where events pile up; its thresholds are below.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact import native
from packbot.contact import normal_watch as watching
from packbot.contact import normal_windows as windows
from packbot.contact.base import (
    Active,
    Crossing,
    ForceReport,
    Key,
    SampleClock,
    StepSpan,
)
from packbot.contact.locks import JointLocks
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_forces import NormalReport
from packbot.contact.normal_windows import Window, WindowTriggers
from packbot.contact.pairs import pair_joints, reach_bounds
from packbot.contact.patch_events import PatchEvents
from packbot.contact.stretch import QuietStretch, Stretched, hold_at_rest, law_stretch
from packbot.contact.timestep import QUIET_STEPS, MoreauJeanStepper
from packbot.ode import DenseSegment, RK45Stepper, StepKernel, StepSizeUnderflow
from packbot.system import System

__all__ = ["NormalLaw"]

log = logging.getLogger(__name__)


FloatArray = NDArray[np.float64]


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
    (:class:`~packbot.contact.timestep.MoreauJeanStepper`, through :meth:`step`): one
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
        self.triggers = WindowTriggers()
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
        self.report = NormalReport(self)  # (its forces at the samples)
        if self.cfg.joint_limits:  # (the step end's screen, the drift projection)
            self._native.watch.set_limits(system.upper, system.lower)
            self.normal.stops = (system.upper, system.lower)
        self._native.set_reach(self.reach, self.cfg.margin, self.cfg.max_step)  # (step_bound)
        self._native.watch.set_pair_joints(*pair_joints(system.model, self.world.pairs))
        self.window: Window | None = None
        self.triggers.reset()
        self._clear: FloatArray | None = None  # a step end the screen found clear (watch)
        self._start_swept = True  # whether last_d was swept at the next step's start
        self._ready: FloatArray | None = None  # a state the native modes are loaded for
        self._offered = False  # whether step_kernel offered the native step at the loop's state
        self._stretch: QuietStretch | None = None  # (the compiled stretch of quiet steps)

    # ------------------------------------------------------------------ windows
    def step(
        self, stepper: RK45Stepper, t: float, y: FloatArray, span: StepSpan
    ) -> DenseSegment | None:
        """The next step from (t, y): a window's, the quiet steps at once, or the stepper's.

        Bounded by :meth:`step_bound`. In a window, its time steps (:meth:`Window.advance
        <packbot.contact.normal_windows.Window.advance>`). Else
        the stepper's step with the native stages of the current modes where they serve
        (:meth:`step_kernel`, the native RODAS4 attempt for its stiff stretches, the native
        first stage after a restart), preceded, with no controller tick before
        ``span.t_end``, by the quiet steps in one native call (:meth:`stretch`: their samples
        recorded, None returned if no step is left to watch). A step-size underflow (a stiff
        or discontinuous stretch) opens a window there (None returned).
        """
        stepper.h_max = self.step_bound(y)
        try:
            if self.window is not None:
                w = self.window
                return w.advance(t, y, span.t_window, self.diag, self.note_min, self.energy)
            kernel = self.step_kernel(t, y)
            if span.several:
                st = self.stretch(stepper, span.t_end, span.t_last, span.t_sched, span.clock)
                if st is not None:
                    span.clock.record_states(st.samples)
                    if st.pending is not None or st.steps:
                        return st.pending
            if kernel is None:
                return stepper.step(span.t_end)
            # (a restart's derivative left to this step: the kernel's first stage)
            first = self._native.first if stepper.f_pending else None
            return stepper.step(span.t_end, kernel, first, self._native.stiff)
        except StepSizeUnderflow:
            if self.window is not None:
                raise
            self._enter(t, y, "the stepper's step size underflowed")
            return None

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """The event functions (none in a window: its steps resolve their contacts)."""
        self._clear = None
        if self.window is not None:
            return []
        self.triggers.steps.append(seg.h)
        y1 = seg.y1
        sw = self._end_sweep(y1)
        code = watching.end_code(self, y1, sw)
        # (the order of JointStops.watch: limits, pairs, modes, holds)
        out = self.stops.crossings(seg, y1, self.active) if code < 0 or code & 8 else []
        out.extend(watching.excursion_crossings(self, seg))
        out.extend(watching.screened_crossings(self, seg, y1, sw, code))
        out.extend(watching.dip_crossings(self, seg, sw))
        out.extend(self._hold_crossings(seg, y1))
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
            if self.triggers.crawling():
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

    def _forces_changed(self, t: float, y: FloatArray) -> None:
        """The forces changed at t (in a window the next step sees them)."""
        self._ready = None
        if self.window is None:
            super()._forces_changed(t, y)

    def _enter(self, t: float, y: FloatArray, why: str, relapse_span: float | None = None) -> None:
        """Start a window at (t, y) (``why``: for the log).

        Its shortest length: :meth:`WindowTriggers.opening
        <packbot.contact.normal_windows.WindowTriggers.opening>` with ``relapse_span`` [s].
        """
        watching.keep_end_eval(self)
        self._ready = None
        min_len = self.triggers.opening(t, relapse_span)
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        self.drive.fdir[:] = 0.0  # Coulomb friction and brakes are rows of the steps
        self.locks = JointLocks()
        stepper = MoreauJeanStepper(
            self.sys, self.drive, self.normal, self.cfg, reach=self.reach, native=self._native
        )
        self.window = Window(stepper, t, t + min_len, self.energy(q, v))
        self.diag.windows += 1
        self.log_event(t, "timestep", q, v, v, None)
        log.debug("t=%.6f: %s: time steps for %.3g s at least", t, why, min_len)

    def _resume(self, t: float, y: FloatArray) -> FloatArray:
        """End the window at (t, y): the event-driven mode restarts from that state."""
        assert self.window is not None
        n = self.n
        self.triggers.closed(t)
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
            # The window's steps integrate (step); the loop's right-hand side only gives the
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
        """The quiet steps from the stepper's state in one native call, or None.

        :func:`~packbot.contact.stretch.law_stretch` (an arm captured at rest is held there
        instead: :meth:`_hold_at_rest`).
        """
        return law_stretch(self, stepper, t_end, t_last, t_sched, clock, type(self) is NormalLaw)

    def _hold_at_rest(self, stepper: RK45Stepper, t_end: float) -> Stretched | None:
        """The arm captured at rest, held there to t_end in one step (pending), or None.

        :func:`~packbot.contact.stretch.hold_at_rest`.
        """
        return hold_at_rest(self, stepper, t_end)

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

    def _limit_held(self, j: int, side: int) -> bool:
        return self.normal.limit_engaged(j, side)

    def _drop_limit(self, j: int, side: int) -> None:
        self.normal.remove_limit(j, side)

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
        watching.keep_end_eval(self)
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
        relapse_span = self.triggers.piled_up(t)
        if relapse_span is not None:
            self._enter(t, y_new, "events piled up", relapse_span)
        elif windows.held_with_contacts(self.normal, self.locks, self.drive, v_new):
            self._enter(t, y_new, "joints held by friction while contacts push")
        elif any(me.kind == "painleve" for me in mode_events):
            self._enter(t, y_new, "no contact mode is consistent (Painleve)")
        return y_new

    def forces(self) -> ForceReport:
        """The current mode's forces at the samples (its :class:`NormalReport`)."""
        return self.report

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
