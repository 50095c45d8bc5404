"""Collision checks of planned joint paths: the first contact along a piecewise-linear path.

:func:`check_path` walks the straight joint-space segments between the configurations of a
path with *conservative advancement*: from a configuration whose smallest signed distance is d
[m], the next one is as far along the segment as the arm may move while every pair stays at
least ``d - max(d, tolerance)`` apart. The step bound is the arm's reach: a point of a piece
carried by joint j lies at most r_j [m] from that joint's axis (:func:`reach_bounds`, from the
model's joint placements and each piece's bounding sphere, whatever the configuration), so a
joint step dq moves it at most ``sum_j r_j |dq_j|``, and a pair of two moving pieces closes by
at most twice that. Hence:

- between two checked configurations no pair penetrates deeper than ``tolerance`` (a contact
  thinner than the tolerance may be stepped over, nothing deeper);
- far from everything the steps are long (a few dozen checks for a free move of the arm), near
  a contact they shrink to ``tolerance / (2 sum_j r_j |dq_j|)`` of the segment.

The first checked configuration that penetrates (signed distance < 0) is reported, located by
bisection to within the same bound on its segment, as a :class:`PathCollision`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.model import Robot
from packbot.validation import finite_number

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld
    from packbot.environment import Environment

__all__ = ["MAX_PATH_CHECKS", "PathCollision", "check_path", "reach_bounds"]

FloatArray = NDArray[np.float64]

#: Most distance queries one :func:`check_path` makes (about 0.1 ms each): a path that needs
#: more (a long path grazing a surface at a tiny tolerance) is refused rather than run for
#: minutes.
MAX_PATH_CHECKS = 200_000
#: Bisection steps that locate the first penetrating configuration on its segment.
_BISECTIONS = 30


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class PathCollision:
    """The first collision along a joint path (:func:`check_path`).

    Attributes:
        index: The segment: between ``q_path[index]`` and ``q_path[index + 1]`` (0 and a
            fraction of 0 when the path starts in collision).
        fraction: Where on that segment [-], in [0, 1].
        q: The configuration there [rad], shape (nq,).
        pair: The penetrating pair's pieces, ``(piece on body 1, piece on body 2)``.
        links: Their links (or obstacle), ``(link1, link2)``.
        distance: The pair's signed distance there [m] (negative: a penetration).
    """

    index: int
    fraction: float
    q: FloatArray = field(repr=False)
    pair: tuple[str, str]
    links: tuple[str, str]
    distance: float

    def __str__(self) -> str:
        return (
            f"{self.links[0]}/{self.pair[0]} - {self.links[1]}/{self.pair[1]} "
            f"({self.distance * 1000:.1f} mm) at {self.fraction:.3f} of segment {self.index}"
        )


@checked_arguments
def reach_bounds(robot: Robot) -> FloatArray:
    """Bounds r_j [m] on the distance of a collision piece from each joint j that carries it.

    Whatever the configuration: the sum, along the kinematic chain from joint j to the
    piece's joint, of the joint placements' lengths, plus the piece's bounding sphere (its
    centre's distance from its joint and its radius). Shape (nv,), in q order.
    """
    model = robot.model
    gm = robot.collision_model
    placement_len = [float(np.linalg.norm(p.translation)) for p in model.jointPlacements]
    # the farthest any piece of joint i's body reaches from joint i's origin [m]
    body_reach = np.zeros(model.njoints)
    for g in gm.geometryObjects:
        geom = g.geometry
        geom.computeLocalAABB()
        centre = g.placement.translation + g.placement.rotation @ np.asarray(geom.aabb_center)
        r = float(np.linalg.norm(centre)) + float(geom.aabb_radius)
        body_reach[g.parentJoint] = max(body_reach[g.parentJoint], r)
    out = np.zeros(model.nv)
    for j in range(1, model.njoints):
        best = 0.0
        for i in range(1, model.njoints):
            if j not in model.supports[i]:
                continue
            chain, k = 0.0, i  # from joint i up to (not including) joint j's placement
            while k != j:
                chain += placement_len[k]
                k = model.parents[k]
            best = max(best, chain + body_reach[i])
        out[model.joints[j].idx_v] = best
    return out


def _closest(world: CollisionWorld, q: FloatArray) -> tuple[float, Any]:
    """A lower bound of the smallest signed distance [m] at q, and its pair (or None).

    The pruned sweep's smallest distance, capped at the world's margin: a pair the pruning
    leaves out has boxes (each inflated by half the margin) apart, so its pieces are more
    than the margin apart (the exact distance where it matters, at a tenth of the cost of
    testing every pair).
    """
    sw = world.sweep(q)
    d = min(float(sw.min_distance), world.margin)
    return d, (world.pairs[int(sw.min_pair)] if sw.min_pair >= 0 else None)


@checked_arguments
def check_path(
    robot: Robot,
    q_path: ArrayLike,
    environment: Environment | None = None,
    *,
    tolerance: float = 1e-3,
    world: CollisionWorld | None = None,
) -> PathCollision | None:
    """The first collision along the straight joint-space segments of a path, or None.

    Conservative advancement (module docstring): the step from a configuration at signed
    distance d is ``max(d, tolerance) / (2 sum_j r_j |dq_j|)`` of a segment whose joint
    motion is dq [rad] (r_j from :func:`reach_bounds`), so no pair penetrates deeper than
    ``tolerance`` between two checked configurations.

    Args:
        robot: The robot (full model: every joint of the path moves as given).
        q_path: The configurations [rad], shape (K, nq), K >= 1; a single one (shape (nq,))
            is checked alone.
        environment: Obstacles; None: the floor alone.
        tolerance: The depth [m] a penetration between two checked configurations may reach
            unseen (the simulator's contact tolerance by default).
        world: A collision world of ``robot`` and ``environment`` to reuse (built if None).

    Returns:
        The first penetrating configuration (segment, fraction, pair, distance), or None when
        the whole path is clear.

    Raises:
        ConfigurationError: A path of the wrong shape or with non-finite values, a tolerance
            that is not positive, or a path that needs more than :data:`MAX_PATH_CHECKS`
            distance queries at that tolerance.
    """
    from packbot.collision import CollisionWorld

    tol = finite_number(
        "tolerance", tolerance, low=0.0, low_open=True, high=0.5, unit="m", what="a distance"
    )
    path = np.asarray(q_path, dtype=float)
    if path.ndim == 1:
        path = path[None, :]
    if path.ndim != 2 or path.shape[1] != robot.nq or len(path) == 0:
        raise ConfigurationError("q_path", path.shape, f"shape (K, {robot.nq}) [rad], K >= 1")
    if not np.all(np.isfinite(path)):
        raise ConfigurationError("q_path", "non-finite values", "finite joint angles [rad]")
    if world is None:
        world = CollisionWorld(robot, environment)
    reach = reach_bounds(robot)
    checks = 0

    def hit(q: FloatArray, index: int, frac: float) -> PathCollision:
        c = world.closest(q)  # the deepest pair there
        pair = c.pair
        return PathCollision(
            index=index,
            fraction=frac,
            q=q.copy(),
            pair=(pair.piece1, pair.piece2),
            links=(pair.link1, pair.link2),
            distance=float(c.distance),
        )

    d, _ = _closest(world, path[0])
    if d < 0.0:
        return hit(path[0], 0, 0.0)
    for k in range(len(path) - 1):
        qa, dq = path[k], path[k + 1] - path[k]
        speed = 2.0 * float(reach @ np.abs(dq))  # [m] of closing per unit of the segment
        if speed == 0.0:
            continue
        s = 0.0
        while s < 1.0:
            s_prev = s
            s = min(1.0, s + max(d, tol) / speed)
            d, _ = _closest(world, qa + s * dq)
            checks += 1
            if checks > MAX_PATH_CHECKS:
                raise ConfigurationError(
                    "tolerance",
                    tol,
                    f"a tolerance the path can be checked at in {MAX_PATH_CHECKS:,} distance "
                    "queries (it runs close to a surface for long: a larger tolerance)",
                )
            if d < 0.0:
                lo, hi = s_prev, s  # clear at lo, penetrating at hi
                for _ in range(_BISECTIONS):
                    if (hi - lo) * speed < tol:
                        break
                    mid = 0.5 * (lo + hi)
                    if _closest(world, qa + mid * dq)[0] < 0.0:
                        hi = mid
                    else:
                        lo = mid
                return hit(qa + hi * dq, k, hi)
    return None


#: The last path :func:`path_warning` warned of (robot, path bytes, environment, what): the same
#: plan rebuilt (a scenario's controller is built for the run, then again for its plots) is
#: said once.
_LAST_WARNED: list[tuple[int, bytes, str, str]] = []


def path_warning(
    robot: Robot,
    q_path: Sequence[ArrayLike] | FloatArray,
    environment: Environment | None,
    what: str,
    world: CollisionWorld | None = None,
) -> PathCollision | None:
    """:func:`check_path`, and a ``logging.warning`` saying ``what`` collides and where.

    The same plan of the same robot and environment is warned of once in a row.
    """
    import logging

    path = np.asarray(q_path, dtype=float)
    found = check_path(robot, path, environment, world=world)
    if found is None:
        return None
    key = (id(robot), path.tobytes(), repr(environment), what)
    if _LAST_WARNED and _LAST_WARNED[0] == key:
        return found
    _LAST_WARNED[:] = [key]
    logging.getLogger("packbot.control").warning(
        "%s collides: %s, at q = %s rad (the simulation runs it as planned: the arm will hit)",
        what,
        found,
        np.array2string(found.q, precision=3, separator=", "),
    )
    return found
