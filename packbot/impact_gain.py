"""The energy the report's law gains at impacts, and the warning at the end of a run.

The 2010 report's impact law (``contact_mode="joint_clamp"`` with the default
``reset_rule="zero"``) can *add* energy at an impact: the reset v_R <- -e v_R on a coupled arm
is not an impulse of the contact (docs/simulator.md, "The impact law"). The law is kept to
reproduce the report; a run whose impacts gained more than :data:`IMPACT_GAIN_WARN_J` in total
logs a warning (logger ``packbot.integrator``, with the other warnings of
:func:`packbot.simulate`) that names the gain and points to the contact-normal mode.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass

from packbot.result import Event, SimResult

__all__ = ["IMPACT_GAIN_WARN_J", "ImpactGain", "impact_gain", "warn_impact_gain"]

log = logging.getLogger("packbot.integrator")  # (simulate's warnings: packbot.inputs too)

#: A run of the report's law whose impacts gained more than this in total warns [J].
IMPACT_GAIN_WARN_J = 1.0


@dataclass(frozen=True)
class ImpactGain:
    """The energy gained at the ``impact`` events of a run.

    Attributes:
        total: The sum of the positive ``energy_after - energy_before`` of the impacts [J].
        count: The impacts that gained energy (a positive change).
        largest: The largest single impact's gain [J] (0 if none gained).
        t: Its time [s] (NaN if none gained).
        pair: Its pair, ``"piece1 - piece2"`` (each ``link/piece``; "" if none gained).
    """

    total: float = 0.0
    count: int = 0
    largest: float = 0.0
    t: float = float("nan")
    pair: str = ""


def impact_gain(events: Iterable[Event]) -> ImpactGain:
    """The energy gained at the ``impact`` events.

    Only ``impact`` events count, and of them only the positive changes ``energy_after -
    energy_before`` (an impact that loses energy does not offset one that gains); the
    ``secondary_intersection`` and ``limit`` resets are not counted here (they are in
    ``Diagnostics.reset_energy_gain``). A change that is not finite is skipped.

    Args:
        events: A run's event log (``SimResult.events``).

    Returns:
        The total, the number of impacts that gained, and the largest with its time and pair.
    """
    total, count, top = 0.0, 0, None
    for e in events:
        gain = e.energy_change
        if e.kind != "impact" or not gain > 0.0 or gain == float("inf"):
            continue
        total += gain
        count += 1
        if top is None or gain > top.energy_change:
            top = e
    if top is None:
        return ImpactGain()
    pair = f"{top.piece1 or top.link1} - {top.piece2 or top.link2}"
    return ImpactGain(total, count, top.energy_change, top.t, pair)


def warn_impact_gain(result: SimResult) -> SimResult:
    """Warn when a run of the report's law gained more than ``IMPACT_GAIN_WARN_J`` at impacts.

    Called by :func:`packbot.simulate` on every finished run; only a run with
    ``contact_mode="joint_clamp"`` can warn. The total is :func:`impact_gain`'s: the positive
    energy changes at ``impact`` events, summed.

    Args:
        result: The finished run.

    Returns:
        The result, unchanged.
    """
    if result.config.contact_mode != "joint_clamp":
        return result
    gain = impact_gain(result.events)
    if gain.total > IMPACT_GAIN_WARN_J:
        log.warning(
            "the impacts gained +%.3f J of energy in total (%d impact(s) gained; the largest "
            "+%.3f J at t = %.4f s, %s): this is the 2010 report's law "
            "(contact_mode='joint_clamp'), whose velocity reset can add energy on a coupled "
            "arm (docs/simulator.md, 'The impact law'); the contact-normal mode "
            "(contact_mode='normal', docs/contact.md) adds no energy at its events",
            gain.total,
            gain.count,
            gain.largest,
            gain.t,
            gain.pair,
        )
    return result
