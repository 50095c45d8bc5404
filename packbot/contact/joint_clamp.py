"""The 2010 report's impact law (``contact_mode="joint_clamp"``).

At an impact between two bodies, the *relevant joints* are those whose motion changes the gap:
joint i is relevant if ``|J_n,i| > threshold * ||J_n||``, where ``J_n = n^T (J_p2 - J_p1)`` is
the normal row of the contact Jacobian at the witness points (n from body 1 to body 2, so the
gap rate is ``d' = J_n v``... with the sign convention ``p2 - p1 = d n``: ``d' = n^T (v_p2 -
v_p1) = J_n v``). This includes the turret and the camera pan, which the report skipped.

Velocity reset, on the relevant joints R (e = restitution):

- ``"zero"`` (the report's): ``v_i <- -e v_i`` for i in R. On a coupled arm this can *add*
  kinetic energy (the joints are not decoupled in M); every impact logs its energy change.
- ``"momentum"``: an impulsive torque on the joints of R only, ``M dv = S_R^T P``, makes
  ``v_R+ = -e v_R-``: the other joints keep their generalized momentum
  (``(M v)_j`` unchanged for j not in R). With e <= 1 it never adds energy.

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

__all__ = ["STILL_SPEED", "clamp_directions", "impact_reset", "relevant_joints"]

FloatArray = NDArray[np.float64]


def relevant_joints(Jn: FloatArray, threshold: float) -> NDArray[np.intp]:
    """Indices i with ``|J_n,i| > threshold * ||J_n||`` (none if J_n is zero)."""
    norm = float(np.linalg.norm(Jn))
    if norm == 0.0:
        return np.zeros(0, dtype=np.intp)
    return np.flatnonzero(np.abs(Jn) > threshold * norm)


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
