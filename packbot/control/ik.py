"""Inverse kinematics of a frame position by damped least squares (Levenberg-Marquardt).

Each iteration solves (J^T J + lambda^2 I) dq = J^T e for the active joints, with e = p* - p(q)
the frame's position error [m] (world frame) and J its 3 x n position Jacobian; the step is
clipped to ``max_step`` [rad] and q to the joint limits. Inactive joints keep their value. The
damping keeps the step bounded near singular configurations and when the target is out of reach
(the result is then the closest point the iteration finds).

Collisions: by default (``collision_free=True``) a solution whose pieces penetrate each other,
the chassis or an obstacle (signed distance < 0, :class:`~packbot.collision.CollisionWorld` of
the robot and the environment) is rejected and the solver starts again from other seeds (random
configurations of the active joints within their limits, drawn from ``seed``); when every
solution that reaches the target collides, :class:`~packbot.errors.IKCollisionError` names the
target and the colliding pair. With ``collision_free=False`` the first solution is returned,
flagged (:attr:`IKResult.colliding`, :attr:`IKResult.pair`, :attr:`IKResult.clearance`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from packbot.continuous_joints import sampling_bounds
from packbot.errors import ConfigurationError, IKCollisionError
from packbot.keywords import checked_arguments
from packbot.model import Robot, _robot_of_model, _same_arm
from packbot.validation import MAX_IK_ITERATIONS, boolean, integer

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld
    from packbot.environment import Environment

__all__ = ["IKResult", "solve_position_ik"]

FloatArray = NDArray[np.float64]
#: Most starts one solve may try (each up to ``max_iter`` iterations).
MAX_IK_SEEDS = 1000


@checked_arguments
@dataclass(kw_only=True)
class IKResult:
    """The outcome of :func:`solve_position_ik`.

    Attributes:
        q: The solution [rad], shape (nq,) of the model solved on.
        error: Remaining position error |p* - p(q)| [m].
        iterations: Iterations used (from the start that gave q).
        success: Whether error <= tol (and ``accept``, and collision free when that was
            asked).
        colliding: Whether q penetrates (a pair's signed distance < 0); None: not checked (a
            model without collision pieces).
        pair: The closest pair's pieces at q, ``(piece1, piece2)`` ("" when not checked or
            none is within the collision world's margin, 0.05 m).
        clearance: Its signed distance [m] (negative: a penetration; inf: no pair within the
            margin; NaN: not checked).
        start: Which start gave q (0: ``q0``, k > 0: the k-th random seed).
    """

    q: FloatArray
    error: float
    iterations: int
    success: bool
    colliding: bool | None = None
    pair: tuple[str, str] = ("", "")
    clearance: float = math.nan
    start: int = 0


def _geometry(model: Any, robot: Any) -> tuple[pin.Model, Robot | None]:
    """The model to solve on and the robot whose collision pieces it has (or None)."""
    if isinstance(model, Robot):
        if robot is not None and robot is not model:
            raise ConfigurationError("robot", robot, "None when model is a packbot.Robot")
        return model.model, model
    if not isinstance(model, pin.Model):
        raise ConfigurationError("model", model, "a pinocchio.Model or a packbot.Robot")
    if robot is not None:
        if not isinstance(robot, Robot) or not _same_arm(model, robot.model):
            raise ConfigurationError(
                "robot", robot, "None or the packbot.Robot of this model (same joints)"
            )
        return model, robot
    return model, _robot_of_model(model)


def _iterate(
    model: pin.Model,
    fid: int,
    p_star: FloatArray,
    q: FloatArray,
    idx: NDArray[np.intp],
    damping: float,
    tol: float,
    max_iter: int,
    max_step: float,
) -> tuple[FloatArray, float, int]:
    """Damped least squares from q: (q, error [m], iterations)."""
    lower = np.asarray(model.lowerPositionLimit, dtype=float)
    upper = np.asarray(model.upperPositionLimit, dtype=float)
    q = np.clip(q, lower, upper)
    data = model.createData()
    err = np.inf
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        e = p_star - data.oMf[fid].translation
        err = float(np.linalg.norm(e))
        if err <= tol:
            break
        Ja = np.asarray(J).reshape(6, model.nv)[:3, idx]
        dq = np.linalg.solve(Ja.T @ Ja + damping**2 * np.eye(len(idx)), Ja.T @ e)
        scale = np.max(np.abs(dq)) / max_step
        if scale > 1:
            dq /= scale
        q[idx] = np.clip(q[idx] + dq, lower[idx], upper[idx])
    else:
        pin.framesForwardKinematics(model, data, q)
        err = float(np.linalg.norm(p_star - data.oMf[fid].translation))
    return q, err, it


def _clearance(world: CollisionWorld, q: FloatArray) -> tuple[float, tuple[str, str]]:
    """The smallest signed distance [m] within the world's margin (inf: none) and its pair."""
    sw = world.sweep(q)
    if sw.min_pair < 0 or not sw.min_distance < world.margin:
        return math.inf, ("", "")
    p = world.pairs[int(sw.min_pair)]
    return float(sw.min_distance), (p.piece1, p.piece2)


#: The last collision world built for a check: (robot, environment, world).
_WORLD: list[tuple[Robot, Any, CollisionWorld]] = []


def _world(robot: Robot, environment: Environment | None) -> CollisionWorld:
    """A collision world of the robot and environment (the last one again if they are)."""
    from packbot.collision import CollisionWorld

    if _WORLD and _WORLD[0][0] is robot and _WORLD[0][1] == environment:
        return _WORLD[0][2]
    world = CollisionWorld(robot, environment)
    _WORLD[:] = [(robot, environment, world)]
    return world


@checked_arguments
def solve_position_ik(
    model: pin.Model | Robot,
    frame: str,
    target: ArrayLike,
    q0: ArrayLike,
    *,
    active: Sequence[int] | None = None,
    damping: float = 1e-2,
    tol: float = 1e-4,
    max_iter: int = 200,
    max_step: float = 0.2,
    accept: Callable[[FloatArray], bool] | None = None,
    collision_free: bool = True,
    robot: Robot | None = None,
    environment: Environment | None = None,
    seeds: int = 8,
    seed: int = 0,
) -> IKResult:
    """Solve p_frame(q) = target [m] for the active joints, from q0, by damped least squares.

    Args:
        model: Pinocchio model (full or reduced; its position limits bound q), or a
            :class:`~packbot.Robot` (its model, and its collision pieces for the check).
        frame: Name of the frame whose origin is placed.
        target: Target position [m], world frame, shape (3,).
        q0: Start configuration [rad], shape (model.nq,).
        active: Indices (into q) of the joints the solver may move; None: all.
        damping: Damping lambda [m] of the least-squares step.
        tol: Success tolerance on the position error [m].
        max_iter: Iteration limit (per start).
        max_step: Largest joint step per iteration [rad].
        accept: Optional check of the final q (e.g. a clearance of your own); False makes
            ``success`` False.
        collision_free: Reject a solution that penetrates (the arm into itself, the chassis,
            the floor or an obstacle) and try the other seeds; raise
            :class:`~packbot.errors.IKCollisionError` when every solution that reaches the
            target collides. False: solve from ``q0`` alone and flag the result
            (``colliding``). Needs the model's collision pieces: ``model`` a Robot, ``robot``
            given, or a pin.Model of a loaded arm's kinematics (``robot.model`` of a robot
            :func:`~packbot.load_robot` returned, a copy of it, with a payload's body or
            another gravity; PackBot's even if not loaded), checked against that robot's
            pieces.
        robot: The Robot of ``model`` (when ``model`` is a pin.Model of another URDF).
        environment: Obstacles of the check; None: the floor alone.
        seeds: Random starts tried after ``q0`` when its solution collides.
        seed: Seed of those starts (the same seed, the same starts).

    Returns:
        The solution, its error, whether it met ``tol`` (and ``accept``, and the check) and
        its clearance. A target out of reach gives the closest point found (``success``
        False), collision free if one was.

    Raises:
        ConfigurationError: Unknown frame, a bad target or q0 shape, a bad setting, or
            ``collision_free=True`` (or an environment) for a model without known collision
            pieces (a reduced pin.Model: pass ``collision_free=False`` and check yourself).
        IKCollisionError: ``collision_free=True`` and every solution that reaches the
            target collides (names the target and the pair).
    """
    integer("ik.max_iter", max_iter, low=1, high=MAX_IK_ITERATIONS, what="a positive integer")
    integer("ik.seeds", seeds, low=0, high=MAX_IK_SEEDS, what="a number of random starts")
    integer("ik.seed", seed, low=0, what="a random seed (an integer >= 0)")
    boolean("ik.collision_free", collision_free)
    pin_model, geom = _geometry(model, robot)
    if geom is None and (collision_free or environment is not None):
        raise ConfigurationError(
            "collision_free" if collision_free else "environment",
            collision_free if collision_free else environment,
            "False (None) for a model packbot has no collision pieces of (a reduced or "
            "another pin.Model; or pass robot=its packbot.Robot, or the Robot as model)",
        )
    if not pin_model.existFrame(frame):
        raise ConfigurationError("ik.frame", frame, "a frame of the model")
    fid = pin_model.getFrameId(frame)
    p_star = np.asarray(target, dtype=float)
    if p_star.shape != (3,) or not np.all(np.isfinite(p_star)):
        raise ConfigurationError("ik.target", target, "3 finite coordinates [m]")
    q = np.array(q0, dtype=float)
    if q.shape != (pin_model.nq,):
        raise ConfigurationError("ik.q0", q.shape, f"shape ({pin_model.nq},)")
    idx = np.arange(pin_model.nv) if active is None else np.asarray(active, dtype=int)

    def solve(start: FloatArray, k: int) -> IKResult:
        qs, err, it = _iterate(pin_model, fid, p_star, start, idx, damping, tol, max_iter, max_step)
        return IKResult(q=qs, error=err, iterations=it, success=err <= tol, start=k)

    world = None if geom is None else _world(geom, environment)

    def checked(res: IKResult) -> IKResult:
        if world is not None:
            res.clearance, res.pair = _clearance(world, res.q)
            res.colliding = res.clearance < 0.0
        res.success = res.success and not (collision_free and res.colliding)
        res.success = res.success and (accept is None or bool(accept(res.q)))
        return res

    first = checked(solve(q, 0))
    if not collision_free or not first.colliding:
        return first
    lower = np.asarray(pin_model.lowerPositionLimit, dtype=float)
    upper = np.asarray(pin_model.upperPositionLimit, dtype=float)
    lo, hi = sampling_bounds(lower, upper, q)
    rng = np.random.default_rng(seed)
    colliding = first if first.error <= tol else None  # the least penetrating on target
    closest = None  # the nearest collision-free solution that misses the target
    for k in range(1, seeds + 1):
        start = q.copy()
        start[idx] = rng.uniform(lo[idx], hi[idx])
        res = checked(solve(start, k))
        if res.colliding:
            if res.error <= tol and (colliding is None or res.clearance > colliding.clearance):
                colliding = res
            continue
        if res.success:
            return res
        if closest is None or res.error < closest.error:
            closest = res
    if colliding is None:  # nothing reaches the target: the closest miss, clear if one is
        return closest if closest is not None else first
    raise IKCollisionError(frame, p_star, colliding.pair, colliding.clearance, seeds + 1, colliding)
