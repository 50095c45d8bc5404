"""What a contact law writes of its events: the run's event log and its energy counters.

:class:`LawLog` writes a law's events to the run's :class:`~packbot.recorder.EventLog` with
the energies before and after and the full velocities, and counts what a velocity reset gained
in the run's :class:`~packbot.result.Diagnostics`; every law and its pools write through one.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.recorder import EventLog
from packbot.result import Diagnostics, Event
from packbot.system import System

__all__ = ["LawLog"]

FloatArray = NDArray[np.float64]


class LawLog:
    """A law's event writer for one phase.

    Args:
        system: The phase's integrated system (joint names, energies, full velocities).
        events: The run's event log.
        diag: The run's diagnostics.
    """

    def __init__(self, system: System, events: EventLog, diag: Diagnostics) -> None:
        self.sys = system
        self.events = events
        self.diag = diag

    def energy(self, q: FloatArray, v: FloatArray) -> float:
        """Total mechanical energy [J]."""
        return self.sys.energy(q, v)

    def event(
        self,
        t: float,
        kind: str,
        q: FloatArray,
        v0: FloatArray,
        v1: FloatArray,
        pair: PairInfo | None,
        d: float = math.nan,
        joints: tuple[str, ...] = (),
        joint: int | None = None,
    ) -> Event:
        """Log an event (energies before and after, full velocities) to the run's event log.

        Returns:
            The event logged.
        """
        sys = self.sys
        e0 = sys.energy(q, v0)
        e1 = e0 if v1 is v0 else sys.energy(q, v1)
        event = Event(
            t,
            kind,
            pair.link1 if pair else (sys.names[joint] if joint is not None else ""),
            pair.link2 if pair else "",
            pair.piece1 if pair else "",
            pair.piece2 if pair else "",
            d,
            joints,
            sys.v_full(v0),
            sys.v_full(v1),
            e0,
            e1,
        )
        self.events.log(event)
        return event

    def reset_gain(self, energy_before: float, energy_after: float) -> None:
        """Count a velocity reset's energy gain in ``Diagnostics.reset_energy_gain`` [J].

        Args:
            energy_before: Total energy before the reset [J].
            energy_after: Total energy after it [J]; only a rise counts (a loss is not a gain).
        """
        self.diag.reset_energy_gain += max(0.0, energy_after - energy_before)
