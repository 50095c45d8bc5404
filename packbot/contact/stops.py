"""The base of every contact law: the constraint pools it holds and the protocol's template.

:class:`JointStops` is the base of every law (and, alone, the law without collisions,
:class:`~packbot.contact.none.NoneLaw`). It holds, for each phase, the law's constraint pools
and its joint locks, and composes them into the protocol (:class:`~packbot.contact.base.
ContactLaw`):

- the joint position stops (:class:`~packbot.contact.position_stops.PositionStops`): a joint
  reaching a limit gets a joint-space impulse on it alone and a clamp, released once it leaves;
- the friction holds (:class:`~packbot.contact.holds.JointHolds`): static joint friction and
  brakes as joint locks, their ``slip`` and the sliding joints' ``stick``;
- the joint locks (:class:`~packbot.contact.locks.JointLocks`): the clamps (of the stops and of
  the report's contacts) and the holds, their sign conditions (``engage``, ``disengage``)
  as event functions; :meth:`JointStops.settle_modes` makes locks and holds consistent after
  any change; the velocity resets (:mod:`packbot.contact.resets`) of a stop or an impact, and
  the events written (:class:`~packbot.contact.law_log.LawLog`);
- the template of the protocol: a law with contacts fills the hooks (``_initial_pairs``,
  ``_contact_crossings``, ``_pair_event``, ``_after_event``, ``_accept``, ``_refresh``,
  ``_limit_held``, ``_drop_limit``) and, where its handling differs, overrides ``_handle``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from packbot.config import SimConfig
from packbot.contact.base import SETTLE, Active, Crossing, ForceReport, Key, StepSpan
from packbot.contact.holds import STICK_SPEED, JointHolds, friction_share
from packbot.contact.law_log import LawLog
from packbot.contact.lock_forces import LockReport
from packbot.contact.lock_step import SCREEN_MARGIN as SCREEN_MARGIN
from packbot.contact.lock_step import NativeLockStep
from packbot.contact.locks import JointLocks
from packbot.contact.position_stops import PositionStops
from packbot.contact.resets import HOLD_KICK, widened_reset
from packbot.drive import Drive
from packbot.ode import DenseSegment, RK45Stepper, StepKernel
from packbot.recorder import EventLog
from packbot.result import Diagnostics
from packbot.system import System

# (HOLD_KICK, STICK_SPEED and friction_share are the resets' and the holds': the hand-off
# reads them here)
__all__ = ["HOLD_KICK", "RECEDE_SPEED", "STICK_SPEED", "JointStops", "friction_share"]

FloatArray = NDArray[np.float64]
#: A clamped joint moving away from its contact or stop faster than this [rad/s] is receding: an
#: engaged clamp on it lets go (it would do positive work).
RECEDE_SPEED = 1e-9


class JointStops:
    """The base of every contact law: its constraint pools and the template of the protocol.

    Args:
        config: Simulation settings.
        system: The integrated system of the first phase.
        drive: The run's torques (free accelerations, the sliding directions ``drive.fdir``).
        events: The run's event log (the law writes its events there).
        diag: The run's diagnostics (the law counts its distance queries and sweeps there).

    Attributes:
        locks: The joint locks: clamps and friction holds.
        active: The active contacts and limit stops (key -> :class:`Active`).
        stops: The joint position stops (:class:`~packbot.contact.position_stops.
            PositionStops`).
        holds: The friction holds (:class:`~packbot.contact.holds.JointHolds`).
        log: The law's event writer (:class:`~packbot.contact.law_log.LawLog`).
        lock_report: The forces at the samples (:class:`~packbot.contact.lock_forces.
            LockReport`: the locks' torques).
    """

    def __init__(
        self,
        config: SimConfig,
        system: System,
        drive: Drive,
        events: EventLog,
        diag: Diagnostics,
    ) -> None:
        self.cfg = config
        self.drive = drive
        self.events = events
        self.diag = diag
        self._locks_only = type(self).accel is JointStops.accel
        self.lock_report = LockReport(self)
        self.rebuild(system)

    # ------------------------------------------------------------------ the protocol
    def rebuild(self, system: System) -> None:
        """A new phase on ``system``: no contact, no stop, no lock."""
        self.sys = system
        self.n = system.nv
        self.locks = JointLocks(system.nv)
        self.active: dict[Key, Active] = {}
        self.log = LawLog(system, self.events, self.diag)
        self.log_event = self.log.event  # (the laws log their events through it)
        self.stops = PositionStops(system, self.cfg, self.log)
        self.holds = JointHolds(system, self.drive, self.log)
        self._lock_step = NativeLockStep(system, self.drive)  # the native step, its screen

    def start(
        self, t: float, y: FloatArray, check: bool, system: System | None = None
    ) -> FloatArray:
        """Contacts (pairs within the contact tolerance) and limit stops at (t, y).

        Each gets its event's handling at t (an impact with zero speed gets its clamps); with
        none, the locks and holds are settled. Returns the state after. A new phase's
        ``system``: :meth:`rebuild` on it first.
        """
        if system is not None:
            self.rebuild(system)
        crossings = self._initial_pairs(y, check)
        crossings.extend(self.stops.present(y))
        if crossings:
            return self._handle(t, y, crossings)
        self.settle_modes(t, y)
        return y

    def accel(self, q: FloatArray, v: FloatArray, a_free: FloatArray) -> FloatArray:
        """Accelerations with the engaged and held locks applied."""
        if self.locks.any_locked:
            return self.locks.accelerations(a_free, self.sys.minv(q))
        return a_free

    def torque_accel(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """Accelerations of the current mode from the joint torques tau [N*m].

        With the locks' alone (:meth:`_locks_now`), two joints or more locked and at most 3
        unlocked: the unlocked block of M (:meth:`JointLocks.reduced_accelerations`, 4 us
        less than ABA and M^-1); otherwise :meth:`accel` of ABA's free accelerations.
        """
        locks = self.locks
        u = locks.unlocked
        if u is not None and len(u) <= 3 and locks.n_locked >= 2 and self._locks_now():
            sys = self.sys
            return locks.reduced_accelerations(sys.mass_upper(q), tau - sys.bias(q, v))
        return self.accel(q, v, self.sys.aba(q, v, tau))

    def _locks_now(self) -> bool:
        """Whether the current mode's accelerations are the locks' alone (no rows of the law)."""
        return self._locks_only

    def step_kernel(self, t: float, y: FloatArray) -> StepKernel | None:
        """The native Dormand-Prince step of the current lock mode, or None (the stages call rhs).

        Offered when the mode's accelerations are the locks' alone (:meth:`_locks_now`), as
        :meth:`NativeLockStep.kernel <packbot.contact.lock_step.NativeLockStep.kernel>` says:
        the stages, the 5th-order solution and the error norm in one call.
        """
        if not self._locks_now():
            return None
        return self._lock_step.kernel(t, y, self.locks)

    def _screened(self, y1: FloatArray) -> bool:
        """Whether the last native step ended at y1 with every lock condition clearly kept.

        False with no such step, or a mode no longer the locks' alone: :meth:`NativeLockStep.
        screened <packbot.contact.lock_step.NativeLockStep.screened>`.
        """
        step = self._lock_step
        return step.rhs is not None and self._locks_now() and step.screened(y1, self.locks)

    def step_bound(self, y: FloatArray) -> float:
        """``max_step``: without a collision world nothing else bounds a step."""
        return self.cfg.max_step

    def step(
        self, stepper: RK45Stepper, t: float, y: FloatArray, span: StepSpan
    ) -> DenseSegment | None:
        """One step of the loop's stepper from (t, y), not past ``span.t_end``.

        Bounded by :meth:`step_bound`, its stages :meth:`step_kernel`'s where that serves; a
        step-size underflow stops the run (only the contact-normal mode takes over there).
        """
        stepper.h_max = self.step_bound(y)
        return stepper.step(span.t_end, self.step_kernel(t, y))

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """Event functions that changed sign over the step (evaluated at its end).

        In this order: limit stops, the law's contacts (pairs, then its modes), the locks' and
        holds' sign conditions, the sliding joints' stops.
        """
        y1 = seg.y1
        out = self.stops.crossings(seg, y1, self.active)
        out.extend(self._contact_crossings(seg, y1))
        out.extend(self._hold_crossings(seg, y1))
        return out

    def handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """Apply the events at t to state y; returns the post-event state.

        :data:`~packbot.contact.base.SETTLE` alone: the forces changed, the modes settled
        again (:meth:`_forces_changed`), y returned.
        """
        if len(crossings) == 1 and crossings[0] is SETTLE:
            self._forces_changed(t, y)
            return y
        y_new = self._handle(t, y, crossings)
        self._after_event(y_new)
        return y_new

    def after_step(self, t: float, y: FloatArray) -> FloatArray | None:
        """An accepted step without event: distances kept, stops released, patches refreshed."""
        self._accept()
        self.release_limits(t, y)
        return self._refresh(t, y)

    def _forces_changed(self, t: float, y: FloatArray) -> None:
        """The forces changed at t (a failure, a payload): locks and holds made consistent."""
        self.settle_modes(t, y)

    def forces(self) -> ForceReport:
        """The current mode's forces: its locks' torques (:attr:`lock_report`)."""
        return self.lock_report

    def held(self) -> tuple[int, ...]:
        """Every joint with a_j = 0 in the current mode (engaged or held), sorted."""
        return self.locks.locked

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m], each held joint's holding torque in place.

        :meth:`JointHolds.friction <packbot.contact.holds.JointHolds.friction>`.
        """
        return self.holds.friction(q, v, applied, friction, self.locks, self.sys)

    # ------------------------------------------------------------------ hooks (no contacts)
    def _initial_pairs(self, y: FloatArray, check: bool) -> list[Crossing]:
        """The pairs in contact at a phase's start, as crossings at that instant."""
        return []

    def _contact_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        """The contacts' event functions that changed sign over the step."""
        return []

    def _pair_event(
        self, t: float, y: FloatArray, q: FloatArray, v: FloatArray, c: Crossing
    ) -> FloatArray:
        """A pair's impact, secondary intersection or release (the report's law)."""
        raise AssertionError(f"{c.kind} of {c.key} without a collision world")

    def _after_event(self, y: FloatArray) -> None:
        """After the events of an instant (the distances at the new state)."""

    def _accept(self) -> None:
        """A step was accepted (the distances at its end become the kept ones)."""

    def _refresh(self, t: float, y: FloatArray) -> FloatArray | None:
        """After an accepted step: a changed state (re-patched contacts), or None."""
        return None

    def _limit_held(self, j: int, side: int) -> bool:
        """Whether a stop's own constraint still holds its joint (it is not released)."""
        return False

    def _drop_limit(self, j: int, side: int) -> None:
        """A limit stop let go (the law's own record of it)."""

    # ------------------------------------------------------------------ events
    def free_accel(self, t: float, y: FloatArray) -> FloatArray:
        """Accelerations of the unconstrained arm at (t, y) [rad/s^2]."""
        return self.drive.free_accel(t, y)

    def energy(self, q: FloatArray, v: FloatArray) -> float:
        """Total mechanical energy [J]."""
        return self.sys.energy(q, v)

    def with_v(self, y: FloatArray, v: FloatArray) -> FloatArray:
        """The state y with its velocities replaced."""
        out = y.copy()
        out[self.n : 2 * self.n] = v
        return out

    def lock_conditions(self, t: float, y: FloatArray) -> dict[tuple[str, int], float]:
        """The locks' and holds' sign conditions at (t, y) (see JointLocks.conditions)."""
        a = self.free_accel(t, y)
        minv = self.sys.minv(y[: self.n]) if self.locks.any_locked else None
        return self.locks.conditions(a, minv)

    def _hold_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        """The locks' and holds' conditions that changed sign, the joints that stopped."""
        return self.holds.crossings(seg, y1, self.locks, self.lock_conditions, self._screened)

    def _handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """The report's handling (and the stops' and holds'): events applied in turn."""
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        flip: int | None = None
        stick: list[int] = []
        for c in sorted(crossings, key=lambda c: c.kind != "release"):
            if c.kind in ("impact", "secondary_intersection", "release"):
                v = self._pair_event(t, y, q, v, c)
            elif c.kind == "limit":
                v = self.limit(t, q, v, c.key[1], c.key[2])
            elif c.kind in ("slip", "stick"):
                v = self._hold_event(t, y, q, v, c, stick)
            else:  # engage / disengage
                flip = c.key[1]
                self.log_event(t, c.kind, q, v, v, None, joints=(self.sys.names[flip],), joint=flip)
        y_new = self.with_v(y, v)
        self.settle_modes(t, y_new, flip=flip, candidates=stick, log_stick=True)
        return y_new

    def _hold_event(
        self, t: float, y: FloatArray, q: FloatArray, v: FloatArray, c: Crossing, stick: list[int]
    ) -> FloatArray:
        """A held joint slips or a sliding one stops at (t, y), velocities v; new v.

        :meth:`JointHolds.event <packbot.contact.holds.JointHolds.event>`.
        """

        def torque(j: int) -> float:
            return self.hold_torque(t, self.with_v(y, v), j)

        return self.holds.event(t, q, v, c, self.locks, torque, stick)

    def hold_torque(self, t: float, y: FloatArray, j: int) -> float:
        """The torque [N*m] joint j's lock needs at (t, y) with the current locked set (and j)."""
        a_free = self.free_accel(t, y)
        return self.holds.torque(j, self.locks, a_free, lambda: self.sys.minv(y[: self.n]))

    def apply_clamps(self) -> None:
        """Give the clamps of the active contacts and stops to the joint locks."""
        self.locks.set_clamps([cl for a in self.active.values() for cl in a.clamps])

    def settle_modes(
        self,
        t: float,
        y: FloatArray,
        *,
        flip: int | None = None,
        candidates: Sequence[int] = (),
        log_stick: bool = False,
    ) -> None:
        """Set the clamps, the engaged locks and the friction holds consistent at (t, y).

        Args:
            t: Time [s].
            y: State (its velocities already reset).
            flip: A clamped joint whose mode an event just changed (see JointLocks).
            candidates: Joints with Coulomb friction that just stopped: they stick, or slide
                on (:meth:`JointHolds.settle <packbot.contact.holds.JointHolds.settle>`).
            log_stick: Log a ``stick`` event for each candidate that sticks.
        """
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
        candidates = self.holds.moving(t, q, v, self.locks, candidates)
        if not (self.locks.signs or self.locks.held or candidates):
            return
        minv = self.sys.minv(q)
        if self.locks.signs:
            self._solve_engaged(t, y, minv, flip)
        if candidates:

            def a_free() -> FloatArray:
                return self.free_accel(t, y)

            self.holds.settle(t, q, v, self.locks, candidates, a_free, minv, log_stick)
            if self.locks.signs:
                self._solve_engaged(t, y, minv, flip)

    def _solve_engaged(self, t: float, y: FloatArray, minv: FloatArray, flip: int | None) -> None:
        """Choose the engaged clamps at (t, y) (the locks' complementarity problem).

        A clamp never does positive work: an engaged clamp holds its joint at a_j = 0 with a
        torque pushing away from its contact or stop, so on a joint moving away from it
        (``s v_j < -RECEDE_SPEED``, after a rebound or an impulse on the joints it is coupled
        to) it would keep that speed against the forces that slow it. Such a clamp lets go
        (:meth:`_let_go`: a limit stop is released, its joint's return is a new ``limit``
        event) and the engaged set is chosen again without it.
        """
        n = self.n
        v = y[n : 2 * n]
        a_free = self.free_accel(t, y)
        self.locks.solve_engaged(a_free, minv, flip=flip)
        for _ in range(n + 1):
            engaged = set(self.locks.engaged) - set(self.locks.held)
            away = [
                (key, cl)
                for key, act in self.active.items()
                for cl in act.clamps
                if cl[0] in engaged and cl[1] * v[cl[0]] < -RECEDE_SPEED
            ]
            if not away:
                return
            for key, cl in away:
                self._let_go(t, y, key, cl)
            self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
            self.locks.solve_engaged(a_free, minv, flip=flip)

    def _let_go(self, t: float, y: FloatArray, key: Key, clamp: tuple[int, int]) -> None:
        """An engaged clamp on a receding joint lets go: a limit stop is released (logged)."""
        if key[0] == "limit" and key in self.active:
            self._release_limit(t, y, key[1], key[2])

    # ------------------------------------------------------------------ stops
    def reset(
        self,
        q: FloatArray,
        v: FloatArray,
        rel: NDArray[np.intp],
        rule: str | None = None,
        restitution: float | None = None,
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        """The reset rule on ``rel``, widened (:func:`~packbot.contact.resets.widened_reset`).

        Args:
            q: Configuration.
            v: Velocities before [rad/s].
            rel: The joints to act on.
            rule: ``"zero"`` or ``"momentum"``; default ``SimConfig.reset_rule``.
            restitution: e in [0, 1]; default ``SimConfig.restitution``.

        Returns:
            The new velocities and the joints acted on.
        """
        cfg = self.cfg
        rule = cfg.reset_rule if rule is None else rule
        e = cfg.restitution if restitution is None else restitution
        minv = self.sys.minv(q) if rule == "momentum" else None
        return widened_reset(v, rel, e, rule, minv, self._widening_clamps(), self.locks.held)

    def _widening_clamps(self) -> list[tuple[int, int]]:
        """The clamps (joint, s) a reset is widened for: those of the active contacts."""
        return [cl for a in self.active.values() for cl in a.clamps]

    def limit(self, t: float, q: FloatArray, v: FloatArray, j: int, side: int) -> FloatArray:
        """Joint j reached its upper (side +1) or lower (-1) stop: impulse and clamp; new v."""
        return self.stops.hit(t, q, v, j, side, self.active, self.reset)

    def release_limits(self, t: float, y: FloatArray) -> None:
        """Limit stops let go when the joint has left the stop (moving away)."""
        for j, side in self.stops.left(y, self.active, self._limit_held):
            self._release_limit(t, y, j, side)
            self.apply_clamps()

    def _release_limit(self, t: float, y: FloatArray, j: int, side: int) -> None:
        """Drop the stop of joint j (side +1 upper, -1 lower); a ``release`` event."""
        self._drop_limit(j, side)
        self.stops.release(t, y, j, side, self.active)
