"""The joint types packbot's native modules rebuild in their own Pinocchio model.

The 1-dof revolute and prismatic joints (``src/native/joints.hpp``, shared by the contact
right-hand side, :mod:`packbot.contact.native`, and the collision sweep,
:mod:`packbot.native_sweep`, which refuses a model with another joint type).
"""

from __future__ import annotations

__all__ = ["SUPPORTED_JOINTS"]

#: The joint types the extensions rebuild (Pinocchio's short names).
SUPPORTED_JOINTS = frozenset(
    {
        "JointModelRX",
        "JointModelRY",
        "JointModelRZ",
        "JointModelRevoluteUnaligned",
        "JointModelPX",
        "JointModelPY",
        "JointModelPZ",
        "JointModelPrismaticUnaligned",
    }
)
