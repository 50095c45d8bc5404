"""Simulation settings: :class:`SimConfig`, the one place for them (scenario files load into it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import (
    GRAVITY_MAX,
    MAX_EVENTS_LIMIT,
    MAX_STEP_MIN,
    RTOL_MAX,
    RTOL_MIN,
    SAMPLE_DT_MIN,
    boolean,
    choice,
    finite_number,
    integer,
    is_number,
    joint_names,
    vector,
)

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

#: Largest contact_tolerance, proximity_tolerance and margin [m]: a quarter of the arm's reach.
DISTANCE_MAX = 0.5
#: Range of the integrator's absolute tolerance [rad, rad/s].
ATOL_MIN, ATOL_MAX = 1e-20, 1.0
#: Smallest nonzero motor lag [s]: the lag's rate 1/T bounds the explicit integrator's step
#: (stable for h < 3.3 T), so a 1 s run needs at least 1 / (3.3 T) steps.
MOTOR_LAG_MIN = 1e-5
#: Largest Coulomb friction coefficient [-] (rubber on rubber is about 1 to 2).
MU_MAX = 10.0


@checked_arguments
@dataclass(kw_only=True)
class SimConfig:
    """Settings of :func:`packbot.simulate`.

    Every field is checked at construction (:meth:`validate`): types are strict (a bool is not
    a number, a string is not a list of joints; ints and NumPy scalars are numbers) and each
    value must lie in its range, given below; a bad one raises a
    :class:`~packbot.errors.ConfigurationError` naming the field, the value and the range.

    Attributes:
        contact_mode: ``"normal"`` (the default: contact-normal constraints on contact patches,
            complementarity and Coulomb friction, time-stepping windows where events pile up;
            see docs/contact.md), ``"joint_clamp"`` (the 2010 report's law: stop and clamp the
            joints between the colliding bodies), or ``"none"`` (no collisions; joint limit
            stops still act if ``joint_limits``). The contact-normal mode is the default because
            it is the physical one: on the report's collapse it rests within 0.02 rad of MuJoCo
            (its settings without sliding lift) and Drake on shoulder and elbow1, link 3 folded
            back (elbow2 +0.89 rad), penetrating 1e-5 m at most (docs/contact.md, "Collapse
            side by side"). The report's law is kept to reproduce the report
            (``sims/collapse.toml``; ``sims/collapse_physical.toml`` is the same start in the
            default mode): it props link 3 upright on the shoulder casing (elbow2 -0.48 rad), a
            rest pose no physics engine reaches, and runs the collapse about 3x faster.
        restitution: Coefficient of restitution e in [0, 1] (0: perfectly inelastic).
        contact_tolerance: Contact tolerance [m]: a contact event fires when a pair's signed
            distance falls to +tol; the simulation keeps every distance >= -tol. In (0, 0.5].
        proximity_tolerance: An active contact is released when its pair separates beyond this
            distance [m] (the report's proximity tolerance); in (contact_tolerance, 0.5].
        rtol: Relative tolerance of the adaptive integrator [-], in [1e-13, 0.1].
        atol: Absolute tolerance of the adaptive integrator [rad, rad/s], in [1e-20, 1].
        sample_dt: Sampling interval of the result [s] (dense output), >= 1e-6 s, and at most
            500,000 samples per run (``duration / sample_dt``, checked by ``simulate``). The
            final state is always a sample, also when ``sample_dt`` does not divide the
            duration (the last interval is then shorter).
        gravity: Gravity vector in the world frame [m/s^2] (tilt it for a robot on a slope);
            each component within +/-100 m/s^2.
        clamp_rule: ``"joint_clamp"`` only. Direction in which a clamped joint may not
            accelerate: ``"velocity"`` (the report's, the default: the joint's velocity at
            impact) or ``"jacobian"`` (the sign of the joint's own contribution to closing the
            gap, J_n,i).
        reset_rule: Impact velocity reset of ``"joint_clamp"``: ``"zero"`` (the report's, the
            default: v_i <- -e v_i on the relevant joints; can add energy on a coupled arm) or
            ``"momentum"`` (an impulse stops the relevant joints; the others keep their
            generalized momentum). It applies to link contacts; a joint-limit stop always uses
            the momentum law on its joint (a hard stop never adds energy).
        relevant_threshold: Joint i is relevant to a contact if |J_n,i| > threshold * ||J_n||;
            in [0, 1), and ``simulate`` requires < 1/sqrt(n) with n the free joints (the
            largest of n components is at least ||J_n|| / sqrt(n), so every contact then has a
            relevant joint).
        joint_limits: Whether joint position limits act as hard stops (impact + clamp).
        locked_joints: Joints held rigid at their initial angle for the whole run (the model is
            reduced with ``pin.buildReducedModel``); results stay in full coordinates. A tuple
            of distinct names (``("camera_tilt",)`` for one; a bare string is refused); at
            least one joint must stay free.
        margin: Query margin of the collision world [m] (pairs farther apart are pruned), in
            (proximity_tolerance, 0.5].
        max_step: Largest integration step [s], >= 1e-9 s, and ``duration / max_step`` at
            most 1,000,000 (checked by ``simulate``).
        rest_speed: Joint speed [rad/s] below which the arm counts as at rest.
        max_events: Stop with an error after this many events (a runaway guard); an integer
            in [1, 100,000].
        joint_friction: Apply the joints' viscous and Coulomb friction from ``robot.params``
            (Coulomb with stick/slip events; see :mod:`packbot.actuators`). Off by default: the
            report's model had none, and the values are estimates.
        effort_saturation: Clip commanded torques to the joints' effort limits [N*m].
        motor_lag: Time constant T of a first-order lag between the (saturated) command and the
            motor torque [s]; 0: no lag, else >= 1e-5 s (a shorter lag makes the explicit
            integrator take at least 1 / (3.3 T) steps per simulated second).
        mu: Coulomb friction coefficient of every contact pair [-] (``contact_mode="normal"``
            and the pairs handed off with ``handoff``; the report's law has no friction), in
            [0, 10]. Default 0.5 (metal on metal or hard plastic, the value of every comparison
            with MuJoCo and Drake in docs/contact.md); 0 is frictionless, which on faceted
            pieces can chatter and keep the arm from resting (``simulate`` warns).
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
            ``handoff`` event. Joints held by friction or a brake are locked in the same problem
            (their holding torques include the contact forces). See docs/contact.md,
            "Hand-off".
    """

    contact_mode: ContactMode = "normal"
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
    mu: float = 0.5
    zeno_speed: float = 1e-2
    handoff: bool = False

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check and normalise every field; raise :class:`ConfigurationError` naming the first bad.

        Called at construction; call it again after changing a field (``simulate`` does). Types
        are strict: a bool is not a number, a string is not a list of joints. The ranges are
        those of docs/simulator.md ("Settings and their ranges").
        """
        self.contact_mode = choice("contact_mode", self.contact_mode, CONTACT_MODES)  # type: ignore[assignment]
        self.clamp_rule = choice("clamp_rule", self.clamp_rule, CLAMP_RULES)  # type: ignore[assignment]
        self.reset_rule = choice("reset_rule", self.reset_rule, RESET_RULES)  # type: ignore[assignment]
        self.restitution = finite_number("restitution", self.restitution, low=0.0, high=1.0)
        self.contact_tolerance = finite_number(
            "contact_tolerance",
            self.contact_tolerance,
            low=0.0,
            high=DISTANCE_MAX,
            low_open=True,
            unit="m",
            what="a finite positive distance",
        )
        self.proximity_tolerance = finite_number(
            "proximity_tolerance",
            self.proximity_tolerance,
            low=self.contact_tolerance,
            high=DISTANCE_MAX,
            low_open=True,
            unit="m",
            what=f"a distance greater than contact_tolerance={self.contact_tolerance:g}",
        )
        self.margin = finite_number(
            "margin",
            self.margin,
            low=self.proximity_tolerance,
            high=DISTANCE_MAX,
            low_open=True,
            unit="m",
            what=f"a distance greater than proximity_tolerance={self.proximity_tolerance:g}",
        )
        self.rtol = finite_number(
            "rtol", self.rtol, low=RTOL_MIN, high=RTOL_MAX, what="a finite positive number"
        )
        self.atol = finite_number(
            "atol",
            self.atol,
            low=ATOL_MIN,
            high=ATOL_MAX,
            unit="rad, rad/s",
            what="a finite positive number",
        )
        self.sample_dt = finite_number(
            "sample_dt",
            self.sample_dt,
            low=SAMPLE_DT_MIN,
            unit="s",
            what="a sampling interval (sampling faster than 1 MHz is refused: sample times are "
            "matched to 1e-12 s and every event is sampled anyway)",
        )
        g = vector("gravity", self.gravity, 3, bound=GRAVITY_MAX, unit="m/s^2")
        self.gravity = (g[0], g[1], g[2])
        self.relevant_threshold = finite_number(
            "relevant_threshold",
            self.relevant_threshold,
            low=0.0,
            high=1.0,
            high_open=True,
            what="a fraction of ||J_n||",
        )
        for flag in ("joint_limits", "joint_friction", "effort_saturation", "handoff"):
            setattr(self, flag, boolean(flag, getattr(self, flag)))
        self.locked_joints = joint_names("locked_joints", self.locked_joints)
        self.max_step = finite_number(
            "max_step",
            self.max_step,
            low=MAX_STEP_MIN,
            unit="s",
            what="a finite time (room above the stepper's smallest step h_min = 1e-12 s)",
        )
        self.rest_speed = finite_number(
            "rest_speed", self.rest_speed, low=0.0, low_open=True, unit="rad/s"
        )
        self.max_events = integer(
            "max_events", self.max_events, low=1, high=MAX_EVENTS_LIMIT, what="a positive integer"
        )
        lag = self.motor_lag
        if is_number(lag) and lag == 0:
            self.motor_lag = 0.0
        else:
            self.motor_lag = finite_number(
                "motor_lag",
                lag,
                low=MOTOR_LAG_MIN,
                unit="s",
                what="0 (no lag) or a time constant (a shorter lag forces about 1 / (3.3 T) "
                "integration steps per simulated second)",
            )
        self.mu = finite_number("mu", self.mu, low=0.0, high=MU_MAX, what="a finite number")
        self.zeno_speed = finite_number(
            "zeno_speed", self.zeno_speed, low=0.0, unit="m/s", what="a finite number"
        )
        if self.handoff and self.contact_mode != "joint_clamp":
            raise ConfigurationError(
                "handoff",
                self.handoff,
                f"False with contact_mode={self.contact_mode!r} (a hand-off goes from the "
                "'joint_clamp' law to the contact-normal machinery: set "
                "contact_mode='joint_clamp', the default is 'normal')",
            )
