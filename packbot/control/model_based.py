"""Base of the controllers that use the arm's model: :class:`ModelBasedController`.

It keeps a copy of the robot's Pinocchio model (armature included, so that RNEA and CRBA see the
reflected rotor inertia) with the controller's own gravity vector, which must match the
simulation's (``SimConfig.gravity``, default (0, 0, -9.81) m/s^2).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import DEFAULT_GRAVITY, controller_model, resolve_gravity
from packbot.control.base import Controller, Sensor

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["ModelBasedController"]

FloatArray = NDArray[np.float64]


class ModelBasedController(Controller):
    """A controller with a model of the arm.

    Subclasses resolve their robot-dependent parameters (named poses, gain tables) in
    :meth:`prepare`, which :meth:`reset` calls and which the registry calls at build time so
    that a bad parameter is reported before any simulation.

    Args:
        dt: Control period [s].
        sensor: Measurement model (default: exact).
        gravity: Gravity the controller assumes [m/s^2], world frame.

    Attributes:
        model: The controller's Pinocchio model (None before :meth:`prepare`).
        data: Its data.
    """

    def __init__(
        self,
        *,
        dt: float = 1e-3,
        sensor: Sensor | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, sensor=sensor)
        self.gravity = resolve_gravity(gravity)
        self.model: pin.Model | None = None
        self.data: pin.Data | None = None

    def prepare(self, robot: Robot) -> None:
        """Bind to a robot: build the model, resolve parameters (raises ConfigurationError)."""
        self.robot = robot
        self.model, self.data = controller_model(robot, self.gravity)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Prepare for ``robot`` (subclasses extend this to set their state from q0, v0)."""
        self.prepare(robot)

    def _md(self) -> tuple[pin.Model, pin.Data]:
        if self.model is None or self.data is None:
            raise RuntimeError(f"{type(self).__name__}: reset() or prepare() was not called")
        return self.model, self.data

    def gravity_torque(self, q: FloatArray) -> FloatArray:
        """Generalized gravity torque g(q) [N*m], shape (nv,): the torque that holds q at rest."""
        model, data = self._md()
        return np.array(pin.computeGeneralizedGravity(model, data, np.asarray(q, dtype=float)))
