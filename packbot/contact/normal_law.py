"""The contact-normal mode's law: events, restarts, and time-stepping windows.

:class:`NormalLaw` integrates the arm with the contact set of
:class:`~packbot.contact.normal.NormalContacts` between events and opens a time-stepping
window (:mod:`packbot.contact.timestep`) where events pile up; its thresholds are below.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo, SweepResult
from packbot.contact import native
from packbot.contact import normal_windows as windows
from packbot.contact.base import Active, Crossing, Key, SampleClock, StepSpan
from packbot.contact.locks import JointLocks
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_forces import mode_forces
from packbot.contact.normal_inside import limit_excursions, pair_dips
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.contact.normal_windows import Window, WindowTriggers
from packbot.contact.pairs import pair_joints, reach_bounds
from packbot.contact.patch_events import PatchEvents
from packbot.contact.stretch import (
    LawInputs,
    QuietStretch,
    Stretched,
    adopt_repatches,
    quiet_stretch,
    repatch_modes,
)
from packbot.contact.timestep import QUIET_STEPS, MoreauJeanStepper, StepSegment
from packbot.contact_forces import SampleForces
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
        self._force_data = system.model.createData()  # (the contact forces' placements)
        self._rest_contacts: tuple[Any, SampleForces | None] = (None, None)
        if self.cfg.joint_limits:  # (the step end's screen, the drift projection)
            self._native.set_limits(system.upper, system.lower)
            self.normal.stops = (system.upper, system.lower)
        self._native.set_reach(self.reach, self.cfg.margin, self.cfg.max_step)  # (step_bound)
        self._native.set_pair_joints(*pair_joints(system.model, self.world.pairs))
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
        code = self._end_code(y1, sw)
        # (the order of JointStops.watch: limits, pairs, modes, holds)
        out = self.stops.crossings(seg, y1, self.active) if code < 0 or code & 8 else []
        out.extend(self._excursion_crossings(seg))
        out.extend(self._screened_crossings(seg, y1, sw, code))
        out.extend(self._dip_crossings(seg, sw))
        out.extend(self._hold_crossings(seg, y1))
        return out

    def _excursion_crossings(self, seg: DenseSegment) -> list[Crossing]:
        """Joints past a stop inside the step and within it at its ends.

        :func:`~packbot.contact.normal_inside.limit_excursions`.
        """
        if not self.cfg.joint_limits or self.normal.resting:
            return []
        return limit_excursions(seg, self._native, self.normal, self.sys.upper, self.sys.lower)

    def _dip_crossings(self, seg: DenseSegment, sw: SweepResult) -> list[Crossing]:
        """Pairs that touch inside the step and are apart at its ends.

        :func:`~packbot.contact.normal_inside.pair_dips`.
        """
        active = np.array([k[1] for k in self.active if k[0] == "pair"], dtype=np.int64)
        # the kept distances are the step start's, unless a re-patch's projection moved it
        # since they were swept (then each pair is queried at the start when needed)
        last = self.last_d if self._start_swept else {}
        self._start_swept = True
        n = self.n

        def screen(pair: int, y: FloatArray) -> float:
            self.diag.distance_queries += 1
            return self.world.screen_distance(y[:n], pair)

        return pair_dips(
            seg, sw, self._native, active, last, self.cfg.margin, screen, self.distance
        )

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
        self._keep_end_eval()
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
        crawl = (windows.CRAWL_STEPS, windows.CRAWL_STEP)
        st = self._stretch = quiet_stretch(self, stepper, clock, self._stretch, crawl)
        stops = [(k[1], k[2]) for k in self.active if k[0] == "limit"]
        upper, lower = self.sys.upper, self.sys.lower
        inputs = LawInputs(
            active=np.array([k[1] for k in self.active if k[0] == "pair"], dtype=np.int64),
            limits=np.array(
                [(j, side, self._limit_held(j, side)) for j, side in stops], dtype=np.int64
            ).reshape(-1, 3),
            lim_value=np.array([upper[j] if side > 0 else lower[j] for j, side in stops]),
            crawl=np.array(self.triggers.steps, dtype=np.float64),
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
            t_end <= t
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
        self.triggers.steps.extend(out["hs"][0].tolist())
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
        relapse_span = self.triggers.piled_up(t)
        if relapse_span is not None:
            self._enter(t, y_new, "events piled up", relapse_span)
        elif self._held_with_contacts(v_new):
            self._enter(t, y_new, "joints held by friction while contacts push")
        elif any(me.kind == "painleve" for me in mode_events):
            self._enter(t, y_new, "no contact mode is consistent (Painleve)")
        return y_new

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
        stopped = (self.drive.path.coulomb > 0.0) & (np.abs(v) <= windows.HOLD_SPEED)
        return bool(stopped.any())

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m]; in a window, the last step's Coulomb and brake torques."""
        w = self.window
        if w is None:
            return super().friction(q, v, applied, friction)
        return np.asarray(friction + w.stepper.joint_torque, dtype=np.float64)

    def contacts(
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
