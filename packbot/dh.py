"""Standard Denavit-Hartenberg kinematics of the arm's two chains (gripper and camera).

Convention (Corke's Robotics Toolbox, "standard DH"): link transform
``A_i(q_i) = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; the tool frame of a chain is
``T = T_base A_1 ... A_n``. The arm branches after ``elbow2``: one chain ends at the gripper tool
frame, the other at the camera's optical frame. This is an independent path to the kinematics,
used to check Pinocchio's model and to document the arm.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from packbot.params import CHAINS, DH_BASE, DHRow

__all__ = ["chain_fk", "dh_transform", "rot_x", "rot_z", "translation"]


def rot_z(theta: float) -> NDArray[np.float64]:
    """Homogeneous rotation about z by ``theta`` [rad]."""
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def rot_x(theta: float) -> NDArray[np.float64]:
    """Homogeneous rotation about x by ``theta`` [rad]."""
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def translation(x: float, y: float, z: float) -> NDArray[np.float64]:
    """Homogeneous translation [m]."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def dh_transform(row: DHRow, q: float) -> NDArray[np.float64]:
    """``Rz(q + offset) Tz(d) Tx(a) Rx(alpha)`` as a 4x4 homogeneous matrix."""
    return rot_z(q + row.offset) @ translation(row.a, 0.0, row.d) @ rot_x(row.alpha)


def chain_fk(
    chain: str,
    q: Mapping[str, float] | Sequence[float],
    rows: Sequence[DHRow] | None = None,
) -> NDArray[np.float64]:
    """Tool frame of a chain in ``base_link`` (4x4), from the DH table.

    Args:
        chain: ``"gripper"`` or ``"camera"``.
        q: Joint angles [rad], by joint name, or in the order of the chain's rows.
        rows: DH rows to use instead of the model's (for tests).
    """
    rows = CHAINS[chain] if rows is None else rows
    T = translation(*DH_BASE)
    for i, row in enumerate(rows):
        qi = q[row.joint] if isinstance(q, Mapping) else q[i]
        T = T @ dh_transform(row, float(qi))
    return T
