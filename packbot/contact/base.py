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
  rebuild`, then :meth:`~ContactLaw.start` (the contacts and stops present);
- every right-hand side: :meth:`~ContactLaw.accel` (the current mode's accelerations);
- before each step: :meth:`~ContactLaw.step_bound`, then :meth:`~ContactLaw.advance` (a law
  that integrates a stretch itself, the contact-normal mode's time-stepping windows, returns
  its step; otherwise the loop's stepper takes it);
- after each step: :meth:`~ContactLaw.watch` (the event functions that changed sign);
  none: the step is accepted, :meth:`~ContactLaw.after_step`; else the loop locates the
  earliest crossing and calls :meth:`~ContactLaw.handle` with the crossings at that instant;
- a failure or a payload change that keeps the phase: :meth:`~ContactLaw.settle`;
- a freezing joint: :meth:`~ContactLaw.held` (the joints its impulse keeps still);
- every sample: :meth:`~ContactLaw.friction`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.ode import DenseSegment, RK45Stepper, StepKernel, StiffKernel
from packbot.system import System

if TYPE_CHECKING:
    from packbot.contact.stretch import SampleClock, Stretched
    from packbot.contact_forces import SampleForces

__all__ = ["Active", "ContactLaw", "Crossing", "Key"]

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


class ContactLaw(Protocol):
    """What the event loop asks of a contact law.

    States are the integrated ones, y = (q, v[, tau_m]) (the motor torques when
    ``SimConfig.motor_lag > 0``); a law changes velocities (an impulse) and, in the
    contact-normal modes, positions (a drift correction), never tau_m.
    """

    def rebuild(self, system: System) -> None:
        """The integrated system changed (a new phase): every contact and mode is forgotten."""
        ...

    def start(self, t: float, y: FloatArray, check: bool) -> FloatArray:
        """The contacts and limit stops present at (t, y); returns the state after.

        Args:
            t: Time [s].
            y: State.
            check: Raise ``InitialCollisionError`` if a pair penetrates (the run's start).
        """
        ...

    def accel(self, q: FloatArray, v: FloatArray, a_free: FloatArray) -> FloatArray:
        """Accelerations [rad/s^2] of the current mode, from the free ones (fixed in a step)."""
        ...

    def torque_accel(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """Accelerations [rad/s^2] of the current mode under the joint torques tau [N*m].

        The right-hand side's call: ``accel`` of the free accelerations (Pinocchio's ABA),
        or a law's own path computing both at once (the contact-normal mode's native call).
        """
        ...

    def step_kernel(self, t: float, y: FloatArray) -> StepKernel | None:
        """A compiled step of the current mode from (t, y), or None: the stages call ``rhs``.

        The stepper's stages (:meth:`packbot.ode.RK45Stepper.step`'s ``kernel``) on the same
        right-hand side, its modes and torques fixed over the step (the contact-normal mode's
        native step).
        """
        ...

    @property
    def stiff_kernel(self) -> StiffKernel | None:
        """The linearly implicit counterpart of :meth:`step_kernel`'s kernel, or None.

        Read right after :meth:`step_kernel` returned a kernel: the stepper's ``stiff``
        (:meth:`packbot.ode.RK45Stepper.step`), for the stretches where the explicit step is
        held at its stability bound.
        """
        ...

    @property
    def first_stage(self) -> Callable[[FloatArray], bool] | None:
        """The compiled step's first stage, which takes a restart's derivative, or None.

        When not None, the loop leaves the derivative at a restart to the next step
        (:meth:`packbot.ode.RK45Stepper.reset`'s ``defer``): this stage at its start when the
        step is the law's :meth:`step_kernel`, else the right-hand side there.
        """
        ...

    def step_bound(self, y: FloatArray) -> float:
        """The longest step [s] from y that the law's event detection allows."""
        ...

    def stretch(
        self,
        stepper: RK45Stepper,
        t_end: float,
        t_last: float,
        t_sched: float,
        clock: SampleClock,
    ) -> Stretched | None:
        """Several steps at once from the stepper's state, or None: the loop steps.

        Offered by the loop right after :meth:`step_kernel`, with no controller tick before
        ``t_end``. When it returned a kernel, a restart's derivative may be pending (then the
        kernel's :attr:`first_stage` computes it) and the stepper may be stiff (then the steps
        are :attr:`stiff_kernel`'s, as the stepper's would be); without one, a law may still
        take steps that need no kernel (the contact-normal mode holds an arm at rest).
        The steps kept are watched and accepted (the law and the stepper are past them; the
        loop records their samples); a pending step is the stepper's last step, not yet
        watched (:class:`~packbot.contact.stretch.Stretched`).

        Args:
            stepper: The loop's stepper.
            t_end: No step beyond this time [s].
            t_last: The run ends here [s].
            t_sched: The next scheduled action [s] (a step ending there is handed back).
            clock: The run's regular samples.
        """
        ...

    def advance(self, t: float, y: FloatArray, t_end: float) -> DenseSegment | None:
        """Steps the law takes itself (a time-stepping window), or None: the loop's stepper.

        One step, or several as one segment (a run of window steps); the loop treats the
        segment as one step.

        Args:
            t: Time [s].
            y: State.
            t_end: The step may not pass this time [s] (the run's end, a scheduled action).
        """
        ...

    def rescue(self, t: float, y: FloatArray) -> bool:
        """The loop's stepper cannot go on from (t, y): take over, or not.

        Returns:
            True if the law takes the next steps itself (:meth:`advance`), False to let the
            run fail (the stepper's step size underflowed).
        """
        ...

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """The law's event functions that changed sign over an accepted step."""
        ...

    def handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Apply the events at t (those located at the earliest crossing); the state after."""
        ...

    def after_step(self, t: float, y: FloatArray) -> FloatArray | None:
        """A step ended at (t, y) with no event; a changed state (the loop restarts) or None."""
        ...

    def settle(self, t: float, y: FloatArray) -> None:
        """The forces changed at t (a failure, a payload): the modes again (y is kept)."""
        ...

    def held(self) -> tuple[int, ...]:
        """The joints the law holds still (engaged locks, friction holds), sorted."""
        ...

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The joint friction torques [N*m] to report: each held joint's holding torque."""
        ...

    def contact_forces(
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
