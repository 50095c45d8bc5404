"""Limit stops and joint holds: what every contact law has, in one place.

:class:`JointStops` is the base of every law (and, alone, the law without collisions,
:class:`~packbot.contact.none.NoneLaw`). It holds the phase's
:class:`~packbot.contact.locks.JointLocks` and the law's active contacts, and does:

- **limit stops**: a joint reaching a position limit (event ``limit``) gets a joint-space
  impulse on that joint alone (the ``momentum`` rule of :func:`impact_reset`, whatever
  ``reset_rule`` says: on a stop the report's ``zero`` rule can add energy) and a clamp,
  unless it bounces off (e > 0); the stop lets go once the joint has left it by 1e-6 rad (a
  ``release`` after an accepted step);
- **joint holds**: the clamps (of the stops and of the report's contacts) and the friction
  holds (static joint friction, brakes) as joint locks; their sign conditions (``engage``,
  ``disengage``, ``slip``) and the sliding joints' stops (``stick``) as event functions;
  :meth:`JointStops.settle_modes` makes locks and holds consistent after any change;
- the template of the protocol (:class:`~packbot.contact.base.ContactLaw`): a law with
  contacts fills the hooks (``_initial_pairs``, ``_contact_crossings``, ``_pair_event``,
  ``_after_event``, ``_accept``, ``_refresh``, ``_limit_held``, ``_drop_limit``) and, where
  its handling differs, overrides ``_handle``.

Velocity reset of an impact or a stop, on the acted joints R (e = restitution):

- ``"zero"`` (the report's): ``v_i <- -e v_i`` for i in R. On a coupled arm this can *add*
  kinetic energy (the joints are not decoupled in M); every impact logs its energy change.
- ``"momentum"``: an impulsive torque on the joints of R only, ``M dv = S_R^T P``, makes
  ``v_R+ = -e v_R-``: the other joints keep their generalized momentum
  (``(M v)_j`` unchanged for j not in R). With e <= 1 it never adds energy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.config import SimConfig
from packbot.contact.base import SETTLE, Active, Crossing, ForceReport, Key, StepSpan
from packbot.contact.lock_step import SCREEN_MARGIN as SCREEN_MARGIN
from packbot.contact.lock_step import NativeLockStep
from packbot.contact.locks import TORQUE_BAND, JointLocks
from packbot.drive import Drive
from packbot.ode import DenseSegment, RK45Stepper, StepKernel
from packbot.recorder import EventLog
from packbot.result import Diagnostics, Event
from packbot.system import System

if TYPE_CHECKING:
    from packbot.contact_forces import SampleForces

__all__ = [
    "HOLD_KICK",
    "RECEDE_SPEED",
    "RETURN_DT",
    "STICK_SPEED",
    "JointStops",
    "friction_share",
    "impact_reset",
    "return_crossing",
]

FloatArray = NDArray[np.float64]
#: Joint speed below which a joint with Coulomb friction counts as stopped (it may stick) [rad/s].
STICK_SPEED = 1e-9
#: A clamped joint moving away from its contact or stop faster than this [rad/s] is receding: an
#: engaged clamp on it lets go (it would do positive work).
RECEDE_SPEED = 1e-9
#: A held joint (Coulomb friction, a brake) that an impulse on its coupled joints sets moving
#: slower than this [rad/s] stays held: the impulse is solved with the joint acted on too (its
#: speed kept at zero, never adding energy). Faster, it slides, its friction opposing (a bounded
#: torque does nothing in an instant). A modelling choice: it ends the Zeno sequence of a stop's
#: bounces under a brake (each bounce kicking the braked joint, which sticks again before the
#: next), as ``SimConfig.zeno_speed`` ends a contact's.
HOLD_KICK = 1e-3
#: Resolution [s] of :func:`return_crossing`'s search (the event loop locates events to 1e-10 s).
RETURN_DT = 1e-10


def return_crossing(
    g: Callable[[float], float], t0: float, t1: float
) -> tuple[Callable[[float], float], float] | None:
    """An event function that starts a step on its event side: the event is its return.

    A step that restarts on an event (a stop or a contact surface just reached, g(t0) <= 0: the
    event loop locates events on their event side) may leave it first: a joint bouncing off its
    stop, a pair rebounding from d = 0. The event of that step is then the function's *return*
    to zero, not its value at t0. This looks for a time t_m in (t0, t1) with g(t_m) > 0 by
    halving the step from its start (down to ``RETURN_DT``).

    Args:
        g: The event function on the step's dense output.
        t0: The step's start [s].
        t1: The step's end [s].

    Returns:
        ``(g_late, g(t_m))`` with ``g_late(t) = g(max(t, t_m))`` (positive up to t_m, so the
        loop's root finding on [t0, t1] finds the return), or None if g is not positive that
        close to t0 (it goes on to the event side at once: the event is at t0).
    """
    h = t1 - t0
    while h > RETURN_DT:
        h *= 0.5
        t_m = t0 + h
        g_m = g(t_m)
        if g_m > 0.0:

            def g_late(t: float, t_m: float = t_m) -> float:
                return g(max(t, t_m))

            return g_late, g_m
    return None


def friction_share(torque: float, bound: float) -> float:
    """The part [N*m] of a held joint's holding torque that its friction or brake carries.

    Within the bound F_j all of it; beyond it (a contact's clamp on the joint pushes too, which
    may supply any torque) the friction carries F_j and the contact the rest.

    Args:
        torque: The torque holding the joint [N*m].
        bound: The joint's friction or brake bound F_j [N*m].
    """
    return float(math.copysign(min(abs(torque), bound), torque))


def impact_reset(
    v: FloatArray, relevant: NDArray[np.intp], e: float, rule: str, minv: FloatArray | None
) -> FloatArray:
    """Post-impact joint velocities [rad/s].

    Args:
        v: Pre-impact velocities.
        relevant: The joints acted on.
        e: Restitution in [0, 1].
        rule: ``"zero"`` or ``"momentum"`` (see the module docstring).
        minv: M^-1 at the impact configuration (``"momentum"`` only).
    """
    if len(relevant) == 0:
        return v.copy()
    if rule == "zero":
        out = v.copy()
        out[relevant] = -e * v[relevant]
        return out
    assert minv is not None
    W = minv[np.ix_(relevant, relevant)]
    P = np.linalg.solve(W, -(1.0 + e) * v[relevant])  # impulsive torques [N m s]
    out = v + minv[:, relevant] @ P
    # The impulse is solved for v_R+ = -e v_R-: write that exactly. The solve leaves rounding
    # residue (~1e-16 rad/s) whose sign would otherwise decide whether a stopped joint counts
    # as moving away from its stop, a branch that another machine's rounding takes the other way.
    out[relevant] = -e * v[relevant]
    return out


class JointStops:
    """Limit stops and joint holds; the base of every contact law.

    Args:
        config: Simulation settings.
        system: The integrated system of the first phase.
        drive: The run's torques (free accelerations, the sliding directions ``drive.fdir``).
        events: The run's event log (the law writes its events there).
        diag: The run's diagnostics (the law counts its distance queries and sweeps there).

    Attributes:
        locks: The joint locks: clamps and friction holds.
        active: The active contacts and limit stops (key -> :class:`Active`).
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
        self.rebuild(system)

    # ------------------------------------------------------------------ the protocol
    def rebuild(self, system: System) -> None:
        """A new phase on ``system``: no contact, no stop, no lock."""
        self.sys = system
        self.n = system.nv
        self.locks = JointLocks(system.nv)
        self.active: dict[Key, Active] = {}
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
        if self.cfg.joint_limits:
            for j in range(self.n):
                for side, lim in ((1, self.sys.upper[j]), (-1, self.sys.lower[j])):
                    if side * (lim - y[j]) <= 0.0:
                        crossings.append(
                            Crossing("limit", ("limit", j, side), lambda t: 0.0, 0.0, 0.0)
                        )
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

        With locks and nothing else (the report's law, no contacts: :meth:`_locks_now`), two
        joints or more locked and at most 3 unlocked, from the unlocked
        joints' block of M (CRBA and the bias forces: :meth:`JointLocks.reduced_accelerations`,
        about 4 us less than ABA, M^-1 and the locked block's solve); otherwise :meth:`accel`
        of the free accelerations (ABA; one lock is a rank-one correction, as cheap).
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

        Offered when the mode's accelerations are the locks' alone (:meth:`_locks_now`) with no
        joint locked, one, or all but at most 3 (:meth:`torque_accel`'s ABA, its rank-one
        correction, or its unlocked block, computed the same way in the extension:
        :meth:`~packbot.contact.native.NativeRhs.set_locks`), and the torques are fixed over
        the step (a held command or none, no motor lag:
        :meth:`~packbot.drive.Drive.step_torques`). The stages, the 5th-order solution and the
        error norm in one call (:class:`~packbot.contact.lock_step.NativeLockStep`); elsewhere
        the stepper's stages call :meth:`torque_accel`.
        """
        if not self._locks_now():
            return None
        return self._lock_step.kernel(t, y, self.locks)

    def _screened(self, y1: FloatArray) -> bool:
        """Whether the last native step ended at y1 with every lock condition clearly kept.

        False also when there was no such step, or the mode is no longer the locks' alone (the
        conditions are then evaluated): :meth:`NativeLockStep.screened
        <packbot.contact.lock_step.NativeLockStep.screened>`.
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

        Bounded by :meth:`step_bound`; its stages are :meth:`step_kernel`'s compiled call
        where that serves, else the stepper's calls of the right-hand side. A step-size
        underflow stops the run (only the contact-normal mode takes over there).
        """
        stepper.h_max = self.step_bound(y)
        return stepper.step(span.t_end, self.step_kernel(t, y))

    def watch(self, seg: DenseSegment) -> list[Crossing]:
        """Event functions that changed sign over the step (evaluated at its end).

        In this order: limit stops, the law's contacts (pairs, then its modes), the locks' and
        holds' sign conditions, the sliding joints' stops.
        """
        y1 = seg.y1
        out = self._limit_crossings(seg, y1)
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
        """The current mode's forces: the law reports them itself (:meth:`held`, ...)."""
        return self

    def held(self) -> tuple[int, ...]:
        """Every joint with a_j = 0 in the current mode (engaged or held), sorted."""
        return self.locks.locked

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """None: the report's clamps act on joints, not as forces on pairs (unknown)."""
        return None

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m] with each held joint's holding torque in place.

        A held joint that a contact's clamp also pushes (its lock torque beyond the bound F_j,
        :class:`~packbot.contact.locks.JointLocks`) is reported with its friction at the bound,
        the rest being the contact's (:func:`friction_share`).
        """
        if self.locks.held:
            friction = friction.copy()
            a_free = self.sys.aba(q, v, applied + friction)
            _, lam = self.locks.torques(a_free, self.sys.minv(q))
            for j, bound in self.locks.held.items():
                friction[j] = friction_share(lam[j], bound)
        return friction

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

    def _limit_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        out: list[Crossing] = []
        if not self.cfg.joint_limits:
            return out
        q1 = y1[: self.n]  # numpy screen first: a limit crossing is rare
        upper, lower = self.sys.upper, self.sys.lower
        for j in ((q1 >= upper) | (q1 <= lower)).nonzero()[0].tolist():
            side, lim = (1, upper[j]) if q1[j] >= upper[j] else (-1, lower[j])
            if ("limit", j, side) in self.active:
                continue

            def g(t: float, j: int = j, side: int = side, lim: float = lim) -> float:
                return float(side * (lim - seg(t)[j]))

            fn: Callable[[float], float] = g
            g0 = side * (lim - seg.y0[j])
            if g0 <= 0.0 and (late := return_crossing(g, seg.t0, seg.t1)) is not None:
                fn, g0 = late  # it left the stop (a bounce): the event is its return
            out.append(Crossing("limit", ("limit", j, side), fn, g0, side * (lim - q1[j])))
        return out

    def _hold_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        n, out = self.n, []
        if self.locks.conditional and not self._screened(y1):
            cond1 = self.lock_conditions(seg.t1, y1)
            bad = [k for k, g in cond1.items() if g < 0.0]
            if bad:
                cond0 = self.lock_conditions(seg.t0, seg.y0)
                for k in bad:

                    def gl(t: float, k: tuple[str, int] = k) -> float:
                        return self.lock_conditions(t, seg(t))[k]

                    kind, j = k
                    if kind == "hold":
                        kind = "slip"
                    else:
                        kind = "disengage" if j in self.locks.engaged else "engage"
                    out.append(Crossing(kind, ("lock", j), gl, cond0.get(k, 1.0), cond1[k]))
        fdir = self.drive.fdir
        if not fdir.any():  # no joint slides with Coulomb friction
            return out
        sliding = (fdir * y1[n : 2 * n] < -STICK_SPEED).nonzero()[0]
        for j in sliding.tolist():

            def gs(t: float, j: int = j) -> float:
                return float(fdir[j] * seg(t)[n + j])

            g0 = float(fdir[j] * seg.y0[n + j])
            g1 = float(fdir[j] * y1[n + j])
            fn: Callable[[float], float] = gs
            if g0 <= 0.0:  # it slipped from rest at the step's start (v = 0)
                if (late := return_crossing(gs, seg.t0, seg.t1)) is not None:
                    fn, g0 = late  # it moved the way it slips, then turned: its return
                else:  # it turns at once (its mobility ~0): it sticks at STICK_SPEED the other way

                    def gt(t: float, j: int = j) -> float:
                        return gs(t, j) + STICK_SPEED

                    fn, g0, g1 = gt, STICK_SPEED, g1 + STICK_SPEED
            out.append(Crossing("stick", ("stick", j), fn, g0, g1))
        return out

    def _handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """The report's handling (and the stops' and holds'): events applied in turn."""
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        fdir = self.drive.fdir
        flip: int | None = None
        stick: list[int] = []
        for c in sorted(crossings, key=lambda c: c.kind != "release"):
            if c.kind in ("impact", "secondary_intersection", "release"):
                v = self._pair_event(t, y, q, v, c)
            elif c.kind == "limit":
                v = self.limit(t, q, v, c.key[1], c.key[2])
            elif c.kind == "slip":
                j = c.key[1]
                lam = self.hold_torque(t, self.with_v(y, v), j)
                self.locks.set_held({k: b for k, b in self.locks.held.items() if k != j})
                fdir[j] = -math.copysign(1.0, lam)
                self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
            elif c.kind == "stick":
                j = c.key[1]
                v[j] = 0.0
                fdir[j] = 0.0
                stick.append(j)
            else:  # engage / disengage
                flip = c.key[1]
                self.log_event(t, c.kind, q, v, v, None, joints=(self.sys.names[flip],), joint=flip)
        y_new = self.with_v(y, v)
        self.settle_modes(t, y_new, flip=flip, candidates=stick, log_stick=True)
        return y_new

    def hold_torque(self, t: float, y: FloatArray, j: int) -> float:
        """The torque [N*m] joint j's lock needs at (t, y) with the current locked set (and j)."""
        n = self.n
        a_free = self.free_accel(t, y)
        held = dict(self.locks.held)
        if j not in held:
            self.locks.set_held({**held, j: 0.0})
        _, lam = self.locks.torques(a_free, self.sys.minv(y[:n]))
        self.locks.set_held(held)
        return lam[j]

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
            candidates: Joints with Coulomb friction that just stopped: they stick if the
                holding torque is within their bound, else they slide on in the direction of
                the net torque.
            log_stick: Log a ``stick`` event for each candidate that sticks.
        """
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        fdir = self.drive.fdir
        self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
        bound = self.drive.path.coulomb
        held = {j: b for j, b in self.locks.held.items() if bound[j] > 0}
        for j in [j for j in held if abs(v[j]) > STICK_SPEED]:
            # An impulse (a limit stop's, a momentum reset's) set a held joint moving: a bounded
            # torque does nothing in an instant, so it slides now, its friction opposing.
            del held[j]
            fdir[j] = math.copysign(1.0, v[j])
            self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
        self.locks.set_held(held)
        for j in np.flatnonzero(bound > 0).tolist():  # directions of the sliding joints
            if j not in held and j not in candidates:
                if abs(v[j]) > STICK_SPEED:
                    fdir[j] = math.copysign(1.0, v[j])
                elif fdir[j] == 0.0:
                    candidates = [*candidates, j]
        if not (self.locks.signs or self.locks.held or candidates):
            return
        minv = self.sys.minv(q)
        if self.locks.signs:
            self._solve_engaged(t, y, minv, flip)
        if candidates:
            for j in candidates:
                fdir[j] = 0.0
            trial = {**self.locks.held, **{j: float(bound[j]) for j in candidates}}
            self.locks.set_held(trial)
            _, lam = self.locks.torques(self.free_accel(t, y), minv)
            keep = dict(self.locks.held)
            for j in candidates:
                signs = self.locks.signs.get(j, set())
                # a contact clamp may supply the torque: both ways (bilateral), or pushing
                pushes = len(signs) == 2 or (len(signs) == 1 and -next(iter(signs)) * lam[j] >= 0)
                if abs(lam[j]) <= bound[j] + 0.5 * TORQUE_BAND or pushes:
                    if log_stick:
                        self.log_event(
                            t, "stick", q, v, v, None, joints=(self.sys.names[j],), joint=j
                        )
                else:
                    keep.pop(j)
                    fdir[j] = -math.copysign(1.0, lam[j])
                    self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
            self.locks.set_held(keep)
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
        """Apply the reset rule on ``rel``, widened where it would push a clamped joint.

        The widening takes in every clamped joint that the impulse would set moving toward its
        own contact: one simultaneous impact, not a cascade of secondary ones; and every held
        joint (friction, a brake) that it would set moving slower than :data:`HOLD_KICK`
        (acted on, a held joint keeps v = 0: -e times its speed before).

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
        acted = np.array(sorted(set(rel.tolist())), dtype=np.intp)
        clamps = self._widening_clamps()
        held = self.locks.held
        for _ in range(self.n + 1):
            v_new = impact_reset(v, acted, e, rule, minv)
            tiny = 1e-12 * (1.0 + float(np.abs(v).max()))
            done = set(acted.tolist())
            more = {j for j, s in clamps if s * v_new[j] > tiny and j not in done}
            more |= {  # a held joint barely kicked stays held: the impulse acts on it too
                j for j in held if STICK_SPEED < abs(v_new[j]) <= HOLD_KICK and j not in done
            }
            if not more:
                return v_new, acted
            acted = np.array(sorted(set(acted.tolist()) | more), dtype=np.intp)
        return v_new, acted

    def _widening_clamps(self) -> list[tuple[int, int]]:
        """The clamps (joint, s) a reset is widened for: those of the active contacts."""
        return [cl for a in self.active.values() for cl in a.clamps]

    def limit(self, t: float, q: FloatArray, v: FloatArray, j: int, side: int) -> FloatArray:
        """Joint j reached its upper (side +1) or lower (-1) stop: impulse and clamp."""
        self.active[("limit", j, side)] = Active(None, [(j, side)])
        v_new, acted = v, np.array([j])
        if side * v[j] > 0.0:
            # A limit stop is a hard stop on this joint alone: a joint-space impulse on it (the
            # "momentum" law, never adding energy for e <= 1), whatever reset_rule says (the
            # report's "zero" rule is its law for link collisions; on a stop it can add energy).
            v_new, acted = self.reset(q, v, np.array([j]), rule="momentum")
            if side * v_new[j] < 0.0:  # it bounced (e > 0): it leaves the stop, nothing to clamp
                self.active.pop(("limit", j, side))
        elif side * v[j] < 0.0:
            # On its stop and leaving it, but too slowly to get off it (the step restarted here
            # found no time with the joint off the stop: the accumulation point of its bounces):
            # it comes to rest on the stop, the clamp then holds it at zero speed (no work).
            v_new, acted = self.reset(q, v, np.array([j]), rule="momentum", restitution=0.0)
        lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
        ev_before, ev_after = self.energy(q, v), self.energy(q, v_new)
        self.note_reset(ev_before, ev_after)
        self.events.log(
            Event(
                t,
                "limit",
                self.sys.names[j],
                "upper" if side > 0 else "lower",
                "",
                "",
                float(side * (lim - q[j])),
                tuple(self.sys.names[i] for i in acted),
                self.sys.v_full(v),
                self.sys.v_full(v_new),
                ev_before,
                ev_after,
            ),
            count=False,
        )
        return v_new

    def release_limits(self, t: float, y: FloatArray) -> None:
        """Limit stops let go when the joint has left the stop (moving away)."""
        for key in [k for k in self.active if k[0] == "limit"]:
            _, j, side = key
            lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
            # Left the stop (an engaged lock would keep a receding joint's speed: work done).
            held = self._limit_held(j, side)
            if side * (lim - y[j]) > 1e-6 and not held:
                self._release_limit(t, y, j, side)
                self.apply_clamps()

    def _release_limit(self, t: float, y: FloatArray, j: int, side: int) -> None:
        """Drop the stop of joint j (side +1 upper, -1 lower); a ``release`` event."""
        n = self.n
        lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
        self._drop_limit(j, side)
        self.active.pop(("limit", j, side))
        energy = self.energy(y[:n], y[n : 2 * n])
        self.events.log(
            Event(
                t,
                "release",
                self.sys.names[j],
                "upper" if side > 0 else "lower",
                distance=float(side * (lim - y[j])),
                relevant_joints=(self.sys.names[j],),
                v_before=self.sys.v_full(y[n : 2 * n]),
                v_after=self.sys.v_full(y[n : 2 * n]),
                energy_before=energy,
                energy_after=energy,
            ),
            count=False,
        )

    def log_event(
        self,
        t: float,
        kind: str,
        q: FloatArray,
        v0: FloatArray,
        v1: FloatArray,
        pair: PairInfo | None,
        d: float = math.nan,
        joints: tuple[str, ...] = (),
        joint: int | None = None,
    ) -> Event:
        """Log an event (energies before and after, full velocities) to the run's event log.

        Returns:
            The event logged.
        """
        e0 = self.energy(q, v0)
        e1 = e0 if v1 is v0 else self.energy(q, v1)
        event = Event(
            t,
            kind,
            pair.link1 if pair else (self.sys.names[joint] if joint is not None else ""),
            pair.link2 if pair else "",
            pair.piece1 if pair else "",
            pair.piece2 if pair else "",
            d,
            joints,
            self.sys.v_full(v0),
            self.sys.v_full(v1),
            e0,
            e1,
        )
        self.events.log(event)
        return event

    def note_reset(self, energy_before: float, energy_after: float) -> None:
        """Count a velocity reset's energy gain in ``Diagnostics.reset_energy_gain`` [J].

        Args:
            energy_before: Total energy before the reset [J].
            energy_after: Total energy after it [J]; only a rise counts (a loss is not a gain).
        """
        self.diag.reset_energy_gain += max(0.0, energy_after - energy_before)
