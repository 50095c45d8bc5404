"""When the contact-normal mode integrates with fixed time steps, and the window that does.

Where events pile up (a stick/slip or jam cascade at one instant, an accumulation of impacts, a
chattering slide), where the stepper crawls (a stiff stretch for an explicit stepper), where
joints held by friction meet pushing contacts, the event-driven restarts would cost more than
they tell: :class:`~packbot.contact.normal_law.NormalLaw` integrates a *window* of fixed time
steps instead (:class:`~packbot.contact.timestep.MoreauJeanStepper`: one complementarity
problem per step, no event location). :class:`WindowTriggers` says when a window opens and
how long it lasts at least (the thresholds below); :class:`Window` is one in progress and
takes its steps.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact.timestep import MoreauJeanStepper
from packbot.contact.window_run import StepChain, run_native
from packbot.ode import DenseSegment
from packbot.result import Diagnostics

if TYPE_CHECKING:
    from packbot.contact.locks import JointLocks
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.drive import Drive

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
    "Window",
    "WindowTriggers",
    "held_with_contacts",
]

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


def held_with_contacts(
    normal: NormalContacts, locks: JointLocks, drive: Drive, v: FloatArray
) -> bool:
    """Joints held (or stopped) by friction or a brake while contact rows push: a window.

    The event-driven modes solve the holds (:class:`~packbot.contact.locks.JointLocks`) and
    the contact forces (:class:`~packbot.contact.normal_contacts.NormalContacts`) apart, which
    is exact while only one of them acts; when both do, the joints' holding torques and the
    contact forces are one problem: a window's steps solve it (boxes and cones together). A
    resting arm (rest capture) needs neither.

    Args:
        normal: The law's contact set.
        locks: The law's joint locks.
        drive: The run's torques (the joints' Coulomb bounds).
        v: Velocities [rad/s] after the restart.
    """
    if not normal.engaged or normal.resting:
        return False
    if locks.held:
        return True
    stopped = (drive.path.coulomb > 0.0) & (np.abs(v) <= HOLD_SPEED)
    return bool(stopped.any())


class WindowTriggers:
    """When a window opens (events piled up, the stepper crawled) and how long it lasts.

    Attributes:
        min_len: The shortest length [s] of the window opened last.
        last_exit: When the last window ended [s] (-inf: none yet).
        recent: The times [s] of the last :data:`CHATTER_EVENTS` restarts.
        steps: The sizes [s] of the last :data:`CRAWL_STEPS` accepted steps.
    """

    def __init__(self) -> None:
        self.min_len = WINDOW_MIN
        self.last_exit = -math.inf
        self.reset()

    def reset(self) -> None:
        """A new phase: the restarts and steps counted so far are forgotten."""
        self.recent: deque[float] = deque(maxlen=CHATTER_EVENTS)
        self.steps: deque[float] = deque(maxlen=CRAWL_STEPS)

    def crawling(self) -> bool:
        """Whether the last :data:`CRAWL_STEPS` steps average less than :data:`CRAWL_STEP`."""
        steps = self.steps
        return len(steps) == CRAWL_STEPS and sum(steps) < CRAWL_STEPS * CRAWL_STEP

    def piled_up(self, t: float) -> float | None:
        """A restart at t [s]: the relapse span [s] of the window it opens, or None (none).

        A window opens after :data:`CASCADE_EVENTS` restarts within :data:`CASCADE_SPAN`
        (:data:`RELAPSE_EVENTS` within :data:`RELAPSE_SPAN` of the last window's end), or
        :data:`CHATTER_EVENTS` within :data:`CHATTER_SPAN` (within :data:`CHATTER_SPAN` of
        the last window's end, :data:`RELAPSE_EVENTS` at the same rate: the chatter came
        back). A chatter that came back within its own span of the last window's end is a
        relapse too (its span is :data:`CHATTER_SPAN`): the window doubles.
        """
        recent = self.recent
        recent.append(t)
        relapse = t - self.last_exit <= RELAPSE_SPAN
        pile = min(RELAPSE_EVENTS, CASCADE_EVENTS) if relapse else CASCADE_EVENTS
        piled = len(recent) >= pile and t - recent[-pile] <= CASCADE_SPAN
        again = t - self.last_exit <= CHATTER_SPAN
        chat = RELAPSE_EVENTS if again else CHATTER_EVENTS
        span = CHATTER_SPAN * chat / CHATTER_EVENTS
        chatter = len(recent) >= chat and t - recent[-chat] <= span
        if not (piled or chatter):
            return None
        recent.clear()
        return CHATTER_SPAN if chatter else RELAPSE_SPAN

    def opening(self, t: float, relapse_span: float | None = None) -> float:
        """A window opens at t [s]: its shortest length [s].

        Twice the last one's when the last one ended within ``relapse_span`` [s] (a
        relapse), else :data:`WINDOW_MIN`.
        """
        span = RELAPSE_SPAN if relapse_span is None else relapse_span
        relapse = t - self.last_exit <= span
        self.min_len = 2.0 * self.min_len if relapse else WINDOW_MIN
        self.steps.clear()
        return self.min_len

    def closed(self, t: float) -> None:
        """The window ended at t [s]."""
        self.last_exit = t


@dataclass
class Window:
    """A time-stepping window in progress.

    Attributes:
        stepper: Its steps (the law's contact set, the phase's system).
        t_start: When it opened [s].
        until: Its earliest exit [s].
        energy_in: The energy when it opened [J].
        quiet: The steps whose signature equalled the previous one.
        last: The previous step's signature.
    """

    stepper: MoreauJeanStepper
    t_start: float
    until: float
    energy_in: float
    quiet: int = 0
    last: Any = None
    # (t, y bytes, pending step) where a native run of window steps stopped (see advance)
    _after_run: tuple[float, bytes, Any] | None = None

    def advance(
        self,
        t: float,
        y: FloatArray,
        t_end: float,
        diag: Diagnostics,
        note_min: Callable[[float, int], None],
        energy: Callable[[FloatArray, FloatArray], float],
    ) -> DenseSegment:
        """The window's time steps from (t, y), not past t_end [s].

        First the steps that keep their contact set, in one native call
        (:func:`~packbot.contact.window_run.run_native`), returned as one segment
        (:class:`~packbot.contact.window_run.StepChain`); the next call then takes the step
        they stopped at (finishing it when they took it: pending), as the step-by-step loop
        would. Else one step.

        Args:
            t: Time [s].
            y: State.
            t_end: The steps may not pass this time [s].
            diag: The run's counters (window steps, sweeps, the energy the steps removed).
            note_min: The law's record of the smallest distance [m] (and its pair).
            energy: The arm's energy E(q, v) [J] (the steps' energy guard).
        """
        self.stepper.forces.clear()  # (the last segment's samples are recorded)
        after, self._after_run = self._after_run, None
        if after is not None and after[0] == t and after[1] == y.tobytes():
            pending = after[2]  # (the step the run stopped at: not offered to a run again)
        else:
            run = run_native(
                self.stepper, t, y, t_end, self.until, self.quiet, self.last, diag.min_distance
            )
            pending = None if run is None else run.pending
            if run is not None and run.steps:
                diag.window_steps += run.steps
                diag.sweeps += run.steps
                for removed in run.removed.tolist():
                    diag.window_energy_removed += removed
                note_min(run.min_d, run.min_pair)
                self.quiet, self.last = run.quiet, run.signature
                self._after_run = (run.times[-1], run.states[-1].tobytes(), pending)
                return StepChain(run.times, list(run.states))
        seg, info = self.stepper.step(t, y, t_end, energy, pending=pending)
        diag.window_steps += 1
        diag.sweeps += 1
        diag.window_energy_removed += info.removed
        note_min(*info.closest)  # the step's sweep at its start (the previous step's end)
        self.quiet = self.quiet + 1 if info.signature == self.last else 0
        self.last = info.signature
        return seg
