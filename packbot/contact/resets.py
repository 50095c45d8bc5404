"""Velocity resets: the impulse of an impact or a stop on the joints it acts on.

On the acted joints R (e = restitution):

- ``"zero"`` (the report's): ``v_i <- -e v_i`` for i in R. On a coupled arm this can *add*
  kinetic energy (the joints are not decoupled in M); every impact logs its energy change.
- ``"momentum"``: an impulsive torque on the joints of R only, ``M dv = S_R^T P``, makes
  ``v_R+ = -e v_R-``: the other joints keep their generalized momentum
  (``(M v)_j`` unchanged for j not in R). With e <= 1 it never adds energy.

:func:`widened_reset` widens R where the impulse would push a clamped joint toward its own
contact or barely kick a held one (:data:`HOLD_KICK`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

from packbot.contact.holds import STICK_SPEED

__all__ = ["HOLD_KICK", "impact_reset", "widened_reset"]

FloatArray = NDArray[np.float64]
#: A held joint (Coulomb friction, a brake) that an impulse on its coupled joints sets moving
#: slower than this [rad/s] stays held: the impulse is solved with the joint acted on too (its
#: speed kept at zero, never adding energy). Faster, it slides, its friction opposing (a bounded
#: torque does nothing in an instant). A modelling choice: it ends the Zeno sequence of a stop's
#: bounces under a brake (each bounce kicking the braked joint, which sticks again before the
#: next), as ``SimConfig.zeno_speed`` ends a contact's.
HOLD_KICK = 1e-3


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


def widened_reset(
    v: FloatArray,
    rel: NDArray[np.intp],
    e: float,
    rule: str,
    minv: FloatArray | None,
    clamps: list[tuple[int, int]],
    held: Iterable[int],
) -> tuple[FloatArray, NDArray[np.intp]]:
    """:func:`impact_reset` on ``rel``, widened where it would push a clamped joint.

    The widening takes in every clamped joint that the impulse would set moving toward its
    own contact: one simultaneous impact, not a cascade of secondary ones; and every held
    joint (friction, a brake) that it would set moving slower than :data:`HOLD_KICK`
    (acted on, a held joint keeps v = 0: -e times its speed before).

    Args:
        v: Velocities before [rad/s].
        rel: The joints to act on.
        e: Restitution in [0, 1].
        rule: ``"zero"`` or ``"momentum"``.
        minv: M^-1 at the configuration (``"momentum"`` only).
        clamps: The clamps (joint, s) the reset is widened for.
        held: The held joints.

    Returns:
        The new velocities and the joints acted on.
    """
    acted = np.array(sorted(set(rel.tolist())), dtype=np.intp)
    for _ in range(len(v) + 1):
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
