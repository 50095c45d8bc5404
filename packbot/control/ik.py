"""Inverse kinematics of a frame position by damped least squares (Levenberg-Marquardt).

Each iteration solves (J^T J + lambda^2 I) dq = J^T e for the active joints, with e = p* - p(q)
the frame's position error [m] (world frame) and J its 3 x n position Jacobian; the step is
clipped to ``max_step`` [rad] and q to the joint limits. Inactive joints keep their value. The
damping keeps the step bounded near singular configurations and when the target is out of reach
(the result is then the closest point the iteration finds).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import MAX_IK_ITERATIONS, integer

__all__ = ["IKResult", "solve_position_ik"]

FloatArray = NDArray[np.float64]


@checked_arguments
@dataclass(kw_only=True)
class IKResult:
    """The outcome of :func:`solve_position_ik`.

    Attributes:
        q: The solution [rad], shape (nq,) of the model solved on.
        error: Remaining position error |p* - p(q)| [m].
        iterations: Iterations used.
        success: Whether error <= tol.
    """

    q: FloatArray
    error: float
    iterations: int
    success: bool


@checked_arguments
def solve_position_ik(
    model: pin.Model,
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
) -> IKResult:
    """Solve p_frame(q) = target [m] for the active joints, from q0, by damped least squares.

    Args:
        model: Pinocchio model (full or reduced); its position limits bound q.
        frame: Name of the frame whose origin is placed.
        target: Target position [m], world frame, shape (3,).
        q0: Start configuration [rad], shape (model.nq,).
        active: Indices (into q) of the joints the solver may move; None: all.
        damping: Damping lambda [m] of the least-squares step.
        tol: Success tolerance on the position error [m].
        max_iter: Iteration limit.
        max_step: Largest joint step per iteration [rad].
        accept: Optional check of the final q (e.g. collision free); False makes ``success``
            False.

    Returns:
        The solution, its error and whether it met ``tol`` (and ``accept``).

    Raises:
        ConfigurationError: Unknown frame, or a bad target or q0 shape.
    """
    integer("ik.max_iter", max_iter, low=1, high=MAX_IK_ITERATIONS, what="a positive integer")
    if not model.existFrame(frame):
        raise ConfigurationError("ik.frame", frame, "a frame of the model")
    fid = model.getFrameId(frame)
    p_star = np.asarray(target, dtype=float)
    if p_star.shape != (3,) or not np.all(np.isfinite(p_star)):
        raise ConfigurationError("ik.target", target, "3 finite coordinates [m]")
    q = np.array(q0, dtype=float)
    if q.shape != (model.nq,):
        raise ConfigurationError("ik.q0", q.shape, f"shape ({model.nq},)")
    idx = np.arange(model.nv) if active is None else np.asarray(active, dtype=int)
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
    ok = err <= tol and (accept is None or accept(q))
    return IKResult(q=q, error=err, iterations=it, success=ok)
