"""Simulation settings: :class:`SimConfig`, the one place for them (scenario files load into it)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

from packbot.errors import ConfigurationError

__all__ = ["CLAMP_RULES", "CONTACT_MODES", "RESET_RULES", "SimConfig"]

ContactMode = Literal["joint_clamp", "normal", "none"]
ClampRule = Literal["velocity", "jacobian"]
ResetRule = Literal["zero", "momentum"]

#: Valid values of :attr:`SimConfig.contact_mode`.
CONTACT_MODES: tuple[str, ...] = get_args(ContactMode)
#: Valid values of :attr:`SimConfig.clamp_rule`.
CLAMP_RULES: tuple[str, ...] = get_args(ClampRule)
#: Valid values of :attr:`SimConfig.reset_rule`.
RESET_RULES: tuple[str, ...] = get_args(ResetRule)


@dataclass(kw_only=True)
class SimConfig:
    """Settings of :func:`packbot.simulate`.

    Attributes:
        contact_mode: ``"joint_clamp"`` (the 2010 report's law: stop and clamp the joints between
            the colliding bodies), ``"normal"`` (contact-normal constraints on contact patches,
            complementarity and Coulomb friction; see docs/contact.md), or ``"none"`` (no
            collisions; joint limit stops still act if ``joint_limits``).
        restitution: Coefficient of restitution e in [0, 1] (0: perfectly inelastic).
        contact_tolerance: Contact tolerance [m]: a contact event fires when a pair's signed
            distance falls to +tol; the simulation keeps every distance >= -tol.
        proximity_tolerance: An active contact is released when its pair separates beyond this
            distance [m] (the report's proximity tolerance); must exceed contact_tolerance.
        rtol: Relative tolerance of the adaptive integrator [-].
        atol: Absolute tolerance of the adaptive integrator [rad, rad/s].
        sample_dt: Sampling interval of the result [s] (dense output).
        gravity: Gravity vector in the world frame [m/s^2] (tilt it for a robot on a slope).
        clamp_rule: Direction in which a clamped joint may not accelerate: ``"velocity"`` (the
            report's, the default: the joint's velocity at impact) or ``"jacobian"`` (the sign
            of the joint's own contribution to closing the gap, J_n,i).
        reset_rule: Impact velocity reset: ``"zero"`` (the report's, the default:
            v_i <- -e v_i on the relevant joints; can add energy on a coupled arm) or
            ``"momentum"`` (an impulse stops the relevant joints; the others keep their
            generalized momentum). It applies to link contacts; a joint-limit stop always uses
            the momentum law on its joint (a hard stop never adds energy).
        relevant_threshold: Joint i is relevant to a contact if |J_n,i| > threshold * ||J_n||.
        joint_limits: Whether joint position limits act as hard stops (impact + clamp).
        locked_joints: Joints held rigid at their initial angle for the whole run (the model is
            reduced with ``pin.buildReducedModel``); results stay in full coordinates.
        margin: Query margin of the collision world [m] (pairs farther apart are pruned).
        max_step: Largest integration step [s].
        rest_speed: Joint speed [rad/s] below which the arm counts as at rest.
        max_events: Stop with an error after this many events (a runaway guard).
        joint_friction: Apply the joints' viscous and Coulomb friction from ``robot.params``
            (Coulomb with stick/slip events; see :mod:`packbot.actuators`). Off by default: the
            report's model had none, and the values are estimates.
        effort_saturation: Clip commanded torques to the joints' effort limits [N*m].
        motor_lag: Time constant T of a first-order lag between the (saturated) command and the
            motor torque [s]; 0: no lag.
        mu: Coulomb friction coefficient of every contact pair [-] (``contact_mode="normal"``
            only; 0: frictionless).
        zeno_speed: Impacts whose fastest approaching point is slower than this are perfectly
            inelastic [m/s] (``"normal"`` only): ends a Zeno sequence of ever closer bounces
            in resting contact.
        handoff: ``contact_mode="joint_clamp"`` only (True with another mode is an error): at a
            ``secondary_intersection`` of a pair (the report's self-diagnosis: a clamped pair
            penetrates anyway), its clamps are released and the pair is handed to the
            contact-normal machinery (patch rows, impulse with ``restitution``, resting contact
            with friction ``mu``, release when its force would pull) instead of applying the
            report's law again; the other pairs' clamps become one-sided joint rows of the same
            complementarity problem while a handed-off pair is in contact. The pair returns to
            the report's law once it separates beyond ``proximity_tolerance``. Logged as a
            ``handoff`` event. See docs/contact.md, "Hand-off".
    """

    contact_mode: ContactMode = "joint_clamp"
    restitution: float = 0.0
    contact_tolerance: float = 1e-3
    proximity_tolerance: float = 5e-3
    rtol: float = 1e-6
    atol: float = 1e-8
    sample_dt: float = 0.01
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    clamp_rule: ClampRule = "velocity"
    reset_rule: ResetRule = "zero"
    relevant_threshold: float = 1e-6
    joint_limits: bool = True
    locked_joints: tuple[str, ...] = ()
    margin: float = 0.05
    max_step: float = 0.05
    rest_speed: float = 1e-3
    max_events: int = 20000
    joint_friction: bool = False
    effort_saturation: bool = True
    motor_lag: float = 0.0
    mu: float = 0.0
    zeno_speed: float = 1e-2
    handoff: bool = False

    def validate(self) -> None:
        """Check every field; raise :class:`ConfigurationError` naming the first bad one."""
        choices = {
            "contact_mode": CONTACT_MODES,
            "clamp_rule": CLAMP_RULES,
            "reset_rule": RESET_RULES,
        }
        for name, valid in choices.items():
            if getattr(self, name) not in valid:
                raise ConfigurationError(name, getattr(self, name), valid)
        positive = (
            "contact_tolerance",
            "proximity_tolerance",
            "rtol",
            "atol",
            "sample_dt",
            "margin",
            "max_step",
            "rest_speed",
            "relevant_threshold",
        )
        for name in positive:
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ConfigurationError(name, v, "a finite positive number")
        if not 0.0 <= self.restitution <= 1.0:
            raise ConfigurationError("restitution", self.restitution, "a number in [0, 1]")
        if self.proximity_tolerance <= self.contact_tolerance:
            raise ConfigurationError(
                "proximity_tolerance",
                self.proximity_tolerance,
                f"a distance greater than contact_tolerance={self.contact_tolerance} [m]",
            )
        if self.margin <= self.proximity_tolerance:
            raise ConfigurationError(
                "margin", self.margin, "a distance greater than proximity_tolerance [m]"
            )
        if len(self.gravity) != 3 or not all(math.isfinite(g) for g in self.gravity):
            raise ConfigurationError("gravity", self.gravity, "3 finite numbers [m/s^2]")
        for name in ("joint_friction", "effort_saturation", "joint_limits", "handoff"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigurationError(name, getattr(self, name), "true or false")
        lag = self.motor_lag
        if not isinstance(lag, (int, float)) or not math.isfinite(lag) or lag < 0:
            raise ConfigurationError("motor_lag", lag, "a finite time >= 0 [s] (0: no lag)")
        if not isinstance(self.max_events, int) or self.max_events < 1:
            raise ConfigurationError("max_events", self.max_events, "a positive integer")
        for name in ("mu", "zeno_speed"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigurationError(name, v, "a finite number >= 0")
        if self.contact_mode == "normal" and self.joint_friction:
            raise ConfigurationError(
                "joint_friction",
                self.joint_friction,
                "False with contact_mode='normal' (joint stick/slip and contact forces are not "
                "yet solved as one problem)",
            )
        if self.handoff and self.contact_mode != "joint_clamp":
            raise ConfigurationError(
                "handoff",
                self.handoff,
                f"False with contact_mode={self.contact_mode!r} (a hand-off goes from the "
                "'joint_clamp' law to the contact-normal machinery)",
            )
        if self.handoff and self.joint_friction:
            raise ConfigurationError(
                "handoff",
                self.handoff,
                "False with joint_friction=True (joint stick/slip and contact forces are not "
                "yet solved as one problem)",
            )
