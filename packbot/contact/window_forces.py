"""The contact forces inside a time-stepping window: each step's impulses over its length.

A window step (:mod:`packbot.contact.timestep`) solves one complementarity problem for the
impulses x [N*s, N*m*s] over its length h; the motion between its ends is linear, so the force
that step applied, and the force its samples report, is the mean x / h. The rows are those of
the contact set the step solved (its pairs' patch points, then its limits), at the step's start
configuration q0, where the step's Jacobians were taken:

* a pair row's block (t1, t2, n) is the force on body 2 [N] in the pair's contact frame at q0:
  ``(x_t1 t1 + x_t2 t2 + x_n n) / h``, the normal part at the point where the bodies touch, the
  friction at each body's own material point (the rows' Jacobians:
  :func:`packbot.contact.conic.step_problem`);
* a limit row's normal impulse is its stop's torque on its joint, ``-side x_n / h`` [N*m];
* a row with no normal impulse is not reported (it is in the set, not in contact).

With these the step's equations close exactly: h (sum of J^T f + the stops' torques) =
M (v1 - v_f) at q0, with v_f the step's free velocity and v1 its end velocity as solved
(tests/test_window_forces.py). A step whose energy guard scaled its end velocity back
(``StepInfo.removed``) reports the impulses it solved, not the scaled ones. A sample at a
window's opening instant is recorded before the window's first step: its forces are not known.
"""

from __future__ import annotations

import bisect
import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.normal_forces import pair_frame, pair_names, pair_points
from packbot.contact_forces import SampleContact, SampleForces

if TYPE_CHECKING:
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.contact.normal_patch import _Pair

__all__ = ["WindowForces", "step_forces"]

FloatArray = NDArray[np.float64]


class WindowForces:
    """The steps of a window kept for their samples' contact forces.

    Args:
        contacts: The window's contact set (its pairs and limits when a step is kept).
        data: A Pinocchio data of the set's model for the placements (not the set's own).
    """

    def __init__(self, contacts: NormalContacts, data: Any) -> None:
        self.contacts = contacts
        self._data = data
        # per step kept: its start and end [s], q0 [rad], x (3 m + boxes), the pairs and the
        # limits (joint, side) of its rows
        self._ends: list[float] = []
        self._steps: list[tuple[float, float, FloatArray, FloatArray, list[_Pair], list[Any]]] = []

    def clear(self) -> None:
        """Forget the steps kept (their samples are recorded)."""
        self._ends.clear()
        self._steps.clear()

    def keep(self, t0: float, t1: float, q0: FloatArray, x: FloatArray) -> None:
        """Keep a step and its impulses on the contact set's rows as they are now.

        Args:
            t0: The step's start [s].
            t1: Its end [s].
            q0: Its start configuration [rad].
            x: Its impulses (:func:`step_forces`).
        """
        c = self.contacts
        self._ends.append(t1 + 1e-12)
        self._steps.append(
            (t0, t1, np.array(q0, dtype=np.float64), np.array(x, dtype=np.float64),
             list(c.pairs.values()), list(c.limits))
        )  # fmt: skip

    def at(self, t: float) -> SampleForces | None:
        """The forces of the step that holds t [s], or None: no step kept holds t.

        The step that holds t is the loop's for a step's samples: the first whose end + 1e-12 s
        reaches t. A time that is not finite (a caller that gave none) is held by no step.
        """
        if not math.isfinite(t):
            return None
        i = bisect.bisect_left(self._ends, t)
        if i >= len(self._steps) or t < self._steps[i][0] - 1e-12:
            return None
        t0, t1, q0, x, pairs, limits = self._steps[i]
        c = self.contacts
        return step_forces(c.model, self._data, q0, x, t1 - t0, pairs, limits, c.nv)


def step_forces(
    model: Any,
    data: Any,
    q0: FloatArray,
    x: FloatArray,
    h: float,
    pairs: list[_Pair],
    limits: list[Any],
    nv: int,
) -> SampleForces:
    """A window step's mean contact forces and stop torques (see the module).

    Args:
        model: The pairs' Pinocchio model.
        data: A data of ``model`` (its placements are computed at q0).
        q0: The step's start configuration [rad].
        x: The step's impulses: per contact row (the pairs' points, then the limits) the
            block (t1, t2, n) [N*s, N*m*s], then the joint boxes'.
        h: The step's length [s].
        pairs: The pairs of its rows, in order.
        limits: Its limits (joint, side), in order.
        nv: Velocity dimension.

    Returns:
        Per patch point with a normal impulse, (names, point, point1, point2 [m], normal,
        mean force on body 2 [N]), world frame; the stops' mean torques [N*m] (nv,).
    """
    limit = np.zeros(nv)
    if not pairs and not limits:
        return SampleForces([], limit)
    pin.forwardKinematics(model, data, q0)
    out: list[SampleContact] = []
    r = 0
    for p in pairs:
        K = len(p.local1)
        blocks = x[3 * r : 3 * (r + K)].reshape(K, 3)
        r += K
        on = np.flatnonzero(blocks[:, 2] > 0.0)
        if not len(on):
            continue
        T = pair_frame(data, p)  # rows t1, t2, n (world)
        n = T[2]
        names = pair_names(p)
        touch, p1, p2 = pair_points(data, p)
        forces = blocks[on] @ T / h
        for j, f in zip(on.tolist(), forces, strict=True):
            out.append((names, touch[j], p1[j], p2[j], n.copy(), f))
    for i, (j, side) in enumerate(limits):
        limit[j] -= side * x[3 * (r + i) + 2] / h  # (the row's Jacobian is -side e_j)
    return SampleForces(out, limit)
