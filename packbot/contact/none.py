"""The law without collisions (``contact_mode="none"``): limit stops and joint holds only.

No collision world is built and no pair is watched: the arm passes through itself, the chassis
and the floor. Its joints still stop at their position limits (a joint-space impulse and a
clamp, :mod:`packbot.contact.stops`), and joint friction and brakes hold them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.contact.stops import JointStops

if TYPE_CHECKING:
    from packbot.contact_forces import SampleContact

FloatArray = NDArray[np.float64]

__all__ = ["NoneLaw"]


class NoneLaw(JointStops):
    """``contact_mode="none"``: :class:`~packbot.contact.stops.JointStops` alone.

    Same arguments as :class:`~packbot.contact.stops.JointStops`; its steps are the locks'
    native Dormand-Prince step where that serves (:meth:`JointStops.step_kernel`).
    """

    def contact_forces(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray]
    ) -> list[SampleContact] | None:
        """No collisions: no contact, ever."""
        return []
