"""The contact set of a time-stepping window's step: the pairs and limits within its reach.

Before a window step's impulses (:class:`~packbot.contact.timestep.MoreauJeanStepper`), every
collision pair within ``d_act`` of touching (:data:`~packbot.contact.timestep.ACTIVE_GAP` plus
twice the distance any point can travel in the step) and, with joint limits on, every joint
within ``h |v_j| +`` :data:`~packbot.contact.timestep.LIMIT_GAP` of a limit join the contact
set, the others leave it. A pair already in the set keeps its patch while the patch describes
the contact (the event-driven mode's rule, :meth:`NormalContacts.stale_pairs
<packbot.contact.normal_contacts.NormalContacts.stale_pairs>`); a new or stale one is patched
at the step's start. :class:`WindowSet` makes those updates for one window.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.system import System

__all__ = ["WindowSet"]

FloatArray = NDArray[np.float64]


class WindowSet:
    """The updates of a window's contact set, step by step.

    Args:
        system: The phase's integrated system (its joint limits).
        contacts: The window's contact set.
        reach: Per velocity index, a bound [m] on the distance from the joint's axis to any
            point it moves (a point's speed is at most ``reach . |v|``).
        limits: Whether the joint limits are rows of the set (``SimConfig.joint_limits``).
    """

    def __init__(
        self, system: System, contacts: NormalContacts, reach: FloatArray, limits: bool
    ) -> None:
        self.sys = system
        self.contacts = contacts
        self.reach = reach
        self.limits = limits
        n = system.nv
        # its joints within reach of their limits, and the limits' keys in the same order,
        # joint by joint, upper (+1) before lower (-1)
        self._near_limit = np.zeros((n, 2), dtype=bool)
        self._limit_keys = [(j, side) for j in range(n) for side in (1, -1)]

    def update(
        self,
        q: FloatArray,
        v: FloatArray,
        v_f: FloatArray,
        h: float,
        active_gap: float,
        limit_reach: FloatArray,
        cached: tuple[bytes, float, Any] | None,
    ) -> tuple[float, int]:
        """The pairs and limits within reach of the step from q form the contact set.

        Args:
            q: The step's start.
            v: Its velocities [rad/s].
            v_f: Its free velocities [rad/s].
            h: The step [s].
            active_gap: The gap [m] a pair joins the set within, at rest.
            limit_reach: Per joint, how near [rad] a limit joins the set.
            cached: The last step's sweep at its end (q bytes, margin [m], result), or None.

        Returns:
            The smallest signed distance of the sweep [m] and its pair (-1: none).
        """
        contacts = self.contacts
        r = self.reach  # (a point's speed is at most r . |v|)
        speed = max(float(r @ np.abs(v)), float(r @ np.abs(v_f)))
        d_act = active_gap + 2.0 * h * speed
        near: dict[int, float] = {}
        closest = (math.inf, -1)
        if contacts.world is not None:
            if cached is not None and cached[0] == q.tobytes() and cached[1] >= d_act:
                sw = cached[2]  # the previous step's sweep at its end, wide enough
            else:
                sw = contacts.world.sweep(q, margin=max(d_act, 1e-9))
            closest = (float(sw.min_distance), int(sw.min_pair))
            within = sw.distances <= d_act
            near = dict(zip(sw.pairs[within].tolist(), sw.distances[within].tolist(), strict=True))
        for k in [k for k in contacts.pairs if k not in near]:
            contacts.remove_pair(k)
        stale = contacts.stale_pairs(q, v, near)
        redo = set(stale) | (near.keys() - contacts.pairs.keys())
        contacts.add_pairs(q, list(redo), tol=d_act)
        if self.limits:
            self.update_limits(q, limit_reach)
        return closest

    def update_limits(self, q: FloatArray, reach: FloatArray) -> None:
        """The joint limits within ``reach`` [rad] of q join the set, the others leave it.

        In the order of the joints, the upper limit before the lower (the rows' order).
        """
        sys, limits = self.sys, self.contacts.limits
        near = self._near_limit  # (joints, 2): upper, lower
        np.less_equal(sys.upper - q, reach, out=near[:, 0])  # (an infinite limit never is)
        np.less_equal(q - sys.lower, reach, out=near[:, 1])
        if not limits and not near.any():
            return  # (the usual step far from the limits: none in the set, none near)
        # the limits within reach in the rows' order: by joint, the upper before the lower
        keys = self._limit_keys
        want = [keys[i] for i in np.flatnonzero(near).tolist()]
        if len(want) == len(limits) and all(k in limits for k in want):
            return  # (the usual step: no change)
        upper, lower = near[:, 0].tolist(), near[:, 1].tolist()
        for j in range(sys.nv):
            for side, within, lim in ((1, upper[j], sys.upper[j]), (-1, lower[j], sys.lower[j])):
                if within:
                    if (j, side) not in limits:
                        self.contacts.add_limit(j, side, float(lim))
                elif (j, side) in limits:
                    self.contacts.remove_limit(j, side)
