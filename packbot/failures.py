"""Joint failures: what a failed joint does, from t = 0 or injected at a time during a run.

A :class:`Failure` names a joint, a kind and an injection time ``t`` [s]. The simulator applies it
in the torque path (:mod:`packbot.actuators`) or, for a frozen joint, by merging the two bodies
with ``pin.buildReducedModel`` (see docs/failures.md):

- ``"loose"``: the motor is cut: zero motor torque whatever the command; the joint's friction and
  reflected rotor inertia stay.
- ``"frozen"``: the joint locks at its angle at time ``t``. Freezing a moving joint is an impact:
  an impulse stops the joint while the rest of the arm keeps its generalized momentum.
- ``"weak"``: the effort limit is scaled by ``scale`` in (0, 1] (a degraded motor, low battery).
- ``"stuck"``: the driver applies the constant torque ``torque`` [N*m] whatever the command
  (a runaway joint: ``torque`` = +/- the effort limit).
- ``"brake"``: the joint's brake holds it until the torque needed to hold exceeds ``threshold``
  [N*m] (default: the joint's effort limit), then the joint slips with the brake's kinetic torque
  ``threshold`` opposing the motion; it holds again when the slip speed returns to zero and the
  holding torque is within the threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

from packbot.errors import ConfigurationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.validation import choice, finite_number, name_str

__all__ = ["FAILURE_KINDS", "Failure", "FailureKind", "validate_failures"]

#: The failure kinds, as a type (the values of :data:`FAILURE_KINDS`).
FailureKind = Literal["loose", "frozen", "weak", "stuck", "brake"]
#: The valid values of :attr:`Failure.kind`.
FAILURE_KINDS: tuple[str, ...] = get_args(FailureKind)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Failure:
    """A joint failure.

    The fields are checked at construction (a :class:`~packbot.errors.ConfigurationError`
    naming the field); whether ``joint`` is a joint of the robot is checked by
    :meth:`validate` and by :func:`packbot.simulate`.

    Attributes:
        joint: The failed joint's name (one of ``robot.params.names``).
        kind: One of :data:`FAILURE_KINDS`.
        t: Injection time [s] (0: failed from the start).
        scale: ``"weak"`` only: effort-limit multiplier in (0, 1] [-] (checked for every kind).
        torque: ``"stuck"`` only: the constant joint torque the driver applies [N*m].
        threshold: ``"brake"`` only: holding (and slipping) torque of the brake [N*m]; None: the
            joint's effort limit.
    """

    joint: str
    kind: FailureKind
    t: float = 0.0
    scale: float = 0.5
    torque: float = 0.0
    threshold: float | None = None

    def __post_init__(self) -> None:
        for fname, value in self._checked().items():
            object.__setattr__(self, fname, value)

    def _checked(self) -> dict[str, object]:
        """The fields checked and normalised (everything but the joint's existence)."""
        kind = choice("failure.kind", self.kind, FAILURE_KINDS)
        threshold = self.threshold
        if threshold is not None:
            threshold = finite_number(
                "failure.threshold",
                threshold,
                low=0.0,
                low_open=True,
                unit="N*m",
                what="None (the effort limit) or a finite positive torque",
            )
        return {
            "joint": name_str("failure.joint", self.joint, "a joint name (a non-empty string)"),
            "kind": kind,
            "t": finite_number("failure.t", self.t, low=0.0, unit="s", what="a finite time"),
            "scale": finite_number(
                "failure.scale", self.scale, low=0.0, high=1.0, low_open=True, what="a number"
            ),
            "torque": finite_number(
                "failure.torque", self.torque, unit="N*m", what="a finite torque"
            ),
            "threshold": threshold,
        }

    @checked_arguments
    def validate(self, joint_names: Sequence[str]) -> None:
        """Raise a :class:`~packbot.errors.PackbotError` naming the first bad field.

        The fields are checked at construction already; this also checks that the joint is one
        of ``joint_names``.

        Args:
            joint_names: The valid joint names.
        """
        self._checked()
        if self.joint not in joint_names:
            raise UnknownNameError("joint", self.joint, joint_names)


@checked_arguments
def validate_failures(failures: Sequence[Failure], joint_names: Sequence[str]) -> None:
    """Validate a list of failures: each one, and at most one failure per joint.

    Raises:
        ConfigurationError: A bad field, or two failures of one joint.
    """
    seen: set[str] = set()
    for f in failures:
        if not isinstance(f, Failure):
            raise ConfigurationError("failures", f, "a list of packbot.Failure")
        f.validate(joint_names)
        if f.joint in seen:
            raise ConfigurationError(
                "failures", f.joint, "at most one failure per joint (this joint has two)"
            )
        seen.add(f.joint)
