"""The law without collisions (``contact_mode="none"``): limit stops and joint holds only.

No collision world is built and no pair is watched: the arm passes through itself, the chassis
and the floor. Its joints still stop at their position limits (a joint-space impulse and a
clamp, :mod:`packbot.contact.stops`), and joint friction and brakes hold them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from packbot.contact.holds import friction_share
from packbot.contact.stops import JointStops
from packbot.contact_forces import SampleForces

FloatArray = NDArray[np.float64]

__all__ = ["NoneLaw"]


class NoneLaw(JointStops):
    """``contact_mode="none"``: :class:`~packbot.contact.stops.JointStops` alone.

    Same arguments as :class:`~packbot.contact.stops.JointStops`; its steps are the locks'
    native Dormand-Prince step where that serves (:meth:`JointStops.step_kernel`).
    """

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """No collisions, no contact; the joint stops' torques: their engaged clamps' lock torques.

        A clamp engaged here is a joint on its position stop (no pair clamps a joint in this
        mode); where friction or a brake also holds the joint, the stop carries what the
        friction's bound does not (:func:`~packbot.contact.holds.friction_share`).
        """
        limit = np.zeros(len(q))
        locks = self.locks
        if not locks.engaged:
            return SampleForces([], limit)
        sys = self.sys
        _, lam = locks.torques(sys.aba(q, v, tau()), sys.minv(q))
        for j in locks.engaged:
            bound = locks.held.get(j)
            limit[j] = lam[j] - (0.0 if bound is None else friction_share(lam[j], bound))
        return SampleForces([], limit)
