"""Task recovery: run any controller, detect a failed joint, then track a task with what is left.

:class:`TaskRecovery` is the "reconfigured" arm of a failure study (:func:`packbot.study`). It
wraps a scenario's own controller (``nominal``: PD, computed torque, Cartesian, reconfigurable,
or None for zero torque) and a task: the positions [m] of a frame (default ``gripper_tool``)
against time [s], as recorded on a healthy run. Until a failure is detected it returns exactly
the nominal controller's command, so that a healthy arm does what the scenario does. It is not
told of failures: a momentum observer (:class:`~packbot.control.detector.MomentumObserver`,
thresholds as :class:`~packbot.control.reconfig.ReconfigurableController`'s) watches the
commanded against the measured motion and flags the failed joint, classified ``"frozen"`` or
``"loose"``. From then on the failed joint is commanded zero and:

- frozen (also a brake that holds, a joint pinned by a contact): the task is tracked with the
  joints that still move the frame, by closed-loop inverse kinematics on the reference
  configuration q_r (q_r' = J^T (J J^T + lambda^2 I)^-1 (x*'(t) + K (x*(t) - p(q_r))), J the
  frame's position Jacobian on the working joints, the joint rates scaled to within
  ``speed_fraction`` of their limits, q_r clipped to the joint limits) and computed torque
  (RNEA of the full model with the frozen joint's speed and acceleration zero: the same torques
  as on the reduced model). The other working joints hold their angle at the detection;
- loose: an underactuated arm cannot follow a moving task; a static one needs the loose link
  at a stable equilibrium of its gravity torque. A
  :class:`~packbot.control.reconfig.ReconfigurableController` (``loose_options`` its settings)
  is started at the detection, told of the failures found so far, and holds the frame at the
  task's final point with the loose link hanging (its joint solve, partial feedback
  linearisation and swing damper). If no stable, collision-free equilibrium puts the frame
  there, it holds where it is (its log says so).

No collision avoidance is planned in the frozen case (the run's contacts are reported).
:attr:`TaskRecovery.log` lists what happened: detections, the switch of strategy and the loose
controller's plans.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    check_gain_spec,
    damping_ratio,
    loop_frequency,
    resolve_gains,
)
from packbot.control.base import Controller
from packbot.control.detector import MomentumObserver, default_threshold
from packbot.control.model_based import ModelBasedController
from packbot.control.reconfig import ReconfigurableController
from packbot.environment import Environment
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.validation import finite_number, name_str, real_array

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["RecoveryEvent", "TaskRecovery"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Settings of the loose-joint controller that ``loose_options`` may set.
LOOSE_OPTIONS: tuple[str, ...] = (
    "speed_fraction",
    "min_move_time",
    "omega",
    "zeta",
    "clearance",
    "ik_seeds",
    "seed",
    "sway_damping",
    "swing_return",
    "swing_check",
    "loose_margin",
)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class RecoveryEvent:
    """An entry of :attr:`TaskRecovery.log`.

    Attributes:
        t: Time [s].
        kind: ``"detect"`` (the observer flagged a joint), ``"track"`` (task tracking with the
            working joints started), ``"loose"`` (the loose-joint controller took over),
            ``"plan"`` / ``"replan"`` (the loose-joint controller's plans), ``"ignored"`` (a
            joint flagged while the loose-joint controller is in charge: not acted on).
        joint: The joint concerned ("" if none).
        detail: What, in words (failure kind, residual, plan result).
    """

    t: float
    kind: str
    joint: str = ""
    detail: str = ""


class TaskRecovery(ModelBasedController):
    """Run a controller; after a detected failure, track a frame's task with the working joints.

    Args:
        nominal: The controller run until a failure is detected (None: zero torque). It must not
            be shared with another simulation (it is reset here).
        task_t: Times of the task samples [s], shape (N,), non-decreasing, N >= 2.
        task_x: Frame positions [m], world frame, shape (N, 3).
        frame: The frame that follows the task.
        omega: Natural frequency of the tracking loop after a detection [rad/s].
        zeta: Its damping ratio [-].
        task_gain: Gain K of the task error in the inverse kinematics [1/s].
        max_task_speed: Largest correction speed K e [m/s] (a large error after a failure is
            closed at this speed).
        speed_fraction: The reference's joint rates stay within this fraction of the speed
            limits [-], in (0, 1] (the whole limit by default: the reduced arm may need faster
            joints than the healthy one to follow the same path).
        damping: Damping lambda of the pseudo-inverse [m].
        observer_gain: Observer gain K_O [1/s], below 2 / dt.
        threshold: Detection threshold [N*m] per joint (a number, nv numbers or {joint: value});
            None: coulomb + viscous * velocity limit + 0.01 * effort limit.
        persistence: Time the residual must stay above the threshold [s].
        joint_friction: The arm's joints have the parameter table's viscous and sliding Coulomb
            friction (``SimConfig.joint_friction``): the observer counts it as a known torque
            (without it, a joint driven past its speed limit reads its viscous torque as a
            failure: a PD hold drove camera_tilt at 7.6 rad/s and it was flagged "loose").
        locked: Joints held rigid by the arm's configuration (``SimConfig.locked_joints``):
            never judged by the observer (they look frozen from the start) and never moved by
            the tracking.
        frozen_speed: A flagged joint slower than this is frozen [rad/s].
        loose_options: Settings of the loose-joint :class:`ReconfigurableController` (keys of
            :data:`LOOSE_OPTIONS`).
        environment: Obstacles the loose-joint controller avoids (None: the floor).
        gravity: Gravity the controller assumes [m/s^2].

    Attributes:
        log: What happened (:class:`RecoveryEvent`).
        failed: Detected failed joints, index -> ``"frozen"`` or ``"loose"``.
        mode: ``"nominal"``, ``"track"`` or ``"loose"``.
        loose_controller: The loose-joint controller once started, else None.
    """

    def __init__(
        self,
        *,
        nominal: Controller | None,
        task_t: ArrayLike,
        task_x: ArrayLike,
        frame: str = "gripper_tool",
        omega: float = 20.0,
        zeta: float = 1.0,
        task_gain: float = 5.0,
        max_task_speed: float = 0.5,
        speed_fraction: float = 1.0,
        damping: float = 0.02,
        observer_gain: float = 50.0,
        threshold: GainLike | None = None,
        persistence: float = 0.02,
        frozen_speed: float = 1e-3,
        loose_options: Mapping[str, Any] | None = None,
        environment: Environment | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
        joint_friction: bool = False,
        locked: Sequence[str] = (),
    ) -> None:
        if nominal is not None and not isinstance(nominal, Controller):
            raise ConfigurationError("nominal", nominal, "None or a packbot.control.Controller")
        dt = 1e-3 if nominal is None else nominal.dt
        sensor = None if nominal is None else nominal.sensor
        super().__init__(dt=dt, sensor=sensor, gravity=gravity)
        self.nominal = nominal
        if not isinstance(joint_friction, bool):
            raise ConfigurationError("joint_friction", joint_friction, "True or False")
        self.joint_friction = joint_friction
        self.locked = tuple(str(x) for x in locked)
        t = real_array("task_t", task_t, expected="task times [s], shape (N,)")
        if t.ndim != 1 or len(t) < 2 or np.any(np.diff(t) < 0):
            raise ConfigurationError("task_t", task_t, "N >= 2 non-decreasing times [s]")
        x = real_array("task_x", task_x, expected="task positions [m], shape (N, 3)")
        if x.shape != (len(t), 3):
            raise ConfigurationError("task_x", x.shape, f"shape ({len(t)}, 3): one per time")
        keep = np.append(np.diff(t) > 0, True)  # duplicate times (events): the later sample
        self.task_t, self.task_x = t[keep], x[keep]
        if len(self.task_t) < 2:
            raise ConfigurationError("task_t", task_t, "at least 2 distinct times [s]")
        self._task_v = np.gradient(self.task_x, self.task_t, axis=0)
        self.frame = name_str("frame", frame, "a frame name (a non-empty string)")
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
        self.observer_gain = finite_number(
            "observer_gain",
            observer_gain,
            low=0.0,
            high=2.0 / self.dt,
            low_open=True,
            high_open=True,
            unit="1/s",
        )
        check_gain_spec(threshold, "threshold", positive=True)
        self.threshold_spec = threshold
        self.persistence = finite_number(
            "persistence", persistence, low=0.0, low_open=True, unit="s"
        )
        self.frozen_speed = finite_number(
            "frozen_speed", frozen_speed, low=0.0, low_open=True, unit="rad/s"
        )
        opts = dict(loose_options or {})
        if not isinstance(loose_options, (Mapping, type(None))):
            raise ConfigurationError("loose_options", loose_options, "a table of settings")
        for key in opts:
            if key not in LOOSE_OPTIONS:
                raise ConfigurationError(f"loose_options.{key}", opts[key], LOOSE_OPTIONS)
        self.loose_options = opts
        if environment is not None and not isinstance(environment, Environment):
            raise ConfigurationError("environment", environment, "None or a packbot.Environment")
        self.environment = environment
        self.log: list[RecoveryEvent] = []
        self.failed: dict[int, str] = {}
        self.mode = "nominal"
        self.loose_controller: ReconfigurableController | None = None
        self.observer: MomentumObserver | None = None
        self._tau_prev = np.zeros(0)
        self._movers = np.zeros(0, dtype=int)
        self._q_ref = np.zeros(0)
        self._v_ref = np.zeros(0)
        self._q_hold = np.zeros(0)
        self._t_last = 0.0
        self._fid = -1
        self._frame_joints: list[int] = []
        self._loose_seen = 0

    # ------------------------------------------------------------------ setup
    def prepare(self, robot: Robot) -> None:
        """Bind to a robot: the model, the frame, the thresholds (raises ConfigurationError)."""
        super().prepare(robot)
        model, _ = self._md()
        if not model.existFrame(self.frame):
            raise UnknownNameError("frame", self.frame, [f.name for f in model.frames])
        self._fid = model.getFrameId(self.frame)
        parent = model.frames[self._fid].parentJoint
        self._frame_joints = sorted(model.joints[j].idx_q for j in model.supports[parent] if j > 0)
        pp = robot.params
        default = default_threshold(pp)
        self.threshold = resolve_gains(robot, self.threshold_spec, "threshold", default)
        if np.any(self.threshold <= 0):
            raise ConfigurationError("threshold", self.threshold_spec, "values > 0 [N*m]")

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Reset the nominal controller and the observer at (q0 [rad], v0 [rad/s])."""
        self.prepare(robot)
        model, _ = self._md()
        q0 = np.asarray(q0, dtype=float)
        v0 = np.asarray(v0, dtype=float)
        if self.nominal is not None:
            self.nominal.reset(robot, t0, q0, v0)
        self.observer = MomentumObserver(
            model,
            robot.params.effort,
            gain=self.observer_gain,
            threshold=self.threshold,
            persistence=self.persistence,
            frozen_speed=self.frozen_speed,
            viscous=robot.params.viscous if self.joint_friction else None,
            coulomb=robot.params.coulomb if self.joint_friction else None,
        )
        self.observer.reset(t0, q0, v0)
        for name in self.locked:
            self.observer.ignored[robot.params.index(name)] = True
        self.log, self.failed, self.mode = [], {}, "nominal"
        self.loose_controller = None
        self._loose_seen = 0
        self._tau_prev = np.zeros(robot.nq)

    # ------------------------------------------------------------------ task
    def task(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The task's position [m] and velocity [m/s] at time t [s] (held after its end)."""
        tt = self.task_t
        tc = min(max(t, float(tt[0])), float(tt[-1]))
        x = np.array([np.interp(tc, tt, self.task_x[:, k]) for k in range(3)])
        if t > tt[-1] or t < tt[0]:
            return x, np.zeros(3)
        return x, np.array([np.interp(tc, tt, self._task_v[:, k]) for k in range(3)])

    # ------------------------------------------------------------------ control
    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Detect, switch strategy if needed, and return the command [N*m], shape (nv,)."""
        assert self.robot is not None and self.observer is not None
        det = self.observer.update(t, q, v, self._tau_prev)
        if det is not None:
            name = self.robot.joint_names[det.joint]
            self.log.append(
                RecoveryEvent(
                    t=t,
                    kind="detect",
                    joint=name,
                    detail=f"{det.kind}: residual {det.residual:.3g} N*m since "
                    f"t = {det.t_onset:.4g} s",
                )
            )
            self._on_detection(t, det.joint, det.kind, q, v)
        if self.mode == "nominal":
            tau = (
                np.zeros(len(q))
                if self.nominal is None
                else np.array(self.nominal.compute(t, q, v), dtype=float)
            )
        elif self.mode == "track":
            tau = self._track(t, q, v)
        else:
            assert self.loose_controller is not None
            tau = np.array(self.loose_controller.compute(t, q, v), dtype=float)
            self._copy_loose_log()
        for j in self.failed:
            tau[j] = 0.0
        self._tau_prev = tau.copy()
        return tau

    def _on_detection(self, t: float, j: int, kind: str, q: FloatArray, v: FloatArray) -> None:
        assert self.robot is not None
        names = self.robot.joint_names
        if self.mode == "loose":
            # The swinging link's transient can push other joints' residuals over their
            # thresholds; the loose-joint controller handles one failed joint at a time.
            self.log.append(
                RecoveryEvent(
                    t=t, kind="ignored", joint=names[j], detail=f"{kind}: a loose joint is handled"
                )
            )
            return
        self.failed[j] = kind
        if kind == "loose":
            self._start_loose(t, q, v)
            return
        # frozen: track the task with the joints that still move the frame
        self.mode = "track"
        rigid = {self.robot.params.index(x) for x in self.locked}
        self._movers = np.array(
            [i for i in self._frame_joints if i not in self.failed and i not in rigid], dtype=int
        )
        self._q_ref = np.array(q, dtype=float)
        self._v_ref = np.array(v, dtype=float)
        for i in self.failed:
            self._v_ref[i] = 0.0
        self._q_hold = np.array(q, dtype=float)
        self._t_last = t
        moving = ", ".join(names[i] for i in self._movers)
        self.log.append(
            RecoveryEvent(t=t, kind="track", joint=names[j], detail=f"tracking with {moving}")
        )

    def _start_loose(self, t: float, q: FloatArray, v: FloatArray) -> None:
        assert self.robot is not None
        from packbot.failures import Failure

        ctrl = ReconfigurableController(
            target=self.task_x[-1],
            frame=self.frame,
            detect=False,
            environment=self.environment,
            dt=self.dt,
            gravity=tuple(self.gravity),
            **self.loose_options,
        )
        ctrl.reset(self.robot, t, np.asarray(q, dtype=float), np.asarray(v, dtype=float))
        names = self.robot.joint_names
        for i, kind in self.failed.items():
            ctrl.on_failure(Failure(joint=names[i], kind=kind), t)  # type: ignore[arg-type]
        self.loose_controller = ctrl
        self.mode = "loose"
        self._loose_seen = len(ctrl.events)  # its initial (healthy) plan is not reported
        x = self.task_x[-1]
        self.log.append(
            RecoveryEvent(
                t=t,
                kind="loose",
                joint=", ".join(names[i] for i in self.failed),
                detail=f"holding the task's final point ({x[0]:.3f}, {x[1]:.3f}, {x[2]:.3f}) m "
                "with the loose link at a stable equilibrium",
            )
        )

    def _copy_loose_log(self) -> None:
        assert self.loose_controller is not None
        events = self.loose_controller.events
        for e in events[self._loose_seen :]:
            if e.kind in ("plan", "replan"):
                self.log.append(RecoveryEvent(t=e.t, kind=e.kind, joint=e.joint, detail=e.detail))
        self._loose_seen = len(events)

    def _track(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        assert self.robot is not None
        model, data = self._md()
        h = max(t - self._t_last, 0.0)
        self._t_last = t
        m = self._movers
        if h > 0 and len(m):
            x_star, xd_star = self.task(t)
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
        held = np.array(
            [i for i in range(len(q)) if i not in self.failed and i not in set(m.tolist())],
            dtype=int,
        )
        a[m] = kp * (self._q_ref[m] - q[m]) + kd * (self._v_ref[m] - v[m])
        if len(held):
            a[held] = kp * (self._q_hold[held] - q[held]) - kd * v[held]
        vv = np.array(v, dtype=float)
        for i in self.failed:
            vv[i] = 0.0
        return np.array(pin.rnea(model, data, np.asarray(q, dtype=float), vv, a), dtype=float)
