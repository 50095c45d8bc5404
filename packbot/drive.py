"""The torques on the integrated joints: the command, the torque path, joint friction.

:class:`Drive` turns a state (t, y) into the torques the dynamics see: the controller's
command (a torque function evaluated at every call, or the command a sampled-data
:class:`~packbot.control.Controller` holds between its ticks, or zero), passed through the
failures and actuator models of :class:`~packbot.actuators.TorquePath` (saturation, motor lag,
cut, stuck and weak motors), plus the joints' viscous and sliding Coulomb friction. Its
:meth:`Drive.free_accel` is the unconstrained acceleration a contact law starts from.

One :class:`Drive` lasts a whole run; :meth:`Drive.phase` points it at the system of a new
phase (a frozen joint merged, a payload picked or dropped). The sliding direction of each joint
with Coulomb friction (:attr:`Drive.fdir`) is state of the joint holds: the contact law sets it
at a ``slip`` or ``stick`` event (:mod:`packbot.contact.stops`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.actuators import TorquePath
from packbot.config import SimConfig
from packbot.control.base import Controller
from packbot.errors import ControllerError
from packbot.failures import Failure
from packbot.model import Robot
from packbot.system import System

__all__ = ["Drive", "TorqueFunction"]

FloatArray = NDArray[np.float64]
#: A continuous-time controller: joint torques [N*m] (shape (nv,), full coordinates) from
#: t [s], q [rad], v [rad/s]; a smooth, stateless function.
TorqueFunction = Callable[[float, FloatArray, FloatArray], Any]


class Drive:
    """The torques of one run on the integrated joints.

    Args:
        robot: The full robot.
        config: Simulation settings (motor lag, joint friction, saturation).
        controller: None (zero command), a sampled-data controller (its held command is set by
            :meth:`hold` at each tick) or a torque function of (t, q, v), full coordinates.

    Attributes:
        lag: Whether the state carries the motor torques (``config.motor_lag > 0``).
        hold_full: The command a sampled-data controller holds [N*m], full coordinates.
        sys: The system of the current phase.
        path: Its torque path (failures and actuators in force).
        fdir: The sliding direction (+1, -1) of each joint with Coulomb friction that slides;
            0 for a joint that is held or has none.
    """

    def __init__(
        self,
        robot: Robot,
        config: SimConfig,
        controller: Controller | TorqueFunction | None,
    ) -> None:
        self.robot = robot
        self.cfg = config
        self.ctrl_obj = controller if isinstance(controller, Controller) else None
        self.ctrl_fn = None if isinstance(controller, Controller) else controller
        self.lag = config.motor_lag > 0.0
        self.hold_full = np.zeros(robot.nq)
        # (command, torque path, its target, its applied torque) of the last call: the held
        # command of a sampled-data controller is the same array between ticks.
        self._cached: tuple[Any, Any, FloatArray, FloatArray] = (
            None,
            None,
            self.hold_full,
            self.hold_full,
        )

    def phase(self, sys: System, failures: Sequence[Failure]) -> None:
        """Start a phase on ``sys``: torque path built, every joint's friction direction 0."""
        self.sys = sys
        self.n = sys.nv
        self.path = TorquePath.build(self.robot.params, sys.free, self.cfg, failures)
        self.fdir = np.zeros(self.n)
        self.tau_zero = np.zeros(self.n)
        self.zero_full = np.zeros(self.robot.nq)  # shared by torque-free samples, never written
        self.tau_hold = sys.reduce(self.hold_full)
        self._effort: tuple[Any, FloatArray] = (None, self.zero_full)

    def effort_full(self) -> FloatArray:
        """The effort limits of the torque path in force [N*m], full coordinates.

        Shared between calls (computed once per torque path): the caller must not modify it.
        """
        path = self.path
        if self._effort[0] is not path:
            eff = self.robot.params.effort.copy()
            eff[self.sys.free] = path.effort
            self._effort = (path, eff)
        return self._effort[1]

    def set_failures(self, failures: Sequence[Failure]) -> None:
        """Rebuild the torque path with the failures now in force (same phase)."""
        self.path = TorquePath.build(self.robot.params, self.sys.free, self.cfg, failures)

    def hold(self, tau: Any, t: float) -> None:
        """A sampled-data controller's new command [N*m], full coordinates, from its tick at t."""
        self.hold_full = self.check_torque(tau, t).copy()
        self.tau_hold = self.sys.reduce(self.hold_full)

    def command(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Commanded torque on the integrated joints [N*m]."""
        if self.ctrl_fn is not None:
            qf, vf = self.sys.q_full(q), self.sys.v_full(v)
            try:
                raw = self.ctrl_fn(t, qf, vf)
            except Exception as exc:
                raise ControllerError(f"raised {type(exc).__name__}: {exc}", t) from exc
            return self.check_torque(raw, t)[self.sys.free]
        if self.ctrl_obj is not None:
            return self.tau_hold
        return self.tau_zero

    def check_torque(self, raw: Any, t: float) -> FloatArray:
        """A controller's torques [N*m] as floats, checked: real, shape (nq,), finite.

        A float64 array of that shape is returned as it is (not a copy: the caller copies what
        it keeps, as :meth:`hold` does).

        Raises:
            ControllerError: Anything else (says when, and which joint).
        """
        nq = self.robot.nq
        if type(raw) is np.ndarray and raw.dtype == np.float64 and raw.shape == (nq,):
            total = float(np.add.reduce(raw))  # (raw.sum() adds a Python layer)
            if total - total == 0.0:  # finite: no inf or nan among them (fast path)
                return raw  # (not copied: every caller copies what it keeps)
        try:
            tau = np.asarray(raw)
        except Exception as exc:  # a ragged list, an object numpy cannot take
            raise ControllerError(f"returned {type(raw).__name__}, not {nq} torques", t) from exc
        if tau.dtype.kind not in "iuf":  # complex, bool, strings, objects
            raise ControllerError(
                f"returned {tau.dtype} values, not real torques (shape ({nq},), float)", t
            )
        tau = tau.astype(float)
        if tau.shape != (nq,):
            raise ControllerError(f"returned shape {tau.shape}, expected ({nq},)", t)
        if not np.all(np.isfinite(tau)):
            bad = self.robot.joint_names[int(np.flatnonzero(~np.isfinite(tau))[0])]
            raise ControllerError(f"returned a non-finite torque for joint {bad!r}", t, bad)
        return tau

    def torques(
        self, t: float, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(command, motor target, applied motor torque, friction) [N*m] at (t, y)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        cmd = self.command(t, q, v)
        path = self.path
        if cmd is self.tau_zero and not self.lag and path.passive:  # the collapse: fast path
            return cmd, cmd, cmd, path.friction(v, self.fdir) if path.rubs else cmd
        if cmd is self._cached[0] and path is self._cached[1]:  # a held command: computed once
            target, applied = self._cached[2], self._cached[3]
        else:
            target = path.target(cmd)
            applied = target if self.lag else path.applied(target)  # with a lag: from y below
            self._cached = (cmd, path, target, applied)
        if self.lag:
            applied = path.applied(y[2 * n :])
        return cmd, target, applied, path.friction(v, self.fdir)

    def step_torques(self, t: float, y: FloatArray) -> tuple[FloatArray, ...] | None:
        """The torques of a step from (t, y) as constants: (applied, viscous, coulomb_dir).

        With a held command (a sampled-data controller between its ticks, or none) and no
        motor lag, :meth:`torques` over the step is ``applied + (-viscous * v - coulomb_dir)``
        [N*m] with these three fixed (``coulomb_dir`` = F_j s_j); None with a torque function
        or a motor lag (the torques depend on t or on the state's tail).
        """
        if self.ctrl_fn is not None or self.lag:
            return None
        path = self.path
        applied = self.torques(t, y)[2]
        return applied, path.viscous, path.coulomb * self.fdir

    def free_accel(self, t: float, y: FloatArray) -> FloatArray:
        """Accelerations [rad/s^2] of the unconstrained arm at (t, y) (no lock, no contact)."""
        n = self.n
        _, _, applied, friction = self.torques(t, y)
        return self.sys.aba(y[:n], y[n : 2 * n], applied + friction)
