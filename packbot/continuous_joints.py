"""A URDF's continuous joints as revolute joints without limits: one coordinate, the angle.

Pinocchio builds a URDF ``continuous`` joint as a *revolute unbounded* joint: two configuration
coordinates (cos theta, sin theta) and one velocity (nq 2, nv 1). Drake and MuJoCo build it as
a revolute (hinge) joint without limits, whose one coordinate is the angle theta [rad]. packbot
does as they do: :func:`continuous_as_angles` rebuilds the model with every unbounded joint
replaced by the revolute joint about the same axis, position limits -inf and +inf, and every
other joint, body, inertia, frame and limit copied as it was.

The two models are the same mechanism: the configuration (cos theta, sin theta) is the image of
theta, and the velocity of either is theta's rate, so the dynamics (mass matrix, bias forces,
Jacobians, frame placements) agree at every theta (to the last bit: Pinocchio evaluates the
same sines and cosines; ``tests/test_continuous_joints.py`` compares them). The state of a
fixed-base arm of revolute, continuous and prismatic joints then lives in R^nv with dq/dt = v
exactly: the angle is unwrapped (a joint that turns twice reads 4 pi), as a multi-turn encoder
reads it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

__all__ = ["continuous_as_angles", "has_continuous_joints", "sampling_bounds"]

#: Pinocchio's unbounded revolute joints (URDF ``continuous``) and their bounded counterparts.
_UNBOUNDED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}
_UNALIGNED = "JointModelRevoluteUnboundedUnaligned"


def has_continuous_joints(model: pin.Model) -> bool:
    """Whether the model has an unbounded revolute joint (a URDF continuous joint)."""
    return any(_is_unbounded(model.joints[i]) for i in range(1, model.njoints))


def _is_unbounded(joint: pin.JointModel) -> bool:
    return joint.shortname() in _UNBOUNDED or joint.shortname() == _UNALIGNED


def _revolute(joint: pin.JointModel) -> pin.JointModel:
    """The revolute joint about the unbounded joint's axis."""
    kind = joint.shortname()
    if kind in _UNBOUNDED:
        return _UNBOUNDED[kind]()
    data = joint.createData()
    joint.calc(data, np.array([1.0, 0.0]))  # (cos 0, sin 0): the motion subspace, (0, axis)
    return pin.JointModelRevoluteUnaligned(np.array(data.S, dtype=float).ravel()[3:])


def continuous_as_angles(model: pin.Model) -> pin.Model:
    """The model with each continuous joint a revolute joint without limits (nq == nv).

    Args:
        model: A model built from a URDF (joints in the parser's order, frames after them).

    Returns:
        ``model`` itself when it has no unbounded joint; else a new model with the same joints
        (names, order, placements, parents), bodies, frames, armature and limits, each
        unbounded revolute joint replaced by the revolute joint about its axis with position
        limits [-inf, inf] [rad].
    """
    if not has_continuous_joints(model):
        return model
    new = pin.Model()
    new.name = model.name
    new.inertias[0] = model.inertias[0]
    for i in range(1, model.njoints):
        joint = model.joints[i]
        sq = slice(joint.idx_q, joint.idx_q + joint.nq)
        sv = slice(joint.idx_v, joint.idx_v + joint.nv)
        if _is_unbounded(joint):
            replaced = _revolute(joint)
            lower, upper, margin = np.full(1, -np.inf), np.full(1, np.inf), np.zeros(1)
        else:
            replaced = joint
            lower = model.lowerPositionLimit[sq]
            upper = model.upperPositionLimit[sq]
            margin = model.positionLimitMargin[sq]
        added = new.addJoint(
            model.parents[i],
            replaced,
            model.jointPlacements[i],
            model.names[i],
            model.lowerEffortLimit[sv],
            model.upperEffortLimit[sv],
            model.lowerVelocityLimit[sv],
            model.upperVelocityLimit[sv],
            lower,
            upper,
            margin,
            model.lowerDryFrictionLimit[sv],
            model.upperDryFrictionLimit[sv],
            model.damping[sv],
        )
        new.appendBodyToJoint(added, model.inertias[i], pin.SE3.Identity())
    for frame in list(model.frames)[1:]:  # (frame 0, the universe, every model has)
        new.addFrame(frame, False)  # (the bodies' inertias are already on their joints)
    new.armature = np.array(model.armature, dtype=float)
    new.rotorInertia = np.array(model.rotorInertia, dtype=float)
    new.rotorGearRatio = np.array(model.rotorGearRatio, dtype=float)
    new.gravity = model.gravity
    return new


def sampling_bounds(
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    centre: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Finite bounds to sample configurations in: the limits where a joint has them.

    A joint without limits (continuous: -inf, inf) takes one turn, ``centre - pi`` to
    ``centre + pi`` [rad], which holds each of its configurations once.

    Args:
        lower: Lower position limits [rad or m] (-inf: none).
        upper: Upper position limits [rad or m] (+inf: none).
        centre: The angles each unlimited joint's turn is centred on [rad] (None: zero).

    Returns:
        (lower, upper), finite, new arrays.
    """
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    c = np.zeros(lo.shape) if centre is None else np.asarray(centre, dtype=float)
    bounded = np.isfinite(lo) & np.isfinite(hi)
    return np.where(bounded, lo, c - np.pi), np.where(bounded, hi, c + np.pi)
