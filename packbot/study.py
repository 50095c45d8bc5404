"""The failure study: what a failure costs, and whether reconfiguration recovers the task.

:func:`study` runs a scenario with ``[[failures]]`` three times:

- ``healthy``: the failures removed; the positions of the robot's tool frame
  (:attr:`packbot.Robot.tool_frame`, PackBot's ``gripper_tool``) against time on this run are the
  *task*;
- ``failed``: the failures injected, the scenario's controller unaware (not informed; a
  reconfigurable controller's detector switched off);
- ``reconfigured``: the failures injected, :class:`~packbot.control.recovery.TaskRecovery` in
  charge: the scenario's controller until its momentum observer flags a joint (it is not told),
  then the healthy task tracked with the joints that still work (a frozen joint), or the task's
  final point held with the loose link at a stable equilibrium (a loose joint).

Each run gets :class:`RunMetrics` against the task (errors [m], detection and recovery times
[s], peak torque [N*m] and its ratio to the effort limit, contacts and their peak approach speed
[m/s], energy [J]). :class:`Recovery` says beforehand whether recovery is possible and why not:
the task's points after the failure tested for reach with the frozen joint at its angle
(:func:`packbot.analysis.reach`), a loose joint without gravity torque (nothing holds it), a
stuck joint, a weak motor that cannot hold the final pose; after the run, a loose joint for which
no stable equilibrium puts the tool on the task. For a loose joint, :class:`LooseSettling`
compares where the arm comes to rest with the equilibria :func:`packbot.analysis.
loose_joint_equilibria` predicts for the other joints' final angles.

A run the simulator refuses (a combination of settings it does not solve, e.g. a hand-off
scenario studied with ``contact_mode="normal"``) or that stops with an error is reported with
its reason (``status`` ``"refused"`` or ``"error"``), not raised.

This module computes; writing the report (JSON, figures, HTML) is :mod:`packbot.viz.study_report`.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, PackbotError, SimulationError
from packbot.keywords import checked_arguments
from packbot.validation import MAX_CONFIG_SAMPLES, finite_number, integer

if TYPE_CHECKING:
    from packbot.analysis import Equilibrium
    from packbot.collision import CollisionWorld
    from packbot.control.base import Controller
    from packbot.control.context import RecoveryEvent
    from packbot.control.strategies import RecoveryStrategy
    from packbot.control.user_code import ControllerSpec, StrategySpec
    from packbot.failures import Failure
    from packbot.model import Robot
    from packbot.result import SimResult
    from packbot.scenario import Scenario

__all__ = [
    "CONTACT_GATE",
    "DEFAULT_TOLERANCE",
    "KEEP_MARGIN",
    "RUN_NAMES",
    "LooseSettling",
    "Reconfiguration",
    "Recovery",
    "RunMetrics",
    "StudyResult",
    "StudyRun",
    "contact_gate",
    "study",
    "verdict_lines",
    "verdict_text",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: The three runs of a study, in order.
RUN_NAMES: tuple[str, ...] = ("healthy", "failed", "reconfigured")
#: Default recovery tolerance on the task error [m].
DEFAULT_TOLERANCE = 0.01
#: PackBot's task frame (its tool frame); a study's task is its robot's ``tool_frame``.
TASK_FRAME = "gripper_tool"
#: A loose joint slower than this at the end is at rest [rad/s].
REST_SPEED = 0.01

RunStatus = Literal["ok", "refused", "error"]


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class RunMetrics:
    """What one run of a study measured, against the task (the healthy run's tool path).

    Attributes:
        detect_time_s: Time of the first failure detection [s] (the reconfigured run's
            observer); None if nothing was detected or the run has no detector.
        detect_delay_s: ``detect_time_s`` minus the first failure's time [s], or None.
        detected_joint: The joint flagged first, or None.
        detected_kind: Its classification (``"frozen"``, ``"loose"``, ``"weak"``, ``"stuck"``,
            ``"brake"``), or None.
        detected_scale: A weak joint's estimated effort scale [-], or None.
        false_detections: Detections of a joint that has not failed, or before its failure.
        recover_time_s: First time at or after the first failure from which the task error
            stays within the tolerance to the end [s]; None if it ends outside (the healthy
            run: the failure's time).
        recovered: Whether the run ends within the tolerance.
        final_task_error_m: Task error at the end [m].
        rms_task_error_m: Root mean square of the task error over time from the first failure
            to the end [m] (time-weighted, trapezoidal).
        max_task_error_m: Largest task error after the first failure [m].
        peak_torque_nm: Largest applied joint torque magnitude [N*m].
        peak_torque_joint: The joint where it occurred.
        peak_torque_ratio: Largest |applied torque| / effort limit over joints and time [-],
            the limit as it is at each sample (a weak joint's reduced one: ``SimResult.effort``).
        peak_torque_ratio_joint: The joint where that ratio is largest.
        contacts: Number of impacts (pairs of pieces coming into contact).
        limit_hits: Number of joint-stop events.
        peak_impact_speed_m_s: Largest approach speed of a pair at an impact [m/s] (the relative
            speed of the witness points along the contact normal; 0 without impacts).
        min_distance_m: Smallest signed distance seen [m].
        energy_initial_j: Total mechanical energy at the start [J].
        energy_final_j: At the end [J].
        events: Number of entries in the event log.
        duration_s: Simulated time [s].
        wall_time_s: Wall-clock time of the simulation [s].
    """

    detect_time_s: float | None
    detect_delay_s: float | None
    detected_joint: str | None
    detected_kind: str | None
    detected_scale: float | None
    false_detections: int
    recover_time_s: float | None
    recovered: bool
    final_task_error_m: float
    rms_task_error_m: float
    max_task_error_m: float
    peak_torque_nm: float
    peak_torque_joint: str
    peak_torque_ratio: float
    peak_torque_ratio_joint: str
    contacts: int
    limit_hits: int
    peak_impact_speed_m_s: float
    min_distance_m: float
    energy_initial_j: float
    energy_final_j: float
    events: int
    duration_s: float
    wall_time_s: float

    def to_dict(self) -> dict[str, Any]:
        """The metrics as a JSON-ready dict (non-finite numbers as None)."""
        return {k: _json_number(v) for k, v in dataclasses.asdict(self).items()}


@checked_arguments
@dataclass(kw_only=True)
class StudyRun:
    """One run of a study.

    Attributes:
        name: ``"healthy"``, ``"failed"`` or ``"reconfigured"``.
        status: ``"ok"``; ``"refused"`` (the simulator refused the combination: ``reason``
            says why); ``"error"`` (the simulation stopped: ``reason``; ``result`` holds the
            samples up to then if any).
        reason: Why the run was refused or stopped ("" when ok).
        result: The simulation result, or None.
        metrics: Its metrics, or None without a result.
        task_error: Task error at each sample of ``result`` [m], or None.
        tool: The tool frame's position at each sample [m], shape (N, 3), or None.
        controller_log: The reconfigured run's :attr:`TaskRecovery.log` (empty otherwise).
        suspended: Intervals [s] in which its observer judged no joint (the arm touched
            something).
    """

    name: str
    status: RunStatus
    reason: str = ""
    result: SimResult | None = None
    metrics: RunMetrics | None = None
    task_error: FloatArray | None = None
    tool: FloatArray | None = None
    controller_log: tuple[RecoveryEvent, ...] = ()
    suspended: tuple[tuple[float, float], ...] = ()

    @property
    def detections(self) -> list[RecoveryEvent]:
        """The ``"detect"`` entries of the controller log."""
        return [e for e in self.controller_log if e.kind == "detect"]


@dataclass(frozen=True, kw_only=True)
class Reconfiguration:
    """Whether the reconfigured run's strategy was applied, against leaving the arm unaware.

    The study runs the strategy and compares its final task error with the failed run's: a
    strategy that ends more than :data:`KEEP_MARGIN` farther from the task is not applied (the
    reconfigured run is then the unaware one, its detections kept; the strategy's run is kept as
    :attr:`StudyResult.attempt`).

    Attributes:
        applied: Whether the strategy's run is the reconfigured run.
        strategy: The strategy's name.
        attempted_final_task_error_m: Where the strategy's run ends [m] (None: no such run).
        unaware_final_task_error_m: Where the failed run ends [m] (None: no such run).
        verdict: The comparison in words, both numbers given.
    """

    applied: bool
    strategy: str
    attempted_final_task_error_m: float | None
    unaware_final_task_error_m: float | None
    verdict: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {k: _json_number(v) for k, v in dataclasses.asdict(self).items()}


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Recovery:
    """Whether recovering the task is possible, and why not.

    Attributes:
        possible: True, False, or None (not decided: e.g. no healthy task).
        reasons: Sentences: why not, or what limits it.
        checks: Per failure, what was tested (JSON-ready dicts).
        harmless: The failure does no harm: the unaware controller ends within the tolerance.
    """

    possible: bool | None
    reasons: tuple[str, ...] = ()
    checks: tuple[dict[str, Any], ...] = ()
    harmless: bool = False


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class LooseSettling:
    """Where a loose joint came to rest in one run, against the predicted equilibria.

    The equilibria are :func:`packbot.analysis.loose_joint_equilibria` of the loose joint with
    the other joints held at their final angles in that run.

    Attributes:
        joint: The loose joint.
        run: ``"failed"`` or ``"reconfigured"``.
        settled_angle_rad: The joint's final angle [rad].
        final_speed_rad_s: Its final speed [rad/s].
        at_rest: Whether that speed is below :data:`REST_SPEED`.
        equilibria: The predicted rest positions.
        nearest_angle_rad: The predicted rest position nearest the final angle [rad] (NaN if
            none: a joint without gravity torque).
        nearest_kind: Its kind (``"root"``, ``"limit"``, "" if none).
        nearest_stable: Whether it is stable.
        offset_rad: Final angle minus that rest position [rad] (NaN if none).
        final_distance_m: Smallest signed distance of the arm at the end [m]: near zero, the
            link rests on a contact rather than at an equilibrium of gravity alone.
        angles_rad: Angles at which the gravity torque was sampled [rad] (for a figure).
        gravity_torque_nm: g_j at those angles, the others at their final angles [N*m].
    """

    joint: str
    run: str
    settled_angle_rad: float
    final_speed_rad_s: float
    at_rest: bool
    equilibria: tuple[Equilibrium, ...]
    nearest_angle_rad: float
    nearest_kind: str
    nearest_stable: bool
    offset_rad: float
    final_distance_m: float
    angles_rad: FloatArray
    gravity_torque_nm: FloatArray

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (without the sampled curve)."""
        return {
            "joint": self.joint,
            "run": self.run,
            "settled_angle_rad": _json_number(self.settled_angle_rad),
            "final_speed_rad_s": _json_number(self.final_speed_rad_s),
            "at_rest": self.at_rest,
            "nearest_angle_rad": _json_number(self.nearest_angle_rad),
            "nearest_kind": self.nearest_kind,
            "nearest_stable": self.nearest_stable,
            "offset_rad": _json_number(self.offset_rad),
            "final_distance_m": _json_number(self.final_distance_m),
            "equilibria": [
                {
                    "angle_rad": e.angle,
                    "kind": e.kind,
                    "stable": e.stable,
                    "stiffness_nm_per_rad": _json_number(e.stiffness),
                    "in_collision": e.in_collision,
                    "min_distance_m": _json_number(e.min_distance),
                }
                for e in self.equilibria
            ],
        }


@checked_arguments
@dataclass(kw_only=True)
class StudyResult:
    """The outcome of :func:`study`.

    Attributes:
        scenario: The scenario studied (its failures and controller).
        robot: The robot simulated.
        duration_s: Simulated time of each run [s].
        tolerance_m: Recovery tolerance on the task error [m].
        contact_mode: The contact mode of the runs.
        task_t: Times of the task [s] (the healthy run's samples; empty without one).
        task_x: The task: the tool frame's positions [m], shape (N, 3).
        healthy: The healthy run.
        failed: The failed run.
        reconfigured: The reconfigured run.
        recovery: Whether recovery is possible, and why not.
        loose: For each loose joint and run, where it settled against the predicted equilibria.
        controller: What controlled the runs: the scenario's controller kind, or the user's
            controller's name.
        reconfiguration: Whether the strategy's run was applied, and both final errors.
        attempt: The strategy's own run when it was not applied (else None).
    """

    scenario: Scenario
    robot: Robot
    duration_s: float
    tolerance_m: float
    contact_mode: str
    task_t: FloatArray
    task_x: FloatArray
    healthy: StudyRun
    failed: StudyRun
    reconfigured: StudyRun
    recovery: Recovery
    loose: tuple[LooseSettling, ...] = ()
    controller: str = ""
    reconfiguration: Reconfiguration | None = None
    attempt: StudyRun | None = None

    @property
    def runs(self) -> dict[str, StudyRun]:
        """The three runs by name (:data:`RUN_NAMES` order)."""
        return {"healthy": self.healthy, "failed": self.failed, "reconfigured": self.reconfigured}

    @property
    def failures(self) -> tuple[Failure, ...]:
        """The scenario's failures."""
        return tuple(self.scenario.failures)

    @property
    def failure_time(self) -> float:
        """The first failure's time [s]."""
        return min(f.t for f in self.scenario.failures)

    def summary(self) -> dict[str, Any]:
        """Everything but the trajectories, JSON-ready (what ``study.json`` holds)."""
        runs: dict[str, Any] = {}
        for name, run in self.runs.items():
            entry: dict[str, Any] = {"status": run.status, "reason": run.reason}
            if run.metrics is not None:
                entry |= run.metrics.to_dict()
            if run.controller_log:
                entry["controller_log"] = [
                    {"t_s": e.t, "kind": e.kind, "joint": e.joint, "detail": e.detail}
                    for e in run.controller_log
                ]
                entry["detections"] = self._detections(run)
            if run.suspended:
                entry["detection_suspended_s"] = [list(iv) for iv in run.suspended]
            runs[name] = entry
        if self.attempt is not None and self.attempt.metrics is not None:
            runs["reconfigured"]["attempt"] = self.attempt.metrics.to_dict()
        return {
            "scenario": self.scenario.name,
            "description": self.scenario.description,
            "controller": self.controller or self.scenario.controller,
            "contact_mode": self.contact_mode,
            "duration_s": self.duration_s,
            "tolerance_m": self.tolerance_m,
            "task_frame": self.robot.tool_frame,
            "failures": [
                {k: _json_number(v) for k, v in dataclasses.asdict(f).items()} | {"t_s": f.t}
                for f in self.failures
            ],
            "recovery": {
                "possible": self.recovery.possible,
                "reasons": list(self.recovery.reasons),
                "checks": list(self.recovery.checks),
                "harmless": self.recovery.harmless,
            },
            "reconfiguration": (
                None if self.reconfiguration is None else self.reconfiguration.to_dict()
            ),
            "runs": runs,
            "loose_equilibria": [s.to_dict() for s in self.loose],
        }

    def _detections(self, run: StudyRun) -> list[dict[str, Any]]:
        """Each detection: time, joint, kind, estimates, delay after the joint's failure."""
        return [
            {
                "t_s": e.t,
                "joint": e.joint,
                "kind": None if e.detection is None else e.detection.kind,
                "scale": None if e.detection is None else _json_number(e.detection.scale),
                "torque_nm": None if e.detection is None else _json_number(e.detection.torque),
                "delay_s": _delay(self.scenario, e),
                "false": _is_false(self.scenario, e),
            }
            for e in run.detections
        ]


def _failure_of(scenario: Scenario, joint: str) -> Failure | None:
    """The joint's first failure in time (a joint may fail again later), or None."""
    of_joint = [f for f in scenario.failures if f.joint == joint]
    return min(of_joint, key=lambda f: f.t) if of_joint else None


def _next_failure_time(scenario: Scenario, failure: Failure) -> float:
    """When the failure's joint fails again [s] (inf: never): the end of this failure's span."""
    later = [f.t for f in scenario.failures if f.joint == failure.joint and f.t > failure.t]
    return min(later, default=math.inf)


def _delay(scenario: Scenario, event: RecoveryEvent) -> float | None:
    """A detection's delay after its joint's failure [s] (None: that joint did not fail)."""
    f = _failure_of(scenario, event.joint)
    return None if f is None else float(event.t - f.t)


def _is_false(scenario: Scenario, event: RecoveryEvent) -> bool:
    """A detection of a joint that has not failed, or before its failure."""
    f = _failure_of(scenario, event.joint)
    return f is None or event.t < f.t


def _json_number(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.floating):
        return _json_number(float(x))
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


# ---------------------------------------------------------------------------------- inputs
def check_failure_within(scenario: Scenario, duration: float | None, field: str) -> None:
    """Refuse a study whose runs end before its first failure (nothing to study).

    Args:
        scenario: The study's scenario (with its failures).
        duration: The runs' duration [s] (None: the scenario's).
        field: The field the error names.

    Raises:
        ConfigurationError: The first failure's time is at or after the runs' end.
    """
    t_end = scenario.duration if duration is None else float(duration)
    t_fail = min((f.t for f in scenario.failures), default=math.inf)
    if t_fail >= t_end:
        raise ConfigurationError(
            field,
            t_end,
            f"a duration [s] longer than the first failure's time, {t_fail:g} s (the runs "
            "would end before the failure)",
        )


def _check_inputs(
    scenario: Scenario | str | Path,
    robot: Robot | None,
    duration: float | None,
    tolerance: float,
    contact_mode: str | None,
    workspace_samples: int,
) -> tuple[Scenario, Robot]:
    from packbot.config import CONTACT_MODES
    from packbot.model import Robot
    from packbot.scenario import Scenario, load_scenario, scenario_robot

    if isinstance(scenario, (str, Path)):
        scenario = load_scenario(scenario)
    elif not isinstance(scenario, Scenario):
        raise ConfigurationError(
            "scenario", scenario, "a scenario name, a TOML path or a packbot.scenario.Scenario"
        )
    if robot is None:
        robot = scenario_robot(scenario)
    elif not isinstance(robot, Robot):
        raise ConfigurationError("robot", robot, "None or a packbot.Robot (from load_robot())")
    if not scenario.failures:
        raise ConfigurationError(
            "scenario.failures",
            [],
            f"a scenario with [[failures]] (scenario {scenario.name!r} has none)",
        )
    if duration is not None:
        finite_number("duration", duration, low=0.0, low_open=True, unit="s", what="a time")
    check_failure_within(
        scenario, duration, "duration" if duration is not None else "scenario.duration"
    )
    finite_number("tolerance", tolerance, low=0.0, low_open=True, unit="m", what="a distance")
    if contact_mode is not None and contact_mode not in CONTACT_MODES:
        raise ConfigurationError("contact_mode", contact_mode, CONTACT_MODES)
    integer("workspace_samples", workspace_samples, low=100, high=MAX_CONFIG_SAMPLES)
    scenario.validate(robot)
    return scenario, robot


# ---------------------------------------------------------------------------------- study
@checked_arguments
def study(
    scenario: Scenario | str | Path,
    *,
    robot: Robot | None = None,
    duration: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    contact_mode: str | None = None,
    workspace_samples: int = 2000,
    seed: int = 0,
    controller: ControllerSpec | None = None,
    recovery: StrategySpec = "builtin",
    progress: Callable[[str], None] | None = None,
    step: Callable[[float], None] | None = None,
    healthy: StudyRun | None = None,
) -> StudyResult:
    """Run a failure study of a scenario with ``[[failures]]``: healthy, failed, reconfigured.

    Args:
        scenario: A scenario name (``sims/``), a TOML path or a :class:`Scenario`.
        robot: The robot (default :func:`packbot.load_robot`).
        duration: Simulated time of each run [s] instead of the scenario's.
        tolerance: Recovery tolerance on the task error [m] (``recover_time_s``,
            ``recovered``).
        contact_mode: A contact mode instead of the scenario's (None: the scenario's). A
            combination the simulator refuses is reported per run with its reason.
        workspace_samples: Samples of the frozen arm's workspace seeding the reach test.
        seed: Seed of the workspace sampler.
        controller: Your controller instead of the scenario's: a
            :class:`~packbot.control.Controller` subclass (made with no arguments, a fresh one
            per run), a factory ``robot -> Controller``, or an import path ``"module:Name"``
            of either (:mod:`packbot.control.user_code`). None: the scenario's ``[controller]``.
        recovery: The reconfigured run's strategy: ``"builtin"``
            (:class:`~packbot.control.strategies.BaselineRecovery`), ``"none"`` (the detections
            go to the controller's own ``on_failure`` hook), a
            :class:`~packbot.control.strategies.RecoveryStrategy` subclass, a factory of one, or
            an import path.
        progress: Called with a line of text as each step starts.
        step: Called with the simulated time [s] after every accepted integration step of each
            run (e.g. to enforce a wall-time limit). A :class:`SimulationError` it raises stops
            that run (its status ``"error"``); any other :class:`PackbotError` stops the study
            (it propagates).
        healthy: The healthy run of this scenario when it was already run (:attr:`StudyResult.
            healthy` of a study of the same scenario, robot, duration, contact mode and
            controller that differs only in its failures: the healthy run has none), so it is
            not simulated again; a study matrix whose axes vary only the failures shares it
            between its cells. Its metrics are measured again against this study's failure
            time. It must start at the scenario's initial state and last the study's duration
            (else a ConfigurationError naming ``healthy``). None: the healthy run is simulated.

    Returns:
        The three runs, their metrics, whether recovery is possible, whether the strategy was
        applied (:class:`Reconfiguration`) and, for a loose joint, where it settled against the
        predicted equilibria.

    Raises:
        ConfigurationError: A bad argument (names it), a scenario without failures.
        UnknownNameError: An unknown scenario name.
    """
    from packbot.control.user_code import controller_factory, describe_spec, strategy_factory

    scenario, robot = _check_inputs(
        scenario, robot, duration, tolerance, contact_mode, workspace_samples
    )
    integer("seed", seed, low=0, what="an integer seed")
    make_ctrl = None if controller is None else controller_factory(controller)
    make_strategy = strategy_factory(recovery)
    if make_ctrl is not None:
        make_ctrl(robot)  # a factory that fails does so before any run
    strategy_name = make_strategy().name or describe_spec(recovery)
    say = progress if progress is not None else (lambda text: log.info("%s", text))
    T = scenario.duration if duration is None else float(duration)
    cm = scenario.config.contact_mode if contact_mode is None else contact_mode
    setup = _RunSetup(
        scenario=scenario,
        robot=robot,
        duration=T,
        contact_mode=contact_mode,
        make_controller=make_ctrl,
        make_strategy=make_strategy,
        step=step,
    )

    if healthy is None:
        say(f"{scenario.name}: healthy run")
        healthy = _run(setup, "healthy", None)
    else:
        say(f"{scenario.name}: healthy run (given: not simulated again)")
        healthy = _given_healthy(healthy, setup)
    task_t = np.zeros(0)
    task_x = np.zeros((0, 3))
    if healthy.result is not None and healthy.status == "ok":
        task_t, task_x = (
            np.asarray(healthy.result.t, dtype=float),
            _tool_path(robot, healthy.result),
        )
    say(f"{scenario.name}: failed run")
    failed = _run(setup, "failed", None)
    say(f"{scenario.name}: reconfigured run")
    if len(task_t) >= 2:
        reconf = _run(setup, "reconfigured", (task_t, task_x))
    else:
        reconf = StudyRun(
            name="reconfigured",
            status="refused",
            reason=f"no task: the healthy run is {healthy.status} ({healthy.reason})",
        )
    t_fail = min(f.t for f in scenario.failures)
    world = _world(robot, scenario)
    for run in (healthy, failed, reconf):
        if run.result is not None and len(task_t) >= 2:
            _measure(run, robot, world, scenario, task_t, task_x, t_fail, float(tolerance))
    reconf, attempt, decision = _keep_better(failed, reconf, strategy_name)
    say(f"{scenario.name}: is recovery possible?")
    recovery_ = _assess(
        scenario, robot, healthy, reconf, task_t, task_x, workspace_samples, seed, float(tolerance)
    )
    f_m = failed.metrics
    if f_m is not None and f_m.recovered and recovery_.possible is not None:
        recovery_ = dataclasses.replace(recovery_, harmless=True)
    loose = _loose_settling(scenario, robot, (failed, reconf))
    return StudyResult(
        scenario=scenario,
        robot=robot,
        duration_s=T,
        tolerance_m=float(tolerance),
        contact_mode=cm,
        task_t=task_t,
        task_x=task_x,
        healthy=healthy,
        failed=failed,
        reconfigured=reconf,
        recovery=recovery_,
        loose=loose,
        controller=scenario.controller if controller is None else describe_spec(controller),
        reconfiguration=decision,
        attempt=attempt,
    )


def verdict_lines(result: StudyResult) -> tuple[str, list[str]]:
    """The study's verdict: a headline and its sentences (what ``packbot study`` prints).

    The headline says whether recovery is possible (or that the failure does no harm); the
    sentences give the reasons, and whether the strategy's run was applied, with both final
    errors.
    """
    rec = result.recovery
    name = result.scenario.name
    who = f"controller {result.controller or result.scenario.controller}"
    if rec.harmless and result.failed.metrics is not None:
        head = f"study {name} ({who}): the failure does no harm"
        m = result.failed.metrics
        lines = [
            f"the unaware controller ends {m.final_task_error_m * 1000:,.1f} mm from the task, "
            f"within the tolerance ({result.tolerance_m * 1000:g} mm)"
        ]
    else:
        verdict = {True: "possible", False: "not possible", None: "not assessed"}[rec.possible]
        head = f"study {name} ({who}): recovery {verdict}"
        lines = []
    lines += list(rec.reasons)
    if result.reconfiguration is not None:
        lines.append(result.reconfiguration.verdict)
    return head, lines


def verdict_text(result: StudyResult) -> str:
    """:func:`verdict_lines` as text: the headline, then one ``  - `` line per sentence."""
    head, lines = verdict_lines(result)
    return "\n".join([head, *(f"  - {x}" for x in lines)])


#: The strategy's run is applied unless it ends more than this farther from the task than the
#: unaware run [m]: a millimetre, above the runs' rounding and the observer's sampling, below
#: any tolerance a study is read with.
KEEP_MARGIN = 1e-3


def _keep_better(
    failed: StudyRun, reconf: StudyRun, strategy: str
) -> tuple[StudyRun, StudyRun | None, Reconfiguration | None]:
    """The reconfigured run to report: the strategy's, or the unaware one where that is better.

    Returns:
        The reconfigured run, the strategy's run if it was not applied (else None), and the
        decision (None where either run has no metrics).
    """
    from packbot.control.context import RecoveryEvent

    fm, rm = failed.metrics, reconf.metrics
    if fm is None or rm is None:
        return reconf, None, None
    a, u = rm.final_task_error_m, fm.final_task_error_m
    if not reconf.detections:
        text = (
            f"the observer flagged no joint: the reconfigured run is the unaware controller's "
            f"(ends {a * 1000:,.1f} mm off)"
        )
        return (
            reconf,
            None,
            Reconfiguration(
                applied=False,
                strategy=strategy,
                attempted_final_task_error_m=a,
                unaware_final_task_error_m=u,
                verdict=text,
            ),
        )
    if a <= u + KEEP_MARGIN:
        text = (
            f"reconfiguration ({strategy}) ends {a * 1000:,.1f} mm off against "
            f"{u * 1000:,.1f} mm unaware: applied"
        )
        return (
            reconf,
            None,
            Reconfiguration(
                applied=True,
                strategy=strategy,
                attempted_final_task_error_m=a,
                unaware_final_task_error_m=u,
                verdict=text,
            ),
        )
    text = (
        f"reconfiguration ({strategy}) would end {a * 1000:,.1f} mm off against "
        f"{u * 1000:,.1f} mm unaware: not applied"
    )
    detect = {
        k: getattr(rm, k)
        for k in (
            "detect_time_s",
            "detect_delay_s",
            "detected_joint",
            "detected_kind",
            "detected_scale",
            "false_detections",
        )
    }
    kept = dataclasses.replace(
        failed,
        name="reconfigured",
        reason=text,
        metrics=dataclasses.replace(fm, **detect),
        controller_log=(
            *reconf.controller_log,
            RecoveryEvent(t=reconf.detections[0].t, kind="not applied", detail=text),
        ),
        suspended=reconf.suspended,
    )
    return (
        kept,
        reconf,
        Reconfiguration(
            applied=False,
            strategy=strategy,
            attempted_final_task_error_m=a,
            unaware_final_task_error_m=u,
            verdict=text,
        ),
    )


def _world(robot: Robot, scenario: Scenario) -> CollisionWorld:
    from packbot.collision import CollisionWorld

    return CollisionWorld(robot, scenario.environment)


def _unaware_params(scenario: Scenario) -> dict[str, Any]:
    """The scenario's controller parameters with a reconfigurable controller's detector off."""
    params = dict(scenario.controller_params)
    if scenario.controller == "reconfig":
        params["detect"] = False
    return params


#: The arm touches something when its smallest signed distance is below this [m]: the contact
#: tolerance of the joint-clamp law's events (1 mm) and the contact-normal mode's patches
#: (within it) with a millimetre to spare.
CONTACT_GATE = 2e-3


def contact_gate(robot: Robot, scenario: Scenario) -> Callable[[FloatArray], bool]:
    """Whether the arm touches something at q (its smallest distance below CONTACT_GATE).

    The reconfigured run's observer asks it while a residual is over its threshold: it has no
    contact forces, so it judges no joint while the arm touches something.
    """
    world = _world(robot, scenario)

    def touching(q: FloatArray) -> bool:
        return bool(world.closest(np.asarray(q, dtype=float)).distance < CONTACT_GATE)

    return touching


@dataclass(frozen=True, kw_only=True)
class _RunSetup:
    """What every run of a study shares."""

    scenario: Scenario
    robot: Robot
    duration: float
    contact_mode: str | None
    make_controller: Callable[[Robot], Controller | None] | None
    make_strategy: Callable[[], RecoveryStrategy]
    step: Callable[[float], None] | None


def _given_healthy(run: Any, setup: _RunSetup) -> StudyRun:
    """A copy of a healthy run given to :func:`study`, checked against its setup, unmeasured."""
    if not isinstance(run, StudyRun) or run.name != "healthy":
        raise ConfigurationError(
            "healthy", run, "None or the StudyRun named 'healthy' of a study of this scenario"
        )
    result = run.result
    if result is not None:
        q0, v0 = setup.scenario.initial_state(setup.robot)
        t_end = float(result.t[-1]) if len(result.t) else 0.0
        start = (np.asarray(result.q[0]), np.asarray(result.v[0])) if len(result.t) else None
        if start is None or not (np.array_equal(start[0], q0) and np.array_equal(start[1], v0)):
            raise ConfigurationError(
                "healthy", "a run from another initial state", "the scenario's initial state"
            )
        if run.status == "ok" and not math.isclose(t_end, setup.duration, rel_tol=1e-12):
            raise ConfigurationError(
                "healthy", f"a run of {t_end:g} s", f"a run of the study's {setup.duration:g} s"
            )
        result = copy.copy(result)
        result.scenario_text = setup.scenario.source_text
    return StudyRun(name="healthy", status=run.status, reason=run.reason, result=result)


def _run(setup: _RunSetup, name: str, task: tuple[FloatArray, FloatArray] | None) -> StudyRun:
    """One run; a refusal (ConfigurationError) or a stop (SimulationError) becomes its status."""
    from packbot.control import build_controller
    from packbot.control.recovery import LOOSE_OPTIONS, TaskRecovery
    from packbot.integrator import simulate

    scenario, robot = setup.scenario, setup.robot
    contact_mode = setup.contact_mode
    try:
        config = scenario.config
        if contact_mode is not None and contact_mode != config.contact_mode:
            config = dataclasses.replace(config, contact_mode=contact_mode)  # type: ignore[arg-type]
        failures = [] if name == "healthy" else list(scenario.failures)
        if setup.make_controller is not None:
            ctrl = setup.make_controller(robot)
        else:
            params = (
                dict(scenario.controller_params) if name == "healthy" else _unaware_params(scenario)
            )
            ctrl = build_controller(
                scenario.controller, robot, params, environment=scenario.environment
            )
        recovery: TaskRecovery | None = None
        if name == "reconfigured":
            assert task is not None
            opts = {k: v for k, v in scenario.controller_params.items() if k in LOOSE_OPTIONS}
            if scenario.controller != "reconfig" or setup.make_controller is not None:
                opts = {}
            recovery = TaskRecovery(
                nominal=ctrl,
                task_t=task[0],
                task_x=task[1],
                strategy=setup.make_strategy(),
                loose_options=opts,
                environment=scenario.environment,
                gravity=tuple(config.gravity),
                joint_friction=bool(config.joint_friction),
                locked=tuple(config.locked_joints),
                payload=scenario.payload,
                in_contact=contact_gate(robot, scenario),
            )
            ctrl = recovery
        q0, v0 = scenario.initial_state(robot)
        kwargs: dict[str, Any] = {
            "controller": ctrl,
            "environment": scenario.environment,
            "config": config,
        }
        if failures:
            kwargs["failures"] = failures
        if scenario.payload is not None:
            kwargs["payload"] = scenario.payload
        if setup.step is not None:
            kwargs["progress"] = setup.step
        result = simulate(robot, q0, v0, setup.duration, **kwargs)
        result.scenario_text = scenario.source_text
    except ConfigurationError as exc:
        log.warning("%s run refused: %s", name, exc)
        return StudyRun(name=name, status="refused", reason=str(exc))
    except SimulationError as exc:
        log.warning("%s run stopped: %s", name, exc)
        partial = exc.result if exc.result is not None else None
        return StudyRun(name=name, status="error", reason=str(exc), result=partial)
    if recovery is None:
        return StudyRun(name=name, status="ok", result=result)
    return StudyRun(
        name=name,
        status="ok",
        result=result,
        controller_log=tuple(recovery.log),
        suspended=tuple(recovery.suspended()),
    )


def _tool_path(robot: Robot, result: SimResult) -> FloatArray:
    """The robot's tool frame positions [m] at each sample, shape (N, 3)."""
    return result.frame_positions(robot.tool_frame, robot)


def _task_at(task_t: FloatArray, task_x: FloatArray, t: FloatArray) -> FloatArray:
    keep = np.append(np.diff(task_t) > 0, True)
    tt, xx = task_t[keep], task_x[keep]
    return np.stack([np.interp(t, tt, xx[:, k]) for k in range(3)], axis=1)


def _measure(
    run: StudyRun,
    robot: Robot,
    world: CollisionWorld,
    scenario: Scenario,
    task_t: FloatArray,
    task_x: FloatArray,
    t_fail: float,
    tol: float,
) -> None:
    res = run.result
    assert res is not None
    t = np.asarray(res.t, dtype=float)
    tool = _tool_path(robot, res)
    err = np.linalg.norm(tool - _task_at(task_t, task_x, t), axis=1)
    run.tool, run.task_error = tool, err
    after = t >= t_fail
    # time-weighted RMS after the failure (duplicate event samples have zero weight)
    ta, ea = t[after], err[after]
    if len(ta) >= 2 and ta[-1] > ta[0]:
        rms = math.sqrt(float(np.trapezoid(ea**2, ta)) / float(ta[-1] - ta[0]))
    else:
        rms = float(ea[-1]) if len(ea) else float(err[-1])
    outside = np.flatnonzero(after & (err > tol))
    if len(outside) == 0:
        recover: float | None = float(t_fail)
    elif outside[-1] == len(t) - 1:
        recover = None
    else:
        recover = float(t[outside[-1] + 1])
    # the limit as it is at each sample (a weak joint's reduced one)
    effort = np.asarray(res.effort, dtype=float)
    tau = np.abs(np.asarray(res.tau, dtype=float))
    k = np.unravel_index(int(np.argmax(tau)), tau.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(effort > 0, tau / np.where(effort > 0, effort, 1.0), 0.0)
    kr = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    detections = run.detections
    detect = detections[0] if detections else None
    det = None if detect is None else detect.detection
    scale = None if det is None or det.kind != "weak" else float(det.scale)
    run.metrics = RunMetrics(
        detect_time_s=None if detect is None else detect.t,
        detect_delay_s=None if detect is None else detect.t - t_fail,
        detected_joint=None if detect is None else detect.joint,
        detected_kind=None if det is None else det.kind,
        detected_scale=scale,
        false_detections=sum(_is_false(scenario, e) for e in detections),
        recover_time_s=recover,
        recovered=bool(err[-1] <= tol),
        final_task_error_m=float(err[-1]),
        rms_task_error_m=rms,
        max_task_error_m=float(np.max(ea)) if len(ea) else float(err[-1]),
        peak_torque_nm=float(tau[k]),
        peak_torque_joint=res.joint_names[int(k[1])],
        peak_torque_ratio=float(ratio[kr]),
        peak_torque_ratio_joint=res.joint_names[int(kr[1])],
        contacts=len(res.events_of("impact")),
        limit_hits=len(res.events_of("limit")),
        peak_impact_speed_m_s=_peak_impact_speed(robot, world, res),
        min_distance_m=float(res.diagnostics.min_distance),
        energy_initial_j=float(res.energy[0]),
        energy_final_j=float(res.energy[-1]),
        events=len(res.events),
        duration_s=float(t[-1] - t[0]),
        wall_time_s=float(res.diagnostics.wall_time),
    )


def impact_speeds(robot: Robot, world: CollisionWorld, result: SimResult) -> list[float]:
    """Approach speed [m/s] of each impact of a result, in the order of its event log.

    The relative velocity of the pair's witness points (before the impact) along the contact
    normal, from the sample at the impact's time (0 where the pair cannot be found).
    """
    import pinocchio as pin

    from packbot.errors import UnknownNameError

    model = robot.model
    data = model.createData()
    t = np.asarray(result.t)
    out: list[float] = []
    for e in result.events_of("impact"):
        idx = int(np.searchsorted(t, e.t, side="left"))
        idx = min(idx, len(t) - 1)
        q = np.asarray(result.q[idx], dtype=float)
        vb = np.asarray(e.v_before if len(e.v_before) == model.nv else result.v[idx], dtype=float)
        try:
            pairs = world.pair_index(e.link1, e.link2, e.piece1 or None, e.piece2 or None)
        except UnknownNameError:
            pairs = []
        if not pairs:
            out.append(0.0)
            continue
        c = world.pair_contact(q, pairs[0])
        pin.computeJointJacobians(model, data, q)

        info = c.pair
        rel = np.zeros(3)
        for joint, p, sign in ((info.joint1, c.p1, 1.0), (info.joint2, c.p2, -1.0)):
            if joint == 0:
                continue  # the chassis and obstacles do not move
            J = np.asarray(pin.getJointJacobian(model, data, joint, pin.WORLD))
            tw = J @ vb  # spatial velocity at the world origin: (linear, angular)
            rel += sign * (tw[:3] + np.cross(tw[3:], p))
        out.append(max(0.0, float(np.dot(rel, c.normal))))
    return out


def _peak_impact_speed(robot: Robot, world: CollisionWorld, result: SimResult) -> float:
    speeds = impact_speeds(robot, world, result)
    return max(speeds) if speeds else 0.0


# ---------------------------------------------------------------------------------- recovery
def _state_at(result: SimResult, t: float) -> FloatArray:
    tt = np.asarray(result.t, dtype=float)
    q = np.asarray(result.q, dtype=float)
    return np.array([np.interp(t, tt, q[:, k]) for k in range(q.shape[1])])


def _assess(
    scenario: Scenario,
    robot: Robot,
    healthy: StudyRun,
    reconf: StudyRun,
    task_t: FloatArray,
    task_x: FloatArray,
    samples: int,
    seed: int,
    tol: float,
) -> Recovery:
    if healthy.result is None or len(task_t) < 2:
        return Recovery(
            possible=None,
            reasons=(f"not assessed: no healthy task ({healthy.status}: {healthy.reason})",),
        )
    res = healthy.result
    frame_joints = _frame_joints(robot)
    possible: bool | None = True
    reasons: list[str] = []
    checks: list[dict[str, Any]] = []
    frozen_like = {f.joint for f in scenario.failures if f.kind in ("frozen", "brake")}
    for f in sorted(scenario.failures, key=lambda f: f.t):
        until = _next_failure_time(scenario, f)  # a joint's next failure ends this one's span
        j = robot.params.index(f.joint)
        q_f = _state_at(res, f.t)
        check: dict[str, Any] = {"joint": f.joint, "kind": f.kind, "t_s": f.t}
        if f.kind in ("frozen", "brake"):
            angle = float(q_f[j])
            check["angle_rad"] = angle
            if f.kind == "brake":
                reasons.append(
                    f"{f.joint} brake: assessed as frozen at {angle:.3f} rad (it holds while the "
                    "torque needed stays below its threshold)"
                )
            if j not in frame_joints:
                check["reachable"] = True
                check["note"] = f"{f.joint} does not move {robot.tool_frame}"
            elif len(frozen_like) > 1:
                check["note"] = "not assessed: more than one frozen joint"
                reasons.append("reach not assessed: more than one frozen joint")
                possible = None if possible else possible
            else:
                ok, text, info = _reach_check(
                    robot, scenario, f.joint, angle, q_f, task_t, task_x, f.t, samples, seed
                )
                check |= info
                if not ok:
                    possible = False
                if text:
                    reasons.append(text)
        elif f.kind in ("loose", "stuck"):
            from packbot.analysis import loose_joint_equilibria

            if f.kind == "stuck" and f.torque != 0.0:
                possible = False
                reasons.append(
                    f"{f.joint} is stuck at {f.torque:g} N*m whatever the command: no controller "
                    "holds it (if flagged, the other joints track the task where it drifts)"
                )
                check["note"] = "stuck joint"
            eqs = loose_joint_equilibria(
                robot,
                f.joint,
                q_f,
                gravity=scenario.config.gravity,
                environment=scenario.environment,
                samples=181,
            )
            check["equilibria_at_failure"] = len(eqs)
            if not eqs:
                possible = False
                reasons.append(
                    f"a loose joint cannot be held: {f.joint} has no gravity torque at any angle "
                    "(a vertical axis), so nothing holds it at an angle"
                )
        elif f.kind == "weak":
            import pinocchio as pin

            from packbot.system import with_payload

            limit = float(robot.params.effort[j] * f.scale)
            p = scenario.payload
            held = p is not None and (p.t_drop is None or p.t_drop > float(res.t[-1]))
            model = (with_payload(robot, p) if held and p is not None else robot).model.copy()
            model.gravity.linear = np.asarray(scenario.config.gravity, dtype=float)
            g_end = float(
                pin.computeGeneralizedGravity(model, model.createData(), np.asarray(res.q[-1]))[j]
            )
            t_res = np.asarray(res.t)
            after = (t_res >= f.t) & (t_res < until)  # while this scale is the limit
            need = float(np.max(np.abs(np.asarray(res.tau)[after, j]), initial=0.0))
            check |= {"limit_nm": limit, "hold_torque_nm": abs(g_end), "task_torque_nm": need}
            if until < math.inf:
                check["until_s"] = until
            if abs(g_end) > limit and until == math.inf:  # the final pose: the last limit
                possible = False
                reasons.append(
                    f"{f.joint} is weak: holding the task's final pose needs {abs(g_end):.3g} N*m, "
                    f"the motor gives at most {limit:.3g} N*m"
                )
            elif need > limit:
                reasons.append(
                    f"{f.joint} is weak: the task needs up to {need:.3g} N*m there, the motor "
                    f"gives {limit:.3g} N*m: it lags (if the observer flags it, the built-in "
                    "strategy moves to a posture the motor holds)"
                )
            else:
                check["note"] = "within the weak motor's limit"
        checks.append(check)
    # after the run: a loose joint for which the controller found no stable equilibrium (joints
    # flagged later, e.g. pinned by a contact after a fall, are not the scenario's failures)
    failed_names = {f.joint for f in scenario.failures}
    for e in reconf.controller_log:
        if e.joint not in failed_names:
            continue
        if e.kind == "replan" and "no stable equilibrium" in e.detail:
            possible = False
            x = task_x[-1]
            reasons.append(
                f"a loose joint cannot be held: no stable, collision-free equilibrium of "
                f"{e.joint} puts {robot.tool_frame} at the task's final point ({x[0]:.3f}, "
                f"{x[1]:.3f}, {x[2]:.3f}) m; the arm holds where it is"
            )
        elif e.kind == "replan" and "frame error" in e.detail:
            try:
                mm = float(e.detail.split("frame error")[1].split("mm")[0])
            except (IndexError, ValueError):
                continue
            if mm * 1e-3 > tol:
                possible = False
                reasons.append(
                    f"a loose joint cannot be held on the task: the best stable equilibrium of "
                    f"{e.joint} leaves {robot.tool_frame} {mm:.3g} mm from its final point"
                )
    if reconf.status == "ok" and not any(e.kind == "detect" for e in reconf.controller_log):
        reasons.append("the reconfigured run's observer flagged no joint")
    return Recovery(possible=possible, reasons=tuple(reasons), checks=tuple(checks))


def _frame_joints(robot: Robot) -> set[int]:
    model = robot.model
    parent = model.frames[model.getFrameId(robot.tool_frame)].parentJoint
    return {model.joints[j].idx_q for j in model.supports[parent] if j > 0}


def _reach_check(
    robot: Robot,
    scenario: Scenario,
    joint: str,
    angle: float,
    q_f: FloatArray,
    task_t: FloatArray,
    task_x: FloatArray,
    t_fail: float,
    samples: int,
    seed: int,
) -> tuple[bool, str, dict[str, Any]]:
    """Are the task's points after the failure reachable with ``joint`` frozen at ``angle``?"""
    from packbot.analysis import reach, workspace

    lo, hi = (
        float(robot.params.lower[robot.params.index(joint)]),
        float(robot.params.upper[robot.params.index(joint)]),
    )
    angle = min(max(angle, lo), hi)
    ws = workspace(
        robot,
        frozen=(joint, angle),
        samples=samples,
        seed=seed,
        q_ref=q_f,
        environment=scenario.environment,
    )
    if len(ws.points) == 0:
        return False, f"{joint} frozen at {angle:.3f} rad: no collision-free configuration", {}
    idx = np.flatnonzero(task_t >= t_fail)
    picks = sorted(set(np.linspace(idx[0], idx[-1], min(7, len(idx))).astype(int).tolist()))
    answers = [
        reach(robot, ws, task_x[i], environment=scenario.environment, seeds=8) for i in picks
    ]
    final = answers[-1]
    n_out = sum(not a.reachable for a in answers)
    info = {
        "reachable": final.reachable,
        "final_point_m": [float(x) for x in task_x[picks[-1]]],
        "closest_approach_m": final.error_m,
        "points_tested": len(answers),
        "points_out_of_reach": n_out,
    }
    x = task_x[picks[-1]]
    if not final.reachable:
        return (
            False,
            f"the task leaves the reduced arm's workspace: its final point ({x[0]:.3f}, "
            f"{x[1]:.3f}, {x[2]:.3f}) m is out of reach with {joint} frozen at {angle:.3f} rad "
            f"(closest approach {final.error_m * 1000:.0f} mm)",
            info,
        )
    if n_out:
        return (
            True,
            f"{n_out} of {len(answers)} task points after the failure are out of reach with "
            f"{joint} frozen at {angle:.3f} rad (the final point is reachable)",
            info,
        )
    return True, "", info


# ---------------------------------------------------------------------------------- item 4
def _loose_settling(
    scenario: Scenario, robot: Robot, runs: tuple[StudyRun, ...]
) -> tuple[LooseSettling, ...]:
    from packbot.analysis import gravity_torque_on, loose_joint_equilibria

    out: list[LooseSettling] = []
    # a loose joint that stays loose to the end (not one that then freezes or is braked)
    loose = [
        f
        for f in scenario.failures
        if f.kind == "loose" and _next_failure_time(scenario, f) == math.inf
    ]
    world = _world(robot, scenario) if loose else None
    for f in loose:
        j = robot.params.index(f.joint)
        lo, hi = float(robot.params.lower[j]), float(robot.params.upper[j])
        for run in runs:
            res = run.result
            if res is None or run.status != "ok":
                continue
            q_end = np.asarray(res.q[-1], dtype=float)
            try:
                eqs = loose_joint_equilibria(
                    robot,
                    f.joint,
                    q_end,
                    gravity=scenario.config.gravity,
                    environment=scenario.environment,
                )
            except PackbotError as exc:  # pragma: no cover - analysis refusal reported
                log.warning("no equilibria for %s: %s", f.joint, exc)
                continue
            angle = float(q_end[j])
            speed = float(abs(res.v[-1][j]))
            near = min(eqs, key=lambda e: abs(e.angle - angle)) if eqs else None
            grid = np.linspace(lo, hi, 361)
            out.append(
                LooseSettling(
                    joint=f.joint,
                    run=run.name,
                    settled_angle_rad=angle,
                    final_speed_rad_s=speed,
                    at_rest=speed < REST_SPEED,
                    equilibria=tuple(eqs),
                    nearest_angle_rad=math.nan if near is None else near.angle,
                    nearest_kind="" if near is None else near.kind,
                    nearest_stable=False if near is None else near.stable,
                    offset_rad=math.nan if near is None else angle - near.angle,
                    final_distance_m=float(world.closest(q_end).distance) if world else math.nan,
                    angles_rad=grid,
                    gravity_torque_nm=gravity_torque_on(
                        robot, f.joint, q_end, grid, gravity=scenario.config.gravity
                    ),
                )
            )
    return tuple(out)
