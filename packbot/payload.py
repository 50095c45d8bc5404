"""A payload held in the gripper: a rigid mass with inertia, picked up and dropped at given times.

While held, the payload is rigidly attached to the body carrying its frame (default the
``gripper_tool`` frame, on the gripper's last moving body): the simulator adds its spatial inertia
to that body's (``pin.Inertia``), so the dynamics change exactly. Picking up an object at rest
while the gripper moves is an inelastic impact (the arm's generalized momentum is conserved);
dropping it removes its inertia (the arm's joint velocities are unchanged).
The payload has no collision geometry of its own (the gripper's pieces still collide).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError

__all__ = ["Payload"]


@dataclass(frozen=True, kw_only=True)
class Payload:
    """A payload.

    Attributes:
        mass: Mass [kg], > 0.
        com: Centre of mass in ``frame`` [m].
        inertia: Rotational inertia about the centre of mass, axes of ``frame``, as
            (ixx, iyy, izz, ixy, ixz, iyz) [kg*m^2]; all zero: a point mass.
        frame: The Pinocchio frame it is held in (``gripper_tool`` by default).
        t_pick: Time it is picked up [s] (0: held from the start).
        t_drop: Time it is dropped [s], or None (held to the end).
    """

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    frame: str = "gripper_tool"
    t_pick: float = 0.0
    t_drop: float | None = None

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field."""
        if not _finite(self.mass) or self.mass <= 0:
            raise ConfigurationError("payload.mass", self.mass, "a finite positive mass [kg]")
        if len(self.com) != 3 or not all(_finite(c) for c in self.com):
            raise ConfigurationError("payload.com", self.com, "3 finite coordinates [m]")
        if len(self.inertia) != 6 or not all(_finite(c) for c in self.inertia):
            raise ConfigurationError(
                "payload.inertia", self.inertia, "6 finite numbers (ixx, iyy, izz, ixy, ixz, iyz)"
            )
        eig = np.linalg.eigvalsh(self.inertia_matrix())
        if eig.min() < -1e-12 * max(1.0, float(abs(eig).max())):
            raise ConfigurationError(
                "payload.inertia", self.inertia, "a positive semi-definite inertia [kg*m^2]"
            )
        if not _finite(self.t_pick) or self.t_pick < 0:
            raise ConfigurationError("payload.t_pick", self.t_pick, "a finite time >= 0 [s]")
        if self.t_drop is not None and not (_finite(self.t_drop) and self.t_drop > self.t_pick):
            raise ConfigurationError(
                "payload.t_drop", self.t_drop, f"a time > t_pick={self.t_pick} [s], or None"
            )

    def inertia_matrix(self) -> NDArray[np.float64]:
        """The 3x3 inertia about the centre of mass [kg*m^2], axes of ``frame``."""
        ixx, iyy, izz, ixy, ixz, iyz = (float(x) for x in self.inertia)
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _finite(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
