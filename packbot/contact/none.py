"""The law without collisions (``contact_mode="none"``): limit stops and joint holds only.

No collision world is built and no pair is watched: the arm passes through itself, the chassis
and the floor. Its joints still stop at their position limits (a joint-space impulse and a
clamp, :mod:`packbot.contact.stops`), and joint friction and brakes hold them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from packbot.contact.stops import JointStops

FloatArray = NDArray[np.float64]

__all__ = ["NoneLaw"]


class NoneLaw(JointStops):
    """``contact_mode="none"``: :class:`~packbot.contact.stops.JointStops` alone.

    Same arguments as :class:`~packbot.contact.stops.JointStops`; its steps are the locks'
    native Dormand-Prince step where that serves (:meth:`JointStops.step_kernel`).
    """
