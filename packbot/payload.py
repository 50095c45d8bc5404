"""A payload held in the gripper: a rigid mass with inertia, picked up and dropped at given times.

While held, the payload is rigidly attached to the body carrying its frame (default the robot's tool
frame: PackBot's ``gripper_tool``, on the gripper's last moving body): the simulator adds its
spatial inertia to that body's (``pin.Inertia``), so the dynamics change exactly. Picking up an
object at rest while the gripper moves is an inelastic impact (the arm's generalized momentum is
conserved); dropping it removes its inertia (the arm's joint velocities are unchanged).
The payload has no collision geometry of its own (the gripper's pieces still collide).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import finite_number, name_str, vector

__all__ = ["Payload"]

#: Largest payload mass [kg] (100 times the arm's): beyond it the arm would break, and the mass
#: matrix's conditioning is ruined.
MASS_MAX = 1000.0
#: Largest centre-of-mass coordinate in the holding frame [m].
COM_MAX = 10.0
#: Largest inertia component [kg*m^2] (MASS_MAX at COM_MAX).
INERTIA_MAX = MASS_MAX * COM_MAX**2


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Payload:
    """A payload. Its fields are checked at construction (a ConfigurationError names the field).

    Attributes:
        mass: Mass [kg], in (0, 1000].
        com: Centre of mass in ``frame`` [m], each coordinate within +/-10 m.
        inertia: Rotational inertia about the centre of mass, axes of ``frame``, as
            (ixx, iyy, izz, ixy, ixz, iyz) [kg*m^2]; all zero: a point mass. Positive
            semi-definite and physical (each principal moment at most the sum of the others).
        frame: The Pinocchio frame it is held in; None: the robot's ``tool_frame`` (PackBot's
            ``gripper_tool``). Checked against the robot by :func:`packbot.simulate`.
        t_pick: Time it is picked up [s] (0: held from the start).
        t_drop: Time it is dropped [s], after ``t_pick``, or None (held to the end).
    """

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    frame: str | None = None
    t_pick: float = 0.0
    t_drop: float | None = None

    def __post_init__(self) -> None:
        for fname, value in self._checked().items():
            object.__setattr__(self, fname, value)

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field (done at construction)."""
        self._checked()

    def _checked(self) -> dict[str, object]:
        """The fields checked and normalised to floats and tuples."""
        mass = finite_number(
            "payload.mass",
            self.mass,
            low=0.0,
            high=MASS_MAX,
            low_open=True,
            unit="kg",
            what="a finite positive mass",
        )
        com = vector("payload.com", self.com, 3, bound=COM_MAX, unit="m")
        inertia = vector("payload.inertia", self.inertia, 6, bound=INERTIA_MAX, unit="kg*m^2")
        eig = np.linalg.eigvalsh(_matrix(inertia))
        tol = 1e-12 * max(1.0, float(abs(eig).max()))
        if eig.min() < -tol:
            raise ConfigurationError(
                "payload.inertia", self.inertia, "a positive semi-definite inertia [kg*m^2]"
            )
        if eig[2] > eig[0] + eig[1] + tol:
            raise ConfigurationError(
                "payload.inertia",
                self.inertia,
                "a physical inertia [kg*m^2]: each principal moment at most the sum of the "
                f"other two (the principal moments are {eig[0]:.4g}, {eig[1]:.4g}, {eig[2]:.4g})",
            )
        t_pick = finite_number(
            "payload.t_pick", self.t_pick, low=0.0, unit="s", what="a finite time"
        )
        t_drop = self.t_drop
        if t_drop is not None:
            t_drop = finite_number(
                "payload.t_drop",
                t_drop,
                low=t_pick,
                low_open=True,
                unit="s",
                what="None (held to the end) or a finite time",
            )
        return {
            "mass": mass,
            "com": com,
            "inertia": inertia,
            "frame": None
            if self.frame is None
            else name_str(
                "payload.frame", self.frame, "a frame name (a non-empty string), or None"
            ),
            "t_pick": t_pick,
            "t_drop": t_drop,
        }

    def held_in(self, tool_frame: str) -> Payload:
        """This payload with its frame named: ``tool_frame`` [-] where ``frame`` is None."""
        return self if self.frame is not None else dataclasses.replace(self, frame=tool_frame)

    def inertia_matrix(self) -> NDArray[np.float64]:
        """The 3x3 inertia about the centre of mass [kg*m^2], axes of ``frame``."""
        return _matrix(self.inertia)


def _matrix(inertia: Sequence[float]) -> NDArray[np.float64]:
    ixx, iyy, izz, ixy, ixz, iyz = (float(x) for x in inertia)
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
