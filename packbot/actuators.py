"""The actuator model: from a commanded joint torque to the torque that acts on the arm.

Pinocchio's ABA ignores the URDF's damping and friction; they act here, in the torque path the
simulator evaluates at every right-hand side. For joint j (all torques at the joint output,
[N*m]; v_j [rad/s]):

1. Command: ``tau_cmd`` from the controller (zero-order hold between ticks).
2. Saturation (``SimConfig.effort_saturation``, always for a ``"weak"`` joint):
   ``tau_sat = clip(tau_cmd, -E_j, E_j)`` with E_j = ``robot.params.effort[j]``, scaled by the
   failure's ``scale`` for a weak joint (the latest weak failure of the joint: a degrading motor
   steps down, each scale of the nominal limit).
3. Motor lag (``SimConfig.motor_lag`` = T > 0 [s]): the motor torque tau_m is a state,
   ``d tau_m / dt = (tau_sat - tau_m) / T``; with T = 0, tau_m = tau_sat.
4. Failures: a ``"loose"`` joint's motor torque is 0, a ``"stuck"`` joint's is the failure's
   constant ``torque`` (saturated like any command); the result is the *applied* motor torque.
5. Friction (``SimConfig.joint_friction``): viscous ``-b_j v_j`` (b_j = ``params.viscous``) and
   Coulomb ``-F_j sign(v_j)`` (F_j = ``params.coulomb``). Coulomb friction is modelled with
   stick and slip as modes of the simulator, not regularised: a joint at rest is *held* (a_j = 0)
   while the torque needed to hold it stays within F_j, and slips when it would exceed it; a
   sliding joint feels the constant -F_j s_j (s_j its direction of motion) until its speed
   crosses zero, where it sticks again if the holding torque is within F_j. Every transition is
   an event located by root finding, so nothing chatters at zero velocity. A ``"brake"`` failure
   adds its threshold to F_j (the brake holds up to it and slips with that torque).

The reflected rotor inertia (armature = gear_ratio^2 * rotor_inertia) is part of the mass matrix
(``robot.model.armature``), so it is not a torque here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from packbot.config import SimConfig
from packbot.failures import Failure
from packbot.model import JointParams

__all__ = ["TorquePath"]

FloatArray = NDArray[np.float64]


@dataclass
class TorquePath:
    """The actuator and failure state of the integrated joints for one phase of a run.

    All arrays have one entry per integrated joint (shape (n,)).

    Attributes:
        effort: Effective effort limits E_j [N*m] (weak joints scaled).
        saturate: Whether each joint's command is clipped to +/- E_j.
        loose: Joints whose motor is cut.
        stuck: Joints driven by a constant torque.
        stuck_torque: That torque [N*m] (0 elsewhere), already saturated.
        viscous: Viscous friction b_j [N*m*s/rad] (0 with joint friction off).
        coulomb: Coulomb (and brake) holding/sliding torque F_j [N*m] (0: none).
        lag: Motor time constant T [s] (0: none).
    """

    effort: FloatArray
    saturate: NDArray[np.bool_]
    loose: NDArray[np.bool_]
    stuck: NDArray[np.bool_]
    stuck_torque: FloatArray
    viscous: FloatArray
    coulomb: FloatArray
    lag: float

    @classmethod
    def build(
        cls,
        params: JointParams,
        free: NDArray[np.intp],
        config: SimConfig,
        failures: Sequence[Failure],
    ) -> TorquePath:
        """The torque path of the integrated joints ``free`` with the failures in force.

        Args:
            params: The full robot's joint parameters.
            free: Indices (full coordinates) of the integrated joints.
            config: Simulation settings (joint_friction, effort_saturation, motor_lag).
            failures: The failures injected so far, in injection order (frozen ones are not
                integrated). A joint's later failure adds to its earlier ones: a later weak
                scale replaces the earlier (both of the nominal limit), a loose motor stops a
                stuck one.
        """
        n_full = len(params.names)
        effort = np.array(params.effort, dtype=float)
        saturate = np.full(n_full, bool(config.effort_saturation))
        loose = np.zeros(n_full, dtype=bool)
        stuck = np.zeros(n_full, dtype=bool)
        stuck_torque = np.zeros(n_full)
        on = 1.0 if config.joint_friction else 0.0
        viscous = on * np.array(params.viscous, dtype=float)
        coulomb = on * np.array(params.coulomb, dtype=float)
        for f in failures:  # in injection order: a later failure of a joint adds to the earlier
            j = params.index(f.joint)
            if f.kind == "weak":
                effort[j] = params.effort[j] * f.scale  # of the nominal limit: the latest holds
                saturate[j] = True
            elif f.kind == "loose":
                loose[j] = True
                stuck[j] = False  # a runaway driver cut
            elif f.kind == "stuck":
                stuck[j] = True
            elif f.kind == "brake":
                coulomb[j] += params.effort[j] if f.threshold is None else f.threshold
        for f in failures:
            if f.kind == "stuck":
                j = params.index(f.joint)
                lim = effort[j] if saturate[j] else np.inf
                stuck_torque[j] = float(np.clip(f.torque, -lim, lim))
        return cls(
            effort=effort[free],
            saturate=saturate[free],
            loose=loose[free],
            stuck=stuck[free],
            stuck_torque=stuck_torque[free],
            viscous=viscous[free],
            coulomb=coulomb[free],
            lag=float(config.motor_lag),
        )

    def __post_init__(self) -> None:
        # Cached: the right-hand side's fast path reads them at every call.
        #: No joint applies a torque of its own (no ``"stuck"`` joint): zero in, zero out.
        self.passive = not bool(self.stuck.any())
        #: Some joint has friction.
        self.rubs = bool(self.viscous.any() or self.coulomb.any())

    def target(self, tau_cmd: FloatArray) -> FloatArray:
        """The saturated command tau_sat [N*m] (what the motor tracks)."""
        return np.where(self.saturate, np.clip(tau_cmd, -self.effort, self.effort), tau_cmd)

    def applied(self, tau_motor: FloatArray) -> FloatArray:
        """The applied motor torque [N*m] from the motor's torque (failures overriding it)."""
        out = np.where(self.loose, 0.0, tau_motor)
        return np.where(self.stuck, self.stuck_torque, out)

    def friction(self, v: FloatArray, direction: FloatArray) -> FloatArray:
        """Viscous plus sliding Coulomb torque [N*m] of the joints not held.

        Args:
            v: Joint velocities [rad/s].
            direction: The sliding direction s_j (+1, -1) of each sliding joint; 0 for held
                joints and joints without Coulomb friction.
        """
        return -self.viscous * v - self.coulomb * direction
