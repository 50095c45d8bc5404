"""Gravity compensation: the joint torque that holds the arm still, tau = g(q).

With exact gravity compensation an arm at rest stays at rest (the net joint torque is zero); a
moving arm is not stopped (there is no damping). g(q) comes from Pinocchio's
``computeGeneralizedGravity`` for the controller's gravity vector.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from packbot.control.model_based import ModelBasedController

__all__ = ["GravityCompensation"]

FloatArray = NDArray[np.float64]


class GravityCompensation(ModelBasedController):
    """Command the gravity torque of the measured configuration, tau = g(q_meas) [N*m].

    Args:
        dt: Control period [s].
        sensor: Measurement model (default: exact).
        gravity: Gravity the controller assumes [m/s^2], world frame.
    """

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """g(q) [N*m], shape (nv,)."""
        return self.gravity_torque(q)
