"""The 2010 report's impact law (``contact_mode="joint_clamp"``).

At an impact between two bodies, the *relevant joints* are those whose motion changes the gap:
joint i is relevant if ``|J_n,i| > threshold * ||J_n||``, where ``J_n = n^T (J_p2 - J_p1)`` is
the normal row of the contact Jacobian at the witness points (n from body 1 to body 2, so the
gap rate is ``d' = J_n v``... with the sign convention ``p2 - p1 = d n``: ``d' = n^T (v_p2 -
v_p1) = J_n v``). This includes the turret and the camera pan, which the report skipped.

Velocity reset, on the relevant joints R (e = restitution), ``reset_rule``: ``"zero"`` (the
report's: ``v_i <- -e v_i`` for i in R; on a coupled arm this can *add* kinetic energy) or
``"momentum"`` (an impulsive torque on the joints of R only, the other joints keeping their
generalized momentum; never adds energy for e <= 1): :mod:`packbot.contact.resets`, whose
impulse the limit stops use too. A reset that would set a joint clamped by another contact
moving toward it is widened to that joint.

Clamp directions (the direction in which a clamped joint may not accelerate):

- ``"velocity"`` (the report's): ``s_i = sign(v_i)`` at impact (the direction it was moving);
  wrong for a joint whose motion was overwhelmed by another's; a joint that was not moving
  (``|v_i| <= STILL_SPEED``) takes the Jacobian sign;
- ``"jacobian"``: ``s_i = -sign(J_n,i)``, the direction in which the joint's own motion closes
  the gap.

A clamp never does positive work. An engaged clamp holds its joint at a_j = 0 with a torque
lambda_j that pushes away from the contact (s_j lambda_j <= 0); if the joint is then moving
*away* from the contact (s_j v_j < 0: after a rebound, e > 0, or an impulse on the joints it is
coupled to), the lock would keep that speed and its power lambda_j v_j would be positive: the
joint climbs against gravity (a shoulder dropped on the floor with e = 1 gained 0.37 J in 1.5 s).
So whenever the locks' engaged set is chosen, an engaged clamp on a receding joint
(``s_j v_j < -RECEDE_SPEED``) is *released* (a ``release`` event naming the pair and, in
``relevant_joints``, the joint; the pair stays active) and the set chosen again
(:meth:`~packbot.contact.stops.JointStops._solve_engaged`). It comes back into force when its
joint turns toward the contact again (``s_j v_j`` through 0: an ``engage`` event, at zero speed,
where the lock does no work), unless the pair has separated beyond the proximity tolerance
first; a pair whose clamps are all released that comes back to the contact tolerance is an
``impact`` again. The same rule as a limit stop's: a joint leaving its stop is not clamped.

A pair restarted at d = 0 exactly (a secondary intersection located on its event side: Coal's
distance of touching pieces) that rebounds is not found again at the step's start: its next
``secondary_intersection`` is its return to d = 0, approaching, where the law applies its reset
(:func:`~packbot.contact.position_stops.return_crossing`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from packbot.contact.base import Active, Crossing, Key
from packbot.contact.pairs import PairLaw
from packbot.contact.position_stops import return_crossing
from packbot.contact.resets import impact_reset
from packbot.ode import DenseSegment
from packbot.system import System

__all__ = ["STILL_SPEED", "JointClampLaw", "clamp_directions", "impact_reset", "relevant_joints"]

FloatArray = NDArray[np.float64]


def relevant_joints(Jn: FloatArray, threshold: float) -> NDArray[np.intp]:
    """Indices i with ``|J_n,i| > threshold * ||J_n||`` (none if J_n is zero)."""
    norm = float(np.linalg.norm(Jn))
    if norm == 0.0:
        return np.zeros(0, dtype=np.intp)
    return np.flatnonzero(np.abs(Jn) > threshold * norm)


#: Below this joint speed [rad/s] the ``"velocity"`` rule has no direction to read (a joint
#: stopped by an earlier impact carries only rounding residue, ~1e-16): the Jacobian sign is used.
STILL_SPEED = 1e-9


def clamp_directions(
    v_before: FloatArray, Jn: FloatArray, relevant: NDArray[np.intp], rule: str
) -> list[tuple[int, int]]:
    """(joint, sign) clamps of an impact: sign is the forbidden acceleration direction."""
    out = []
    for i in relevant:
        s = -np.sign(Jn[i])
        if rule == "velocity" and abs(v_before[i]) > STILL_SPEED:
            s = np.sign(v_before[i])
        out.append((int(i), int(s) if s != 0 else 1))
    return out


def _ident(d: float) -> float:
    """The secondary intersection's event function of the distance d [m]: d itself."""
    return d


class JointClampLaw(PairLaw):
    """The report's law (``contact_mode="joint_clamp"``): impact, reset, clamps.

    Pair events: ``impact`` when an inactive pair's distance falls to the contact tolerance
    (the reset on the relevant joints, widened; the pair's clamps); ``release`` when an active
    pair separates beyond the proximity tolerance (its clamps removed);
    ``secondary_intersection`` when an active, clamped pair's distance falls below zero (the
    report's self-diagnosis: logged, and the law applied again with the current geometry, the
    clamps merged). A clamp on a receding joint is released and comes back when the joint turns
    (module docstring). Same arguments as :class:`~packbot.contact.stops.JointStops`.

    Attributes:
        receding: Pair key -> the clamps (joint, s) of that active pair released because their
            joint moved away from the contact; each comes back into force when its joint turns.
    """

    def rebuild(self, system: System) -> None:
        """A new phase: no contact, no released clamp."""
        super().rebuild(system)
        self.receding: dict[Key, list[tuple[int, int]]] = {}

    def handle(self, t: float, y: FloatArray, crossings: Sequence[Crossing]) -> FloatArray:
        """The events at t; a released clamp whose joint turned is back in force first."""
        for c in crossings:
            if c.key[0] == "recede":
                self._restore(c.key[2], c.key[3])
        return super().handle(t, y, crossings)

    def _restore(self, key: Key, clamp: tuple[int, int]) -> None:
        """A released clamp of pair ``key`` back in force (if the pair is still active)."""
        rest = [cl for cl in self.receding.get(key, []) if cl != clamp]
        if rest:
            self.receding[key] = rest
        else:
            self.receding.pop(key, None)
        if key in self.active and clamp not in self.active[key].clamps:
            self.active[key].clamps.append(clamp)

    def _widening_clamps(self) -> list[tuple[int, int]]:
        """The clamps in force and the released ones (an impulse may turn a receding joint)."""
        out = super()._widening_clamps()
        for key, clamps in self.receding.items():
            if key in self.active:
                out.extend(clamps)
        return out

    def _contact_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        out = super()._contact_crossings(seg, y1)
        if self.receding:
            out.extend(self._turn_crossings(seg, y1))
        return out

    def _turn_crossings(self, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
        """A released clamp's joint that turned toward its contact (s v_j through 0)."""
        n, out = self.n, []
        self.receding = {k: cl for k, cl in self.receding.items() if k in self.active}
        for key, clamps in self.receding.items():
            for j, s in clamps:
                g1 = float(-s * y1[n + j])
                if g1 > 0.0:
                    continue

                def g(t: float, j: int = j, s: int = s) -> float:
                    return float(-s * seg(t)[n + j])

                g0 = float(-s * seg.y0[n + j])
                out.append(Crossing("engage", ("recede", j, key, (j, s)), g, g0, g1))
        return out

    def _solve_engaged(self, t: float, y: FloatArray, minv: FloatArray, flip: int | None) -> None:
        """The engaged set, released clamps whose joint an impulse stopped or turned back first.

        Then the base rule: an engaged clamp on a receding joint lets go (:meth:`_let_go`).
        """
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        back = [
            (key, cl)
            for key, clamps in self.receding.items()
            if key in self.active
            for cl in clamps
            if cl[1] * v[cl[0]] >= -STILL_SPEED
        ]
        for key, cl in back:  # an impulse stopped or turned a receding joint: clamped again
            self._restore(key, cl)
            self.log_event(t, "engage", q, v, v, None, joints=(self.sys.names[cl[0]],), joint=cl[0])
        if back:
            self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
        super()._solve_engaged(t, y, minv, flip)

    def _let_go(self, t: float, y: FloatArray, key: Key, clamp: tuple[int, int]) -> None:
        """A pair's clamp on a receding joint is released until the joint turns."""
        if key[0] == "pair":
            self._recede(t, y, key, clamp)
        else:
            super()._let_go(t, y, key, clamp)

    def _recede(self, t: float, y: FloatArray, key: Key, clamp: tuple[int, int]) -> None:
        """Release clamp (j, s) of the active pair ``key``: its joint moves away (logged).

        The pair stays active; the clamp waits in ``receding`` for its joint to turn. The event
        is a ``release`` naming the pair and, in ``relevant_joints``, the joint released (a
        pair's own release names no joint).
        """
        n = self.n
        act = self.active[key]
        act.clamps.remove(clamp)
        self.receding.setdefault(key, []).append(clamp)
        assert act.pair is not None
        v = y[n : 2 * n]
        self.log_event(
            t,
            "release",
            y[:n],
            v,
            v,
            act.pair,
            d=self.distance(act.pair.index, y),
            joints=(self.sys.names[clamp[0]],),
        )

    def _pairs_to_check(self, pairs: list[int], distances: list[float]) -> Iterable[int]:
        """The pairs that can have an event: the active ones, and those within reach.

        Within the contact tolerance (an inactive pair farther away has none:
        :meth:`_pair_crossings`). A subclass with its own pair events (the hand-off's
        handed-off pairs) checks them all.
        """
        if type(self)._pair_crossings is not JointClampLaw._pair_crossings:
            return super()._pairs_to_check(pairs, distances)
        tol = self.cfg.contact_tolerance
        active = self.active
        if not active:
            return [i for i, d in enumerate(distances) if d <= tol]
        return [i for i, d in enumerate(distances) if d <= tol or ("pair", pairs[i]) in active]

    def _pair_crossings(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[Crossing]:
        cfg = self.cfg
        if key in self.active:
            if d1 > cfg.proximity_tolerance:
                return [
                    self._pair_crossing(
                        "release", key, p_idx, seg, d0, d1, lambda d: cfg.proximity_tolerance - d
                    )
                ]
            released = not self.active[key].clamps and key in self.receding
            if released and d1 <= cfg.contact_tolerance < d0:
                # Every clamp of the pair released (it rebounds): coming back to the contact
                # tolerance, it is an impact again (the law: reset, new clamps).
                return [
                    self._pair_crossing(
                        "impact", key, p_idx, seg, d0, d1, lambda d: d - cfg.contact_tolerance
                    )
                ]
            if d1 < 0.0 <= d0:
                return [self._surface_crossing(key, p_idx, seg, d0, d1)]
            return []
        if d1 <= cfg.contact_tolerance:
            return [
                self._pair_crossing(
                    "impact", key, p_idx, seg, d0, d1, lambda d: d - cfg.contact_tolerance
                )
            ]
        return []

    def _surface_crossing(
        self, key: Key, p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> Crossing:
        """An active pair's distance falling below zero over the step: a secondary intersection.

        A step that starts on the surface (d0 = 0: the pair's last event left it exactly
        touching, Coal's distance of two touching pieces) has two cases. If the pair leaves the
        surface first (it is not approaching: a resting or separating contact, e.g. after a
        rebound), the event is its *return* to d = 0 later in the step, approaching, where the
        law applies its reset; it is located from the first time found with d > 0 (halving the
        step from its start). If the distance is below zero arbitrarily close to the step's
        start, the pair penetrates at once: the event is at the step's start (the law again).
        """
        if d0 > 0.0:
            return self._pair_crossing("secondary_intersection", key, p_idx, seg, d0, d1, _ident)

        def g(t: float) -> float:
            return self.distance(p_idx, seg(t))

        late = return_crossing(g, seg.t0, seg.t1)
        if late is not None:  # off the surface first: the event is the pair's return
            return Crossing("secondary_intersection", key, late[0], late[1], d1)
        return Crossing("secondary_intersection", key, g, d0, d1)

    def _pair_event(
        self, t: float, y: FloatArray, q: FloatArray, v: FloatArray, c: Crossing
    ) -> FloatArray:
        if c.kind == "release":
            self.receding.pop(c.key, None)
            act = self.active.pop(c.key, None)
            if act is not None and act.pair is not None:
                self.log_event(t, "release", q, v, v, act.pair, d=self.distance(act.pair.index, y))
            return v
        return self.impact(t, q, v, c.key[1], c.kind)

    def impact(self, t: float, q: FloatArray, v: FloatArray, p_idx: int, kind: str) -> FloatArray:
        """The law at pair p_idx: relevant joints, clamps, the reset if approaching; logged."""
        cfg = self.cfg
        c = self.world.pair_contact(q, p_idx)
        J1 = self.sys.point_jacobian(q, c.pair.joint1, c.p1)
        J2 = self.sys.point_jacobian(q, c.pair.joint2, c.p2)
        Jn = c.normal @ (J2 - J1)
        rel = relevant_joints(Jn, cfg.relevant_threshold)
        clamps = clamp_directions(v, Jn, rel, cfg.clamp_rule)
        key = ("pair", p_idx)
        if key in self.active:  # secondary intersection: add the new clamps
            old = self.active[key].clamps
            clamps = sorted(set(old) | set(clamps))
        self.receding.pop(key, None)  # the law again: its clamps are the merged ones
        self.active[key] = Active(c.pair, clamps)
        v_new, acted = v, rel
        if float(Jn @ v) < 0.0 and len(rel):  # approaching: apply the reset
            v_new, acted = self.reset(q, v, rel)
        event = self.log_event(
            t,
            kind,
            q,
            v,
            v_new,
            c.pair,
            d=c.distance,
            joints=tuple(self.sys.names[i] for i in acted),
        )
        self.log.reset_gain(event.energy_before, event.energy_after)
        return v_new
