"""Cartesian (task-space) PD control of a frame, through the frame Jacobian.

tau = g(q) + J^T F + N^T tau_posture - D v, where

- J (6 x nv) is the frame Jacobian in the LOCAL_WORLD_ALIGNED convention (origin of the frame,
  world axes), its top 3 rows the linear part J_p and bottom 3 the angular part J_w;
- F = [Kp (p* - p) - Kd J_p v ; Kr log(R* R^T) - Dr J_w v] the task wrench [N, N*m] (the
  rotational part only when an orientation target is set);
- tau_posture = Kq (q_posture - q) a joint spring toward a posture, projected by
  N^T = I - J^T (J^T)^+ (damped pseudo-inverse) so that it does not disturb the task;
- D v a joint damping that damps the null-space motion (and the joints the task does not see).

With gravity compensated, the stiffness part is the gradient of a potential whose minimum is the
target, and the damping is dissipative, so the arm converges to the target when it is reachable
(and to the closest reachable point otherwise).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    QLike,
    check_gain_spec,
    check_q_spec,
    controlled_frame,
    frame_spec,
    loop_frequency,
    resolve_gains,
    resolve_q,
    resolve_vector3,
)
from packbot.control.base import Sensor
from packbot.control.model_based import ModelBasedController
from packbot.control.pd import default_gains
from packbot.errors import ConfigurationError
from packbot.validation import finite_number, is_number, real_array

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["CartesianPD", "frame_jacobian", "frame_pose"]

FloatArray = NDArray[np.float64]


def frame_pose(model: pin.Model, data: pin.Data, q: FloatArray, frame: int) -> pin.SE3:
    """World placement of a frame at configuration q [rad]."""
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[frame].copy()


def frame_jacobian(model: pin.Model, data: pin.Data, q: FloatArray, frame: int) -> FloatArray:
    """6 x nv Jacobian of a frame, LOCAL_WORLD_ALIGNED (linear rows first) [m/rad, rad/rad]."""
    J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
    return np.asarray(J).reshape(6, model.nv)


def _gain3(value: Any, field: str) -> FloatArray:
    expected = "a number or 3 finite numbers >= 0"
    if is_number(value):
        arr = np.full(3, finite_number(field, value, low=0.0, what="a finite gain"))
    else:
        arr = resolve_vector3(value, field, expected)
    if np.any(arr < 0):
        raise ConfigurationError(field, value, expected)
    return arr


def _position_spec(value: Any, field: str) -> None:
    """Check a target position: a pose name or 3 finite coordinates [m]."""
    if isinstance(value, str) and value:
        return
    resolve_vector3(value, field, "3 finite coordinates [m] or a pose name")


def _rotation(spec: Any) -> FloatArray:
    """A 3x3 rotation matrix (world frame) from a matrix."""
    expected = "None, a 3x3 rotation matrix or a pose name"
    R = real_array("controller.orientation", spec, shape=(3, 3), expected=expected)
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
        raise ConfigurationError("controller.orientation", spec, expected)
    return R


class CartesianPD(ModelBasedController):
    """Task-space PD on a frame's position (and optionally orientation), gravity compensated.

    Args:
        target: Target position of the frame [m], world frame, or a pose name (the frame's
            position at that pose).
        frame: The controlled frame; None: the robot's tool frame (:attr:`packbot.Robot.tool_frame`,
            PackBot's ``gripper_tool``).
        orientation: Target orientation: None (position only), a 3x3 rotation matrix (world
            frame), or a pose name (the frame's orientation at that pose).
        kp: Translational stiffness [N/m]: a number or 3 numbers (world x, y, z).
        kd: Translational damping [N*s/m].
        kp_rot: Rotational stiffness [N*m/rad].
        kd_rot: Rotational damping [N*m*s/rad].
        posture: Null-space posture (nq angles, pose name or {joint: angle}); None: q0.
        k_posture: Posture stiffness [N*m/rad] per joint; None: M_ii omega_posture^2.
        damping: Joint damping [N*m*s/rad] per joint; None: 2 M_ii omega_posture.
        omega_posture: Frequency of the default posture and damping gains [rad/s], below the
            Nyquist rate pi / dt.
        pinv_damping: Damping of the pseudo-inverse in the null-space projector [m], in
            (0, 1].
        dt: Control period [s].
        sensor: Measurement model.
        gravity: Gravity the controller assumes [m/s^2].
    """

    def __init__(
        self,
        *,
        target: str | Sequence[float] | FloatArray,
        frame: str | None = None,
        orientation: str | FloatArray | Sequence[Sequence[float]] | None = None,
        kp: float | Sequence[float] = 400.0,
        kd: float | Sequence[float] = 80.0,
        kp_rot: float | Sequence[float] = 20.0,
        kd_rot: float | Sequence[float] = 2.0,
        posture: QLike | None = None,
        k_posture: GainLike | None = None,
        damping: GainLike | None = None,
        omega_posture: float = 4.0,
        pinv_damping: float = 1e-3,
        dt: float = 1e-3,
        sensor: Sensor | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, sensor=sensor, gravity=gravity)
        _position_spec(target, "controller.target")
        if orientation is not None and not (isinstance(orientation, str) and orientation):
            _rotation(orientation)
        check_q_spec(posture, "controller.posture")
        check_gain_spec(k_posture, "controller.k_posture")
        check_gain_spec(damping, "controller.damping")
        self.target_spec = target
        self.frame_spec = frame_spec("controller.frame", frame)
        self.frame = "" if frame is None else frame
        self.orientation_spec = orientation
        self.kp, self.kd = _gain3(kp, "controller.kp"), _gain3(kd, "controller.kd")
        self.kp_rot = _gain3(kp_rot, "controller.kp_rot")
        self.kd_rot = _gain3(kd_rot, "controller.kd_rot")
        self.posture_spec = posture
        self.k_posture_spec, self.damping_spec = k_posture, damping
        self.omega_posture = loop_frequency(omega_posture, "controller.omega_posture", self.dt)
        self.pinv_damping = finite_number(
            "controller.pinv_damping",
            pinv_damping,
            low=0.0,
            high=1.0,
            low_open=True,
            unit="m",
            what="a damping of the pseudo-inverse",
        )
        self.frame_id = -1
        self.target = np.zeros(3)
        self.rotation: FloatArray | None = None
        self.posture = np.zeros(0)
        self.k_posture = np.zeros(0)
        self.damping = np.zeros(0)

    def prepare(self, robot: Robot, q0: FloatArray | None = None) -> None:
        """Resolve the frame, target, posture and gains for ``robot``."""
        super().prepare(robot)
        model, data = self._md()
        self.frame, self.frame_id = controlled_frame(model, robot, self.frame_spec)
        self.target = self._resolve_position(robot, self.target_spec)
        self.rotation = self._resolve_rotation(robot, self.orientation_spec)
        base = robot.pose(robot.home_pose) if q0 is None else np.asarray(q0, dtype=float)
        spec = self.posture_spec
        self.posture = (
            base.copy() if spec is None else resolve_q(robot, spec, "controller.posture", base)
        )
        kq0, d0 = default_gains(model, data, self.posture, self.omega_posture, 1.0)
        self.k_posture = resolve_gains(robot, self.k_posture_spec, "controller.k_posture", kq0)
        self.damping = resolve_gains(robot, self.damping_spec, "controller.damping", d0)

    def _resolve_position(self, robot: Robot, spec: Any) -> FloatArray:
        if isinstance(spec, str):
            model, data = self._md()
            return frame_pose(model, data, robot.pose(spec), self.frame_id).translation.copy()
        return resolve_vector3(spec, "controller.target", "3 finite coordinates [m] or a pose name")

    def _resolve_rotation(self, robot: Robot, spec: Any) -> FloatArray | None:
        if spec is None:
            return None
        if isinstance(spec, str):
            model, data = self._md()
            return frame_pose(model, data, robot.pose(spec), self.frame_id).rotation.copy()
        return _rotation(spec)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Resolve everything; the posture defaults to q0."""
        self.prepare(robot, q0)

    def task_error(self, q: FloatArray) -> FloatArray:
        """Task error: position p* - p [m] (world frame), then log(R* R^T) [rad] if oriented."""
        model, data = self._md()
        M = frame_pose(model, data, q, self.frame_id)
        e = self.target - M.translation
        if self.rotation is None:
            return e
        return np.concatenate([e, pin.log3(self.rotation @ M.rotation.T)])

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """G + J^T F + N^T Kq (q_posture - q) - D v [N*m]."""
        model, data = self._md()
        J6 = frame_jacobian(model, data, q, self.frame_id)  # also places the frames
        oMf = data.oMf[self.frame_id]
        Jp = J6[:3]
        F = self.kp * (self.target - oMf.translation) - self.kd * (Jp @ v)
        J, W = Jp, F
        if self.rotation is not None:
            Jw = J6[3:]
            Fr = self.kp_rot * pin.log3(self.rotation @ oMf.rotation.T) - self.kd_rot * (Jw @ v)
            J, W = J6, np.concatenate([F, Fr])
        tau_post = self.k_posture * (self.posture - q)
        # N^T tau = tau - J^T (J J^T + l^2 I)^-1 J tau: the posture torque minus its task part.
        lam = self.pinv_damping**2 * np.eye(J.shape[0])
        tau_null = tau_post - J.T @ np.linalg.solve(J @ J.T + lam, J @ tau_post)
        return self.gravity_torque(q) + J.T @ W + tau_null - self.damping * v
