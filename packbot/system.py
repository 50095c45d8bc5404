"""The dynamic system a simulation integrates: the (possibly reduced) Pinocchio model.

Joints listed in :attr:`SimConfig.locked_joints` are removed with ``pin.buildReducedModel``,
which merges the bodies on either side of a locked joint exactly (inertia and collision pieces
placed at the locked angle). The simulator integrates the reduced coordinates; everything it
returns is mapped back to the full model's coordinates (locked joints constant, zero speed).

Energy: kinetic 0.5 v^T M(q) v with M including the armature (reflected rotor inertia), plus
the potential energy of gravity [J].
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.collision import CollisionWorld
from packbot.config import SimConfig
from packbot.environment import Environment
from packbot.errors import UnknownNameError
from packbot.model import JointParams, Robot
from packbot.payload import Payload

__all__ = ["System", "with_payload"]

FloatArray = NDArray[np.float64]


def _skew(r: FloatArray) -> FloatArray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


class System:
    """The model being integrated and the maps between its coordinates and the full model's.

    Args:
        robot: The full robot.
        q0: Initial configuration, full coordinates [rad] (locked joints stay there).
        config: Simulation settings (gravity, locked joints, contact mode, margin).
        environment: Static obstacles (None: the floor).
        locked: Joints to lock (default: ``config.locked_joints``); frozen joints join them.
        payload: A payload held in the gripper (its inertia added to the carrying body).

    Attributes:
        robot: The (reduced) robot the simulation integrates.
        full: The full robot.
        model: Its Pinocchio model, gravity and armature set.
        data: Its Pinocchio data.
        free: Indices of the integrated joints in the full coordinates.
        q_locked: Full configuration supplying the locked joints [rad].
        world: The collision world, or None when ``contact_mode == "none"``.
        lower: Lower limits of the integrated joints [rad].
        upper: Upper limits of the integrated joints [rad].
        names: Names of the integrated joints.
    """

    def __init__(
        self,
        robot: Robot,
        q0: FloatArray,
        config: SimConfig,
        environment: Environment | None,
        *,
        locked: Sequence[str] | None = None,
        payload: Payload | None = None,
    ) -> None:
        self.full = robot
        self.q_locked = np.array(q0, dtype=float)
        names = config.locked_joints if locked is None else locked
        idx = [robot.params.index(n) for n in names]
        self.free = np.array([i for i in range(robot.nq) if i not in idx], dtype=int)
        base = robot if payload is None else with_payload(robot, payload)
        self.robot = base if not idx else _reduced(base, idx, self.q_locked)
        self.model = self.robot.model.copy()
        self.model.gravity.linear = np.asarray(config.gravity, dtype=float)
        self.data = self.model.createData()
        self.names = self.robot.params.names
        self.lower = self.robot.params.lower
        self.upper = self.robot.params.upper
        self.nv = int(self.model.nv)
        self._lower = strict_lower(self.nv)
        # the strict lower triangle's flat indices in an (nv, nv) C-ordered matrix, and those
        # of the upper entries mirroring them
        self._lower_flat = self._lower[0] * self.nv + self._lower[1]
        self._upper_flat = self._lower[1] * self.nv + self._lower[0]
        nq = robot.nq
        self._qv0 = np.concatenate([self.q_locked, np.zeros(nq)])
        self._qv_idx = np.concatenate([self.free, nq + self.free])
        self.world: CollisionWorld | None = None
        if config.contact_mode != "none":
            self.world = CollisionWorld(self.robot, environment, margin=config.margin)

    # --------------------------------------------------------------- coordinates
    def reduce(self, x_full: FloatArray) -> FloatArray:
        """Full-model vector (q, v or tau) -> the integrated joints' entries."""
        return np.asarray(x_full, dtype=float)[self.free]

    def q_full(self, q: FloatArray) -> FloatArray:
        """Integrated configuration -> full configuration [rad]."""
        out = self.q_locked.copy()
        out[self.free] = q
        return out

    def v_full(self, v: FloatArray) -> FloatArray:
        """Integrated velocity -> full velocity [rad/s] (locked joints at zero)."""
        out = np.zeros(self.full.nq)
        out[self.free] = v
        return out

    def qv_full(self, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Integrated state (q, v, ...) -> full (q [rad], v [rad/s]), in one fresh buffer.

        The same numbers as :meth:`q_full` and :meth:`v_full` (two views of one new array: one
        copy and one indexed assignment instead of two of each).
        """
        out = self._qv0.copy()
        out[self._qv_idx] = y[: 2 * self.nv]
        nq = self.full.nq
        return out[:nq], out[nq:]

    # --------------------------------------------------------------- dynamics
    def aba(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """Joint accelerations of the unconstrained arm [rad/s^2] (armature included).

        Pinocchio's ABA in the world convention: the arithmetic of the compiled right-hand
        side (``ContactRhs``, which takes M^-1 from the same pass), so that both give the same
        numbers to the bit (tests/test_native*.py compare them).
        """
        return pin.aba(self.model, self.data, q, v, tau, pin.Convention.WORLD)

    def bias(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """Bias torques C(q, v) v + g(q) [N*m] (Pinocchio's nonLinearEffects)."""
        return pin.nonLinearEffects(self.model, self.data, q, v)

    def minv(self, q: FloatArray) -> FloatArray:
        """Inverse joint-space mass matrix M(q)^-1 (symmetric, armature included)."""
        return self._symmetric(pin.computeMinverse(self.model, self.data, q))

    def mass_upper(self, q: FloatArray) -> FloatArray:
        """The upper triangle of M(q) [kg m^2] (CRBA's; the strict lower one is not filled)."""
        return pin.crba(self.model, self.data, q)

    def mass_matrix(self, q: FloatArray) -> FloatArray:
        """Joint-space mass matrix M(q) [kg m^2] (armature included)."""
        return self._symmetric(pin.crba(self.model, self.data, q))

    def _symmetric(self, upper: FloatArray) -> FloatArray:
        """Fill the strict lower triangle from the upper one (Pinocchio fills the upper)."""
        out = np.array(upper, dtype=float, order="C")
        flat = out.reshape(-1)  # a view (out is a fresh C-ordered copy)
        flat[self._lower_flat] = flat[self._upper_flat]
        return out

    def energy(self, q: FloatArray, v: FloatArray) -> float:
        """Kinetic (with armature) plus gravitational potential energy [J]."""
        kinetic = 0.5 * float(v @ self.mass_matrix(q) @ v)
        return kinetic + float(pin.computePotentialEnergy(self.model, self.data, q))

    def point_jacobian(self, q: FloatArray, joint: int, point: FloatArray) -> FloatArray:
        """3 x nv Jacobian of the velocity of a world point fixed to a joint's body.

        Args:
            q: Configuration [rad].
            joint: Pinocchio joint index of the body (0: the fixed chassis or world).
            point: The point, world frame [m].

        Returns:
            J with v_point = J v, world-frame axes [m/rad].
        """
        if joint == 0:
            return np.zeros((3, self.nv))
        pin.computeJointJacobians(self.model, self.data, q)
        J = pin.getJointJacobian(self.model, self.data, joint, pin.LOCAL_WORLD_ALIGNED)
        J = np.asarray(J).reshape(6, self.nv)  # pin returns a flat 6-vector when nv == 1
        r = np.asarray(point) - self.data.oMi[joint].translation
        return J[:3] - _skew(r) @ J[3:]


#: strict_lower's arrays, by size
_STRICT_LOWER: dict[int, tuple[NDArray[np.intp], NDArray[np.intp]]] = {}


def strict_lower(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """``np.tril_indices(n, -1)``, made once per n (read-only: index arrays to share)."""
    out = _STRICT_LOWER.get(n)
    if out is None:
        rows, cols = np.tril_indices(n, -1)
        rows.setflags(write=False)
        cols.setflags(write=False)
        out = _STRICT_LOWER[n] = (rows, cols)
    return out


def _reduced(robot: Robot, locked: list[int], q_ref: FloatArray) -> Robot:
    """The robot with the given joints (indices into q) locked at q_ref."""
    ids = [robot.model.getJointId(robot.params.names[i]) for i in locked]
    model, (coll, vis) = pin.buildReducedModel(
        robot.model, [robot.collision_model, robot.visual_model], ids, q_ref
    )
    keep = [i for i in range(robot.nq) if i not in locked]
    p = robot.params
    params = JointParams(
        names=tuple(p.names[i] for i in keep),
        lower=p.lower[keep],
        upper=p.upper[keep],
        velocity=p.velocity[keep],
        effort=p.effort[keep],
        gear_ratio=p.gear_ratio[keep],
        rotor_inertia=p.rotor_inertia[keep],
        armature=p.armature[keep],
        viscous=p.viscous[keep],
        coulomb=p.coulomb[keep],
        table=p.table,
    )
    model.armature = params.armature.copy()
    poses = {name: q[keep] for name, q in robot.poses.items()}
    return dataclasses.replace(
        robot, model=model, collision_model=coll, visual_model=vis, poses=poses, params=params
    )


def with_payload(robot: Robot, payload: Payload) -> Robot:
    """The robot with the payload's spatial inertia added to the body carrying its frame.

    Raises:
        UnknownNameError: The payload's frame is not a frame of the model.
    """
    model = robot.model.copy()
    name = robot.tool_frame if payload.frame is None else payload.frame
    if not model.existFrame(name):
        raise UnknownNameError("frame", name, [str(f.name) for f in model.frames])
    frame = model.frames[model.getFrameId(name)]
    inertia = pin.Inertia(
        float(payload.mass), np.asarray(payload.com, dtype=float), payload.inertia_matrix()
    )
    model.appendBodyToJoint(frame.parentJoint, inertia, frame.placement)
    return dataclasses.replace(robot, model=model)
