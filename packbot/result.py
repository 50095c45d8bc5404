"""What a simulation returns: :class:`SimResult`, its event log and diagnostics."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from packbot.config import SimConfig
from packbot.errors import UnknownNameError
from packbot.failures import Failure

__all__ = ["EVENT_KINDS", "Diagnostics", "Event", "SimResult"]

EventKind = Literal[
    "impact",
    "limit",
    "release",
    "secondary_intersection",
    "handoff",
    "engage",
    "disengage",
    "slip",
    "stick",
    "repatch",
    "painleve",
    "failure",
    "freeze",
    "pick",
    "drop",
]
#: The kinds of event the simulator logs.
EVENT_KINDS: tuple[str, ...] = (
    "impact",  # a pair's signed distance fell to the contact tolerance: impact law applied
    "limit",  # a joint reached a position limit: the same impact law and clamp
    "release",  # an active contact or limit stop let go (separated, or its clamp would pull)
    "secondary_intersection",  # an active, clamped pair penetrated anyway (report's self-diagnosis)
    "handoff",  # the same with SimConfig.handoff: its clamps released, the pair handed to the
    # contact-normal machinery (velocities before/after its restart's impulse)
    "engage",  # a clamped joint started to accelerate toward its contact: its lock engaged
    "disengage",  # a locked joint's constraint torque would pull: its lock let go
    "slip",  # a joint held by static friction or a brake needed more than its holding torque;
    # normal mode: a sticking contact's friction force reached the cone (link1/link2: the pair)
    "stick",  # a sliding joint with Coulomb friction stopped and its holding torque suffices;
    # normal mode: a sliding contact stopped sliding (friction holds it)
    "repatch",  # normal mode: a pair in contact penetrated: its patch was recomputed
    "painleve",  # normal mode: no consistent contact forces (friction): handled impulsively
    "failure",  # a joint failure was injected (link1: joint, link2: kind)
    "freeze",  # the impulse that stops a freezing joint (link1: joint; distance: its angle)
    "pick",  # the payload was picked up (generalized momentum kept)
    "drop",  # the payload was dropped
)


@dataclass(frozen=True)
class Event:
    """One entry of the event log.

    Attributes:
        t: Time [s].
        kind: One of :data:`EVENT_KINDS`.
        link1: Body 1 (distal) of the pair, or the joint name for a limit.
        link2: Body 2 (proximal, chassis or obstacle), or ``"upper"``/``"lower"`` for a limit.
        piece1: Convex piece on body 1 ("" for a limit).
        piece2: Convex piece on body 2 ("" for a limit).
        distance: Signed distance of the pair at the event [m] (limit: distance to the stop
            [rad]).
        relevant_joints: Joints the law acted on (impact: the relevant joints).
        v_before: Joint velocities before [rad/s], full coordinates, shape (nv,).
        v_after: Joint velocities after [rad/s], shape (nv,).
        energy_before: Total mechanical energy before [J].
        energy_after: Total mechanical energy after [J].
    """

    t: float
    kind: str
    link1: str = ""
    link2: str = ""
    piece1: str = ""
    piece2: str = ""
    distance: float = float("nan")
    relevant_joints: tuple[str, ...] = ()
    v_before: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    v_after: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    energy_before: float = float("nan")
    energy_after: float = float("nan")

    @property
    def energy_change(self) -> float:
        """Energy after minus before [J] (positive: the event added energy)."""
        return self.energy_after - self.energy_before


@dataclass
class Diagnostics:
    """Work done and invariants seen by a run.

    Attributes:
        steps: Accepted integration steps.
        rejected_steps: Rejected integration steps.
        rhs_calls: Right-hand-side evaluations.
        sweeps: Collision sweeps (one per accepted step, plus root finding).
        distance_queries: Single-pair distance evaluations during event location.
        restarts: Integrator restarts (after events).
        wall_time: Wall-clock time of the run [s].
        min_distance: Smallest signed distance seen at any accepted step or sample [m].
        min_distance_pair: Links of that pair, ``"link1/piece1 - link2/piece2"``.
        reset_energy_gain: Total energy the report's velocity resets added [J]: the sum, over
            the ``impact``, ``secondary_intersection`` and ``limit`` events, of each one's
            ``energy_after - energy_before`` where positive (the ``"zero"`` reset on a coupled
            arm can add kinetic energy; docs/simulator.md, "The impact law").
    """

    steps: int = 0
    rejected_steps: int = 0
    rhs_calls: int = 0
    sweeps: int = 0
    distance_queries: int = 0
    restarts: int = 0
    wall_time: float = 0.0
    min_distance: float = float("inf")
    min_distance_pair: str = ""
    reset_energy_gain: float = 0.0


@dataclass
class SimResult:
    """The outcome of :func:`packbot.simulate`.

    Attributes:
        t: Sample times [s], shape (N,): every ``sample_dt`` from the dense output, plus the
            instants just before and just after every event (equal times, pre first).
        q: Joint positions [rad], shape (N, nq), full model coordinates.
        v: Joint velocities [rad/s], shape (N, nv).
        tau: Applied motor torques [N*m], shape (N, nv): the command after the failures,
            saturation and motor lag (friction not included).
        energy: Total mechanical energy (kinetic incl. armature + potential) [J], shape (N,).
        events: The event log, in time order.
        rest_time: First time after which every joint speed stays below
            ``config.rest_speed`` to the end [s], or None.
        joint_names: Names of the columns of q, v, tau.
        config: The settings of the run.
        diagnostics: Work done and invariants seen.
        tau_cmd: Commanded torques [N*m], shape (N, nv) (a sampled-data controller's held
            command).
        tau_friction: Joint friction torques [N*m], shape (N, nv) (viscous + Coulomb; for a
            joint held by static friction or a brake, the holding torque).
        effort: Effective effort limits [N*m], shape (N, nv) (a weak joint's scaled).
        failures: The failures injected during the run.
        control_ticks: Number of ticks of a sampled-data controller.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    tau: NDArray[np.float64]
    energy: NDArray[np.float64]
    events: list[Event]
    rest_time: float | None
    joint_names: tuple[str, ...]
    config: SimConfig
    diagnostics: Diagnostics
    tau_cmd: NDArray[np.float64]
    tau_friction: NDArray[np.float64]
    effort: NDArray[np.float64]
    failures: tuple[Failure, ...] = ()
    control_ticks: int = 0

    def events_of(self, *kinds: str) -> list[Event]:
        """The events of the given kinds (each one of :data:`EVENT_KINDS`).

        Raises:
            UnknownNameError: A kind that is not an event kind (a typo would give no events).
        """
        for kind in kinds:
            if kind not in EVENT_KINDS:
                raise UnknownNameError("event kind", kind, EVENT_KINDS)
        return [e for e in self.events if e.kind in kinds]

    def joint(self, name: str) -> int:
        """Column index of a joint.

        Raises:
            UnknownNameError: No joint of that name.
        """
        if name not in self.joint_names:
            raise UnknownNameError("joint", name, self.joint_names)
        return self.joint_names.index(name)


def rest_time(t: NDArray[np.float64], v: NDArray[np.float64], speed: float) -> float | None:
    """First time after which every joint speed stays below ``speed`` [rad/s] to the end."""
    moving = np.flatnonzero(np.abs(v).max(axis=1) >= speed)
    if len(moving) == 0:
        return float(t[0])
    last = moving[-1]
    if last == len(t) - 1:
        return None
    return float(t[last + 1])
