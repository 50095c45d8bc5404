"""Contact laws: what happens at an impact and while bodies stay in contact.

Every law is one class behind one protocol (:class:`~packbot.contact.base.ContactLaw`), which
is all the event loop (:mod:`packbot.integrator`) knows of it:

- :mod:`packbot.contact.base`: the protocol and the records the loop and the laws share;
- :mod:`packbot.contact.stops`: the base of every law, composing the constraint pools every
  law has: the joint position stops (:mod:`packbot.contact.position_stops`), the friction holds
  (:mod:`packbot.contact.holds`), the joint locks (:mod:`packbot.contact.locks`), the velocity
  resets (:mod:`packbot.contact.resets`); :mod:`packbot.contact.pairs`: the signed distances of
  a law with collisions;
- :mod:`packbot.contact.none`: ``contact_mode="none"`` (no collisions, limit stops only);
- :mod:`packbot.contact.joint_clamp`: the 2010 report's law (``contact_mode="joint_clamp"``):
  relevant joints, velocity reset rules, clamp directions;
- :mod:`packbot.contact.normal`, :mod:`packbot.contact.lcp`: the contact-normal mode;
- :mod:`packbot.contact.handoff`: ``SimConfig.handoff``, a joint_clamp pair handed to the normal
  mode at a secondary intersection, the remaining clamps as rows of its problem;
- :mod:`packbot.contact.locks`: unilateral joint locks ("clamps") and friction holds.
"""

from __future__ import annotations

from packbot.config import SimConfig
from packbot.contact.base import ContactLaw
from packbot.contact.handoff import HandoffLaw
from packbot.contact.joint_clamp import (
    JointClampLaw,
    clamp_directions,
    impact_reset,
    relevant_joints,
)
from packbot.contact.locks import JointLocks
from packbot.contact.none import NoneLaw
from packbot.contact.normal import NormalLaw
from packbot.contact.pairs import PairLaw
from packbot.drive import Drive
from packbot.recorder import EventLog
from packbot.result import Diagnostics
from packbot.system import System

__all__ = [
    "ContactLaw",
    "HandoffLaw",
    "JointClampLaw",
    "JointLocks",
    "NoneLaw",
    "NormalLaw",
    "clamp_directions",
    "impact_reset",
    "law_class",
    "make_law",
    "relevant_joints",
]

#: The law of each ``SimConfig.contact_mode`` (``handoff=True``: :class:`HandoffLaw`).
LAWS: dict[str, type[NoneLaw | PairLaw]] = {
    "none": NoneLaw,
    "joint_clamp": JointClampLaw,
    "normal": NormalLaw,
}


def law_class(config: SimConfig) -> type[NoneLaw | PairLaw]:
    """The law a configuration asks for: its ``contact_mode``, with its ``handoff``."""
    if config.handoff:
        return HandoffLaw
    return LAWS[config.contact_mode]


def make_law(
    config: SimConfig, system: System, drive: Drive, events: EventLog, diag: Diagnostics
) -> ContactLaw:
    """The contact law of a run, built on the first phase's system.

    Args:
        config: The settings (``contact_mode``, ``handoff`` and the law's parameters).
        system: The integrated system.
        drive: The run's torques.
        events: The run's event log.
        diag: The run's diagnostics.
    """
    return law_class(config)(config, system, drive, events, diag)
