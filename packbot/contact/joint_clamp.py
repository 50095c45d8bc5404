"""The 2010 report's impact law (``contact_mode="joint_clamp"``).

At an impact between two bodies, the *relevant joints* are those whose motion changes the gap:
joint i is relevant if ``|J_n,i| > threshold * ||J_n||``, where ``J_n = n^T (J_p2 - J_p1)`` is
the normal row of the contact Jacobian at the witness points (n from body 1 to body 2, so the
gap rate is ``d' = J_n v``... with the sign convention ``p2 - p1 = d n``: ``d' = n^T (v_p2 -
v_p1) = J_n v``). This includes the turret and the camera pan, which the report skipped.

Velocity reset, on the relevant joints R (e = restitution), ``reset_rule``: ``"zero"`` (the
report's: ``v_i <- -e v_i`` for i in R; on a coupled arm this can *add* kinetic energy) or
``"momentum"`` (an impulsive torque on the joints of R only, the other joints keeping their
generalized momentum; never adds energy for e <= 1); :func:`~packbot.contact.stops.impact_reset`
(in :mod:`packbot.contact.stops`, where the limit stops use it too). A reset that would set a
joint clamped by another contact moving toward it is widened to that joint.

Clamp directions (the direction in which a clamped joint may not accelerate):

- ``"velocity"`` (the report's): ``s_i = sign(v_i)`` at impact (the direction it was moving);
  wrong for a joint whose motion was overwhelmed by another's; a joint that was not moving
  (``|v_i| <= STILL_SPEED``) takes the Jacobian sign;
- ``"jacobian"``: ``s_i = -sign(J_n,i)``, the direction in which the joint's own motion closes
  the gap.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from packbot.contact.base import Active, Crossing, Key
from packbot.contact.pairs import PairLaw
from packbot.contact.stops import impact_reset
from packbot.ode import DenseSegment

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


class JointClampLaw(PairLaw):
    """The report's law (``contact_mode="joint_clamp"``): impact, reset, clamps.

    Pair events: ``impact`` when an inactive pair's distance falls to the contact tolerance
    (the reset on the relevant joints, widened; the pair's clamps); ``release`` when an active
    pair separates beyond the proximity tolerance (its clamps removed);
    ``secondary_intersection`` when an active, clamped pair's distance falls below zero (the
    report's self-diagnosis: logged, and the law applied again with the current geometry, the
    clamps merged). Same arguments as :class:`~packbot.contact.stops.JointStops`.
    """

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
            if d1 < 0.0 <= d0:
                return [
                    self._pair_crossing(
                        "secondary_intersection", key, p_idx, seg, d0, d1, lambda d: d
                    )
                ]
            return []
        if d1 <= cfg.contact_tolerance:
            return [
                self._pair_crossing(
                    "impact", key, p_idx, seg, d0, d1, lambda d: d - cfg.contact_tolerance
                )
            ]
        return []

    def _pair_event(
        self, t: float, y: FloatArray, q: FloatArray, v: FloatArray, c: Crossing
    ) -> FloatArray:
        if c.kind == "release":
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
        self.note_reset(event.energy_before, event.energy_after)
        return v_new
