"""The protocol between the event loop and a contact law, and the records they share.

The event loop (:mod:`packbot.integrator`) integrates, locates events and asks the law; it never
asks which law it holds. A law (:class:`ContactLaw`) is built with what it needs of the arm, the
phase's :class:`~packbot.system.System` (model, mass matrix, Jacobians, its collision world) and
the run's :class:`~packbot.drive.Drive` (the torques, hence the free accelerations), and writes
its events to the run's :class:`~packbot.recorder.EventLog` and its counters to the run's
:class:`~packbot.result.Diagnostics`. The laws: :class:`~packbot.contact.none.NoneLaw`,
:class:`~packbot.contact.joint_clamp.JointClampLaw`, :class:`~packbot.contact.normal.NormalLaw`,
:class:`~packbot.contact.handoff.HandoffLaw`; :func:`packbot.contact.make_law` picks one from
a :class:`~packbot.config.SimConfig`.

Who calls what, and when (docs/simulator.md, "The loop and the contact laws"):

- a new phase (the run's start, a frozen joint merged, a payload change): :meth:`~ContactLaw.
  start` (the contacts and stops present; on the new phase's system);
- every right-hand side: :meth:`~ContactLaw.torque_accel` (the current mode's accelerations);
- each step: :meth:`~ContactLaw.step` (the law bounds it and takes it: with the loop's
  stepper, several quiet steps at once, or its own time-stepping window);
- after each step: :meth:`~ContactLaw.watch` (the event functions that changed sign);
  none: the step is accepted, :meth:`~ContactLaw.after_step`; else the loop locates the
  earliest crossing and calls :meth:`~ContactLaw.handle` with the crossings at that instant;
- a failure or a payload change that keeps the phase: :meth:`~ContactLaw.handle` with
  :data:`SETTLE` (the forces changed: an event without an event function);
- a freezing joint, and every sample: :meth:`~ContactLaw.forces`, the report of the current
  mode's forces (:class:`ForceReport`: the joints held still, the friction column with their
  holding torques, the contacts' forces).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.ode import DenseSegment, RK45Stepper
from packbot.system import System

if TYPE_CHECKING:
    from packbot.contact_forces import SampleForces

__all__ = [
    "SETTLE",
    "Active",
    "ContactLaw",
    "Crossing",
    "ForceReport",
    "Key",
    "SampleClock",
    "StepSpan",
]

FloatArray = NDArray[np.float64]
#: An event function's identity: ``("pair", index)``, ``("limit", joint, side)``,
#: ``("lock", joint)``, ``("stick", joint)`` or ``("mode", kind, index)``.
Key = tuple[Any, ...]


@dataclass
class Active:
    """An active contact: a pair (None for a limit stop) and the clamps it imposes.

    Its key in a law's ``active`` is ``("pair", index)`` or ``("limit", joint, side)`` with side
    +1 for the upper stop and -1 for the lower one. The clamps are (joint, s) pairs: joint may
    not accelerate in direction s (:mod:`packbot.contact.locks`); the contact-normal mode's
    contacts have none.
    """

    pair: PairInfo | None
    clamps: list[tuple[int, int]]


@dataclass
class Crossing:
    """An event function that changed sign within a step.

    Attributes:
        kind: The event it is (``"impact"``, ``"limit"``, ``"release"``, ``"slip"``, ...).
        key: Its identity.
        g: The function of time on the step's dense output; the event is where it falls to 0.
        g0: Its value at the step's start (<= 0: already on the event side there).
        g1: Its value at the step's end (< 0).
        root: Where it falls to 0 found in one call, ``root(t0, t1, g0, g1, xtol)`` with the
            result of :func:`packbot.ode.locate_root` on ``g`` (NaN: not found that way, the
            loop locates it on ``g``); None: the loop locates it on ``g``.
    """

    kind: str
    key: Key
    g: Callable[[float], float]
    g0: float
    g1: float
    root: Callable[[float, float, float, float, float], float] | None = None


#: The forces changed at an instant without an event function crossing (a failure that keeps
#: the phase, a payload picked up): handed to :meth:`ContactLaw.handle` alone, it makes the
#: law's locks, holds and modes consistent with the new forces, the state kept.
SETTLE = Crossing("settle", ("settle",), lambda t: 0.0, 0.0, 0.0)


class SampleClock(Protocol):
    """The regular samples' clock of a run (:class:`packbot.recorder.Recorder` is one)."""

    dt: float  #: the interval of the regular samples [s]
    duration: float  #: the run's duration [s]
    next_sample: int  #: the index of the next regular sample (at ``next_sample * dt``)

    def record_states(self, ys: FloatArray) -> None:
        """Keep the next regular samples from their states ys, shape (m, n), in order."""


@dataclass(frozen=True)
class StepSpan:
    """How far the loop lets the next step go (:meth:`ContactLaw.step`).

    Attributes:
        t_end: The stepper's step ends here at the latest [s]: the duration, the next
            scheduled action, or the next controller tick while the ticks change the command.
        t_window: A time-stepping window's step ends here at the latest [s]: the duration or
            the next scheduled time, every controller tick included (a window lands on each).
        t_sched: The next scheduled action [s] (a stretch hands back a step ending there).
        t_last: The run ends here [s].
        several: Whether several steps may be taken at once (no controller tick before
            ``t_end``).
        clock: The run's regular samples (a stretch records its steps' samples there).
    """

    t_end: float
    t_window: float
    t_sched: float
    t_last: float
    several: bool
    clock: SampleClock


class ContactLaw(Protocol):
    """What the event loop asks of a contact law.

    States are the integrated ones, y = (q, v[, tau_m]) (the motor torques when
    ``SimConfig.motor_lag > 0``); a law changes velocities (an impulse) and, in the
    contact-normal modes, positions (a drift correction), never tau_m.
    """

    def start(
        self, t: float, y: FloatArray, check: bool, system: System | None = None
    ) -> FloatArray:
        """A phase starts at (t, y): the contacts and limit stops present; the state after.

        Args:
            t: Time [s].
            y: State.
            check: Raise ``InitialCollisionError`` if a pair penetrates (the run's start).
            system: The new phase's integrated system (a frozen joint merged, a payload
                change): every contact, stop, lock and mode of the last phase is forgotten
                first. None: the system the law holds (the run's start).
        """
        ...

    def torque_accel(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """Accelerations [rad/s^2] of the current mode under the joint torques tau [N*m].

        The right-hand side's call, fixed within a step (the mode changes only at events).
        """
        ...

    def step(
        self, stepper: RK45Stepper, t: float, y: FloatArray, span: StepSpan
    ) -> DenseSegment | None:
        """The next step from the loop's state (t, y), at the stepper's state.

        The law bounds the step (its event detection's longest step), then takes it: with the
        loop's stepper (its own compiled stages where they serve), several at once (a stretch
        of quiet steps: their samples go to ``span.clock``), or itself (a time-stepping
        window's steps, one segment).

        Returns:
            The step to watch (:meth:`watch`), or None: there is none to watch, the loop
            goes on from the stepper's state (the steps taken are accepted and sampled, or
            none was taken: the stepper could not go on and the law takes the next steps
            itself).

        Raises:
            StepSizeUnderflow: The stepper cannot go on and the law cannot either.
        """
        ...

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """The law's event functions that changed sign over an accepted step."""
        ...

    def handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Apply the events at t (those located at the earliest crossing); the state after.

        ``crossings`` may be ``[SETTLE]`` alone: the forces changed at t (a failure, a
        payload), the locks, holds and modes made consistent again; y is returned as it is.
        """
        ...

    def after_step(self, t: float, y: FloatArray) -> FloatArray | None:
        """A step ended at (t, y) with no event; a changed state (the loop restarts) or None."""
        ...

    def forces(self) -> ForceReport:
        """The report of the current mode's forces (a freezing joint's, every sample's)."""
        ...


class ForceReport(Protocol):
    """A law's forces in its current mode, as a freeze and the samples read them."""

    def held(self) -> tuple[int, ...]:
        """The joints held still (engaged locks, friction holds), sorted."""
        ...

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The joint friction torques [N*m] to report: each held joint's holding torque.

        ``friction`` itself (the same array) when no joint is held: the recorder then
        measures a step's samples at once (:func:`packbot.recorder.measure_many`).
        """
        ...

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """The contacts of the current mode at (q, v) under the joint torques ``tau()`` [N*m].

        ``tau`` is called only when the law has contacts to report (it may call the user's
        torque function); ``t`` [s] is the sample's time (a time-stepping window reads the
        forces of the step that holds it). The contacts, each (names, point, point1, point2
        [m], normal, force on body 2 [N]), world frame (:mod:`packbot.contact_forces`; empty:
        no contact), and the joint position stops' torques [N*m]; None: the law cannot say
        (the report's clamps).
        """
        ...
