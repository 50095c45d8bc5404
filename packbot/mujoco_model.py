"""An independent MuJoCo model of the arm, built from our URDF, for cross-checking the collapse.

:func:`build_mujoco_model` loads ``robot.urdf_path`` with MuJoCo's own URDF reader (its
``<mujoco><compiler .../></mujoco>`` extension), after rewriting the URDF text in memory:

- mesh URIs ``package://packbot/meshes/X.stl`` become file names ``X.stl`` with ``meshdir``
  pointing at the URDF's ``meshes/`` directory; another arm's (``package://`` of other packages,
  relative paths) their absolute paths, resolved as :func:`packbot.load_robot` resolved them
  (``robot.package_dirs``), and the visuals MuJoCo cannot read (COLLADA) dropped (MuJoCo
  collides the convex hull of each mesh, which matches our convex pieces);
- the locked joints become ``fixed`` joints whose origin includes their locked angle
  (``origin * Rot(axis, q_j)``), so the welded bodies sit where our locked model has them;
- ``<dynamics>`` (joint damping and friction) is removed: no damping, no joint friction.

The compiled spec then gets: every hinge's armature from ``robot.params.armature``, limited
joints with the URDF range, the floor (our default :class:`~packbot.environment.Environment`,
the halfspace z <= 0) as a plane, Coulomb friction ``mu`` on every geom (elliptic cone),
a stiff ``solref`` (default: time constant ``2 * timestep``, critical damping, the stiffest that
MuJoCo allows without instability) on contacts and limits, and one ``<exclude>`` per SRDF pair
(the robot's SRDF, ``packbot_eod.srdf`` for PackBot: adjacent and never-colliding links), so
that MuJoCo tests the same candidate pairs as :class:`~packbot.collision.CollisionWorld`
(MuJoCo also skips bodies welded together, which we only skip when their distance cannot
change). The chassis ``base_link`` is
welded to the world.

:func:`run_collapse` integrates it with zero control from a pose and reports the rest pose, the
rest time (same rule as :func:`packbot.result.rest_time`) and the deepest penetration.

Requires the optional dependency ``mujoco`` (``pip install packbot[test]``).
"""

from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, ModelError, UnknownNameError
from packbot.resources import resolve_mesh_uri

if TYPE_CHECKING:
    from packbot.environment import Environment
    from packbot.model import Robot

__all__ = [
    "MUJOCO_INTEGRATORS",
    "WRIST_JOINTS",
    "MujocoArm",
    "MujocoIntegrator",
    "MujocoRun",
    "build_mujoco_model",
    "generate_mjcf",
    "run_collapse",
    "sliding_lift",
]

#: The joints held rigid in the report's collapse (wrist, camera and gripper).
WRIST_JOINTS: tuple[str, ...] = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")

#: MuJoCo integrators :func:`build_mujoco_model` accepts (``mjINT_EULER``, ...).
MujocoIntegrator = Literal["euler", "implicitfast", "rk4"]
MUJOCO_INTEGRATORS: tuple[str, ...] = get_args(MujocoIntegrator)

_PACKAGE = "package://packbot/meshes/"


def _mujoco() -> Any:
    try:
        import mujoco
    except ImportError as exc:  # optional dependency
        raise ModelError(
            "packbot.mujoco_model needs the optional dependency 'mujoco' "
            "(pip install 'packbot[test]' or pip install mujoco)"
        ) from exc
    return mujoco


@dataclass(kw_only=True)
class MujocoArm:
    """A compiled MuJoCo model of the arm and the map between its coordinates and ours.

    Attributes:
        model: The compiled ``mujoco.MjModel``.
        joint_names: Our joint names, in our q order (all ``robot.nq`` of them).
        qpos_index: For each of our joints, its MuJoCo ``qpos`` address, or -1 if locked.
        q_locked: Our full q [rad] whose locked entries the welded joints were built at.
        locked_joints: The joints made fixed.
        mu: Coulomb friction coefficient of every geom [-].
        timestep: MuJoCo step [s].
        solref: (time constant [s], damping ratio [-]) of contacts and joint limits.
        integrator: MuJoCo integrator, one of :data:`MUJOCO_INTEGRATORS`.
        xml: The rewritten URDF text that MuJoCo loaded.
    """

    model: Any
    joint_names: tuple[str, ...]
    qpos_index: NDArray[np.intp]
    q_locked: NDArray[np.float64]
    locked_joints: tuple[str, ...]
    mu: float
    timestep: float
    solref: tuple[float, float]
    integrator: MujocoIntegrator
    xml: str = field(repr=False)

    def to_qpos(self, q: Sequence[float] | NDArray[np.float64]) -> NDArray[np.float64]:
        """MuJoCo qpos of our q [rad] (locked entries are ignored: they are built in)."""
        q = np.asarray(q, dtype=float)
        if q.shape != (len(self.joint_names),):
            raise ConfigurationError("q", q.shape, f"shape ({len(self.joint_names)},)")
        qpos = np.zeros(self.model.nq)
        free = self.qpos_index >= 0
        qpos[self.qpos_index[free]] = q[free]
        return qpos

    def from_qpos(self, qpos: NDArray[np.float64]) -> NDArray[np.float64]:
        """Our full q [rad] of a MuJoCo qpos (locked entries from :attr:`q_locked`)."""
        q = self.q_locked.copy()
        free = self.qpos_index >= 0
        q[free] = np.asarray(qpos)[self.qpos_index[free]]
        return q


@dataclass(kw_only=True)
class MujocoRun:
    """Outcome of :func:`run_collapse`.

    Attributes:
        t: Sample times [s], shape (N,).
        q: Our full q at the samples [rad], shape (N, nq).
        q_rest: q at the end of the run [rad], shape (nq,).
        rest_time: First time after which every joint speed stays below ``rest_speed`` [s]
            (checked at every step), or None if still moving at the end.
        max_penetration: Deepest penetration over the run, max(0, -contact dist) [m].
        steps: MuJoCo steps taken.
        wall_time: Wall-clock time of the stepping loop [s], the Python work of reading every
            step (contacts, speeds, samples) included: not MuJoCo's stepping speed (a bare
            ``mj_step`` loop is several times faster; docs/performance.md).
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    q_rest: NDArray[np.float64]
    rest_time: float | None
    max_penetration: float
    steps: int
    wall_time: float


def _check_positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ConfigurationError(name, value, "a finite positive number")


def _srdf_pairs(path: Path) -> list[tuple[str, str]]:
    root = ET.parse(path).getroot()
    return [(e.attrib["link1"], e.attrib["link2"]) for e in root.iter("disable_collisions")]


def _rewrite_urdf(
    text: str,
    meshdir: Path,
    locked: dict[str, float],
    compiler: dict[str, str],
    package_dirs: Sequence[Path] = (),
) -> str:
    """The URDF as MuJoCo reads it, the locked joints fixed.

    PackBot's meshes by file name in ``meshdir``, another arm's by their absolute path
    (resolved in its folder and ``package_dirs``); the visuals MuJoCo cannot read are dropped
    (it discards the visuals anyway).
    """
    root = ET.fromstring(text)
    for link in root.iter("link"):  # unique geom names (MuJoCo warns on duplicates)
        for el in (*link.findall("collision"), *link.findall("visual")):
            if "name" in el.attrib:
                el.attrib["name"] = f"{link.attrib['name']}__{el.attrib['name']}"
        for el in link.findall("visual"):
            mesh = el.find("geometry/mesh")
            if mesh is not None and Path(mesh.attrib.get("filename", "")).suffix.lower() not in (
                ".stl",
                ".obj",
                ".msh",
            ):
                link.remove(el)
    for mesh in root.iter("mesh"):
        name = mesh.attrib["filename"]
        if name.startswith(_PACKAGE):
            mesh.attrib["filename"] = Path(name[len(_PACKAGE) :]).name
            continue
        found = resolve_mesh_uri(name, meshdir.parent, package_dirs)
        mesh.attrib["filename"] = str(found) if found is not None else Path(name).name
    for joint in root.iter("joint"):
        for dyn in joint.findall("dynamics"):
            joint.remove(dyn)
        name = joint.attrib["name"]
        if name not in locked:
            continue
        origin = joint.find("origin")
        if origin is None:
            origin = ET.SubElement(joint, "origin")
        xyz = [float(x) for x in origin.attrib.get("xyz", "0 0 0").split()]
        rpy = [float(x) for x in origin.attrib.get("rpy", "0 0 0").split()]
        axis_el = joint.find("axis")
        axis = np.array(
            [float(x) for x in (axis_el.attrib["xyz"] if axis_el is not None else "1 0 0").split()]
        )
        rot = pin.rpy.rpyToMatrix(*rpy) @ pin.exp3(axis / np.linalg.norm(axis) * locked[name])
        origin.attrib["xyz"] = " ".join(repr(float(x)) for x in xyz)
        origin.attrib["rpy"] = " ".join(repr(float(x)) for x in pin.rpy.matrixToRpy(rot))
        joint.attrib["type"] = "fixed"
        for tag in ("axis", "limit", "mimic", "safety_controller", "calibration"):
            for el in joint.findall(tag):
                joint.remove(el)
    ext = ET.SubElement(root, "mujoco")
    ET.SubElement(ext, "compiler", {"meshdir": str(meshdir), **compiler})
    return ET.tostring(root, encoding="unicode")


def build_mujoco_model(
    robot: Robot,
    *,
    q_locked: Sequence[float] | NDArray[np.float64] | None = None,
    locked_joints: Sequence[str] | None = None,
    timestep: float = 5e-4,
    mu: float = 0.5,
    solref: tuple[float, float] | None = None,
    solimp: tuple[float, float, float] = (0.99, 0.999, 0.001),
    integrator: MujocoIntegrator = "euler",
    environment: Environment | None = None,
    srdf: Path | str | None = None,
    joint_dynamics: bool = False,
) -> MujocoArm:
    """Build a MuJoCo model of the arm from ``robot.urdf_path``.

    Args:
        robot: The loaded robot (its URDF, armature and gravity are used).
        q_locked: Our full q [rad] giving the angles of the locked joints; None: the robot's
            :attr:`~packbot.Robot.home_pose` (PackBot's "drive").
        locked_joints: Joints made fixed at their ``q_locked`` angle; None: PackBot's
            :data:`WRIST_JOINTS` (the report's collapse), none of another arm's.
        timestep: MuJoCo integration step [s].
        mu: Coulomb (sliding) friction coefficient of every geom [-]; 0: frictionless
            (``condim=1``).
        solref: (time constant [s], damping ratio [-]) of contacts and joint limits; None:
            ``(2 * timestep, 1.0)``.
        solimp: MuJoCo impedance (dmin, dmax, width [m]) of contacts and joint limits.
        integrator: ``"euler"`` (MuJoCo's default, semi-implicit), ``"implicitfast"`` or
            ``"rk4"``. With ``"euler"`` and the default ``solref`` a sliding contact lifts off at
            a normal speed of about mu times its sliding speed, whatever the timestep (MuJoCo's
            convex contact model; docs/contact.md, "MuJoCo as a reference"): for a reference
            of Coulomb sliding use ``"rk4"``, or a ``solref`` time constant of at least ten
            timesteps.
        environment: Static obstacles; only halfspaces are supported (each becomes a plane);
            None: the floor z = 0.
        srdf: SRDF of link pairs never to test; None: the robot's (:attr:`~packbot.Robot.
            srdf_path`; none: only MuJoCo's own parent-child exclusion).
        joint_dynamics: Keep the joints' friction (``SimConfig.joint_friction``): each hinge's
            viscous friction ``robot.params.viscous`` [N*m*s/rad] as MuJoCo ``damping`` and its
            Coulomb friction ``robot.params.coulomb`` [N*m] as ``frictionloss``; False: none.

    Returns:
        The compiled model and the coordinate map.

    Raises:
        UnknownNameError: A locked joint that the robot does not have.
        ConfigurationError: A bad step, friction, solref, integrator, q_locked or a
            non-halfspace obstacle.
        ModelError: mujoco is not installed, or it rejects the model.
    """
    if locked_joints is None:
        locked_joints = WRIST_JOINTS if robot.is_packbot else ()
    spec, xml, q_lock, ref = _arm_spec(
        robot,
        q_locked=q_locked,
        locked_joints=locked_joints,
        timestep=timestep,
        mu=mu,
        solref=solref,
        solimp=solimp,
        integrator=integrator,
        environment=environment,
        srdf=srdf,
        joint_dynamics=joint_dynamics,
    )
    urdf = Path(robot.urdf_path)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not compile the model of {urdf}: {exc}") from exc
    return _arm(model, robot, q_lock, locked_joints, mu, timestep, ref, integrator, xml)


def _arm_spec(
    robot: Robot,
    *,
    q_locked: Sequence[float] | NDArray[np.float64] | None,
    locked_joints: Sequence[str],
    timestep: float,
    mu: float,
    solref: tuple[float, float] | None,
    solimp: tuple[float, float, float],
    integrator: MujocoIntegrator,
    environment: Environment | None,
    srdf: Path | str | None,
    joint_dynamics: bool = False,
) -> tuple[Any, str, NDArray[np.float64], tuple[float, float]]:
    """The uncompiled MjSpec of :func:`build_mujoco_model`.

    Returns the spec, the URDF text it read, q_locked [rad] and solref; ``joint_dynamics`` keeps
    the URDF's viscous damping and Coulomb friction (otherwise both are zero).
    """
    mujoco = _mujoco()
    from packbot.environment import Environment

    names = tuple(robot.joint_names)
    for j in locked_joints:
        if j not in names:
            raise UnknownNameError("joint", j, names)
    _check_positive("timestep", timestep)
    if integrator not in MUJOCO_INTEGRATORS:
        raise ConfigurationError("integrator", integrator, MUJOCO_INTEGRATORS)
    if not isinstance(mu, (int, float)) or not math.isfinite(mu) or mu < 0:
        raise ConfigurationError("mu", mu, "a finite number >= 0")
    ref = (2.0 * timestep, 1.0) if solref is None else (float(solref[0]), float(solref[1]))
    _check_positive("solref[0]", ref[0])
    _check_positive("solref[1]", ref[1])
    q_lock = robot.pose(robot.home_pose) if q_locked is None else np.asarray(q_locked, dtype=float)
    if q_lock.shape != (robot.nq,):
        raise ConfigurationError("q_locked", q_lock.shape, f"shape ({robot.nq},)")
    env = Environment() if environment is None else environment
    planes = []
    for obs in env.obstacles:
        if obs.kind != "halfspace":
            raise ConfigurationError(
                "environment", obs.name, "halfspace obstacles only (MuJoCo planes)"
            )
        planes.append(obs)

    urdf = Path(robot.urdf_path)
    locked = {j: float(q_lock[names.index(j)]) for j in locked_joints}
    compiler = {
        "angle": "radian",
        "discardvisual": "true",
        "fusestatic": "false",
        "balanceinertia": "false",
        "autolimits": "true",
        "strippath": "false",
    }
    xml = _rewrite_urdf(
        urdf.read_text(), urdf.parent / "meshes", locked, compiler, robot.package_dirs
    )
    try:
        spec = mujoco.MjSpec.from_string(xml)
    except ValueError as exc:
        raise ModelError(f"MuJoCo rejected the URDF {urdf}: {exc}") from exc

    spec.option.timestep = timestep
    spec.option.gravity = np.asarray(robot.model.gravity.linear, dtype=float)
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.integrator = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }[integrator]
    imp = [solimp[0], solimp[1], solimp[2], 0.5, 2.0]
    for joint in spec.joints:
        if joint.name not in names:
            raise ModelError(f"MuJoCo joint {joint.name!r} is not one of ours: {names}")
        i = names.index(joint.name)
        joint.armature = float(robot.params.armature[i])
        if joint_dynamics:
            joint.damping = np.full_like(
                np.atleast_1d(joint.damping), float(robot.params.viscous[i])
            )
            joint.frictionloss = float(robot.params.coulomb[i])
        else:
            joint.damping = np.zeros_like(np.atleast_1d(joint.damping))
            joint.frictionloss = 0.0
        joint.solref_limit = list(ref)
        joint.solimp_limit = imp
    for obs in planes:
        n = np.asarray(obs.normal, dtype=float)
        n = n / np.linalg.norm(n)
        quat = np.zeros(4)
        mujoco.mju_quatZ2Vec(quat, n)
        spec.worldbody.add_geom(
            name=obs.name,
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0.0, 0.0, 1.0],
            pos=n * obs.offset,
            quat=quat,
        )
    for geom in spec.geoms:
        geom.friction = [mu, 0.005, 0.0001]
        geom.condim = 3 if mu > 0 else 1
        geom.solref = list(ref)
        geom.solimp = imp
        geom.margin = 0.0
        geom.gap = 0.0
    srdf_path = robot.srdf_path if srdf is None else Path(srdf)
    for a, b in () if srdf_path is None else _srdf_pairs(srdf_path):
        spec.add_exclude(bodyname1=a, bodyname2=b)
    return spec, xml, q_lock, ref


def generate_mjcf(robot: Robot) -> str:
    """The MJCF text of the shipped MuJoCo model (``urdf/packbot/packbot_eod.xml``).

    The model of :func:`build_mujoco_model` with every joint free (none locked), each hinge with
    its armature [kg*m^2], its URDF viscous damping [N*m*s/rad] and Coulomb friction [N*m], the
    floor plane, and the SRDF's disabled link pairs as ``<exclude>``; meshes are read from
    ``meshes/`` beside the file, so ``mujoco.MjModel.from_xml_path`` loads it as it is.

    For a MuJoCo user's first ``ctrl`` and first render it also has one ``<motor>`` per joint
    (named as the joint, ``gear`` 1: ``ctrl`` is the joint torque [N*m]; ``ctrlrange`` and
    ``forcerange`` +/- the joint's effort limit ``robot.params.effort``, so a command beyond
    saturates as packbot's ``effort_saturation`` does), a headlight and a directional light
    from above (the sun), and a free camera looking at the arm.

    Raises:
        ModelError: mujoco is not installed, or it rejects the model.
    """
    mujoco = _mujoco()
    spec, _, _, _ = _arm_spec(
        robot,
        q_locked=None,
        locked_joints=(),
        timestep=5e-4,
        mu=0.5,
        solref=None,
        solimp=(0.99, 0.999, 0.001),
        integrator="euler",
        environment=None,
        srdf=None,
        joint_dynamics=True,
    )
    spec.modelname = "packbot_eod"
    _add_motors_and_lights(mujoco, spec, robot)
    try:
        spec.compile()
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not compile the model of {robot.urdf_path}: {exc}") from exc
    xml = str(spec.to_xml())
    meshdir = f'meshdir="{Path(robot.urdf_path).parent / "meshes"}/"'
    if meshdir not in xml:
        meshdir = meshdir.replace('/"', '"')
    if meshdir not in xml:
        raise ModelError(f"MuJoCo's MJCF of {robot.urdf_path} has no {meshdir}")
    xml = xml.replace(meshdir, 'meshdir="meshes"', 1)
    xml = _as_motors(xml, robot.joint_names)
    header = (
        f"<!-- GENERATED by `packbot generate-model` from packbot/params.py with MuJoCo "
        f"{mujoco.__version__}: do not edit. -->\n"
    )
    return header + xml


def _as_motors(xml: str, joints: Sequence[str]) -> str:
    """The actuators written as ``<motor>`` (MuJoCo writes its ``<general>`` equivalent).

    A ``<general>`` with the default gain, no bias and no dynamics is a ``<motor>``; written
    as one (with its ``gear="1"`` spelt out) it reads as what it is.

    Raises:
        ModelError: An actuator of a joint is not written as expected.
    """
    for name in joints:
        old = f'<general name="{name}" joint="{name}" '
        if xml.count(old) != 1:
            raise ModelError(f"MuJoCo's MJCF has no plain actuator of joint {name!r}")
        xml = xml.replace(old, f'<motor name="{name}" joint="{name}" gear="1" ', 1)
    return xml


def _add_motors_and_lights(mujoco: Any, spec: Any, robot: Robot) -> None:
    """A torque motor per joint (gear 1, +/- the effort limit), lights and the free camera."""
    for i, name in enumerate(robot.joint_names):
        effort = float(robot.params.effort[i])
        spec.add_actuator(
            name=name,
            target=name,
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            gear=[1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
            ctrlrange=[-effort, effort],
            forcelimited=mujoco.mjtLimited.mjLIMITED_TRUE,
            forcerange=[-effort, effort],
        )
    head = spec.visual.headlight
    head.ambient = [0.3, 0.3, 0.3]
    head.diffuse = [0.5, 0.5, 0.5]
    head.specular = [0.1, 0.1, 0.1]
    head.active = 1
    kind = getattr(mujoco, "mjtLightType", None)  # MuJoCo >= 3.3: a light type, not a flag
    directional = {"type": kind.mjLIGHT_DIRECTIONAL} if kind is not None else {"directional": True}
    spec.worldbody.add_light(
        name="sun",
        pos=[0.5, 0.0, 4.0],
        dir=[0.0, 0.0, -1.0],
        castshadow=True,
        diffuse=[0.6, 0.6, 0.6],
        specular=[0.2, 0.2, 0.2],
        **directional,
    )
    spec.stat.center = [0.6, 0.0, 0.6]  # the free camera looks at the arm [m]
    spec.stat.extent = 2.0


def _arm(
    model: Any,
    robot: Robot,
    q_lock: NDArray[np.float64],
    locked_joints: Sequence[str],
    mu: float,
    timestep: float,
    ref: tuple[float, float],
    integrator: MujocoIntegrator,
    xml: str,
) -> MujocoArm:
    mujoco = _mujoco()
    names = tuple(robot.joint_names)
    locked = set(locked_joints)
    qpos_index = np.full(len(names), -1, dtype=np.intp)
    for i, name in enumerate(names):
        if name in locked:
            continue
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ModelError(f"joint {name!r} missing from the MuJoCo model")
        qpos_index[i] = int(model.jnt_qposadr[jid])
    return MujocoArm(
        model=model,
        joint_names=names,
        qpos_index=qpos_index,
        q_locked=q_lock.copy(),
        locked_joints=tuple(locked_joints),
        mu=float(mu),
        timestep=float(timestep),
        solref=ref,
        integrator=integrator,
        xml=xml,
    )


def run_collapse(
    arm: MujocoArm,
    q0: Sequence[float] | NDArray[np.float64],
    duration: float,
    *,
    rest_speed: float = 1e-3,
    sample_dt: float = 0.01,
) -> MujocoRun:
    """Integrate the MuJoCo model with zero control from rest at ``q0``.

    Args:
        arm: From :func:`build_mujoco_model`.
        q0: Our full initial q [rad] (locked entries must equal ``arm.q_locked``).
        duration: Simulated time [s].
        rest_speed: Joint speed [rad/s] below which the arm counts as at rest.
        sample_dt: Sampling interval of the returned trajectory [s].

    Returns:
        The run (rest pose, rest time, deepest penetration, samples, wall time).

    Raises:
        ConfigurationError: Bad duration, rest_speed, sample_dt, or q0 disagreeing with the
            model's locked angles.
    """
    mujoco = _mujoco()
    _check_positive("duration", duration)
    _check_positive("rest_speed", rest_speed)
    _check_positive("sample_dt", sample_dt)
    q0 = np.asarray(q0, dtype=float)
    qpos0 = arm.to_qpos(q0)
    lock = arm.qpos_index < 0
    if not np.allclose(q0[lock], arm.q_locked[lock], atol=1e-12):
        raise ConfigurationError("q0", q0[lock].tolist(), f"locked angles {arm.q_locked[lock]}")
    model = arm.model
    data = mujoco.MjData(model)
    data.qpos[:] = qpos0
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    n = round(duration / arm.timestep)
    every = max(1, round(sample_dt / arm.timestep))
    ts = [0.0]
    qs = [arm.from_qpos(data.qpos)]
    min_dist = 0.0
    last_moving: float | None = 0.0 if np.abs(data.qvel).max(initial=0.0) >= rest_speed else None
    start = time.perf_counter()
    for k in range(1, n + 1):
        mujoco.mj_step(model, data)
        if data.ncon:
            min_dist = min(min_dist, float(data.contact.dist[: data.ncon].min()))
        if np.abs(data.qvel).max(initial=0.0) >= rest_speed:
            last_moving = data.time
        if k % every == 0 or k == n:
            ts.append(float(data.time))
            qs.append(arm.from_qpos(data.qpos))
    wall = time.perf_counter() - start
    t_end = float(data.time)
    if last_moving is None:
        rest: float | None = 0.0
    elif last_moving >= t_end - 0.5 * arm.timestep:
        rest = None
    else:
        rest = float(last_moving + arm.timestep)
    return MujocoRun(
        t=np.asarray(ts),
        q=np.asarray(qs),
        q_rest=qs[-1].copy(),
        rest_time=rest,
        max_penetration=max(0.0, -min_dist),
        steps=n,
        wall_time=wall,
    )


_SLIDER_XML = """<mujoco>
  <option timestep="{dt}" integrator="{integ}" cone="elliptic" gravity="0 0 -9.81"/>
  <default>
    <geom friction="{mu} 0.005 0.0001" solref="{tau} {zeta}" solimp="{imp}" condim="3"/>
  </default>
  <worldbody>
    <geom type="plane" size="0 0 1"/>
    <body pos="0 0 0.05">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>"""


def sliding_lift(
    *,
    timestep: float = 5e-4,
    integrator: MujocoIntegrator = "euler",
    solref: tuple[float, float] | None = None,
    solimp: tuple[float, float, float] = (0.99, 0.999, 0.001),
    mu: float = 0.5,
    speed: float = 1.0,
    duration: float = 0.3,
) -> float:
    """Sliding-induced lift of MuJoCo's contact model with the settings of the arm model.

    A 1 kg sphere (radius 5 cm) that can only translate along x and z (slide joints: it can
    slide but not roll) settles on the plane z = 0, is then launched along +x at ``speed``
    [m/s] and slides to a stop under friction ``mu``. Under Coulomb's law it never leaves the
    plane (normal speed 0 while sliding); MuJoCo's convex contact model gives it an upward
    speed of up to about mu * speed with its default Euler integrator and a ``solref`` time
    constant of two steps, whatever the step.

    Args:
        timestep: MuJoCo step [s].
        integrator: One of :data:`MUJOCO_INTEGRATORS`.
        solref: (time constant [s], damping ratio [-]); None: ``(2 * timestep, 1.0)`` as in
            :func:`build_mujoco_model`.
        solimp: MuJoCo impedance (dmin, dmax, width [m]).
        mu: Coulomb friction coefficient [-], > 0.
        speed: Launch speed [m/s], > 0.
        duration: Time simulated after the launch [s].

    Returns:
        The largest upward speed of the sphere after the launch divided by ``mu * speed``
        [-] (0 for Coulomb sliding).

    Raises:
        ConfigurationError: A bad step, integrator, solref, mu, speed or duration.
        ModelError: mujoco is not installed.
    """
    mujoco = _mujoco()
    for name, value in (("timestep", timestep), ("mu", mu), ("speed", speed)):
        _check_positive(name, value)
    _check_positive("duration", duration)
    if integrator not in MUJOCO_INTEGRATORS:
        raise ConfigurationError("integrator", integrator, MUJOCO_INTEGRATORS)
    ref = (2.0 * timestep, 1.0) if solref is None else (float(solref[0]), float(solref[1]))
    _check_positive("solref[0]", ref[0])
    _check_positive("solref[1]", ref[1])
    xml = _SLIDER_XML.format(
        dt=timestep,
        integ={"euler": "Euler", "implicitfast": "implicitfast", "rk4": "RK4"}[integrator],
        mu=mu,
        tau=ref[0],
        zeta=ref[1],
        imp=" ".join(str(x) for x in solimp),
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(round(0.3 / timestep)):  # settle into the plane
        mujoco.mj_step(model, data)
    data.qvel[:] = (speed, 0.0)
    vz_max = 0.0
    for _ in range(round(duration / timestep)):
        mujoco.mj_step(model, data)
        vz_max = max(vz_max, float(data.qvel[1]))
    return vz_max / (mu * speed)
