"""Joint PD control with gravity compensation: tau = g(q) + Kp (q_target - q) - Kd v.

With exact gravity compensation the closed loop around q_target is, to first order, M q'' =
-Kp e - Kd e': each joint a mass-spring-damper. The default gains place every joint's natural
frequency at ``omega`` [rad/s] with damping ratio ``zeta`` using the diagonal of the mass matrix
M(q_target) (armature included): Kp_i = M_ii omega^2, Kd_i = 2 zeta omega M_ii.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    QLike,
    check_gain_spec,
    check_q_spec,
    damping_ratio,
    loop_frequency,
    resolve_gains,
    resolve_q,
)
from packbot.control.base import Sensor
from packbot.control.model_based import ModelBasedController
from packbot.validation import boolean

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["JointPD", "default_gains"]

FloatArray = NDArray[np.float64]


def default_gains(
    model: pin.Model, data: pin.Data, q: FloatArray, omega: float, zeta: float
) -> tuple[FloatArray, FloatArray]:
    """Decoupled PD gains from the mass matrix diagonal at q.

    Args:
        model: Pinocchio model (armature set).
        data: Its data.
        q: Configuration [rad].
        omega: Natural frequency of every joint [rad/s].
        zeta: Damping ratio [-].

    Returns:
        (Kp [N*m/rad], Kd [N*m*s/rad]), each shape (nv,).
    """
    m = np.diag(pin.crba(model, data, np.asarray(q, dtype=float))).copy()
    return m * omega**2, 2.0 * zeta * omega * m


class JointPD(ModelBasedController):
    """Joint PD regulation to a fixed target, with gravity compensation.

    Args:
        target: Target configuration: nq angles [rad], a pose name or a {joint: angle} table
            (other joints from q0); None: hold the initial configuration q0.
        kp: Stiffness [N*m/rad]: a number, nv numbers or a {joint: gain} table; None: from
            ``omega``.
        kd: Damping [N*m*s/rad], same forms; None: from ``omega`` and ``zeta``.
        omega: Natural frequency of the default gains [rad/s], below the Nyquist rate
            pi / dt.
        zeta: Damping ratio of the default gains [-], in (0, 100].
        gravity_compensation: Add g(q) to the command.
        dt: Control period [s].
        sensor: Measurement model.
        gravity: Gravity the controller assumes [m/s^2].

    Raises:
        ConfigurationError: A bad setting (its form and range are checked at construction;
            names and lengths against the robot by :meth:`prepare`).
    """

    def __init__(
        self,
        *,
        target: QLike | None = None,
        kp: GainLike | None = None,
        kd: GainLike | None = None,
        omega: float = 15.0,
        zeta: float = 1.0,
        gravity_compensation: bool = True,
        dt: float = 1e-3,
        sensor: Sensor | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, sensor=sensor, gravity=gravity)
        check_q_spec(target, "controller.target")
        check_gain_spec(kp, "controller.kp")
        check_gain_spec(kd, "controller.kd")
        self.target_spec = target
        self.kp_spec, self.kd_spec = kp, kd
        self.omega = loop_frequency(omega, "controller.omega", self.dt)
        self.zeta = damping_ratio(zeta, "controller.zeta")
        self.gravity_compensation = boolean("controller.gravity_compensation", gravity_compensation)
        self.target: FloatArray | None = None
        self.kp = np.zeros(0)
        self.kd = np.zeros(0)

    def prepare(self, robot: Robot, q0: FloatArray | None = None) -> None:
        """Resolve the target and gains for ``robot`` (q0 supplies the target if None)."""
        super().prepare(robot)
        model, data = self._md()
        base = robot.pose(robot.home_pose) if q0 is None else np.asarray(q0, dtype=float)
        if self.target_spec is None:
            self.target = base.copy()
        else:
            self.target = resolve_q(robot, self.target_spec, "controller.target", base)
        kp0, kd0 = default_gains(model, data, self.target, self.omega, self.zeta)
        self.kp = resolve_gains(robot, self.kp_spec, "controller.kp", kp0)
        self.kd = resolve_gains(robot, self.kd_spec, "controller.kd", kd0)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Resolve target and gains (the target defaults to q0)."""
        self.prepare(robot, q0)

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """g(q) + Kp (q_target - q) - Kd v [N*m]."""
        assert self.target is not None
        tau = self.kp * (self.target - q) - self.kd * v
        if self.gravity_compensation:
            tau += self.gravity_torque(q)
        return tau
