"""The ticks of a sampled-data controller inside the loop's steps: a held command costs no step.

A :class:`~packbot.control.Controller` ticks every ``dt``: it is called once per tick, in order,
on the state at the tick, and its command is held until the next tick (zero-order hold). A tick
whose command is the held one does not change the dynamics, so the integration step need not end
there and the stepper need not restart (its step size and its last derivative stay valid).

The loop therefore ends its steps at the ticks only while the command changes from tick to tick
(:attr:`Ticks.cut`: the last two ticks changed it; a single change after held ticks, an arm at
rest drifting in its last bits, is more likely followed by held ticks again). Otherwise it takes
the stepper's natural step (up to the next failure or payload change, the run's end,
``max_step``) and visits the ticks inside it in order (:meth:`Ticks.inside`), each on the step's
dense output, and only those before the step's first event. The first tick whose command differs
from the held one ends the step there: the loop keeps the step up to that tick (the state there
is the dense output's, as at an event), applies the new command and restarts. So the controller
is never called for a tick that is later discarded, and never on a state past an event.

"The held one" means: equal, or so close that holding it changes the state by less than
:data:`HOLD_FRACTION` of the stepper's absolute tolerance ``atol`` over a step. A command that
differs by du [N*m] changes the accelerations by |da| <= |du| / lambda (2-norms), lambda the
smallest eigenvalue of the mass matrix M, which is at least the smallest armature of the
integrated joints (M is the rigid body's positive semi-definite mass matrix plus the diagonal
armature). A lock or a contact constraint projects da M-orthogonally, which does not lengthen it
in the M-norm, so the bound holds with them (|da|_2 <= |da|_M / sqrt(lambda) <= |du| / lambda);
a sliding contact's friction row is no projection: the factor 1000 below is the margin there.
Over a step of h <= ``max_step`` that moves v by at most |du| h / lambda and q by at most
|du| h^2 / (2 lambda), the motor torques (with a motor lag) by at most |du|. So
|du| <= HOLD_FRACTION * atol * lambda / max(h, h^2 / 2) (and <= HOLD_FRACTION * atol with a motor
lag) keeps the change of every component within HOLD_FRACTION * atol per step, a thousandth of
what the stepper's error control allows. An arm at rest under a high-gain law changes its
command by about 1e-13 N*m from tick to tick (the state's last bits, amplified by the gains); a
moving arm by millinewton-metres or more. With no armature (lambda = 0) or ``atol`` = 0 only an
identical command is held.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact_forces import ContactForce, SampleForces, joint_torque
from packbot.control.base import Controller
from packbot.drive import Drive
from packbot.errors import ControllerError
from packbot.ode import DenseSegment
from packbot.result import Event
from packbot.schedule import Schedule

__all__ = ["HOLD_FRACTION", "Ticks"]

FloatArray = NDArray[np.float64]

#: A new command is the held one when holding it instead changes the state by less than this
#: fraction of ``atol`` over a step (see the module docstring) [-].
HOLD_FRACTION = 1e-3
#: The events whose velocity jump is a contact's impulse (a contact-sensing controller is told).
IMPULSIVE = ("impact", "secondary_intersection", "handoff")
#: Times closer than this are the same instant [s] (as in the loop).
_SAME_T = 1e-12


class Ticks:
    """The controller's ticks of one run.

    Args:
        schedule: The run's scheduled actions (the next tick's time, the tick count).
        drive: The run's torques (the held command).
        events: The run's event log (its impacts: a contact-sensing controller's impulses).

    Attributes:
        cut: Whether the next tick ends the step (the last two ticks changed the command).
    """

    def __init__(self, schedule: Schedule, drive: Drive, events: Sequence[Event] = ()) -> None:
        self.schedule = schedule
        self.drive = drive
        self.events = events
        self._seen = 0  # the events a contact-sensing controller was told of
        self.controller: Controller | None = drive.ctrl_obj
        self.cut = True
        self._changed = True  # the last tick changed the command
        self._sys: object = None  # the phase whose bound on a command change is _bound
        self._bound = 0.0
        #: The contacts of a state (the loop's :func:`~packbot.recorder.contact_sampler`), for a
        #: contact-sensing controller; None: none told.
        self.contacts: Callable[[float, FloatArray], SampleForces | None] | None = None
        self._data: Any = None  # (the full model's, for the contacts' joint torque)

    def command(self, t: float, y: FloatArray) -> FloatArray:
        """Call the controller on state y at t; its command [N*m], full coordinates, checked.

        Raises:
            ControllerError: The controller raised or returned bad torques.
        """
        assert self.controller is not None
        qf, vf = self.drive.sys.qv_full(y)  # fresh: the controller may keep them
        if self.controller.contact_sensing:
            self._sense(t, y, qf)
        try:
            raw = self.controller.step(t, qf, vf)
        except ControllerError:
            raise
        except Exception as exc:
            raise ControllerError(f"raised {type(exc).__name__}: {exc}", t) from exc
        return self.drive.check_torque(raw, t)

    def _sense(self, t: float, y: FloatArray, qf: FloatArray) -> None:
        """Tell a contact-sensing controller the contacts at (t, y) and their joint torque.

        The joint torque is the contacts' (J^T f), the joint position stops' and the report's
        law's clamps' together.
        """
        assert self.controller is not None
        found = None if self.contacts is None else self.contacts(t, y)
        ctrl = self.controller
        model = self.drive.robot.model
        if self._data is None:
            self._data = model.createData()
        new = self.events[self._seen :]
        self._seen = len(self.events)
        # the events of one instant share their velocities (one handling): one jump per instant
        jumps: dict[float, tuple[FloatArray, FloatArray]] = {}
        for ev in new:
            if ev.kind in IMPULSIVE and len(ev.v_after) == model.nv:
                first = jumps.get(ev.t, (np.asarray(ev.v_before), None))[0]
                jumps[ev.t] = (first, np.asarray(ev.v_after))
        dv = np.zeros(model.nv)
        for before, after in jumps.values():
            dv += after - before
        M = pin.crba(model, self._data, qf)
        M = np.triu(M) + np.triu(M, 1).T
        ctrl.contact_impulse = M @ dv  # (M at the tick: the impacts were within a period)
        if found is None:
            ctrl.contacts = ctrl.contact_torque = None
            return
        ctrl.contacts = [ContactForce.from_sample(c) for c in found.contacts]
        # (the joint stops' and the report's clamps' torques with the contacts': all the arm's
        # known external torque)
        tau_c = joint_torque(model, self._data, qf, found.contacts) + found.limit_torque
        if found.clamp_torque is not None:
            tau_c = tau_c + found.clamp_torque
        ctrl.contact_torque = tau_c

    def same(self, tau: FloatArray) -> bool:
        """Whether a new command is the held one (see :data:`HOLD_FRACTION`)."""
        du = tau - self.drive.hold_full
        if not np.count_nonzero(du):  # (a C call; ndarray.any goes through Python)
            return True
        sys = self.drive.sys
        if sys is not self._sys:  # a new phase: its smallest armature
            self._sys = sys
            cfg = self.drive.cfg
            lam = float(np.min(sys.model.armature)) if sys.nv else 0.0
            h = cfg.max_step
            bound = HOLD_FRACTION * cfg.atol * lam / max(h, 0.5 * h * h)
            if self.drive.lag:
                bound = min(bound, HOLD_FRACTION * cfg.atol)
            self._bound = bound
        return math.sqrt(float(du @ du)) <= self._bound

    def apply(self, t: float, tau: FloatArray) -> None:
        """The command of the tick at t changes: hold it from t on; the next tick is due."""
        self.drive.hold(tau, t)
        self.schedule.ticked()
        self.cut = self._changed
        self._changed = True

    def tick(self, t: float, y: FloatArray) -> bool:
        """The tick due at t on state y; whether it changed the command (the loop restarts)."""
        tau = self.command(t, y)
        if self.same(tau):
            self.schedule.ticked()
            self.cut = self._changed = False
            return False
        self.apply(t, tau)
        return True

    def inside(
        self, seg: DenseSegment, t_stop: float, keep: Callable[[DenseSegment, float], None]
    ) -> tuple[float, FloatArray] | None:
        """The ticks strictly inside a step, before t_stop, in order, on its dense output.

        Each tick whose command is the held one is counted and passed. The first tick whose
        command changes stops the visit: it is returned, not yet applied (:meth:`apply`).

        Args:
            seg: The step.
            t_stop: The step's first event, or its end [s]; a tick at it (within 1e-12 s) or
                after it is left to the loop.
            keep: Keeps the step's samples up to a time [s] (``Recorder.record``): called up to
                just before a tick whose controller call raises (the partial result ends there).

        Returns:
            (t, new command) of the first tick that changes the command, or None.
        """
        sched = self.schedule
        while sched.next_tick < t_stop - _SAME_T:
            t = sched.next_tick
            try:
                tau = self.command(t, seg(t))
            except ControllerError:
                keep(seg, t - 1e-11)
                raise
            if not self.same(tau):
                return t, tau
            sched.ticked()
            self.cut = self._changed = False
        return None
