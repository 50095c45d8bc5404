"""The controller interface: a sampled-data controller with state, fed by measurements.

A real arm controller runs at a fixed rate on encoder readings and holds its torque command
between ticks. :class:`Controller` models that: the simulator calls :meth:`Controller.step` at
t = 0, dt, 2 dt, ... (each tick is a time event of the integrator, so the held torque is constant
inside an integration step and the right-hand side stays smooth), passing the true state; the
controller sees it through its :class:`Sensor` (quantisation, seeded noise) and returns the
commanded joint torque, held until the next tick (zero-order hold). The command then passes
through the failure and actuator models (effort limits, friction) before it acts.

**Contact sensing.** A controller whose class sets ``contact_sensing = True`` is told, before
each tick, the contact forces at the tick's state (the simulator knows them: a force-torque
sensor on every link): :attr:`Controller.contacts` (a list of
:class:`~packbot.contact_forces.ContactForce`, world frame) and :attr:`Controller.
contact_torque` (their joint torque [N*m], shape (nv,), with the joint position stops' and the
report's law's clamps' torques added: M a + C v + g = tau + contact_torque).
Under the report's law (``joint_clamp``) the list is empty (its contacts act through clamps on
joints: ``contact_torque`` holds their torques). Both are None where the contact law cannot say
(a time-stepping window's opening instant) and before the first tick; an empty list and zeros
with no contact. Inside a time-stepping window of the contact-normal
mode they are the forces of the window step ending at the tick (its impulses over its length).
The impacts between two ticks are impulses, not forces at a tick: :attr:`Controller.
contact_impulse` is their joint impulse [N*m*s] (M (v+ - v-) summed; M at the tick).

A plain function ``tau(t, q, v)`` is also accepted by :func:`packbot.simulate`: it is treated as
a continuous-time controller evaluated at every right-hand side (it must be a smooth, stateless
function of its arguments).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import check_subclass, checked_arguments
from packbot.validation import CONTROL_DT_MIN, finite_number, integer

if TYPE_CHECKING:
    from packbot.contact_forces import ContactForce
    from packbot.failures import Failure
    from packbot.model import Robot

__all__ = ["Controller", "Sensor"]

FloatArray = NDArray[np.float64]

#: Largest velocity noise [rad/s] (ten times the fastest joint's speed limit).
NOISE_V_MAX = 100.0


@checked_arguments
@dataclass(kw_only=True)
class Sensor:
    """What the controller measures: joint encoders (and velocities derived from them).

    Checked at construction: resolution and noise_q in [0, pi] rad, noise_v in [0, 100] rad/s,
    seed an integer >= 0.

    Attributes:
        resolution: Encoder quantum [rad] (0: exact positions). Positions are rounded to it.
        noise_q: Standard deviation of white position noise [rad] (0: none).
        noise_v: Standard deviation of white velocity noise [rad/s] (0: none).
        seed: Seed of the noise generator (a run is reproducible).
    """

    resolution: float = 0.0
    noise_q: float = 0.0
    noise_v: float = 0.0
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.validate()
        self.reset()

    def validate(self) -> None:
        """Check and normalise the fields; raise :class:`ConfigurationError` naming a bad one."""
        for fname, high, unit in (
            ("resolution", math.pi, "rad"),
            ("noise_q", math.pi, "rad"),
            ("noise_v", NOISE_V_MAX, "rad/s"),
        ):
            x = finite_number(
                f"sensor.{fname}", getattr(self, fname), low=0.0, high=high, unit=unit
            )
            setattr(self, fname, x)
        self.seed = integer("sensor.seed", self.seed, low=0, what="an integer seed")

    def reset(self) -> None:
        """Restart the noise sequence from the seed."""
        self._rng = np.random.default_rng(self.seed)

    def measure(self, q: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Measured (q [rad], v [rad/s]) from the true state."""
        qm = np.array(q, dtype=float)
        vm = np.array(v, dtype=float)
        if self.noise_q > 0:
            qm += self.noise_q * self._rng.standard_normal(qm.shape)
        if self.noise_v > 0:
            vm += self.noise_v * self._rng.standard_normal(vm.shape)
        if self.resolution > 0:
            qm = self.resolution * np.round(qm / self.resolution)
        return qm, vm


@checked_arguments
class Controller(ABC):
    """Base class of sampled-data controllers.

    Subclasses implement :meth:`compute` (and :meth:`on_reset` / :meth:`on_failure` if they keep
    state). All vectors are in the full model's coordinates, shape (nv,).

    Every subclass (a user's own too) gets its constructor's arguments checked
    (:func:`packbot.keywords.check_subclass`, from ``__init_subclass__``): an unknown, misspelt
    or missing keyword raises :class:`~packbot.errors.KeywordError` naming it and the valid
    ones.

    Args:
        dt: Control period [s] (default 1 ms), >= 1e-6 s.
        sensor: The measurement model (default: exact).

    Raises:
        ConfigurationError: A bad ``dt`` or ``sensor`` (checked at construction).
        KeywordError: An unknown or missing keyword, or too many positional arguments.
    """

    #: Whether the simulator tells the controller the contact forces before each tick
    #: (:attr:`contacts`, :attr:`contact_torque`; see the module).
    contact_sensing: ClassVar[bool] = False
    #: The contacts at the tick's state (world frame), or None: not known (see the module).
    contacts: list[ContactForce] | None = None
    #: Their joint torque with the joint stops' and clamps' [N*m], shape (nv,), or None: not
    #: known.
    contact_torque: FloatArray | None = None
    #: The joint impulse [N*m*s] of the impacts since the previous tick, shape (nv,): M (v+ -
    #: v-) summed over them (zeros: none), or None before the first tick.
    contact_impulse: FloatArray | None = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        check_subclass(cls)

    def __init__(self, *, dt: float = 1e-3, sensor: Sensor | None = None) -> None:
        self.dt = finite_number(
            "controller.dt",
            dt,
            low=CONTROL_DT_MIN,
            unit="s",
            what="a control period (a loop faster than 1 MHz is refused)",
        )
        if sensor is not None and not isinstance(sensor, Sensor):
            raise ConfigurationError(
                "controller.sensor", sensor, "None or a packbot.control.Sensor"
            )
        self.sensor = sensor if sensor is not None else Sensor()
        self.robot: Robot | None = None

    def reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Called once by the simulator before the first tick.

        Args:
            robot: The (full, healthy) robot model the controller is designed for.
            t0: Start time [s].
            q0: Initial configuration [rad].
            v0: Initial velocity [rad/s].
        """
        self.robot = robot
        self.sensor.reset()
        self.on_reset(robot, t0, q0, v0)

    def step(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """One control tick: measure the true state, compute the command [N*m], shape (nv,).

        The command is returned as computed (the simulator checks that it is nv real, finite
        torques: a complex or non-numeric value is an error there, not silently converted).
        """
        qm, vm = self.sensor.measure(q, v)
        return np.asarray(self.compute(t, qm, vm))

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:  # noqa: B027
        """Hook for subclasses: set up state (default: nothing)."""

    def on_failure(self, failure: Failure, t: float) -> None:  # noqa: B027
        """Hook: the scenario tells the controller that a joint failed (default: ignore).

        Called by the simulator at the failure's injection time when the scenario says the
        controller is informed (``simulate(..., inform_controller=True)``).
        """

    @abstractmethod
    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """The torque command [N*m], shape (nv,), from measured q [rad] and v [rad/s] at t [s]."""
