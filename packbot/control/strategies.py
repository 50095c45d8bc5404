"""Recovery strategies: what the reconfigured run does when its observer finds a failure.

A strategy is a :class:`RecoveryStrategy`: one method, :meth:`RecoveryStrategy.on_failure`,
called at each detection with a :class:`~packbot.control.context.FailureReport` (the failure
as estimated, the measured state, the earlier failures, the run's context) and the controller
in charge; it returns the controller in charge from then on: the same one (reconfigured, e.g.
through its own :meth:`~packbot.control.Controller.on_failure`), another one, or None (zero
torque). A new controller is reset by the run at the detection's state (``reset(robot, t, q,
v)``), told of every failure found so far (``on_failure(failure, t)``, as a simulator that
informs its controller would) and run at the run's control period. A strategy is made fresh
for each run (a class, instantiated with no arguments, or a factory), so it may keep state.

- :class:`NoRecovery` (``"none"``): the detection is passed to the controller's own
  ``on_failure`` hook, the controller stays in charge (a controller without that hook goes on
  as in the failed run; the detections are still reported);
- :class:`BaselineRecovery` (``"builtin"``): per failure kind, what is still working:

  - weak: a posture on the task's final point (or the nearest) whose gravity torques every
    motor holds with margin, reached by a move shaped so that the weakened motor drives it
    (:mod:`packbot.control.weak_transition`), tracked with its command clipped
    (:class:`~packbot.control.weak_joint.WeakJointTracker`); where no such move is found, the
    controller in charge stays;
  - frozen, a holding brake, stuck: the task tracked with the other joints
    (:class:`~packbot.control.reduced_arm.ReducedArmTracker`; a stuck joint, or a brake that
    slipped, followed where it drifts);
  - loose: the task's final point held with the loose link at a predicted stable equilibrium
    (:class:`~packbot.control.reconfig.ReconfigurableController`, its equilibria those of
    :func:`packbot.analysis.loose_joint_equilibria`); later detections are ignored.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from packbot.control.base import Controller
from packbot.control.context import FailureReport, RecoveryEvent
from packbot.failures import Failure
from packbot.keywords import check_subclass

__all__ = ["STRATEGY_NAMES", "BaselineRecovery", "NoRecovery", "RecoveryStrategy"]

#: Holdable postures a weak joint's move may go to (the best first) [-].
GOALS = 2

#: The built-in strategies by name.
STRATEGY_NAMES: tuple[str, ...] = ("builtin", "none")


class RecoveryStrategy(ABC):
    """Base of the recovery strategies (module docstring).

    Attributes:
        name: A short name for reports (the class's name by default).
        events: What the strategy did, as log entries (the run adds them to its log).
    """

    name: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        check_subclass(cls)  # a misspelt keyword of a strategy (a user's too): KeywordError

    def __init__(self) -> None:
        self.events: list[RecoveryEvent] = []

    def note(self, t: float, kind: str, joint: str = "", detail: str = "") -> None:
        """Add an entry to :attr:`events` (time [s], kind, joint, what in words)."""
        self.events.append(RecoveryEvent(t=t, kind=kind, joint=joint, detail=detail))

    @abstractmethod
    def on_failure(self, report: FailureReport, controller: Controller | None) -> Controller | None:
        """A failure was detected: return the controller in charge from now on.

        Args:
            report: The failure as estimated, the state, the earlier failures, the context.
            controller: The controller in charge (the scenario's, or one this strategy
                returned before; None: zero torque).

        Returns:
            ``controller`` itself (possibly reconfigured), a new controller (reset by the run
            at the detection's state and told of the failures so far), or None (zero torque).
        """


class NoRecovery(RecoveryStrategy):
    """No strategy: the controller's own ``on_failure`` hook receives the detected failure."""

    name = "none"

    def on_failure(self, report: FailureReport, controller: Controller | None) -> Controller | None:
        """Call ``controller.on_failure(report.failure, report.t)``; keep the controller."""
        if controller is not None:
            controller.on_failure(report.failure, report.t)
        return controller


class BaselineRecovery(RecoveryStrategy):
    """Per failure kind, a strategy that uses what still works (module docstring).

    Args:
        omega: Natural frequency of the tracking loops [rad/s].
        zeta: Their damping ratio [-].
        task_gain: Task error gain of the reduced arm's inverse kinematics [1/s].
        max_task_speed: Its largest correction speed [m/s].
        speed_fraction: Its joint rates within this fraction of the speed limits [-].
        damping: Damping of its pseudo-inverse [m].
    """

    name = "builtin"

    def __init__(
        self,
        *,
        omega: float = 20.0,
        zeta: float = 1.0,
        task_gain: float = 5.0,
        max_task_speed: float = 0.5,
        speed_fraction: float = 1.0,
        damping: float = 0.02,
    ) -> None:
        super().__init__()
        self.tracking = {
            "omega": omega,
            "zeta": zeta,
            "task_gain": task_gain,
            "max_task_speed": max_task_speed,
            "speed_fraction": speed_fraction,
            "damping": damping,
        }
        self.mode = "nominal"
        # fail at construction, not at the first detection
        from packbot.control._common import damping_ratio, loop_frequency

        loop_frequency(omega, "omega", 1e-3)
        damping_ratio(zeta, "zeta")

    def on_failure(self, report: FailureReport, controller: Controller | None) -> Controller | None:
        """Hand over to the strategy of the failures found so far (module docstring)."""
        f = report.failure
        if self.mode == "loose":
            self.note(report.t, "ignored", f.joint, f"{f.kind}: a loose joint is handled")
            return controller
        latest: dict[str, Failure] = {}
        for g in report.all_failures:
            latest[g.joint] = g
        kinds = {name: g.kind for name, g in latest.items()}
        if "loose" in kinds.values():
            return self._loose(report, latest)
        held = [n for n, k in kinds.items() if k == "frozen"]
        drifting = [n for n, k in kinds.items() if k in ("stuck", "brake")]
        weak = {n: g for n, g in latest.items() if g.kind == "weak"}
        if weak:
            return self._weak(report, weak, [*held, *drifting], controller)
        return self._track(report, held, drifting)

    def _track(
        self, report: FailureReport, held: Sequence[str], drifting: Sequence[str]
    ) -> Controller:
        from packbot.control.reduced_arm import ReducedArmTracker

        ctx = report.context
        ctrl = ReducedArmTracker(
            context=ctx, held=held, drifting=drifting, gravity=ctx.gravity, **self.tracking
        )
        ctrl.prepare(ctx.robot)
        self.mode = "track"
        moving = ", ".join(ctx.robot.joint_names[i] for i in ctrl.movers)
        self.note(report.t, "track", report.failure.joint, f"tracking with {moving}")
        return ctrl

    def _weak(
        self,
        report: FailureReport,
        weak: dict[str, Failure],
        fixed: Sequence[str],
        controller: Controller | None,
    ) -> Controller | None:
        """A holdable posture on the task's final point and a move the weak motor drives.

        (:mod:`packbot.control.weak_transition`); where no posture holds or no move within
        the limits gets there, the controller in charge stays.
        """
        from packbot.control.weak_joint import WeakJointTracker
        from packbot.control.weak_transition import holdable_reach, plan_transition

        ctx = report.context
        robot = ctx.robot
        idx = robot.params.index
        limits = {
            n: float(robot.params.effort[idx(n)]) * (g.scale if math.isfinite(g.scale) else 0.5)
            for n, g in weak.items()
        }
        by_index = {idx(n): lim for n, lim in limits.items()}
        fixed_idx = [idx(n) for n in fixed]
        omega, zeta = self.tracking["omega"], self.tracking["zeta"]
        who = ", ".join(weak)
        postures = holdable_reach(ctx, report.q, by_index, fixed=fixed_idx)
        reaching = [h for h in postures if h.reaches]
        goals = (reaching or postures)[:GOALS]
        move = None
        if goals:
            move = plan_transition(
                ctx, report.t, report.q, report.v, [h.q for h in goals], by_index, fixed=fixed_idx
            )
        if move is not None:
            tr = move.transition
            chosen = min(goals, key=lambda h: float(np.max(np.abs(h.q - tr.goal))))
            self.mode = "weak"
            self.note(
                report.t,
                "weak",
                who,
                f"{chosen.describe(robot.joint_names, list(by_index))}; a {tr.duration:.2f} s "
                f"move there (planned torques at most {move.peak_torque_ratio:.0%} of their "
                f"limits, clearance {move.min_distance_m * 1000:.0f} mm)",
            )
            return WeakJointTracker(
                context=ctx,
                goal=tr.goal,
                limits=limits,
                held=fixed,
                gravity=ctx.gravity,
                transition=tr,
                omega=omega,
                zeta=zeta,
            )
        # no move the motors drive: the controller in charge stays (a nearby posture reached by
        # a move that exceeds them did worse than doing nothing: docs/study.md)
        why = (
            "no posture the motors hold was found"
            if not goals
            else f"no move within the limits to the {len(goals)} holdable posture(s) found"
        )
        self.note(report.t, "weak", who, f"{why}: the controller stays")
        return controller

    def _loose(self, report: FailureReport, latest: dict[str, Failure]) -> Controller:
        from packbot.control.reconfig import ReconfigurableController

        ctx = report.context
        ctrl = ReconfigurableController(
            target=ctx.final_point,
            frame=ctx.frame,
            detect=False,
            environment=ctx.environment,
            gravity=tuple(ctx.gravity),
            **dict(ctx.loose_options),
        )
        names = [n for n, g in latest.items() if g.kind in ("loose", "frozen")]
        self.mode = "loose"
        x = ctx.final_point
        self.note(
            report.t,
            "loose",
            ", ".join(names),
            f"holding the task's final point ({x[0]:.3f}, {x[1]:.3f}, {x[2]:.3f}) m with the "
            "loose link at a stable equilibrium",
        )
        return ctrl
