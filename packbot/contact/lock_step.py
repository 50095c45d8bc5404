"""The joint locks' native step: one compiled Dormand-Prince attempt and its end's screen.

:class:`NativeLockStep` is what :class:`~packbot.contact.stops.JointStops` holds of the
extension (``packbot._native``) for one phase: the native right-hand side (built at the
phase's first native step), the torques loaded in it, the step it hands the stepper
(:meth:`NativeLockStep.kernel`) and the screen of the locks' and holds' conditions at that
step's end (:meth:`NativeLockStep.screened`). The law decides when its mode's accelerations
are the locks' alone (:meth:`JointStops.step_kernel
<packbot.contact.stops.JointStops.step_kernel>`); this object decides the rest.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from packbot.contact import native
from packbot.contact.locks import ACCEL_BAND, TORQUE_BAND, JointLocks
from packbot.drive import Drive
from packbot.errors import ModelError
from packbot.ode import StepKernel
from packbot.system import System

__all__ = ["SCREEN_MARGIN", "NativeLockStep"]

FloatArray = NDArray[np.float64]
#: The end of a native step (:meth:`JointStops.step_kernel
#: <packbot.contact.stops.JointStops.step_kernel>`) screens the locks' and holds' conditions
#: from its last stage: when every one is above this share of its terms' scale [-] (far above
#: the rounding by which the stage's arithmetic differs from :meth:`JointStops.lock_conditions
#: <packbot.contact.stops.JointStops.lock_conditions>`'), none changed sign; otherwise they are
#: evaluated as without the native step.
SCREEN_MARGIN = 1e-9


class NativeLockStep:
    """The native step of one phase's lock modes (its own state: one per phase).

    Args:
        system: The phase's integrated system (its model and joint count).
        drive: The run's torques (:meth:`~packbot.drive.Drive.step_torques`).

    Attributes:
        rhs: The native right-hand side, built at the first native step (None before, or for
            a model with a joint type the extension does not rebuild, e.g. a continuous joint
            in the ``none`` mode, which has no collision world: the stepper's stages then call
            the law's right-hand side).
    """

    def __init__(self, system: System, drive: Drive) -> None:
        self.sys = system
        self.drive = drive
        self.rhs: native.NativeRhs | None = None
        self._tried = False

    def kernel(self, t: float, y: FloatArray, locks: JointLocks) -> StepKernel | None:
        """The native step from (t, y) with the current locked set, or None (Python stages).

        For a mode whose accelerations are the locks' alone: offered with no joint locked,
        one, or all but at most 3 (:meth:`JointStops.torque_accel
        <packbot.contact.stops.JointStops.torque_accel>`'s ABA, its rank-one correction, or
        its unlocked block: :meth:`~packbot.contact.native.NativeLocks.set`), and torques
        fixed over the step (:meth:`~packbot.drive.Drive.step_torques`).

        Args:
            t: The step's start [s].
            y: The state there.
            locks: The law's joint locks.
        """
        k = locks.n_locked
        if k >= 2 and self.sys.nv - k > 3:
            return None
        rhs = self.rhs
        if rhs is None:
            if self._tried:
                return None
            self._tried = True
            try:
                rhs = self.rhs = native.native_rhs(self.sys.model)
            except ModelError:  # a joint type the extension does not rebuild: the stages
                return None
        torques = self.drive.step_torques(t, y)
        if torques is None:
            return None
        rhs.locks.set(locks.locked_index)
        rhs.hold_torque(*torques)
        return rhs.step

    def screened(self, y1: FloatArray, locks: JointLocks) -> bool:
        """Whether the last native step ended at y1 with every lock condition clearly kept.

        From its FSAL stage's accelerations and lock torques (the current locked set's, at
        y1): every condition of :meth:`JointLocks.conditions_of
        <packbot.contact.locks.JointLocks.conditions_of>` above :data:`SCREEN_MARGIN` of
        its scale (1 + max |a| + max |lambda|), computed in the extension
        (:meth:`~packbot.contact.native.NativeLocks.end_screen`). False also when there was no
        such step with this locked set (the conditions are then evaluated).

        Args:
            y1: The step's end state.
            locks: The law's joint locks.
        """
        rhs = self.rhs
        if rhs is None or not rhs.locks.holds(locks.locked_index):
            return False  # (the locks changed since the step: e.g. a clamp after it)
        rows = locks.screen_rows()
        return rhs.locks.end_screen(rows, y1, SCREEN_MARGIN, TORQUE_BAND, ACCEL_BAND) > 0.0
