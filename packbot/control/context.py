"""What a recovery strategy is told: :class:`RecoveryContext`, :class:`FailureReport`.

The reconfigured run of a failure study (:func:`packbot.study`) is not told of the failures: its
momentum observer (:mod:`packbot.control.detector`) finds them. Each detection is handed to the
run's recovery strategy (:mod:`packbot.control.strategies`) as a :class:`FailureReport`: the
failure as estimated (a :class:`~packbot.failures.Failure` with the detected joint, kind,
detection time and, for a weak joint, the estimated effort scale), the observer's
:class:`~packbot.control.detector.Detection`, the measured state, the failures reported before,
and the :class:`RecoveryContext`: what the run knows besides its measurements (the robot, the
task, the obstacles, gravity, the declared payload, the locked joints).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import DEFAULT_GRAVITY, controller_model
from packbot.keywords import checked_arguments

if TYPE_CHECKING:
    from packbot.control.detector import Detection
    from packbot.environment import Environment
    from packbot.failures import Failure
    from packbot.model import Robot
    from packbot.payload import Payload

__all__ = ["FailureReport", "ModelSwitch", "RecoveryContext", "RecoveryEvent"]

FloatArray = NDArray[np.float64]


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class RecoveryEvent:
    """An entry of a reconfigured run's log (:attr:`packbot.control.TaskRecovery.log`).

    Attributes:
        t: Time [s].
        kind: ``"detect"`` (the observer flagged a joint), ``"switch"`` (the strategy put
            another controller in charge), ``"track"`` / ``"loose"`` / ``"weak"`` (what the
            built-in strategy does), ``"plan"`` / ``"replan"`` (the loose-joint controller's
            plans), ``"ignored"`` (a detection not acted on), ``"suspended"`` (no joint judged
            while the arm touched something: ``detail`` gives the interval).
        joint: The joint concerned ("" if none).
        detail: What, in words (failure kind and estimate, residual, plan result).
        detection: The observer's detection (``"detect"`` entries), else None.
    """

    t: float
    kind: str
    joint: str = ""
    detail: str = ""
    detection: Detection | None = None


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class RecoveryContext:
    """What the reconfigured run knows besides its measurements.

    Attributes:
        robot: The robot (healthy model).
        task_t: Times of the task [s], shape (N,), increasing (duplicates removed).
        task_x: The frame's task positions [m], shape (N, 3).
        frame: The frame that follows the task ("": the robot's tool frame,
            :attr:`packbot.Robot.tool_frame`, set to its name).
        environment: Obstacles (None: the floor).
        gravity: Gravity [m/s^2].
        joint_friction: Whether the joints have the parameter table's friction.
        locked: Joints held rigid by the arm's configuration.
        payload: The declared payload (its pick-up and drop times), or None.
        loose_options: Settings of the loose-joint controller
            (:data:`packbot.control.recovery.LOOSE_OPTIONS` keys).
    """

    robot: Robot
    task_t: FloatArray
    task_x: FloatArray
    frame: str = ""
    environment: Environment | None = None
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY
    joint_friction: bool = False
    locked: tuple[str, ...] = ()
    payload: Payload | None = None
    loose_options: Mapping[str, Any] = field(default_factory=dict)
    _task_v: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.frame:
            object.__setattr__(self, "frame", self.robot.tool_frame)
        object.__setattr__(self, "_task_v", np.gradient(self.task_x, self.task_t, axis=0))

    def task(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The task's position [m] and velocity [m/s] at time t [s] (held after its end)."""
        tt = self.task_t
        tc = min(max(t, float(tt[0])), float(tt[-1]))
        x = np.array([np.interp(tc, tt, self.task_x[:, k]) for k in range(3)])
        if t > tt[-1] or t < tt[0]:
            return x, np.zeros(3)
        return x, np.array([np.interp(tc, tt, self._task_v[:, k]) for k in range(3)])

    @property
    def final_point(self) -> FloatArray:
        """The task's last position [m]."""
        return np.array(self.task_x[-1], dtype=float)

    def payload_held(self, t: float) -> bool:
        """Whether the declared payload is held at time t [s]."""
        p = self.payload
        if p is None:
            return False
        return t >= p.t_pick - 1e-12 and (p.t_drop is None or t < p.t_drop - 1e-12)


class ModelSwitch:
    """A controller's models of the arm without and with the declared payload.

    Args:
        context: The run's context (robot, payload).
        gravity: Gravity the controller assumes [m/s^2].
    """

    def __init__(self, context: RecoveryContext, gravity: Sequence[float] | FloatArray) -> None:
        from packbot.system import with_payload

        g = np.asarray(gravity, dtype=float)
        self.context = context
        self.base: tuple[pin.Model, pin.Data] = controller_model(context.robot, g)
        self.loaded: tuple[pin.Model, pin.Data] | None = None
        if context.payload is not None:
            self.loaded = controller_model(with_payload(context.robot, context.payload), g)

    def at(self, t: float) -> tuple[pin.Model, pin.Data]:
        """The model (and its data) for time t [s]: with the payload while it is held."""
        if self.loaded is not None and self.context.payload_held(t):
            return self.loaded
        return self.base


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class FailureReport:
    """A detected failure, as a recovery strategy receives it.

    Attributes:
        failure: The failure as estimated: the detected joint and kind, ``t`` the detection
            time [s]; ``scale`` the estimated effort scale (weak), ``torque`` the estimated
            torque (stuck), ``threshold`` the estimated brake torque (brake).
        detection: The observer's detection (residual [N*m], onset [s], torques).
        t: Time of the detection [s].
        q: Measured positions at the detection [rad].
        v: Measured velocities [rad/s].
        earlier: The failures reported before this one, in order.
        context: What the run knows besides its measurements.
    """

    failure: Failure
    detection: Detection
    t: float
    q: FloatArray
    v: FloatArray
    earlier: tuple[Failure, ...]
    context: RecoveryContext

    @property
    def all_failures(self) -> tuple[Failure, ...]:
        """The earlier failures and this one."""
        return (*self.earlier, self.failure)
