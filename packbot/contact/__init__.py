"""Contact laws: what happens at an impact and while bodies stay in contact.

- :mod:`packbot.contact.locks`: unilateral joint locks ("clamps"), shared by joint-limit stops and
  the report's law: a clamped joint may not accelerate toward its contact.
- :mod:`packbot.contact.joint_clamp`: the 2010 report's impact law (``contact_mode="joint_clamp"``):
  relevant joints, velocity reset rules, clamp directions.
- :mod:`packbot.contact.normal`, :mod:`packbot.contact.lcp`: the contact-normal mode.
- :mod:`packbot.contact.handoff`: ``SimConfig.handoff``, a joint_clamp pair handed to the normal
  mode at a secondary intersection, the remaining clamps as rows of its problem.
"""

from packbot.contact.joint_clamp import clamp_directions, impact_reset, relevant_joints
from packbot.contact.locks import JointLocks

__all__ = ["JointLocks", "clamp_directions", "impact_reset", "relevant_joints"]
