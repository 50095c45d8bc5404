"""Task recovery: run any controller, detect a failed joint, hand over to a recovery strategy.

:class:`TaskRecovery` is the controller of the "reconfigured" run of a failure study
(:func:`packbot.study`). It wraps the scenario's own controller (``nominal``: a built-in one,
a user's :class:`~packbot.control.Controller`, or None for zero torque) and a task: the
positions [m] of a frame (default the robot's tool frame) against time [s], as recorded on a healthy
run. Until a failure is detected it returns exactly the nominal controller's command, so that a
healthy arm does what the scenario does. It is not told of failures: a momentum observer
(:class:`~packbot.control.detector.MomentumObserver`, thresholds as
:class:`~packbot.control.reconfig.ReconfigurableController`'s) watches the commanded against
the measured motion, knowing what was declared (the joints' friction, the locked joints, a
scheduled payload, and, through ``in_contact``, when the arm touches something), and flags the
failed joint with its kind and estimate.

Each detection goes to the recovery ``strategy`` (:mod:`packbot.control.strategies`; default
:class:`~packbot.control.strategies.BaselineRecovery`) as a
:class:`~packbot.control.context.FailureReport`; the controller it returns is in charge from
then on (a new one reset at the detection's state and told of the failures so far).
:attr:`TaskRecovery.log` lists what happened: detections, switches, the strategy's notes, the
loose-joint controller's plans and the intervals in which no joint was judged (a contact).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    check_gain_spec,
    controlled_frame,
    frame_spec,
    resolve_gains,
)
from packbot.control.base import Controller
from packbot.control.context import FailureReport, ModelSwitch, RecoveryContext, RecoveryEvent
from packbot.control.detector import Detection, MomentumObserver, default_threshold
from packbot.control.strategies import BaselineRecovery, RecoveryStrategy
from packbot.environment import Environment
from packbot.errors import ConfigurationError
from packbot.failures import Failure
from packbot.payload import Payload
from packbot.validation import finite_number, real_array

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["LOOSE_OPTIONS", "RecoveryEvent", "TaskRecovery"]

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


def estimated_failure(det: Detection, joint: str) -> Failure:
    """The :class:`~packbot.failures.Failure` a detection estimates (kind, time, estimates)."""
    kw: dict[str, Any] = {}
    if det.kind == "weak" and np.isfinite(det.scale):
        kw["scale"] = float(det.scale)
    elif det.kind == "stuck" and np.isfinite(det.torque):
        kw["torque"] = float(det.torque)
    elif det.kind == "brake" and np.isfinite(det.torque) and det.torque > 0:
        kw["threshold"] = float(det.torque)
    return Failure(joint=joint, kind=det.kind, t=det.t, **kw)  # type: ignore[arg-type]


class TaskRecovery(Controller):
    """Run a controller; on each detected failure, let a recovery strategy take over.

    Args:
        nominal: The controller run until a failure is detected (None: zero torque). It must not
            be shared with another simulation (it is reset here).
        task_t: Times of the task samples [s], shape (N,), non-decreasing, N >= 2.
        task_x: Frame positions [m], world frame, shape (N, 3).
        frame: The frame that follows the task; None: the robot's tool frame
            (:attr:`packbot.Robot.tool_frame`, PackBot's ``gripper_tool``).
        strategy: The recovery strategy (None: a :class:`BaselineRecovery` with the tracking
            settings below). Made for this run (it may keep state).
        omega: Natural frequency of the built-in strategy's tracking loops [rad/s].
        zeta: Their damping ratio [-].
        task_gain: Gain K of the task error in the reduced arm's inverse kinematics [1/s].
        max_task_speed: Largest correction speed K e [m/s].
        speed_fraction: The reduced arm's joint rates within this fraction of the speed
            limits [-], in (0, 1].
        damping: Damping lambda of the pseudo-inverse [m].
        observer_gain: Observer gain K_O [1/s], below 2 / dt.
        threshold: Detection threshold [N*m] per joint (a number, nv numbers or {joint: value});
            None: coulomb + viscous * velocity limit + 0.01 * effort limit.
        persistence: Time the residual must stay above the threshold [s].
        frozen_speed: A flagged joint slower than this is frozen [rad/s].
        loose_options: Settings of the loose-joint :class:`ReconfigurableController` (keys of
            :data:`LOOSE_OPTIONS`).
        environment: Obstacles (None: the floor).
        gravity: Gravity the controller assumes [m/s^2].
        joint_friction: The arm's joints have the parameter table's viscous and sliding Coulomb
            friction (``SimConfig.joint_friction``): the observer counts it as a known torque.
        locked: Joints held rigid by the arm's configuration (``SimConfig.locked_joints``):
            never judged by the observer and never moved by the strategies.
        payload: The scenario's declared payload: the observer's model holds it from its pick-up
            to its drop (None: none).
        in_contact: Callable of the measured q [rad]: whether the arm touches something; no
            joint is judged then where the simulator cannot tell the contact forces (None: the
            observer is not told of contacts there). Where it can, the observer counts them
            (the class senses contacts: :attr:`~packbot.control.Controller.contact_sensing`).

    Attributes:
        log: What happened (:class:`RecoveryEvent`).
        failed: Detected failed joints, index -> kind.
        detections: The observer's detections, in order.
        mode: ``"nominal"`` until the first detection, then ``"recovery"``.
        active: The controller in charge (None: zero torque).
    """

    contact_sensing = True

    def __init__(
        self,
        *,
        nominal: Controller | None,
        task_t: ArrayLike,
        task_x: ArrayLike,
        frame: str | None = None,
        strategy: RecoveryStrategy | None = None,
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
        payload: Payload | None = None,
        in_contact: Callable[[FloatArray], bool] | None = None,
    ) -> None:
        if nominal is not None and not isinstance(nominal, Controller):
            raise ConfigurationError("nominal", nominal, "None or a packbot.control.Controller")
        dt = 1e-3 if nominal is None else nominal.dt
        sensor = None if nominal is None else nominal.sensor
        super().__init__(dt=dt, sensor=sensor)
        self.nominal = nominal
        if not isinstance(joint_friction, bool):
            raise ConfigurationError("joint_friction", joint_friction, "True or False")
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
        self.frame_spec = frame_spec("frame", frame)
        self.frame = "" if frame is None else frame
        if strategy is not None and not isinstance(strategy, RecoveryStrategy):
            raise ConfigurationError(
                "strategy", strategy, "None (built-in) or a packbot.control.RecoveryStrategy"
            )
        self.strategy = strategy or BaselineRecovery(
            omega=omega,
            zeta=zeta,
            task_gain=task_gain,
            max_task_speed=max_task_speed,
            speed_fraction=speed_fraction,
            damping=damping,
        )
        # the tracking settings are checked even when a strategy of one's own is given
        for name, value, unit in (
            ("task_gain", task_gain, "1/s"),
            ("damping", damping, "m"),
        ):
            finite_number(name, value, low=0.0, unit=unit)
        finite_number("max_task_speed", max_task_speed, low=0.0, low_open=True, unit="m/s")
        finite_number("speed_fraction", speed_fraction, low=0.0, high=1.0, low_open=True)
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
        if not isinstance(loose_options, (Mapping, type(None))):
            raise ConfigurationError("loose_options", loose_options, "a table of settings")
        opts = dict(loose_options or {})
        for key in opts:
            if key not in LOOSE_OPTIONS:
                raise ConfigurationError(f"loose_options.{key}", opts[key], LOOSE_OPTIONS)
        self.loose_options = opts
        if environment is not None and not isinstance(environment, Environment):
            raise ConfigurationError("environment", environment, "None or a packbot.Environment")
        if payload is not None and not isinstance(payload, Payload):
            raise ConfigurationError("payload", payload, "None or a packbot.Payload")
        if in_contact is not None and not callable(in_contact):
            raise ConfigurationError("in_contact", in_contact, "None or a callable(q) -> bool")
        self.environment = environment
        self.gravity = tuple(float(g) for g in gravity)
        self.joint_friction = joint_friction
        self.locked = tuple(str(x) for x in locked)
        self.payload = payload
        self.in_contact = in_contact
        self.context: RecoveryContext | None = None
        self.log: list[RecoveryEvent] = []
        self.failed: dict[int, str] = {}
        self.detections: list[Detection] = []
        self.mode = "nominal"
        self.active: Controller | None = nominal
        self.observer: MomentumObserver | None = None
        self._tau_prev = np.zeros(0)
        self._seen = 0  # entries of the active controller's own event list copied

    # ------------------------------------------------------------------ setup
    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Reset the nominal controller and the observer at (q0 [rad], v0 [rad/s])."""
        q0 = np.asarray(q0, dtype=float)
        v0 = np.asarray(v0, dtype=float)
        self.frame = controlled_frame(robot.model, robot, self.frame_spec)[0]
        threshold = resolve_gains(
            robot, self.threshold_spec, "threshold", default_threshold(robot.params)
        )
        if np.any(threshold <= 0):
            raise ConfigurationError("threshold", self.threshold_spec, "values > 0 [N*m]")
        self.context = RecoveryContext(
            robot=robot,
            task_t=self.task_t,
            task_x=self.task_x,
            frame=self.frame,
            environment=self.environment,
            gravity=self.gravity,  # type: ignore[arg-type]
            joint_friction=self.joint_friction,
            locked=self.locked,
            payload=self.payload,
            loose_options=self.loose_options,
        )
        if self.nominal is not None:
            self.nominal.reset(robot, t0, q0, v0)
        models = ModelSwitch(self.context, self.gravity)
        p = self.payload
        self.observer = MomentumObserver(
            models.base[0],
            robot.params.effort,
            gain=self.observer_gain,
            threshold=threshold,
            persistence=self.persistence,
            frozen_speed=self.frozen_speed,
            viscous=robot.params.viscous if self.joint_friction else None,
            coulomb=robot.params.coulomb if self.joint_friction else None,
            payload_model=None if models.loaded is None else models.loaded[0],
            t_pick=0.0 if p is None else p.t_pick,
            t_drop=None if p is None else p.t_drop,
            in_contact=self.in_contact,
        )
        self.observer.reset(t0, q0, v0)
        for name in self.locked:
            self.observer.ignored[robot.params.index(name)] = True
        self.log, self.failed, self.detections, self.mode = [], {}, [], "nominal"
        self.active = self.nominal
        self.strategy.events.clear()
        self._seen = 0
        self._tau_prev = np.zeros(robot.nq)

    # ------------------------------------------------------------------ control
    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Detect, hand over if needed, and return the command [N*m], shape (nv,)."""
        assert self.robot is not None and self.observer is not None
        det = self.observer.update(
            t, q, v, self._tau_prev, self.contact_torque, self.contact_impulse
        )
        if det is not None:
            self._on_detection(det, t, q, v)
        if self.active is None:
            tau = np.zeros(len(q))
        else:
            tau = np.array(self.active.compute(t, q, v), dtype=float)
            self._copy_events()
        self._tau_prev = tau.copy()
        return tau

    def _on_detection(self, det: Detection, t: float, q: FloatArray, v: FloatArray) -> None:
        assert self.robot is not None and self.context is not None
        name = self.robot.joint_names[det.joint]
        self.log.append(
            RecoveryEvent(
                t=t,
                kind="detect",
                joint=name,
                detail=f"{det.describe()}: residual {det.residual:.3g} N*m since "
                f"t = {det.t_onset:.4g} s",
                detection=det,
            )
        )
        earlier = tuple(
            estimated_failure(d, self.robot.joint_names[d.joint]) for d in self.detections
        )
        self.detections.append(det)
        self.failed[det.joint] = det.kind
        report = FailureReport(
            failure=estimated_failure(det, name),
            detection=det,
            t=t,
            q=np.array(q, dtype=float),
            v=np.array(v, dtype=float),
            earlier=earlier,
            context=self.context,
        )
        before = self.active
        after = self.strategy.on_failure(report, before)
        self.log.extend(self.strategy.events)
        self.strategy.events.clear()
        self.mode = "recovery"
        if after is not None and not isinstance(after, Controller):
            raise ConfigurationError(
                f"{type(self.strategy).__name__}.on_failure",
                after,
                "the controller in charge: a packbot.control.Controller or None",
            )
        if after is not before:
            if after is not None:
                after.reset(self.robot, t, report.q, report.v)
                events = getattr(after, "events", None)
                self._seen = len(events) if isinstance(events, list) else 0
                for f in report.all_failures:
                    after.on_failure(f, t)
            what = "zero torque" if after is None else type(after).__name__
            self.log.append(RecoveryEvent(t=t, kind="switch", joint=name, detail=what))
        self.active = after

    def _copy_events(self) -> None:
        """The loose-joint controller's plans, into the log."""
        events = getattr(self.active, "events", None)
        if not isinstance(events, list) or self.active is self.nominal:
            return
        for e in events[self._seen :]:
            if getattr(e, "kind", "") in ("plan", "replan"):
                self.log.append(RecoveryEvent(t=e.t, kind=e.kind, joint=e.joint, detail=e.detail))
        self._seen = len(events)

    def suspended(self) -> list[tuple[float, float]]:
        """Intervals [s] in which no joint was judged because the arm touched something."""
        return [] if self.observer is None else list(self.observer.contact_intervals)
