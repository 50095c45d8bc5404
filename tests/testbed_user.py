"""A user's controller and recovery strategy, as a control engineer writes them.

For tests/test_testbed.py: ``Reach`` is a computed-torque reach of ``gripper_tool`` from
where the arm starts to (1.2, 0, 1.0) m in 3 s (its own inverse kinematics, a quintic, RNEA);
``FirstFailure`` is a strategy that keeps the controller and remembers what it was told.
Module-level, so that a study matrix's workers can import them.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from packbot.control import Controller, QuinticSegment, RecoveryStrategy, solve_position_ik

#: The reach's target [m] and duration [s].
TARGET = (1.2, 0.0, 1.0)
DURATION = 3.0


class Reach(Controller):
    """Computed-torque reach of gripper_tool to TARGET in DURATION (elbow up, from stand's IK)."""

    def on_reset(self, robot, t0, q0, v0):  # type: ignore[no-untyped-def]
        self.model = robot.model.copy()
        self.data = self.model.createData()
        ik = solve_position_ik(
            self.model, "gripper_tool", TARGET, robot.pose("stand"), active=[0, 1, 2, 3]
        )
        self.plan = QuinticSegment(q0=q0, q1=ik.q, t0=t0, duration=DURATION)
        self.told: list[tuple[str, str, float]] = []

    def on_failure(self, failure, t):  # type: ignore[no-untyped-def]
        self.told.append((failure.joint, failure.kind, failure.scale))

    def compute(self, t, q, v):  # type: ignore[no-untyped-def]
        qd, vd, ad = self.plan(t)
        return pin.rnea(self.model, self.data, q, v, ad + 400.0 * (qd - q) + 40.0 * (vd - v))


class FirstFailure(RecoveryStrategy):
    """Keep the controller; remember the reports (class-level, to read them after a run)."""

    name = "first-failure"
    reports: list = []  # noqa: RUF012 - shared on purpose: the study makes the instances

    def on_failure(self, report, controller):  # type: ignore[no-untyped-def]
        FirstFailure.reports.append(report)
        self.note(report.t, "kept", report.failure.joint, "the controller stays")
        return controller


def reach_factory(robot):  # type: ignore[no-untyped-def]
    """A factory robot -> Controller."""
    return Reach()


__all__ = ["DURATION", "TARGET", "FirstFailure", "Reach", "reach_factory"]
_ = np
