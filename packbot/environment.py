"""The static environment: the floor, boxes, walls and convex meshes placed in the world frame.

The world frame is ``base_link``'s: origin on the ground under the tracks, x forward, z up. The
chassis belongs to the robot model, not to the environment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, ConvexityError

__all__ = ["FLOOR", "OBSTACLE_KINDS", "Environment", "Obstacle"]

ObstacleKind = Literal["box", "halfspace", "convex"]
#: The valid obstacle kinds.
OBSTACLE_KINDS: tuple[str, ...] = ("box", "halfspace", "convex")
#: A convex obstacle thinner than this fraction of its size (or of its distance from its frame's
#: origin) is degenerate.
FLATNESS_RTOL = 1e-6


@dataclass(frozen=True, kw_only=True)
class Obstacle:
    """A static convex obstacle.

    Attributes:
        name: Unique name (reported as the "link" of contacts with it).
        kind: ``"box"``, ``"halfspace"`` or ``"convex"``.
        size: Box full extents along its x, y, z [m].
        xyz: Position of the obstacle frame in the world [m] (box centre; convex vertices'
            frame).
        rpy: Orientation of the obstacle frame, roll-pitch-yaw [rad] (R = Rz(y) Ry(p) Rx(r)).
        normal: Halfspace outward normal in the world (unit after normalisation) [-].
        offset: Halfspace offset [m]: the solid is ``normal . x <= offset``.
        points: Convex vertices in the obstacle frame [m]; the obstacle is their hull.
    """

    name: str
    kind: ObstacleKind
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0
    points: tuple[tuple[float, float, float], ...] = ()

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field."""
        if not self.name:
            raise ConfigurationError("obstacle.name", self.name, "a non-empty name")
        if self.kind not in OBSTACLE_KINDS:
            raise ConfigurationError(f"obstacle {self.name!r}: kind", self.kind, OBSTACLE_KINDS)
        for fname in ("xyz", "rpy", "normal", "size"):
            v = getattr(self, fname)
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise ConfigurationError(f"obstacle {self.name!r}: {fname}", v, "3 finite numbers")
        if self.kind == "box" and min(self.size) <= 0:
            raise ConfigurationError(
                f"obstacle {self.name!r}: size", self.size, "3 positive extents [m]"
            )
        if self.kind == "halfspace":
            if float(np.linalg.norm(self.normal)) < 1e-12:
                raise ConfigurationError(f"obstacle {self.name!r}: normal", self.normal, "non-zero")
            if not math.isfinite(self.offset):
                raise ConfigurationError(f"obstacle {self.name!r}: offset", self.offset, "finite")
        if self.kind == "convex":
            try:
                pts = np.asarray(self.points, dtype=float)
            except (TypeError, ValueError):  # ragged or not numbers
                raise ConfigurationError(
                    f"obstacle {self.name!r}: points", self.points, "(N, 3) numbers [m]"
                ) from None
            if pts.size and not np.all(np.isfinite(pts)):
                raise ConfigurationError(
                    f"obstacle {self.name!r}: points", self.points, "finite coordinates [m]"
                )
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
                raise ConvexityError(self.name, f"needs >= 4 points (N, 3), got shape {pts.shape}")
            # Thickness along the least principal axis against the size (and the distance from
            # the frame origin, which sets Qhull's roundoff): Qhull crashes the process on
            # nearly flat input (thickness 1e-8 of the size), so reject it well before that.
            centred = pts - pts.mean(axis=0)
            axes = np.linalg.svd(centred, full_matrices=False)[2]
            extent = np.ptp(centred @ axes.T, axis=0)
            scale = max(float(extent[0]), float(np.abs(pts).max()))
            if not extent[2] > FLATNESS_RTOL * scale:
                raise ConvexityError(
                    self.name,
                    f"degenerate: its points span no volume (thickness {extent[2]:.3g} m over "
                    f"an extent of {extent[0]:.3g} m); give >= 4 points not in one plane",
                )

    def placement(self) -> pin.SE3:
        """Pose of the obstacle frame in the world (identity for a halfspace)."""
        if self.kind == "halfspace":
            return pin.SE3.Identity()
        return pin.SE3(pin.rpy.rpyToMatrix(*self.rpy), np.asarray(self.xyz, dtype=float))

    def shape(self) -> coal.CollisionGeometry:
        """The Coal shape, in the obstacle frame."""
        self.validate()
        if self.kind == "box":
            return coal.Box(*self.size)
        if self.kind == "halfspace":
            n = np.asarray(self.normal, dtype=float)
            nn = float(np.linalg.norm(n))
            return coal.Halfspace(n / nn, self.offset / nn)
        vec = coal.StdVec_Vec3s()
        vec.extend(np.asarray(self.points, dtype=float))
        return coal.Convex.convexHull(vec, True, "Qt")

    def world_aabb(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper corners of the world-frame bounding box [m].

        A halfspace's box is infinite but for its one face when its normal is axis-aligned.
        """
        if self.kind == "halfspace":
            n = np.asarray(self.normal, dtype=float)
            n = n / np.linalg.norm(n)
            lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
            axis = int(np.argmax(np.abs(n)))
            offset = self.offset / float(np.linalg.norm(self.normal))
            if abs(abs(n[axis]) - 1.0) < 1e-12:  # axis-aligned: one finite face
                if n[axis] > 0:
                    hi[axis] = offset
                else:
                    lo[axis] = -offset
            return lo, hi
        M = self.placement()
        if self.kind == "box":
            local = np.array(
                [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float
            ) * (np.asarray(self.size) / 2)
        else:
            local = np.asarray(self.points, dtype=float)
        world = local @ M.rotation.T + M.translation
        return world.min(axis=0), world.max(axis=0)


#: The floor the robot stands on: the halfspace z <= 0.
FLOOR = Obstacle(name="floor", kind="halfspace", normal=(0.0, 0.0, 1.0), offset=0.0)


@dataclass(frozen=True)
class Environment:
    """The static obstacles of a simulation. ``Environment()`` is the floor alone.

    Attributes:
        obstacles: The obstacles; their names must be unique.
    """

    obstacles: tuple[Obstacle, ...] = field(default=(FLOOR,))

    @classmethod
    def empty(cls) -> Environment:
        """No obstacles at all, not even the floor."""
        return cls(obstacles=())

    def with_obstacles(self, *obstacles: Obstacle) -> Environment:
        """A copy with more obstacles."""
        return Environment(obstacles=(*self.obstacles, *obstacles))

    def validate(self) -> None:
        """Raise a :class:`ConfigurationError` for duplicate names or a bad obstacle."""
        seen: set[str] = set()
        for ob in self.obstacles:
            ob.validate()
            if ob.name in seen:
                raise ConfigurationError("obstacle.name", ob.name, "a name not used twice")
            seen.add(ob.name)
