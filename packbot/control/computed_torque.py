"""Computed-torque tracking of a joint trajectory (inverse dynamics by RNEA).

tau = M(q) (a_d + Kp (q_d - q) + Kd (v_d - v)) + C(q, v) v + g(q), evaluated in one call of
Pinocchio's RNEA (armature included). With an exact model the tracking error obeys
e'' + Kd e' + Kp e = 0 for each joint independently; the default gains put both poles at
-omega (critical damping).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    check_gain_spec,
    damping_ratio,
    loop_frequency,
    resolve_gains,
)
from packbot.control.base import Sensor
from packbot.control.model_based import ModelBasedController
from packbot.errors import ConfigurationError
from packbot.validation import real_array

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["ComputedTorque", "computed_torque"]

FloatArray = NDArray[np.float64]
#: A reference: t [s] -> (q_d [rad], v_d [rad/s], a_d [rad/s^2]), e.g. a JointTrajectory.
Reference = Callable[[float], tuple[FloatArray, FloatArray, FloatArray]]


def computed_torque(
    model: pin.Model,
    data: pin.Data,
    q: FloatArray,
    v: FloatArray,
    ref: tuple[FloatArray, FloatArray, FloatArray],
    kp: FloatArray,
    kd: FloatArray,
) -> FloatArray:
    """The computed-torque law [N*m], shape (nv,).

    Args:
        model: Pinocchio model (armature and gravity set).
        data: Its data.
        q: Measured positions [rad].
        v: Measured velocities [rad/s].
        ref: Desired (q_d [rad], v_d [rad/s], a_d [rad/s^2]).
        kp: Position gains [1/s^2], shape (nv,).
        kd: Velocity gains [1/s], shape (nv,).
    """
    qd, vd, ad = ref
    a = ad + kp * (qd - q) + kd * (vd - v)
    return np.array(pin.rnea(model, data, q, v, a))


class ComputedTorque(ModelBasedController):
    """Track a joint trajectory by computed torque.

    Args:
        trajectory: The reference, t -> (q_d, v_d, a_d) in full coordinates (a
            :class:`~packbot.control.trajectory.JointTrajectory`).
        kp: Position gains [1/s^2]: number, nv numbers or {joint: gain}; None: omega^2.
        kd: Velocity gains [1/s], same forms; None: 2 zeta omega.
        omega: Natural frequency of the default gains [rad/s], below the Nyquist rate
            pi / dt.
        zeta: Damping ratio of the default gains [-], in (0, 100].
        dt: Control period [s].
        sensor: Measurement model.
        gravity: Gravity the controller assumes [m/s^2].
    """

    def __init__(
        self,
        *,
        trajectory: Reference,
        kp: GainLike | None = None,
        kd: GainLike | None = None,
        omega: float = 20.0,
        zeta: float = 1.0,
        dt: float = 1e-3,
        sensor: Sensor | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, sensor=sensor, gravity=gravity)
        if not callable(trajectory):
            raise ConfigurationError(
                "controller.trajectory", trajectory, "a callable t -> (q, v, a)"
            )
        check_gain_spec(kp, "controller.kp")
        check_gain_spec(kd, "controller.kd")
        self.trajectory = trajectory
        self.kp_spec, self.kd_spec = kp, kd
        self.omega = loop_frequency(omega, "controller.omega", self.dt)
        self.zeta = damping_ratio(zeta, "controller.zeta")
        self.kp = np.zeros(0)
        self.kd = np.zeros(0)

    def prepare(self, robot: Robot) -> None:
        """Build the model and resolve the gains."""
        super().prepare(robot)
        n = robot.nq
        self.kp = resolve_gains(robot, self.kp_spec, "controller.kp", np.full(n, self.omega**2))
        self.kd = resolve_gains(
            robot, self.kd_spec, "controller.kd", np.full(n, 2 * self.zeta * self.omega)
        )
        expected = f"a callable t -> (q, v, a), each of shape ({n},)"
        try:
            ref = self.trajectory(0.0)
        except Exception as exc:  # a user's callable: any error is a bad setting
            raise ConfigurationError(
                "controller.trajectory", self.trajectory, f"{expected} (at t = 0 it raised {exc!r})"
            ) from exc
        if not isinstance(ref, (tuple, list)) or len(ref) != 3:
            raise ConfigurationError("controller.trajectory", f"t=0 -> {ref!r}", expected)
        for name, x in zip(("q", "v", "a"), ref, strict=True):
            real_array("controller.trajectory", x, shape=(n,), expected=f"{name}: {expected}")

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """RNEA(q, v, a_d + Kp e + Kd e') [N*m]."""
        model, data = self._md()
        return computed_torque(model, data, q, v, self.trajectory(t), self.kp, self.kd)
