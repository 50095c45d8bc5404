"""The checks of :func:`packbot.simulate`'s arguments, before anything runs.

Every argument's type and range, and the limits that protect the machine, checked where the
duration is known (docs/simulator.md, "Inputs: checks, ranges and limits").
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.config import SimConfig
from packbot.control.base import Controller
from packbot.environment import Environment
from packbot.errors import ConfigurationError, InitialCollisionError, UnknownNameError
from packbot.failures import Failure, validate_failures
from packbot.model import Robot
from packbot.payload import Payload
from packbot.validation import (
    CONTROL_DT_MIN,
    MAX_SAMPLES,
    MAX_STEPS,
    V0_MAX,
    boolean,
    finite_number,
    joint_names,
    real_array,
)

__all__ = ["check_arguments", "check_initial_state", "check_inputs", "warn_settings"]

log = logging.getLogger("packbot.integrator")

FloatArray = NDArray[np.float64]


def check_inputs(
    robot: Any,
    q0: Any,
    v0: Any,
    duration: Any,
    config: Any,
    failures: Any,
    payload: Any,
    controller: Any,
    environment: Any,
    inform_controller: Any,
    progress: Any,
) -> tuple[FloatArray, FloatArray, float, tuple[Failure, ...]]:
    """Check every argument of :func:`simulate`; return (q0, v0, duration, failures) normalised.

    Besides each argument's type and range, the limits that protect the machine are checked
    here, where the duration is known (docs/simulator.md, "Inputs: checks, ranges and limits").
    """
    if not isinstance(robot, Robot):
        raise ConfigurationError("robot", robot, "a packbot.Robot (from packbot.load_robot())")
    if not isinstance(config, SimConfig):
        raise ConfigurationError("config", config, "None or a packbot.SimConfig")
    config.validate()  # a SimConfig can be changed after its construction
    duration = finite_number(
        "duration", duration, low=0.0, low_open=True, unit="s", what="a finite positive time"
    )
    n_samples = duration / config.sample_dt
    if n_samples > MAX_SAMPLES:
        raise ConfigurationError(
            "sample_dt",
            config.sample_dt,
            f"a sampling interval >= duration / {MAX_SAMPLES:,} = {duration / MAX_SAMPLES:.3g} s "
            f"for duration={duration:g} s (at most {MAX_SAMPLES:,} samples per run: each "
            "takes about 1.7 kB of memory while the run lasts)",
        )
    if duration / config.max_step > MAX_STEPS:
        raise ConfigurationError(
            "max_step",
            config.max_step,
            f"a step >= duration / {MAX_STEPS:,} = {duration / MAX_STEPS:.3g} s for "
            f"duration={duration:g} s (a run may not force more than {MAX_STEPS:,} steps)",
        )
    if isinstance(failures, (Failure, str, bytes, Mapping)) or not isinstance(
        failures, (list, tuple)
    ):
        raise ConfigurationError("failures", failures, "a list of packbot.Failure")
    failures = tuple(failures)
    validate_failures(failures, robot.joint_names)
    locked = joint_names("locked_joints", config.locked_joints, robot.joint_names)
    frozen = [f.joint for f in failures if f.kind == "frozen"]
    if len(set(locked) | set(frozen)) >= robot.nq:
        what = "locked_joints" if len(locked) >= robot.nq else "locked_joints and frozen failures"
        raise ConfigurationError(
            "locked_joints",
            locked,
            f"at least one joint left free ({what} cover all {robot.nq} joints)",
        )
    n_free = robot.nq - len(locked)
    bound = 1.0 / math.sqrt(n_free)
    if config.relevant_threshold >= bound:
        raise ConfigurationError(
            "relevant_threshold",
            config.relevant_threshold,
            f"a fraction < 1/sqrt({n_free}) = {bound:.4g} with {n_free} free joints (the "
            f"largest of {n_free} components of J_n is at least ||J_n|| / sqrt({n_free}), so "
            "below this bound every contact has a relevant joint)",
        )
    for f in failures:
        if f.joint in locked:
            raise ConfigurationError(
                "failures", f.joint, "a joint that is not in config.locked_joints"
            )
    if payload is not None:
        if not isinstance(payload, Payload):
            raise ConfigurationError("payload", payload, "a packbot.Payload or None")
        payload.validate()
        frame = payload.held_in(robot.tool_frame).frame
        if not robot.model.existFrame(frame):
            raise UnknownNameError("frame", frame, [str(f.name) for f in robot.model.frames])
    if environment is not None:
        if not isinstance(environment, Environment):
            raise ConfigurationError("environment", environment, "None or a packbot.Environment")
        environment.validate()
    if isinstance(controller, Controller):
        dt = finite_number(
            "controller.dt",
            getattr(controller, "dt", None),
            low=CONTROL_DT_MIN,
            unit="s",
            what="a control period (a Controller subclass must call Controller.__init__)",
        )
        if duration / dt > MAX_STEPS:
            raise ConfigurationError(
                "controller.dt",
                controller.dt,
                f"a control period >= duration / {MAX_STEPS:,} = {duration / MAX_STEPS:.3g} s "
                f"for duration={duration:g} s (at most {MAX_STEPS:,} control ticks per run: "
                "each cuts an integration step)",
            )
    elif controller is not None and (not callable(controller) or isinstance(controller, type)):
        raise ConfigurationError(
            "controller",
            controller,
            "None, a packbot.control.Controller or a function tau(t, q, v)",
        )
    boolean("inform_controller", inform_controller)
    if progress is not None and not callable(progress):
        raise ConfigurationError("progress", progress, "None or a function progress(t)")
    nq = robot.nq
    q = real_array(
        "q0", q0, shape=(nq,), expected=f"an array of shape ({nq},) [rad]", shape_error_value=True
    )
    v = real_array(
        "v0", v0, shape=(nq,), expected=f"an array of shape ({nq},) [rad/s]", shape_error_value=True
    )
    fast = np.flatnonzero(np.abs(v) > V0_MAX)
    if len(fast):
        raise ConfigurationError(
            "v0",
            "; ".join(f"{robot.joint_names[i]}={v[i]:g}" for i in fast),
            f"joint speeds within +/-{V0_MAX:g} rad/s (50 times the fastest joint's velocity "
            "limit; more is a unit mistake: deg/s or rpm)",
        )
    robot.check_within_limits(q, "q0")
    idx = [robot.params.index(nm) for nm in locked]
    if np.any(v[idx] != 0.0):
        raise ConfigurationError("v0", v.tolist(), "zero velocity on the locked joints")
    return q, v, duration, failures


def warn_settings(config: SimConfig) -> None:
    """Warn of settings that run but may not do what one expects."""
    if config.contact_mode == "normal" and config.mu == 0.0:
        log.warning(
            "contact_mode='normal' with mu = 0 (the default is 0.5): frictionless contact on "
            "faceted pieces can chatter (an impact every few ms) and an arm may never come to "
            "rest (docs/contact.md, 'Open problems')"
        )
    default_mu = SimConfig.__dataclass_fields__["mu"].default
    if config.contact_mode == "joint_clamp" and config.mu != default_mu:
        log.warning(
            "mu = %g is set but contact_mode='joint_clamp' (the report's law) has no friction: "
            "a clamped joint holds whatever the friction, mu does nothing here (the "
            "contact-normal mode, contact_mode='normal', uses it)",
            config.mu,
        )


def check_arguments(
    robot: Robot,
    q0: Any,
    v0: Any,
    duration: float,
    *,
    controller: Any = None,
    environment: Environment | None = None,
    config: SimConfig | None = None,
    failures: Any = (),
    payload: Payload | None = None,
    inform_controller: bool = False,
    progress: Any = None,
) -> None:
    """Check :func:`packbot.simulate`'s arguments as it does before a run, without running it.

    Everything but the initial collision check (which needs the collision world): types,
    ranges, names, and the limits that protect the machine. Used to refuse a bad scenario before
    anything is written.

    Raises:
        ConfigurationError: A bad argument (see :func:`packbot.simulate`).
        UnknownNameError: An unknown locked joint, failed joint or payload frame.
    """
    check_inputs(
        robot,
        q0,
        v0,
        duration,
        SimConfig() if config is None else config,
        failures,
        payload,
        controller,
        environment,
        inform_controller,
        progress,
    )


def check_initial_state(
    robot: Robot,
    q0: Any,
    *,
    environment: Environment | None = None,
    config: SimConfig | None = None,
) -> None:
    """Raise if the initial configuration penetrates, as :func:`packbot.simulate` does at its start.

    Builds the same collision world as the run (its locked joints, its environment) and tests
    every pair at q0; nothing with ``contact_mode="none"``. Call it after :func:`check_arguments`
    (the arguments are assumed valid).

    Raises:
        InitialCollisionError: A pair penetrates at q0 (names the pairs and depths).
    """
    from packbot.system import System

    cfg = SimConfig() if config is None else config
    q = np.asarray(q0, dtype=float)
    system = System(robot, q, cfg, environment, locked=tuple(cfg.locked_joints))
    world = system.world
    if world is None:
        return
    sw = world.sweep(system.reduce(q))
    bad = [(world.pairs[p], d) for p, d in zip(sw.pairs, sw.distances, strict=True) if d < 0]
    if bad:
        raise InitialCollisionError([(p.piece1, p.piece2, d) for p, d in bad])
