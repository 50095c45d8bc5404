"""Task tracking with the joints that still work: :class:`ReducedArmTracker`.

After a joint freezes (or a brake holds it, or its driver is stuck at a torque), the arm that is
left still moves the frame with the other joints. The tracker follows a task (frame positions
[m] against time [s], held at its last point after its end) by closed-loop inverse kinematics on
a reference configuration q_r::

    q_r' = J^T (J J^T + lambda^2 I)^-1 (x*'(t) + K (x*(t) - p(q_r)))

J the frame's position Jacobian on the working joints, the correction K e capped at
``max_task_speed``, the joint rates scaled to within ``speed_fraction`` of their limits, q_r
clipped to the joint limits; and computed torque (RNEA of the model with the failed joints'
speeds and accelerations zero: the reduced model's torques). Failed joints are commanded zero.

- ``held`` joints (frozen, a brake that holds) stay at their angle: their reference is fixed;
- ``drifting`` joints (stuck at a torque the controller cannot oppose) move on their own: the
  reference takes their measured angle at every tick, so the working joints compensate for where
  they are.

No collision avoidance is planned (a study reports the run's contacts).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import DEFAULT_GRAVITY, damping_ratio, loop_frequency
from packbot.control.context import ModelSwitch
from packbot.control.model_based import ModelBasedController
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.validation import finite_number

if TYPE_CHECKING:
    from packbot.control.context import RecoveryContext
    from packbot.model import Robot

__all__ = ["ReducedArmTracker"]

FloatArray = NDArray[np.float64]


class ReducedArmTracker(ModelBasedController):
    """Track a task's frame positions with the working joints (module docstring).

    Args:
        context: The task, frame, payload and locked joints (:class:`RecoveryContext`).
        held: Failed joints that stay at their angle (frozen, a holding brake).
        drifting: Failed joints that move on their own (stuck).
        omega: Natural frequency of the tracking loop [rad/s].
        zeta: Its damping ratio [-].
        task_gain: Gain K of the task error [1/s].
        max_task_speed: Largest correction speed K e [m/s].
        speed_fraction: The reference's joint rates within this fraction of the speed limits.
        damping: Damping lambda of the pseudo-inverse [m].
        dt: Control period [s].
        gravity: Gravity the controller assumes [m/s^2].

    Raises:
        ConfigurationError: A bad setting (names it).
    """

    def __init__(
        self,
        *,
        context: RecoveryContext,
        held: Sequence[str] = (),
        drifting: Sequence[str] = (),
        omega: float = 20.0,
        zeta: float = 1.0,
        task_gain: float = 5.0,
        max_task_speed: float = 0.5,
        speed_fraction: float = 1.0,
        damping: float = 0.02,
        dt: float = 1e-3,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, gravity=gravity)
        self.context = context
        self.held_names = tuple(held)
        self.drifting_names = tuple(drifting)
        self.omega = loop_frequency(omega, "omega", self.dt)
        self.zeta = damping_ratio(zeta, "zeta")
        self.task_gain = finite_number("task_gain", task_gain, low=0.0, unit="1/s")
        self.max_task_speed = finite_number(
            "max_task_speed", max_task_speed, low=0.0, low_open=True, unit="m/s"
        )
        self.speed_fraction = finite_number(
            "speed_fraction", speed_fraction, low=0.0, high=1.0, low_open=True
        )
        self.damping = finite_number("damping", damping, low=0.0, unit="m")
        self.movers = np.zeros(0, dtype=int)
        self._failed = np.zeros(0, dtype=int)
        self._drift = np.zeros(0, dtype=int)
        self._held = np.zeros(0, dtype=int)
        self._others = np.zeros(0, dtype=int)
        self._q_ref = np.zeros(0)
        self._v_ref = np.zeros(0)
        self._q_hold = np.zeros(0)
        self._t_last = 0.0
        self._fid = -1
        self._models: ModelSwitch | None = None

    def prepare(self, robot: Robot) -> None:
        """Bind to a robot: the model (with the payload if held), the frame, the joint sets."""
        super().prepare(robot)
        self._models = ModelSwitch(self.context, self.gravity)
        self.model, self.data = self._models.at(0.0)
        model = self.model
        frame = self.context.frame
        if not model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in model.frames])
        self._fid = model.getFrameId(frame)
        names = robot.joint_names
        for name in (*self.held_names, *self.drifting_names):
            if name not in names:
                raise ConfigurationError("held/drifting", name, names)
        idx = robot.params.index
        self._failed = np.array(
            sorted({idx(n) for n in (*self.held_names, *self.drifting_names)}), dtype=int
        )
        self._drift = np.array(sorted(idx(n) for n in self.drifting_names), dtype=int)
        self._held = np.array(sorted(idx(n) for n in self.held_names), dtype=int)
        rigid = {idx(x) for x in self.context.locked}
        parent = model.frames[self._fid].parentJoint
        chain = sorted(model.joints[j].idx_q for j in model.supports[parent] if j > 0)
        failed = set(self._failed.tolist())
        self.movers = np.array([i for i in chain if i not in failed and i not in rigid], dtype=int)
        moving = failed | set(self.movers.tolist())
        self._others = np.array([i for i in range(model.nq) if i not in moving], dtype=int)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Start the reference at the measured state (the held joints' speeds zero)."""
        self.prepare(robot)
        self._q_ref = np.array(q0, dtype=float)
        self._v_ref = np.array(v0, dtype=float)
        self._v_ref[self._failed] = 0.0
        self._q_hold = np.array(q0, dtype=float)
        self._t_last = t0

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """The tracking torque [N*m]; zero on the failed joints."""
        assert self.robot is not None and self._models is not None
        model, data = self.model, self.data = self._models.at(t)
        h = max(t - self._t_last, 0.0)
        self._t_last = t
        m = self.movers
        if len(self._drift):
            self._q_ref[self._drift] = q[self._drift]
        if h > 0 and len(m):
            x_star, xd_star = self.context.task(t)
            J = pin.computeFrameJacobian(
                model, data, self._q_ref, self._fid, pin.LOCAL_WORLD_ALIGNED
            )
            Jm = np.asarray(J)[:3, m]
            e = x_star - data.oMf[self._fid].translation
            corr = self.task_gain * e
            n_corr = float(np.linalg.norm(corr))
            if n_corr > self.max_task_speed:
                corr *= self.max_task_speed / n_corr
            xd = xd_star + corr
            qd = Jm.T @ np.linalg.solve(Jm @ Jm.T + self.damping**2 * np.eye(3), xd)
            vmax = self.speed_fraction * self.robot.params.velocity[m]
            s = float(np.max(np.abs(qd) / vmax))
            if s > 1:
                qd /= s
            lower = np.asarray(model.lowerPositionLimit)[m]
            upper = np.asarray(model.upperPositionLimit)[m]
            self._q_ref[m] = np.clip(self._q_ref[m] + h * qd, lower, upper)
            self._v_ref[m] = qd
        kp, kd = self.omega**2, 2 * self.zeta * self.omega
        a = np.zeros(len(q))
        a[m] = kp * (self._q_ref[m] - q[m]) + kd * (self._v_ref[m] - v[m])
        o = self._others
        if len(o):
            a[o] = kp * (self._q_hold[o] - q[o]) - kd * v[o]
        vv = np.array(v, dtype=float)
        vv[self._held] = 0.0
        tau = np.array(pin.rnea(model, data, np.asarray(q, dtype=float), vv, a), dtype=float)
        tau[self._failed] = 0.0
        return tau
