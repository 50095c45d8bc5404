"""The static environment: the floor, boxes, walls and convex meshes placed in the world frame.

The world frame is ``base_link``'s: origin on the ground under the tracks, x forward, z up. The
chassis belongs to the robot model, not to the environment.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, ConvexityError
from packbot.geometry import convex_piece
from packbot.keywords import checked_arguments
from packbot.validation import (
    MAX_CONVEX_POINTS,
    MAX_OBSTACLES,
    at_most,
    choice,
    finite_number,
    name_str,
    real_array,
    vector,
)

__all__ = ["FLOOR", "OBSTACLE_KINDS", "Environment", "Obstacle"]

ObstacleKind = Literal["box", "halfspace", "convex"]
#: The valid obstacle kinds.
OBSTACLE_KINDS: tuple[str, ...] = ("box", "halfspace", "convex")
#: A convex obstacle thinner than this fraction of its size (or of its distance from its frame's
#: origin) is degenerate.
FLATNESS_RTOL = 1e-6
#: Largest coordinate, extent or offset of an obstacle [m]: a world of a kilometre around the
#: robot (the arm reaches about 2 m).
COORD_MAX = 1000.0


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Obstacle:
    """A static convex obstacle. Its fields are checked at construction.

    Coordinates, extents and the offset are finite and within +/-1000 m; a box has positive
    extents, a halfspace a non-zero normal, a convex obstacle >= 4 points spanning a volume.

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

    def __post_init__(self) -> None:
        for fname, value in self._checked().items():
            object.__setattr__(self, fname, value)

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field (done at construction).

        Raises:
            ConfigurationError: A bad field.
            ConvexityError: The points of a convex obstacle span no volume.
        """
        self._checked()

    def _checked(self) -> dict[str, object]:
        """The fields checked and normalised to floats and tuples."""
        nm = name_str("obstacle.name", self.name)
        where = f"obstacle {nm!r}: "
        kind = choice(f"{where}kind", self.kind, OBSTACLE_KINDS)
        out: dict[str, object] = {"name": nm, "kind": kind}
        for fname in ("xyz", "rpy", "normal", "size"):
            bound = None if fname == "rpy" else COORD_MAX
            unit = {"rpy": "rad", "normal": "-"}.get(fname, "m")
            out[fname] = vector(f"{where}{fname}", getattr(self, fname), 3, bound=bound, unit=unit)
        out["offset"] = finite_number(
            f"{where}offset", self.offset, low=-COORD_MAX, high=COORD_MAX, unit="m"
        )
        size = out["size"]
        assert isinstance(size, tuple)
        if kind == "box" and min(size) <= 0:
            raise ConfigurationError(f"{where}size", self.size, "3 positive extents [m]")
        normal = out["normal"]
        assert isinstance(normal, tuple)
        if kind == "halfspace" and float(np.linalg.norm(normal)) < 1e-12:
            raise ConfigurationError(f"{where}normal", self.normal, "a non-zero vector")
        if kind == "convex":
            out["points"] = self._points(where)
        elif not (isinstance(self.points, (list, tuple)) and len(self.points) == 0):
            raise ConfigurationError(
                f"{where}points", self.points, "no points: only a 'convex' obstacle has points"
            )
        else:
            out["points"] = ()
        return out

    def _points(self, where: str) -> tuple[tuple[float, float, float], ...]:
        expected = f"(N, 3) finite coordinates [m], N >= 4, each within +/-{COORD_MAX:g} m"
        if isinstance(self.points, (list, tuple, np.ndarray)) and len(self.points) == 0:
            raise ConvexityError(self.name, "needs >= 4 points (N, 3), got none")
        if isinstance(self.points, (list, tuple, np.ndarray)):
            at_most(f"{where}points", self.points, len(self.points), MAX_CONVEX_POINTS, "points")
        pts = real_array(f"{where}points", self.points, expected=expected)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
            raise ConvexityError(self.name, f"needs >= 4 points (N, 3), got shape {pts.shape}")
        if np.any(np.abs(pts) > COORD_MAX):
            raise ConfigurationError(f"{where}points", self.points, expected)
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
        return tuple((float(x), float(y), float(z)) for x, y, z in pts)

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
        return convex_piece(np.asarray(self.points, dtype=float))

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


@checked_arguments
@dataclass(frozen=True)
class Environment:
    """The static obstacles of a simulation. ``Environment()`` is the floor alone.

    Attributes:
        obstacles: The obstacles; their names must be unique.
    """

    obstacles: tuple[Obstacle, ...] = field(default=(FLOOR,))

    @classmethod
    @checked_arguments
    def empty(cls) -> Environment:
        """No obstacles at all, not even the floor."""
        return cls(obstacles=())

    @checked_arguments
    def with_obstacles(self, *obstacles: Obstacle) -> Environment:
        """A copy with more obstacles."""
        return Environment(obstacles=(*self.obstacles, *obstacles))

    def __post_init__(self) -> None:
        object.__setattr__(self, "obstacles", self._checked())

    def validate(self) -> None:
        """Raise a :class:`ConfigurationError` for duplicate names or a bad obstacle.

        Done at construction already.
        """
        self._checked()
        for ob in self.obstacles:
            ob.validate()

    def _checked(self) -> tuple[Obstacle, ...]:
        obstacles = self.obstacles
        if isinstance(obstacles, Obstacle) or not isinstance(obstacles, (list, tuple)):
            raise ConfigurationError(
                "environment.obstacles", obstacles, "a tuple of packbot.Obstacle"
            )
        at_most("environment.obstacles", obstacles, len(obstacles), MAX_OBSTACLES, "obstacles")
        seen: set[str] = set()
        for k, ob in enumerate(obstacles):
            if not isinstance(ob, Obstacle):
                raise ConfigurationError(f"environment.obstacles[{k}]", ob, "a packbot.Obstacle")
            if ob.name in seen:
                raise ConfigurationError("obstacle.name", ob.name, "a name not used twice")
            seen.add(ob.name)
        return tuple(obstacles)
