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

A joint may fail more than once, at different times (a degrading motor: weak 0.7 at 1 s, then
weak 0.3 at 2 s; a weak joint that then freezes): each failure adds to the joint's earlier ones
and none heals them (:func:`check_sequence` says which sequences can happen).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

from packbot.errors import ConfigurationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.validation import choice, finite_number, name_str

__all__ = [
    "FAILURE_KINDS",
    "FOLLOWERS",
    "Failure",
    "FailureKind",
    "check_sequence",
    "validate_failures",
]

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


#: What may follow a failure of a joint, by kind: a failure is never healed, each later failure of
#: the joint degrades it further (see :func:`check_sequence`).
FOLLOWERS: dict[str, tuple[str, ...]] = {
    "weak": ("weak", "loose", "frozen", "stuck", "brake"),  # a weaker motor, or worse
    "stuck": ("weak", "loose", "frozen", "brake"),  # a weaker runaway, cut, seized or braked
    "loose": ("frozen", "brake"),  # the motor is cut: only the joint itself can change
    "brake": ("weak", "loose", "frozen", "stuck"),  # the brake stays on; the motor may fail
    "frozen": (),  # locked for good: nothing follows
}


@checked_arguments
def check_sequence(failures: Sequence[Failure], field: str = "failures") -> None:
    """Check that the failures of each joint, in time order, make a sequence that can happen.

    A joint may fail several times (a degrading motor: ``weak`` 0.7 at 1 s, then ``weak`` 0.3
    at 2 s); each failure adds to the earlier ones and none heals them:

    - one failure of a joint at one time (two at the same instant are ambiguous);
    - nothing after ``"frozen"`` (the joint is locked for good);
    - a later ``"weak"`` has a smaller ``scale`` than the joint's earlier one (the scale is of
      the nominal effort limit, not of the weakened one; a motor degrades, it does not
      recover);
    - after ``"loose"`` (the motor cut) only ``"brake"`` or ``"frozen"``;
    - ``"stuck"`` and ``"brake"`` at most once per joint (a brake, once on, stays on: there
      is no release);
    - :data:`FOLLOWERS` lists what may follow each kind.

    Args:
        failures: The failures, in any order (their list order names them in errors).
        field: The name of the list in errors (``failures[k].t``, ``failures[k].kind``, ...).

    Raises:
        ConfigurationError: The first failure that cannot follow its joint's earlier one,
            naming its field (``{field}[k].t``, ``.kind`` or ``.scale``), the value and what
            may follow.
    """
    order = sorted(range(len(failures)), key=lambda k: failures[k].t)
    history: dict[str, list[Failure]] = {}
    for k in order:
        f = failures[k]
        before = history.setdefault(f.joint, [])
        if before:
            last = before[-1]
            since = f"{f.joint} is {last.kind} from t={last.t:g} s"
            if f.t - last.t <= 1e-12:  # the schedule's simultaneity
                raise ConfigurationError(
                    f"{field}[{k}].t",
                    f.t,
                    f"a time after t={last.t:g} s ({f.joint} already fails then: one failure "
                    "of a joint at a time)",
                )
            follow = FOLLOWERS[last.kind]
            kinds = {b.kind for b in before}
            if f.kind not in follow:
                allowed = ", ".join(repr(x) for x in follow) or "nothing (frozen for good)"
                raise ConfigurationError(
                    f"{field}[{k}].kind", f.kind, f"what may follow ({since}): {allowed}"
                )
            if f.kind in ("stuck", "brake") and f.kind in kinds:
                raise ConfigurationError(
                    f"{field}[{k}].kind",
                    f.kind,
                    f"a kind {f.joint} has not had (it is {f.kind} already: a brake stays on, "
                    "a runaway driver runs away once)",
                )
            weak = [b for b in before if b.kind == "weak"]
            if f.kind == "weak" and weak and f.scale >= weak[-1].scale:
                raise ConfigurationError(
                    f"{field}[{k}].scale",
                    f.scale,
                    f"a scale below {weak[-1].scale:g} ({f.joint} is weak at {weak[-1].scale:g} "
                    f"from t={weak[-1].t:g} s: a motor degrades, it does not recover; the scale "
                    "is of the nominal effort limit)",
                )
        before.append(f)


@checked_arguments
def validate_failures(failures: Sequence[Failure], joint_names: Sequence[str]) -> None:
    """Validate a list of failures: each one, and each joint's sequence (:func:`check_sequence`).

    Raises:
        ConfigurationError: A bad field, or a failure that cannot follow its joint's earlier
            one (two at one time, anything after frozen, a weak joint growing stronger, ...).
    """
    for f in failures:
        if not isinstance(f, Failure):
            raise ConfigurationError("failures", f, "a list of packbot.Failure")
        f.validate(joint_names)
    check_sequence(failures)
