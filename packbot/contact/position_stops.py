"""The joint position stops: a pool of one-sided constraints every law holds.

A joint reaching a position limit (event ``limit``) gets a joint-space impulse on that joint
alone (the ``momentum`` rule of :func:`~packbot.contact.stops.impact_reset`, whatever
``reset_rule`` says: on a stop the report's ``zero`` rule can add energy) and a clamp, unless
it bounces off (e > 0); the stop lets go once the joint has left it by :data:`LEAVE_GAP` (a
``release`` after an accepted step). :class:`PositionStops` finds the stops present at a
phase's start and those reached over a step, applies a stop's impulse and says which stops
were left; the law keeps the stops engaged among its active contacts (keys ``("limit", joint,
side)``, side +1 for the upper stop and -1 for the lower one) and logs through its
:class:`~packbot.contact.law_log.LawLog`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
from numpy.typing import NDArray

from packbot.config import SimConfig
from packbot.contact.base import Active, Crossing, Key
from packbot.contact.law_log import LawLog
from packbot.ode import DenseSegment
from packbot.result import Event
from packbot.system import System

__all__ = ["LEAVE_GAP", "RETURN_DT", "PositionStops", "return_crossing"]

FloatArray = NDArray[np.float64]
#: Resolution [s] of :func:`return_crossing`'s search (the event loop locates events to 1e-10 s).
RETURN_DT = 1e-10
#: A joint this far off its stop [rad] (moving away) has left it: the stop lets go.
LEAVE_GAP = 1e-6
#: ``reset(q, v, joints, rule, restitution)``: the law's velocity reset on ``joints`` (widened
#: where it would push a clamped joint): the velocities after and the joints acted on.
Reset = Callable[..., tuple[FloatArray, NDArray[np.intp]]]


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


class PositionStops:
    """The joint position stops of one phase (none when ``SimConfig.joint_limits`` is off).

    Args:
        system: The phase's integrated system (its limits, joint names, energies).
        config: Simulation settings (``joint_limits``).
        log: The law's event writer.
    """

    def __init__(self, system: System, config: SimConfig, log: LawLog) -> None:
        self.sys = system
        self.on = config.joint_limits
        self.log = log

    def limit(self, j: int, side: int) -> float:
        """Joint j's upper (side +1) or lower (-1) limit [rad]."""
        return float(self.sys.upper[j] if side > 0 else self.sys.lower[j])

    def present(self, y: FloatArray) -> list[Crossing]:
        """The stops the joints are on (or past) at state y, as crossings at that instant."""
        out: list[Crossing] = []
        if not self.on:
            return out
        for j in range(self.sys.nv):
            for side, lim in ((1, self.sys.upper[j]), (-1, self.sys.lower[j])):
                if side * (lim - y[j]) <= 0.0:
                    out.append(Crossing("limit", ("limit", j, side), lambda t: 0.0, 0.0, 0.0))
        return out

    def crossings(
        self, seg: DenseSegment, y1: FloatArray, active: dict[Key, Active]
    ) -> list[Crossing]:
        """The stops not engaged (not in ``active``) that a joint reached over the step."""
        out: list[Crossing] = []
        if not self.on:
            return out
        q1 = y1[: self.sys.nv]  # numpy screen first: a limit crossing is rare
        upper, lower = self.sys.upper, self.sys.lower
        for j in ((q1 >= upper) | (q1 <= lower)).nonzero()[0].tolist():
            side, lim = (1, upper[j]) if q1[j] >= upper[j] else (-1, lower[j])
            if ("limit", j, side) in active:
                continue

            def g(t: float, j: int = j, side: int = side, lim: float = lim) -> float:
                return float(side * (lim - seg(t)[j]))

            fn: Callable[[float], float] = g
            g0 = side * (lim - seg.y0[j])
            if g0 <= 0.0 and (late := return_crossing(g, seg.t0, seg.t1)) is not None:
                fn, g0 = late  # it left the stop (a bounce): the event is its return
            out.append(Crossing("limit", ("limit", j, side), fn, g0, side * (lim - q1[j])))
        return out

    def hit(
        self,
        t: float,
        q: FloatArray,
        v: FloatArray,
        j: int,
        side: int,
        active: dict[Key, Active],
        reset: Reset,
    ) -> FloatArray:
        """Joint j reached its upper (side +1) or lower (-1) stop: impulse and clamp; new v.

        The stop's clamp goes into ``active``; the impulse is ``reset``'s (the law's, widened).
        """
        active[("limit", j, side)] = Active(None, [(j, side)])
        v_new, acted = v, np.array([j])
        if side * v[j] > 0.0:
            # A limit stop is a hard stop on this joint alone: a joint-space impulse on it (the
            # "momentum" law, never adding energy for e <= 1), whatever reset_rule says (the
            # report's "zero" rule is its law for link collisions; on a stop it can add energy).
            v_new, acted = reset(q, v, np.array([j]), rule="momentum")
            if side * v_new[j] < 0.0:  # it bounced (e > 0): it leaves the stop, nothing to clamp
                active.pop(("limit", j, side))
        elif side * v[j] < 0.0:
            # On its stop and leaving it, but too slowly to get off it (the step restarted here
            # found no time with the joint off the stop: the accumulation point of its bounces):
            # it comes to rest on the stop, the clamp then holds it at zero speed (no work).
            v_new, acted = reset(q, v, np.array([j]), rule="momentum", restitution=0.0)
        sys, log = self.sys, self.log
        ev_before, ev_after = log.energy(q, v), log.energy(q, v_new)
        log.reset_gain(ev_before, ev_after)
        log.events.log(
            Event(
                t,
                "limit",
                sys.names[j],
                "upper" if side > 0 else "lower",
                "",
                "",
                float(side * (self.limit(j, side) - q[j])),
                tuple(sys.names[i] for i in acted),
                sys.v_full(v),
                sys.v_full(v_new),
                ev_before,
                ev_after,
            ),
            count=False,
        )
        return v_new

    def left(
        self, y: FloatArray, active: dict[Key, Active], held: Callable[[int, int], bool]
    ) -> Iterator[tuple[int, int]]:
        """The engaged stops (j, side) whose joint has left them at y (moving away), in turn.

        ``held(j, side)``: whether the law's own constraint on the stop still holds its joint
        (then it is not left: an engaged lock would keep a receding joint's speed, work done),
        asked of each stop after the law released those before it.
        """
        for key in [k for k in active if k[0] == "limit"]:
            _, j, side = key
            if side * (self.limit(j, side) - y[j]) > LEAVE_GAP and not held(j, side):
                yield j, side

    def release(
        self, t: float, y: FloatArray, j: int, side: int, active: dict[Key, Active]
    ) -> None:
        """Drop the stop of joint j (side +1 upper, -1 lower) from ``active``; a ``release``."""
        sys = self.sys
        n = sys.nv
        active.pop(("limit", j, side))
        energy = self.log.energy(y[:n], y[n : 2 * n])
        self.log.events.log(
            Event(
                t,
                "release",
                sys.names[j],
                "upper" if side > 0 else "lower",
                distance=float(side * (self.limit(j, side) - y[j])),
                relevant_joints=(sys.names[j],),
                v_before=sys.v_full(y[n : 2 * n]),
                v_after=sys.v_full(y[n : 2 * n]),
                energy_before=energy,
                energy_after=energy,
            ),
            count=False,
        )
