"""The joint holds: a pool of the joints that Coulomb friction or a brake holds still.

A joint with Coulomb friction (or a brake, a bound F_j [N*m]) that stops sticks while the
torque holding it stays within F_j (a friction hold: a joint lock of
:class:`~packbot.contact.locks.JointLocks`), and slips once it would need more (``slip``,
sliding the way that torque pushes); a sliding joint whose speed falls through zero stops
(``stick``) and becomes a candidate that sticks or slides on. The sliding directions live in
the drive (``Drive.fdir``: the torques read them). :class:`JointHolds` holds these rules for
one phase: the holds' and the locks' sign conditions as event functions, the ``slip`` and
``stick`` events, and the settling of the held set after any change; the law gives it its
joint locks (which a time-stepping window replaces) and its lock conditions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from packbot.contact.base import Crossing
from packbot.contact.law_log import LawLog
from packbot.contact.locks import TORQUE_BAND, JointLocks
from packbot.contact.position_stops import return_crossing
from packbot.drive import Drive
from packbot.ode import DenseSegment
from packbot.system import System

__all__ = ["STICK_SPEED", "JointHolds", "friction_share"]

FloatArray = NDArray[np.float64]
#: Joint speed below which a joint with Coulomb friction counts as stopped (it may stick) [rad/s].
STICK_SPEED = 1e-9
#: The locks' and holds' sign conditions at (t, y) (``JointLocks.conditions``, or the law's own).
Conditions = Callable[[float, FloatArray], dict[tuple[str, int], float]]


def friction_share(torque: float, bound: float) -> float:
    """The part [N*m] of a held joint's holding torque that its friction or brake carries.

    Within the bound F_j all of it; beyond it (a contact's clamp on the joint pushes too, which
    may supply any torque) the friction carries F_j and the contact the rest.

    Args:
        torque: The torque holding the joint [N*m].
        bound: The joint's friction or brake bound F_j [N*m].
    """
    return float(math.copysign(min(abs(torque), bound), torque))


class JointHolds:
    """The friction holds of one phase (Coulomb friction, brakes) and their events.

    Args:
        system: The phase's integrated system (joint names).
        drive: The run's torques (the bounds ``drive.path.coulomb``, the directions ``fdir``).
        log: The law's event writer.
    """

    def __init__(self, system: System, drive: Drive, log: LawLog) -> None:
        self.n = system.nv
        self.names = system.names
        self.drive = drive
        self.log = log

    def _log(self, t: float, kind: str, q: FloatArray, v: FloatArray, j: int) -> None:
        """Log a joint's hold event (``slip``, ``stick``) at (t, q, v)."""
        self.log.event(t, kind, q, v, v, None, joints=(self.names[j],), joint=j)

    def crossings(
        self,
        seg: DenseSegment,
        y1: FloatArray,
        locks: JointLocks,
        conditions: Conditions,
        screened: Callable[[FloatArray], bool],
    ) -> list[Crossing]:
        """The locks' and holds' sign conditions that changed sign, then the joints that stopped.

        Args:
            seg: The step.
            y1: Its end.
            locks: The law's joint locks.
            conditions: The locks' and holds' conditions at (t, y).
            screened: Whether the step's native end found every condition clearly kept.
        """
        n, out = self.n, []
        if locks.conditional and not screened(y1):
            cond1 = conditions(seg.t1, y1)
            bad = [k for k, g in cond1.items() if g < 0.0]
            if bad:
                cond0 = conditions(seg.t0, seg.y0)
                for k in bad:

                    def gl(t: float, k: tuple[str, int] = k) -> float:
                        return conditions(t, seg(t))[k]

                    kind, j = k
                    if kind == "hold":
                        kind = "slip"
                    else:
                        kind = "disengage" if j in locks.engaged else "engage"
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

    def event(
        self,
        t: float,
        q: FloatArray,
        v: FloatArray,
        c: Crossing,
        locks: JointLocks,
        hold_torque: Callable[[int], float],
        stick: list[int],
    ) -> FloatArray:
        """A held joint slips, or a sliding one stops (kind ``slip``, ``stick``); new v.

        The slip takes the direction of the torque the hold needed (``hold_torque(j)``, at
        the state with the velocities v); a stopped joint joins ``stick``, the candidates that
        :meth:`settle` holds or lets slide on.
        """
        j = c.key[1]
        fdir = self.drive.fdir
        if c.kind == "slip":
            lam = hold_torque(j)
            locks.set_held({k: b for k, b in locks.held.items() if k != j})
            fdir[j] = -math.copysign(1.0, lam)
            self._log(t, "slip", q, v, j)
        elif c.kind == "stick":
            v = v.copy()
            v[j] = 0.0
            fdir[j] = 0.0
            stick.append(j)
        return v

    def torque(
        self, j: int, locks: JointLocks, a_free: FloatArray, minv: Callable[[], FloatArray]
    ) -> float:
        """The torque [N*m] joint j's lock needs with the current locked set (and j).

        Args:
            j: The joint.
            locks: The law's joint locks (j held for the solve, if it is not).
            a_free: The free accelerations [rad/s^2].
            minv: M^-1 at the state.
        """
        held = dict(locks.held)
        if j not in held:
            locks.set_held({**held, j: 0.0})
        _, lam = locks.torques(a_free, minv())
        locks.set_held(held)
        return float(lam[j])

    def moving(
        self, t: float, q: FloatArray, v: FloatArray, locks: JointLocks, candidates: Sequence[int]
    ) -> Sequence[int]:
        """The held joints that move slip, the sliding joints' directions; the candidates.

        An impulse (a limit stop's, a momentum reset's) that set a held joint moving lets it
        slide now, its friction opposing (a bounded torque does nothing in an instant). A
        sliding joint slides the way it moves; a stopped one not held is a candidate too.
        """
        fdir = self.drive.fdir
        bound = self.drive.path.coulomb
        held = {j: b for j, b in locks.held.items() if bound[j] > 0}
        for j in [j for j in held if abs(v[j]) > STICK_SPEED]:
            del held[j]
            fdir[j] = math.copysign(1.0, v[j])
            self._log(t, "slip", q, v, j)
        locks.set_held(held)
        for j in np.flatnonzero(bound > 0).tolist():  # directions of the sliding joints
            if j not in held and j not in candidates:
                if abs(v[j]) > STICK_SPEED:
                    fdir[j] = math.copysign(1.0, v[j])
                elif fdir[j] == 0.0:
                    candidates = [*candidates, j]
        return candidates

    def settle(
        self,
        t: float,
        q: FloatArray,
        v: FloatArray,
        locks: JointLocks,
        candidates: Sequence[int],
        a_free: Callable[[], FloatArray],
        minv: FloatArray,
        log_stick: bool,
    ) -> None:
        """The stopped candidates stick, or slide on in the direction of the net torque.

        Each sticks if its holding torque (all the candidates held at their bounds, the free
        accelerations ``a_free()``) is within its bound, or a contact clamp on it supplies the
        torque (both ways, or pushing); ``log_stick``: a ``stick`` event for each.
        """
        fdir = self.drive.fdir
        bound = self.drive.path.coulomb
        for j in candidates:
            fdir[j] = 0.0
        trial = {**locks.held, **{j: float(bound[j]) for j in candidates}}
        locks.set_held(trial)
        _, lam = locks.torques(a_free(), minv)
        keep = dict(locks.held)
        for j in candidates:
            signs = locks.signs.get(j, set())
            # a contact clamp may supply the torque: both ways (bilateral), or pushing
            pushes = len(signs) == 2 or (len(signs) == 1 and -next(iter(signs)) * lam[j] >= 0)
            if abs(lam[j]) <= bound[j] + 0.5 * TORQUE_BAND or pushes:
                if log_stick:
                    self._log(t, "stick", q, v, j)
            else:
                keep.pop(j)
                fdir[j] = -math.copysign(1.0, lam[j])
                self._log(t, "slip", q, v, j)
        locks.set_held(keep)

    def friction(
        self,
        q: FloatArray,
        v: FloatArray,
        applied: FloatArray,
        friction: FloatArray,
        locks: JointLocks,
        system: System,
    ) -> FloatArray:
        """The friction torques [N*m] with each held joint's holding torque in place.

        ``friction`` itself when no joint is held. A held joint that a contact's clamp also
        pushes (its lock torque beyond the bound F_j, :class:`~packbot.contact.locks.
        JointLocks`) is reported with its friction at the bound, the rest being the contact's
        (:func:`friction_share`).
        """
        if locks.held:
            friction = friction.copy()
            a_free = system.aba(q, v, applied + friction)
            _, lam = locks.torques(a_free, system.minv(q))
            for j, bound in locks.held.items():
                friction[j] = friction_share(lam[j], bound)
        return friction
