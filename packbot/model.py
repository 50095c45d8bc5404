"""Load the PackBot EOD model: :func:`load_robot` returns a :class:`Robot`.

The Pinocchio models come from ``urdf/packbot/packbot_eod.urdf``; actuator data (gear ratios, rotor
inertias, friction) from the parameter table :mod:`packbot.params`. The armature
``gear_ratio^2 * rotor_inertia`` is written into ``model.armature``, which Pinocchio's ABA and
CRBA add to the joint-space mass matrix. Collision meshes are replaced by their convex hulls
(``coal.Convex``), so that Coal's GJK/EPA returns signed distances (negative when penetrating).

Before Pinocchio sees a URDF, :func:`load_robot` parses it with :mod:`xml.etree` and checks it
(:func:`check_urdf`): well-formed XML with a ``<robot>`` root; one tree of uniquely named links
and joints; positive finite masses; inertia tensors that are positive definite and obey the
triangle inequality; finite, non-inverted joint limits with positive effort and velocity limits;
the arm's joint names of :mod:`packbot.params`; mesh files that exist, can be read and look like
meshes. Each failure is a :class:`packbot.errors.URDFError` (a :class:`ModelError`) naming the
file, the element and the fix.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import params as P
from packbot.continuous_joints import continuous_as_angles, sampling_bounds
from packbot.errors import (
    ConfigurationError,
    ConvexityError,
    JointMismatchError,
    ResourceNotFound,
    UnknownNameError,
    URDFError,
)
from packbot.geometry import convex_piece, primitive_vertices
from packbot.keywords import checked_arguments
from packbot.resources import SRDF_NAME, URDF_NAME, data_dir, search_package_dirs
from packbot.robots import ROBOTS, robot_files
from packbot.urdf_check import INERTIA_RTOL as INERTIA_RTOL  # re-exported: the checks' tolerance
from packbot.urdf_check import URDFChecker
from packbot.validation import finite_number

__all__ = ["JointParams", "Robot", "check_urdf", "link_adjacency", "load_robot"]

log = logging.getLogger(__name__)

#: Relative tolerance between a collision mesh's volume and its convex hull's.
CONVEXITY_RTOL = 1e-6


@checked_arguments
@dataclass(frozen=True)
class JointParams:
    """Per-joint actuator and limit data, as arrays in the model's velocity order (shape (nv,)).

    Attributes:
        names: Joint names, model order.
        lower: Lower position limits [rad or m] (-inf: none, a continuous joint).
        upper: Upper position limits [rad or m] (+inf: none, a continuous joint).
        velocity: Velocity limits [rad/s].
        effort: Effort limits [N*m].
        gear_ratio: Gear ratios [-].
        rotor_inertia: Rotor inertias [kg*m^2].
        armature: Reflected rotor inertias ``gear_ratio^2 * rotor_inertia`` [kg*m^2].
        viscous: Viscous friction coefficients [N*m*s/rad].
        coulomb: Coulomb friction torques [N*m].
        table: The full parameter table (dotted name -> :class:`packbot.params.Param`).
    """

    names: tuple[str, ...]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    velocity: NDArray[np.float64]
    effort: NDArray[np.float64]
    gear_ratio: NDArray[np.float64]
    rotor_inertia: NDArray[np.float64]
    armature: NDArray[np.float64]
    viscous: NDArray[np.float64]
    coulomb: NDArray[np.float64]
    table: Mapping[str, P.Param] = field(repr=False)

    @property
    def bounded(self) -> NDArray[np.bool_]:
        """Whether each joint has position limits (a continuous joint has none: -inf, inf)."""
        return np.isfinite(self.lower) & np.isfinite(self.upper)

    def sampling_bounds(
        self, centre: NDArray[np.float64] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Finite bounds to sample configurations in [rad or m]: the limits where there are.

        A joint without limits (continuous) takes one turn, ``centre - pi`` to ``centre + pi``,
        which holds every configuration of it once.

        Args:
            centre: The angles each unlimited joint's turn is centred on [rad] (None: zero).
        """
        return sampling_bounds(self.lower, self.upper, centre)

    @checked_arguments
    def index(self, joint: str) -> int:
        """Index of a joint in these arrays (and in q and v).

        Raises:
            UnknownNameError: No joint of that name.
        """
        try:
            return self.names.index(joint)
        except ValueError:
            raise UnknownNameError("joint", joint, self.names) from None


@checked_arguments
@dataclass
class Robot:
    """A fixed-base arm: PackBot's EOD arm on its chassis, or an arm loaded from its URDF.

    Attributes:
        model: Pinocchio kinematic/dynamic model (fixed base; PackBot's nq = nv = 8).
        collision_model: Pinocchio geometry model; every piece a ``coal.Convex``.
        visual_model: Pinocchio geometry model for display.
        poses: Named poses, name -> q (shape (nq,)) [rad].
        params: Joint limits and actuator data (see :class:`JointParams`).
        urdf_path: The URDF this robot was loaded from.
        adjacent_links: Pairs of links joined by one joint of the *healthy* arm (or on one
            body): their pieces touch by design and are never tested. Kept unchanged when joints
            are locked (a reduced model merges bodies, but two links that were not neighbours
            stay testable).
        srdf_path: The SRDF whose disabled link pairs the collision world leaves out (PackBot:
            the shipped one unless another was given); None: no pair but the adjacent ones.
        tool_frame: The frame the Cartesian controllers and the study's task move [-].
        package_dirs: The folders its ``package://`` mesh URIs were resolved in (the loader's).
    """

    model: pin.Model
    collision_model: pin.GeometryModel
    visual_model: pin.GeometryModel
    poses: dict[str, NDArray[np.float64]]
    params: JointParams
    urdf_path: Path
    adjacent_links: frozenset[frozenset[str]] = frozenset()
    srdf_path: Path | None = None
    tool_frame: str = P.TOOL_FRAMES["gripper"]
    package_dirs: tuple[Path, ...] = ()

    def __post_init__(self) -> None:
        if not self.adjacent_links:
            self.adjacent_links = link_adjacency(self.model)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the actuated joints, in q order."""
        return self.params.names

    @property
    def is_packbot(self) -> bool:
        """Whether this is PackBot (its parameter table, poses and scenarios apply)."""
        return bool(self.params.table)

    @property
    def home_pose(self) -> str:
        """The pose a controller's default target or posture is before a run supplies q0.

        The first named pose: PackBot's ``drive``, another arm's ``zero``.

        Raises:
            UnknownNameError: The robot has no named pose.
        """
        if not self.poses:
            raise UnknownNameError("pose", None, ["a robot with named poses"])
        return next(iter(self.poses))

    @property
    def nq(self) -> int:
        """Number of configuration coordinates."""
        return int(self.model.nq)

    @checked_arguments
    def pose(self, name: str) -> NDArray[np.float64]:
        """A copy of a named pose's q [rad].

        Raises:
            UnknownNameError: No pose of that name; lists the valid ones.
        """
        if not isinstance(name, str) or name not in self.poses:
            raise UnknownNameError("pose", name, self.poses)
        return self.poses[name].copy()

    @checked_arguments
    def q_from(self, values: Mapping[str, float], base: str | None = None) -> NDArray[np.float64]:
        """Build q [rad] from joint values by name, the others from pose ``base`` (or zero).

        Raises:
            ConfigurationError: ``values`` is not a {joint: angle} table, or an angle is not a
                finite number.
            UnknownNameError: A joint name that the model does not have, or an unknown pose.
        """
        if not isinstance(values, Mapping):
            raise ConfigurationError("values", values, "a {joint: angle [rad]} table")
        q = self.pose(base) if base is not None else np.zeros(self.nq)
        for name, val in values.items():
            q[self.params.index(name)] = finite_number(
                str(name), val, unit="rad", what="a finite angle"
            )
        return q

    @checked_arguments
    def check_within_limits(self, q: NDArray[np.float64], field_name: str = "q") -> None:
        """Raise :class:`ConfigurationError` naming the joints of q outside their limits."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.nq,):
            raise ConfigurationError(field_name, q.shape, f"shape ({self.nq},)")
        bad = [
            f"{n}={v:.4f} not in [{lo:.4f}, {hi:.4f}]"
            for n, v, lo, hi in zip(
                self.params.names, q, self.params.lower, self.params.upper, strict=True
            )
            if not lo <= v <= hi
        ]
        if bad:
            raise ConfigurationError(field_name, "; ".join(bad), "joint angles within limits [rad]")


def _joint_params(model: pin.Model) -> JointParams:
    specs = {j.name: j for j in P.JOINTS}
    names = tuple(model.names[1:])
    if set(names) != set(specs):  # check_urdf catches this first, naming the file
        raise JointMismatchError(
            "urdf",
            [n for n in specs if n not in names],
            [n for n in names if n not in specs],
            names,
            P.ARM_JOINTS,
        )
    # Model order may differ from the table's: map through names.
    ordered = [specs[n] for n in names]
    arr = lambda f: np.array([f(j) for j in ordered], dtype=float)  # noqa: E731
    ratio = arr(lambda j: j.gear_ratio)
    rotor = arr(lambda j: j.rotor_inertia)
    for n in names:
        idx = model.joints[model.getJointId(n)].idx_v
        if idx != names.index(n):  # pragma: no cover - revolute chains keep this true
            raise URDFError("urdf", f"joint {n!r}", "joint order differs from velocity order")
    return JointParams(
        names=names,
        **_model_limits(model),
        gear_ratio=ratio,
        rotor_inertia=rotor,
        armature=ratio**2 * rotor,
        viscous=arr(lambda j: j.viscous),
        coulomb=arr(lambda j: j.coulomb),
        table=dict(P.TABLE),
    )


def _convexify(geom_model: pin.GeometryModel, exact: bool = True) -> None:
    """Replace every mesh by its convex hull.

    ``exact``: the mesh must have been convex (PackBot's pieces are, by design); otherwise the
    hull stands for the mesh, and the volume it adds is logged.
    """
    for go in geom_model.geometryObjects:
        mesh = go.geometry
        if not hasattr(mesh, "buildConvexHull"):
            corners = primitive_vertices(mesh)
            if corners is not None:  # a URDF box, cylinder or sphere: its convex piece
                go.geometry = convex_piece(corners)
            continue
        pts = np.asarray(mesh.vertices(), dtype=float)
        if not np.all(np.isfinite(pts)):
            raise ConvexityError(go.name, "mesh has a non-finite vertex coordinate (NaN or inf)")
        if len(pts) < 4:
            raise ConvexityError(go.name, f"mesh has {len(pts)} vertices, needs >= 4")
        spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
        if spread[2] <= 1e-6 * max(spread[0], 1e-300):  # (nearly) flat: Qhull would crash
            raise ConvexityError(go.name, "degenerate mesh: its vertices span no volume")
        vol = float(mesh.computeVolume())
        mesh.buildConvexHull(True, "Qt")
        hull = mesh.convex
        hull_vol = float(hull.computeVolume())
        if hull_vol <= 0.0:
            raise ConvexityError(go.name, "degenerate mesh: its hull has no volume", vol, hull_vol)
        if not exact:
            if abs(hull_vol - vol) > CONVEXITY_RTOL * hull_vol:
                log.info(
                    "%s: its convex hull stands for the mesh (%.3g m^3 against %.3g m^3)",
                    go.name,
                    hull_vol,
                    vol,
                )
        elif abs(hull_vol - vol) > CONVEXITY_RTOL * hull_vol:
            raise ConvexityError(
                go.name,
                f"mesh is not convex: volume {vol:.6g} m^3 differs from its hull's {hull_vol:.6g} "
                f"m^3 by {100 * (hull_vol - vol) / hull_vol:.3g} %; split it into convex pieces",
                vol,
                hull_vol,
            )
        go.geometry = hull


def _name_pieces(geom_model: pin.GeometryModel, model: pin.Model, packbot: bool = True) -> None:
    """Name each piece ``link/part`` (Pinocchio names them link_k).

    PackBot's parts are the parameter table's; another arm's are numbered, ``link/k`` (k
    counting the link's pieces from 0).
    """
    parts = (
        {link.name: [p.name for p in link.parts if p.collision] for link in P.LINKS}
        if packbot
        else {}
    )
    count: dict[str, int] = {}
    for go in geom_model.geometryObjects:
        link = str(model.frames[go.parentFrame].name)
        k = count.get(link, 0)
        count[link] = k + 1
        names = parts.get(link, [])
        go.name = f"{link}/{names[k]}" if k < len(names) else f"{link}/{k}"


@checked_arguments
def check_urdf(path: str | Path) -> str:
    """Parse and check a URDF file for :func:`load_robot`.

    Checks: the file is well-formed XML whose root is ``<robot>``; link and joint names are
    unique and the joints make one tree; every ``<inertial>`` has a positive finite mass [kg] and
    an inertia tensor [kg*m^2] that is positive definite and obeys the triangle inequality;
    revolute and prismatic joints have finite limits with lower < upper, and positive effort and
    velocity limits; axes are non-zero; the movable joints are exactly the arm's joints of
    :mod:`packbot.params`, each revolute; every mesh resolves (``package://packbot/`` is the
    URDF's folder) to a file that exists, can be read and is not an obviously broken STL.

    Args:
        path: The URDF file (it must exist).

    Returns:
        The URDF text for Pinocchio, with every mesh file name replaced by its absolute path.

    Raises:
        URDFSyntaxError: Empty file, malformed XML (with the line), no ``<robot>`` root.
        InertialError: A non-positive or non-finite mass, an unphysical inertia tensor.
        JointError: An inverted or non-finite limit, a non-positive effort or velocity limit, a
            bad joint type or axis.
        JointMismatchError: The arm's joints are missing or renamed, or there are extra ones.
        MeshError: A mesh that cannot be resolved, is missing, unreadable or corrupt.
        URDFError: Any other structural problem (duplicate names, not a tree, bad numbers).
    """
    return URDFChecker(Path(path)).run()


@checked_arguments
def load_robot(
    urdf: str | Path | None = None,
    *,
    package_dirs: Sequence[str | Path] | str | Path | None = None,
    srdf: str | Path | None = None,
    tool_frame: str | None = None,
    armature: Mapping[str, float] | str | Path | None = None,
) -> Robot:
    """Load PackBot's EOD arm, or any fixed-base arm described in URDF.

    The URDF is checked first (see :func:`check_urdf`), so that a bad model raises an error
    naming the file, the element and the fix, never Pinocchio's bare exceptions. A file whose
    ``<robot name>`` is ``packbot_eod`` is PackBot: its joints must be the parameter table's,
    which supplies the armature, friction, poses and scenarios. Any other file is an arm of
    revolute, continuous, prismatic and fixed joints (a continuous joint's coordinate its angle,
    without limits: :mod:`packbot.continuous_joints`): limits, effort and velocity limits, damping
    (viscous friction) and friction (Coulomb) from its ``<limit>`` and ``<dynamics>``, zero
    armature, each collision mesh replaced by its convex hull (logged with the volume it
    adds), the poses ``"zero"`` (q = 0 clipped into the limits) and ``"middle"``.

    Args:
        urdf: A URDF file to load instead of the shipped one (``packbot.urdf_path()``), or the
            name of an arm of :data:`packbot.robots.ROBOTS` (``"ur5"``, ``"panda"``: with its
            SRDF and tool frame, from the ``arms`` extra). Mesh URIs ``package://packbot/...``
            and relative paths resolve to that file's directory.
        package_dirs: Folders holding the ROS packages that ``package://<package>/`` mesh URIs
            name (each folder holds packages, or is one); ``ROS_PACKAGE_PATH``'s are searched
            after them.
        srdf: An SRDF whose ``disable_collisions`` pairs are not tested. None: PackBot's
            shipped SRDF for PackBot, none for another arm (every pair of non-adjacent links
            is tested).
        tool_frame: The frame the Cartesian controllers and the failure study's task move.
            None: PackBot's ``gripper_tool``, or another arm's last frame.
        armature: The joints' armature (the rotor's reflected inertia, added to M's diagonal)
            [kg*m^2, kg for a prismatic joint], joint name -> value, or a sidecar TOML file
            with an ``[armature]`` table of the same; the joints it names replace the URDF's
            zero (PackBot's sourced table's value). None: PackBot's table, another arm's zero.

    Returns:
        The robot, with armature set and convex collision pieces.

    Raises:
        ConfigurationError: ``urdf`` is not a path, ``package_dirs`` not folders.
        ResourceNotFound: The URDF or SRDF file is missing (or is a directory).
        URDFError: The URDF is malformed or unphysical, PackBot's joints are not the arm's, a
            joint type packbot does not simulate, or a mesh is missing, unreadable or corrupt
            (the subclasses of :class:`URDFError`).
        ConvexityError: One of PackBot's collision meshes is not convex, or a mesh is
            degenerate.
        UnknownNameError: ``tool_frame`` is not a frame of the model.
    """
    if urdf is not None and not isinstance(urdf, (str, os.PathLike)):
        raise ConfigurationError(
            "urdf", urdf, f"a path to a URDF file, a name of {sorted(ROBOTS)}, or None for PackBot"
        )
    if isinstance(urdf, str) and urdf in ROBOTS and not Path(urdf).is_file():
        named = robot_files(urdf)
        urdf = named.urdf
        srdf = named.srdf if srdf is None else srdf
        tool_frame = named.tool_frame if tool_frame is None else tool_frame
        given = [] if package_dirs is None else list(search_package_dirs(package_dirs))
        package_dirs = [*given, *named.package_dirs]
    path = Path(urdf) if urdf is not None else data_dir("urdf") / URDF_NAME
    if not path.is_file():
        hint = "it is a directory: pass the .urdf file in it" if path.is_dir() else ""
        raise ResourceNotFound(path, hint)
    dirs = search_package_dirs(package_dirs)
    checker = URDFChecker(path, dirs)
    text = checker.run()
    try:
        model = continuous_as_angles(pin.buildModelFromXML(text))
    except (ValueError, RuntimeError) as exc:  # checked above: should not happen
        raise URDFError(path, "", f"Pinocchio cannot build the model: {exc}") from exc
    try:
        collision = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
        visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    except (ValueError, RuntimeError) as exc:  # Coal could not parse a mesh
        raise checker.mesh_error(exc) from exc
    packbot = checker.is_packbot
    _name_pieces(collision, model, packbot)
    _name_pieces(visual, model, packbot)
    _convexify(collision, exact=packbot)
    params = _joint_params(model) if packbot else _urdf_joint_params(model)
    if armature is not None:
        params = dataclasses.replace(params, armature=_armature(armature, params))
    model.armature = params.armature.copy()
    model.gravity.linear = np.array([0.0, 0.0, -P.GRAVITY])
    if packbot:
        poses = {name: np.zeros(model.nq) for name in P.POSES}
        for name, values in P.POSES.items():
            for joint, val in values.items():
                poses[name][params.index(joint)] = val
    else:
        poses = {
            "zero": np.clip(np.zeros(model.nq), params.lower, params.upper),
            "middle": 0.5 * np.add(*params.sampling_bounds()),  # (a continuous joint's 0)
        }
    srdf_file = _srdf_file(srdf, packbot)
    frame = _tool_frame(model, tool_frame, packbot)
    log.debug("loaded %s: nq=%d, %d collision pieces", path, model.nq, collision.ngeoms)
    robot = Robot(
        model,
        collision,
        visual,
        poses,
        params,
        path,
        srdf_path=srdf_file,
        tool_frame=frame,
        package_dirs=tuple(dirs),
    )
    _LOADED[:] = [r for r in _LOADED if r() is not None] + [weakref.ref(robot)]
    return robot


def _armature(spec: Mapping[str, float] | str | Path, params: JointParams) -> NDArray[np.float64]:
    """The armature array [kg*m^2] of ``load_robot(armature=)``: a mapping or a TOML file's.

    Raises:
        ConfigurationError: Not a mapping or a file path, a file without an ``[armature]``
            table, or a value that is not a finite number >= 0.
        ResourceNotFound: The file is missing.
        UnknownNameError: A joint the arm does not have.
    """
    from packbot import tomlfile

    values: Any = spec
    if isinstance(spec, (str, os.PathLike)):
        path = Path(spec)
        if not path.is_file():
            raise ResourceNotFound(path, "pass an existing TOML file with an [armature] table")
        tomlfile.check_file_size(path, "armature", str(path))
        values = tomlfile.loads(path.read_text(), "armature", str(path)).get("armature")
        if not isinstance(values, dict):
            raise ConfigurationError(
                "armature", str(path), "a TOML file with an [armature] table (joint = value)"
            )
    if not isinstance(values, Mapping):
        raise ConfigurationError(
            "armature", spec, "a mapping joint -> armature [kg*m^2], a TOML file, or None"
        )
    out = np.array(params.armature, dtype=np.float64)
    for name, value in values.items():
        if name not in params.names:
            raise UnknownNameError("armature joint", name, params.names)
        out[params.names.index(name)] = finite_number(
            f"armature.{name}", value, low=0.0, unit="kg*m^2"
        )
    return out


def _srdf_file(srdf: str | Path | None, packbot: bool) -> Path | None:
    if srdf is None:
        return data_dir("urdf") / SRDF_NAME if packbot else None
    if not isinstance(srdf, (str, os.PathLike)):
        raise ConfigurationError("srdf", srdf, "a path to an SRDF file, or None")
    path = Path(srdf)
    if not path.is_file():
        raise ResourceNotFound(path, "pass an existing SRDF file, or None")
    return path


def _tool_frame(model: pin.Model, name: str | None, packbot: bool) -> str:
    if name is None:
        return (
            P.TOOL_FRAMES["gripper"] if packbot else str(model.frames[len(model.frames) - 1].name)
        )
    if not isinstance(name, str) or not model.existFrame(name):
        raise UnknownNameError("tool_frame", name, [str(f.name) for f in model.frames])
    return name


def _model_limits(model: pin.Model) -> dict[str, NDArray[np.float64]]:
    """The model's position [rad or m], velocity and effort limits, as JointParams takes them."""
    return {
        "lower": np.array(model.lowerPositionLimit, dtype=float),
        "upper": np.array(model.upperPositionLimit, dtype=float),
        "velocity": np.array(model.velocityLimit, dtype=float),
        "effort": np.array(model.effortLimit, dtype=float),
    }


def _urdf_joint_params(model: pin.Model) -> JointParams:
    """Joint data of an arm other than PackBot, from its URDF (model order)."""
    names = tuple(str(n) for n in model.names[1:])
    nv = model.nv
    return JointParams(
        names=names,
        **_model_limits(model),
        gear_ratio=np.ones(nv),
        rotor_inertia=np.zeros(nv),
        armature=np.zeros(nv),
        viscous=np.array(model.damping, dtype=float),
        coulomb=np.array(model.friction, dtype=float),
        table={},
    )


_SHIPPED: list[Robot] = []
#: The robots :func:`load_robot` returned that are still alive, oldest first.
_LOADED: list[weakref.ref[Robot]] = []


def _shipped_robot() -> Robot:
    """The shipped robot, loaded once (for reading: frames, kinematics, collision pieces)."""
    if not _SHIPPED:
        _SHIPPED.append(load_robot())
    return _SHIPPED[0]


def _robot_of_model(model: pin.Model) -> Robot | None:
    """The loaded robot whose arm ``model`` is (:func:`_same_arm`), or None.

    The robots :func:`load_robot` returned and still alive, the latest first, then the shipped
    PackBot (loaded once if needed).
    """
    for ref in reversed(_LOADED):
        robot = ref()
        if robot is not None and _same_arm(model, robot.model):
            return robot
    shipped = _shipped_robot()
    return shipped if _same_arm(model, shipped.model) else None


def _same_arm(a: pin.Model, b: pin.Model) -> bool:
    """Whether two models have the same joints and joint placements (the same kinematics).

    A copy, a model with a payload's body appended or other gravity is the same arm; a
    reduced model (locked joints merged) or another URDF's is not.
    """
    if a.nq != b.nq or a.njoints != b.njoints or list(a.names) != list(b.names):
        return False
    return all(
        np.allclose(pa.homogeneous, pb.homogeneous, rtol=0.0, atol=1e-12)
        for pa, pb in zip(a.jointPlacements, b.jointPlacements, strict=True)
    )


def link_adjacency(model: pin.Model) -> frozenset[frozenset[str]]:
    """Pairs of links (BODY frames) on one joint's body or on a joint and its parent joint.

    Args:
        model: A Pinocchio model (the healthy arm's, so that locking joints later does not make
            distant links "adjacent").
    """
    bodies = [(str(f.name), int(f.parentJoint)) for f in model.frames if f.type == pin.BODY]
    parents = model.parents
    out = set()
    for i, (n1, j1) in enumerate(bodies):
        for n2, j2 in bodies[i + 1 :]:
            if j1 == j2 or parents[j1] == j2 or parents[j2] == j1:
                out.add(frozenset((n1, n2)))
    return frozenset(out)
