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

import logging
import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import params as P
from packbot.errors import (
    ConfigurationError,
    ConvexityError,
    InertialError,
    JointError,
    JointMismatchError,
    MeshError,
    ResourceNotFound,
    UnknownNameError,
    URDFError,
    URDFSyntaxError,
)
from packbot.keywords import checked_arguments
from packbot.resources import URDF_NAME, data_dir, resolve_mesh_uri
from packbot.validation import finite_number

__all__ = ["JointParams", "Robot", "check_urdf", "link_adjacency", "load_robot"]

log = logging.getLogger(__name__)

#: Relative tolerance between a collision mesh's volume and its convex hull's.
CONVEXITY_RTOL = 1e-6
#: Relative tolerance on principal moments of inertia a <= b <= c: a > rtol * c (positive
#: definite) and a + b >= c (1 - rtol) (triangle inequality: a thin plate has a + b = c exactly;
#: the URDF prints 12 significant digits).
INERTIA_RTOL = 1e-9


@checked_arguments
@dataclass(frozen=True)
class JointParams:
    """Per-joint actuator and limit data, as arrays in the model's velocity order (shape (nv,)).

    Attributes:
        names: Joint names, model order.
        lower: Lower position limits [rad].
        upper: Upper position limits [rad].
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
    """The PackBot EOD arm on its chassis.

    Attributes:
        model: Pinocchio kinematic/dynamic model (fixed base ``base_link``; nq = nv = 8).
        collision_model: Pinocchio geometry model; every piece a ``coal.Convex``.
        visual_model: Pinocchio geometry model for display.
        poses: Named poses, name -> q (shape (nq,)) [rad].
        params: Joint limits and actuator data (see :class:`JointParams`).
        urdf_path: The URDF this robot was loaded from.
        adjacent_links: Pairs of links joined by one joint of the *healthy* arm (or on one
            body): their pieces touch by design and are never tested. Kept unchanged when joints
            are locked (a reduced model merges bodies, but two links that were not neighbours
            stay testable).
    """

    model: pin.Model
    collision_model: pin.GeometryModel
    visual_model: pin.GeometryModel
    poses: dict[str, NDArray[np.float64]]
    params: JointParams
    urdf_path: Path
    adjacent_links: frozenset[frozenset[str]] = frozenset()

    def __post_init__(self) -> None:
        if not self.adjacent_links:
            self.adjacent_links = link_adjacency(self.model)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the actuated joints, in q order."""
        return self.params.names

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
        lower=np.array(model.lowerPositionLimit, dtype=float),
        upper=np.array(model.upperPositionLimit, dtype=float),
        velocity=np.array(model.velocityLimit, dtype=float),
        effort=np.array(model.effortLimit, dtype=float),
        gear_ratio=ratio,
        rotor_inertia=rotor,
        armature=ratio**2 * rotor,
        viscous=arr(lambda j: j.viscous),
        coulomb=arr(lambda j: j.coulomb),
        table=dict(P.TABLE),
    )


def _convexify(geom_model: pin.GeometryModel) -> None:
    """Replace every mesh by its convex hull, checking that the mesh was convex."""
    for go in geom_model.geometryObjects:
        mesh = go.geometry
        if not hasattr(mesh, "buildConvexHull"):
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
        if abs(hull_vol - vol) > CONVEXITY_RTOL * hull_vol:
            raise ConvexityError(
                go.name,
                f"mesh is not convex: volume {vol:.6g} m^3 differs from its hull's {hull_vol:.6g} "
                f"m^3 by {100 * (hull_vol - vol) / hull_vol:.3g} %; split it into convex pieces",
                vol,
                hull_vol,
            )
        go.geometry = hull


def _name_pieces(geom_model: pin.GeometryModel, model: pin.Model) -> None:
    """Name each piece ``link/part`` after the parameter table (Pinocchio names them link_k)."""
    parts = {link.name: [p.name for p in link.parts if p.collision] for link in P.LINKS}
    count: dict[str, int] = {}
    for go in geom_model.geometryObjects:
        link = str(model.frames[go.parentFrame].name)
        k = count.get(link, 0)
        count[link] = k + 1
        names = parts.get(link, [])
        go.name = f"{link}/{names[k]}" if k < len(names) else f"{link}/{k}"


# --- URDF checks: parse with xml.etree before Pinocchio, so that every error names its element ---

_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_REGENERATE = "or regenerate the shipped model with `packbot generate-model`"
_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@dataclass(frozen=True)
class _MeshRef:
    """A ``<mesh>`` of a link: its URI as written and the file it resolves to."""

    link: str
    uri: str
    path: Path


def _number(raw: str) -> float | None:
    """The float an attribute holds, or None when it is not one number (``"nan"`` is one)."""
    try:
        return float(raw)
    except ValueError:
        return None


def _numbers(raw: str, n: int) -> list[float] | None:
    """The n finite floats of a space-separated attribute, or None."""
    vals = [_number(x) for x in raw.split()]
    if len(vals) != n or any(v is None or not math.isfinite(v) for v in vals):
        return None
    return [float(v) for v in vals if v is not None]


def _mesh_problem(path: Path) -> str | None:
    """What is wrong with a mesh file (missing, unreadable, obviously not a mesh), or None.

    Binary STL files must hold the triangles their header announces; ASCII STL and other formats
    are left to Coal's loader (whose errors :func:`load_robot` maps back to the mesh).
    """
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        return "the mesh file does not exist"
    except OSError as exc:
        return f"the mesh file cannot be read ({exc.strerror or exc})"
    if not path.is_file():
        return "the mesh path is a directory" if path.is_dir() else "not a regular file"
    try:
        with path.open("rb") as f:
            head = f.read(84)
    except OSError as exc:
        return f"the mesh file cannot be read ({exc.strerror or exc})"
    if path.suffix.lower() != ".stl":
        return None if size > 0 else "the mesh file is empty"
    if size == 0:
        return "the mesh file is empty"
    if size >= 84:
        count = int.from_bytes(head[80:84], "little")
        if size >= 84 + 50 * count:
            if count == 0:
                return "the binary STL file holds no triangles"
            return _stl_vertices_problem(path, count)
    if head[:5].lower() == b"solid":
        return None  # ASCII STL: Coal's loader parses it
    return (
        f"not an STL file: {size} bytes, neither an ASCII STL (starting with 'solid') nor a "
        "binary STL (84 header bytes + 50 bytes per triangle); the file is corrupt or truncated"
    )


#: A binary STL triangle: normal, three vertices (float32), attribute byte count.
_STL_TRIANGLE = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


def _stl_vertices_problem(path: Path, count: int) -> str | None:
    """Whether a binary STL's vertices are all finite (Coal's loader would not say)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        return f"the mesh file cannot be read ({exc.strerror or exc})"
    tri = np.frombuffer(data, dtype=_STL_TRIANGLE, count=count, offset=84)
    bad = int(np.count_nonzero(~np.isfinite(tri["vertices"]).all(axis=(1, 2))))
    if bad:
        return f"{bad} of its {count} triangles have a non-finite vertex coordinate (NaN or inf)"
    return None


class _URDFChecker:
    """Parse and check one URDF file; see :func:`check_urdf`."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.dir = path.resolve().parent
        self.meshes: list[_MeshRef] = []

    # -- helpers -------------------------------------------------------------------------------

    def _error(self, element: str, problem: str, fix: str = "") -> URDFError:
        return URDFError(self.path, element, problem, fix)

    def _vector(self, element: str, el: ET.Element | None, attr: str, n: int = 3) -> None:
        raw = el.get(attr) if el is not None else None
        if raw is not None and _numbers(raw, n) is None:
            raise self._error(
                f"{element} {attr}={raw!r}", f"is not {n} finite numbers", f"write {n} numbers"
            )

    def _origin(self, element: str, el: ET.Element | None) -> None:
        self._vector(f"{element} <origin>", el, "xyz")
        self._vector(f"{element} <origin>", el, "rpy")

    def _positive(self, element: str, el: ET.Element, attrs: tuple[str, ...], unit: str) -> None:
        for attr in attrs:
            raw = el.get(attr)
            val = _number(raw) if raw is not None else None
            if val is None or not (math.isfinite(val) and val > 0):
                raise self._error(
                    f"{element} {attr}={raw!r}",
                    "is not a positive finite number" if raw is not None else "is missing",
                    f"give a positive size [{unit}]",
                )

    # -- the checks ----------------------------------------------------------------------------

    def parse(self) -> ET.Element:
        """Read and parse the file, strip XML namespaces, check that its root is ``<robot>``."""
        try:
            data = self.path.read_bytes()
        except OSError as exc:
            raise URDFSyntaxError(
                self.path, "", f"the file cannot be read ({exc.strerror or exc})", "check it"
            ) from None
        if not data.strip():
            raise URDFSyntaxError(
                self.path, "", "the file is empty", f"pass a URDF file, {_REGENERATE}"
            )
        if b"<!ENTITY" in data:  # an entity bomb or an external file: refused whatever expat does
            line = data[: data.index(b"<!ENTITY")].count(b"\n") + 1
            raise URDFSyntaxError(
                self.path,
                "<!ENTITY>",
                "the file declares XML entities, which a URDF does not use (they can expand to "
                "gigabytes, or read other files)",
                "remove the <!DOCTYPE> and write the values out",
                line=line,
            )
        try:
            root = ET.fromstring(data)
        except ET.ParseError as exc:
            line, col = exc.position
            reason = str(exc).split(": line ")[0]
            if reason in ("no element found", "unclosed token"):
                reason += " (the file ends before its elements are closed: truncated?)"
            raise URDFSyntaxError(
                self.path,
                "",
                f"not well-formed XML at column {col}: {reason}",
                f"repair the XML there, {_REGENERATE}",
                line=line,
            ) from None
        for el in root.iter():
            if isinstance(el.tag, str) and el.tag.startswith("{"):
                el.tag = el.tag.split("}", 1)[1]
        if root.tag != "robot":
            raise URDFSyntaxError(
                self.path,
                f"<{root.tag}>",
                "the root element is not <robot>: this is not a URDF file",
                "pass a URDF, an XML file whose root element is <robot name=...>",
            )
        return root

    def links(self, root: ET.Element) -> dict[str, ET.Element]:
        """Check every link's name, inertial and geometry; collect its meshes."""
        links: dict[str, ET.Element] = {}
        for el in root.findall("link"):
            name = el.get("name")
            if not name:
                raise self._error("<link>", "a link has no name", "give every <link> a name")
            if name in links:
                raise self._error(f"link {name!r}", "is defined twice", "rename one of them")
            links[name] = el
            self._inertial(name, el)
            for kind in ("visual", "collision"):
                for k, vis in enumerate(el.findall(kind)):
                    self._geometry(name, f"link {name!r} <{kind}> #{k + 1}", vis)
        if not links:
            raise URDFSyntaxError(
                self.path, "<robot>", "has no <link>", f"describe the robot's links, {_REGENERATE}"
            )
        return links

    def _inertial(self, link: str, el: ET.Element) -> None:
        inertial = el.find("inertial")
        if inertial is None:
            return  # a massless frame (e.g. a tool point)
        self._origin(f"link {link!r} <inertial>", inertial.find("origin"))
        mass_el = inertial.find("mass")
        raw = mass_el.get("value") if mass_el is not None else None
        fix = "give the link a positive finite <mass value> [kg]"
        if raw is None:
            raise InertialError(self.path, link, "mass", None, "<inertial> has no mass", fix)
        mass = _number(raw)
        if mass is None:
            raise InertialError(self.path, link, "mass", raw, f"mass {raw!r} is not a number", fix)
        if not (math.isfinite(mass) and mass > 0):
            raise InertialError(
                self.path, link, "mass", mass, f"mass {raw} kg is not positive and finite", fix
            )
        inertia_el = inertial.find("inertia")
        fix = (
            "give <inertia ixx ixy ixz iyy iyz izz> [kg*m^2] whose principal moments are positive "
            "and each at most the sum of the other two, as for any real body"
        )
        if inertia_el is None:
            raise InertialError(self.path, link, "inertia", None, "<inertial> has no inertia", fix)
        vals: dict[str, float] = {}
        for key in _INERTIA_KEYS:
            raw = inertia_el.get(key)
            val = _number(raw) if raw is not None else None
            if val is None or not math.isfinite(val):
                raise InertialError(
                    self.path,
                    link,
                    "inertia",
                    raw,
                    f"{key}={raw!r} is not a finite number" if raw is not None else f"no {key}",
                    fix,
                )
            vals[key] = val
        ixx, ixy, ixz, iyy, iyz, izz = (vals[k] for k in _INERTIA_KEYS)
        # URDF gives the six entries of a symmetric tensor: it cannot be non-symmetric.
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        a, b, c = np.linalg.eigvalsh(tensor)
        desc = ", ".join(f"{k}={inertia_el.get(k)}" for k in _INERTIA_KEYS)
        moments = f"principal moments {a:.6g}, {b:.6g}, {c:.6g} kg*m^2"
        if a <= INERTIA_RTOL * c:  # zero or negative, up to rounding
            raise InertialError(
                self.path,
                link,
                "inertia",
                vals,
                f"({desc}) is not positive definite: {moments}",
                fix,
            )
        if a + b < c * (1 - INERTIA_RTOL):
            raise InertialError(
                self.path,
                link,
                "inertia",
                vals,
                f"({desc}) violates the triangle inequality: {moments}, {a:.6g} + {b:.6g} < "
                f"{c:.6g}",
                fix,
            )

    def _geometry(self, link: str, element: str, el: ET.Element) -> None:
        self._origin(element, el.find("origin"))
        geo = el.find("geometry")
        shapes = [] if geo is None else [g for g in geo if isinstance(g.tag, str)]
        if not shapes:
            raise self._error(element, "has no <geometry> shape", "add <geometry><mesh .../>")
        shape = shapes[0]
        where = f"{element} <{shape.tag}>"
        if shape.tag == "box":
            raw = shape.get("size", "")
            size = _numbers(raw, 3)
            if size is None or min(size) <= 0:
                raise self._error(
                    f"{where} size={raw!r}", "is not 3 positive lengths", "fix it [m]"
                )
        elif shape.tag == "cylinder":
            self._positive(where, shape, ("radius", "length"), "m")
        elif shape.tag == "sphere":
            self._positive(where, shape, ("radius",), "m")
        elif shape.tag == "mesh":
            uri = shape.get("filename", "")
            scale = shape.get("scale")
            if scale is not None:
                vals = _numbers(scale, 3)
                if vals is None or min(abs(v) for v in vals) == 0:
                    raise MeshError(
                        self.path,
                        link,
                        uri,
                        None,
                        f"scale={scale!r} is not 3 finite non-zero numbers",
                        "fix the scale (or omit it for 1 1 1)",
                    )
            if not uri:
                raise MeshError(
                    self.path, link, uri, None, "<mesh> has no filename", "name the mesh file"
                )
            resolved = resolve_mesh_uri(uri, self.dir)
            if resolved is None:
                raise MeshError(
                    self.path,
                    link,
                    uri,
                    None,
                    "packbot cannot resolve this URI",
                    "write package://packbot/<path relative to the URDF's folder>, a path relative "
                    "to that folder, or an absolute path",
                )
            shape.set("filename", str(resolved))
            self.meshes.append(_MeshRef(link, uri, resolved))
        else:
            raise self._error(
                where, "is not a URDF shape", "use <mesh>, <box>, <cylinder> or <sphere>"
            )

    def joints(self, root: ET.Element, links: Mapping[str, ET.Element]) -> list[str]:
        """Check the joints and the tree they make; return the movable joints in file order."""
        seen: set[str] = set()
        parent_of: dict[str, tuple[str, str]] = {}  # child link -> (joint, parent link)
        movable: list[str] = []
        types: dict[str, str] = {}
        for el in root.findall("joint"):
            name = el.get("name")
            if not name:
                raise self._error("<joint>", "a joint has no name", "give every <joint> a name")
            if name in seen:
                raise JointError(self.path, name, "", name, "defined twice", "rename one")
            seen.add(name)
            jtype = el.get("type", "")
            types[name] = jtype
            if jtype not in _JOINT_TYPES:
                raise JointError(
                    self.path,
                    name,
                    "",
                    jtype,
                    f"type {jtype!r} is not a URDF joint type",
                    f"use one of {', '.join(_JOINT_TYPES)}",
                )
            ends = []
            for tag in ("parent", "child"):
                end = el.find(tag)
                link = end.get("link") if end is not None else None
                if not link:
                    raise JointError(
                        self.path, name, tag, None, f"has no <{tag} link=...>", "name the link"
                    )
                if link not in links:
                    raise JointError(
                        self.path,
                        name,
                        tag,
                        link,
                        f"link {link!r} is not defined",
                        f"use one of the links {', '.join(links)}, or define it",
                    )
                ends.append(link)
            parent, child = ends
            if child in parent_of:
                raise JointError(
                    self.path,
                    name,
                    "child",
                    child,
                    f"link {child!r} is already the child of joint {parent_of[child][0]!r}",
                    "a link has one parent joint: attach it once",
                )
            parent_of[child] = (name, parent)
            self._origin(f"joint {name!r}", el.find("origin"))
            if jtype != "fixed":
                movable.append(name)
                self._axis(name, el.find("axis"))
            if jtype in ("revolute", "prismatic", "continuous"):
                self._limits(name, jtype, el.find("limit"))
            dyn = el.find("dynamics")
            for attr in ("damping", "friction"):
                raw = dyn.get(attr) if dyn is not None else None
                val = _number(raw) if raw is not None else 0.0
                if val is None or not (math.isfinite(val) and val >= 0):
                    raise JointError(
                        self.path,
                        name,
                        "dynamics",
                        raw,
                        f"{attr}={raw!r} is not a finite number >= 0",
                        "fix it, or omit it (packbot takes friction from packbot/params.py)",
                    )
        self._tree(links, parent_of)
        for name in P.ARM_JOINTS:
            if name in types and types[name] != "revolute":
                raise JointError(
                    self.path,
                    name,
                    "",
                    types[name],
                    f"type is {types[name]!r}",
                    "packbot's arm joints are 'revolute' (with limits)",
                )
        missing = [n for n in P.ARM_JOINTS if n not in movable]
        unexpected = [n for n in movable if n not in P.ARM_JOINTS]
        if missing or unexpected:
            raise JointMismatchError(self.path, missing, unexpected, movable, P.ARM_JOINTS)
        return movable

    def _axis(self, joint: str, el: ET.Element | None) -> None:
        raw = el.get("xyz") if el is not None else None
        if raw is None:
            return  # URDF default 1 0 0
        vals = _numbers(raw, 3)
        if vals is None or math.hypot(*vals) == 0:
            raise JointError(
                self.path,
                joint,
                "axis",
                raw,
                f"xyz={raw!r} is not a non-zero vector of 3 finite numbers",
                "give the joint axis as a unit vector",
            )

    def _limits(self, joint: str, jtype: str, el: ET.Element | None) -> None:
        angular = jtype != "prismatic"
        pos, vel, eff = ("rad", "rad/s", "N*m") if angular else ("m", "m/s", "N")
        if el is None:
            if jtype == "continuous":
                return
            raise JointError(
                self.path,
                joint,
                "limit",
                None,
                f"a {jtype} joint needs a <limit>",
                f"add <limit lower upper [{pos}] effort [{eff}] velocity [{vel}]>",
            )
        vals: dict[str, float] = {}
        keys = (
            ("effort", "velocity")
            if jtype == "continuous"
            else ("lower", "upper", "effort", "velocity")
        )
        for key in keys:
            raw = el.get(key)
            if raw is None and key in ("lower", "upper"):
                raw = "0"  # the URDF default
            val = _number(raw) if raw is not None else None
            if val is None or not math.isfinite(val):
                raise JointError(
                    self.path,
                    joint,
                    "limit",
                    raw,
                    f"{key}={raw!r} is not a finite number" if raw is not None else f"no {key}",
                    f"give finite limits: lower, upper [{pos}], effort [{eff}], velocity [{vel}]",
                )
            vals[key] = val
        if "lower" in vals and vals["lower"] >= vals["upper"]:
            lo, hi = vals["lower"], vals["upper"]
            what = "above" if lo > hi else "equal to"
            raise JointError(
                self.path,
                joint,
                "limit",
                (lo, hi),
                f"lower limit {lo:g} {pos} is {what} the upper limit {hi:g} {pos}"
                + (" (inverted)" if lo > hi else " (no range)"),
                "give lower < upper" + (": swap them" if lo > hi else ""),
            )
        for key, unit in (("effort", eff), ("velocity", vel)):
            if vals[key] <= 0:
                raise JointError(
                    self.path,
                    joint,
                    "limit",
                    vals[key],
                    f"{key} limit {vals[key]:g} {unit} is not positive",
                    f"give a positive {key} limit [{unit}] (a failed joint is a packbot Failure, "
                    "not a URDF edit)",
                )

    def _tree(
        self, links: Mapping[str, ET.Element], parent_of: Mapping[str, tuple[str, str]]
    ) -> None:
        roots = [n for n in links if n not in parent_of]
        if len(roots) != 1:
            raise self._error(
                "links",
                f"{len(roots)} links have no parent joint ({', '.join(roots) or 'a cycle'}), "
                "a URDF is one tree with one root",
                "connect every link but the root (base_link) to its parent with a <joint>",
            )
        children: dict[str, list[str]] = {}
        for child, (_, parent) in parent_of.items():
            children.setdefault(parent, []).append(child)
        reached, todo = set(roots), list(roots)
        while todo:
            for c in children.get(todo.pop(), []):
                if c not in reached:
                    reached.add(c)
                    todo.append(c)
        cut = [n for n in links if n not in reached]
        if cut:
            raise self._error(
                "links",
                f"links {', '.join(cut)} form a cycle, not reachable from the root {roots[0]!r}",
                "a URDF is a tree: remove the joint that closes the loop",
            )

    def run(self) -> str:
        """All checks; the URDF text for Pinocchio, mesh file names made absolute."""
        root = self.parse()
        links = self.links(root)
        self.joints(root, links)
        self.mesh_files()
        return ET.tostring(root, encoding="unicode")

    def mesh_files(self) -> None:
        """Check that every mesh file exists, can be read and looks like a mesh."""
        problems: dict[Path, str | None] = {}
        for ref in self.meshes:
            if ref.path not in problems:
                problems[ref.path] = _mesh_problem(ref.path)
            problem = problems[ref.path]
            if problem is not None:
                raise MeshError(
                    self.path,
                    ref.link,
                    ref.uri,
                    ref.path,
                    problem,
                    "restore the file (package://packbot/ stands for the URDF's folder), "
                    + _REGENERATE,
                )

    def mesh_error(self, exc: Exception) -> URDFError:
        """Map a Pinocchio/Coal mesh loading error to the mesh and link it names."""
        text = str(exc)
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
        for ref in self.meshes:
            if str(ref.path) in text:
                idx = next((i for i, ln in enumerate(lines) if str(ref.path) in ln), 0)
                reason = lines[idx + 1] if idx + 1 < len(lines) else text
                return MeshError(
                    self.path,
                    ref.link,
                    ref.uri,
                    ref.path,
                    f"Coal cannot load the mesh: {reason}",
                    "replace it with a valid mesh file (STL, OBJ, DAE)",
                )
        return self._error(
            "", f"Pinocchio cannot build its geometry: {lines[0] if lines else text}"
        )


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
    return _URDFChecker(Path(path)).run()


@checked_arguments
def load_robot(urdf: str | Path | None = None) -> Robot:
    """Load the PackBot EOD model.

    The URDF is checked first (see :func:`check_urdf`), so that a bad model raises an error
    naming the file, the element and the fix, never Pinocchio's bare exceptions.

    Args:
        urdf: A URDF file to load instead of the shipped one (``packbot.urdf_path()``). Mesh URIs
            ``package://packbot/...`` and relative paths resolve to that file's directory.

    Returns:
        The robot, with armature set from the parameter table and convex collision pieces.

    Raises:
        ConfigurationError: ``urdf`` is not a path.
        ResourceNotFound: The URDF file is missing (or is a directory).
        URDFError: The URDF is malformed or unphysical, its joints are not the arm's, or a mesh
            is missing, unreadable or corrupt (the subclasses of :class:`URDFError`).
        ConvexityError: A collision mesh is not convex, or is degenerate.
    """
    if urdf is not None and not isinstance(urdf, (str, os.PathLike)):
        raise ConfigurationError("urdf", urdf, "a path to a URDF file, or None for the shipped one")
    path = Path(urdf) if urdf is not None else data_dir("urdf") / URDF_NAME
    if not path.is_file():
        hint = "it is a directory: pass the .urdf file in it" if path.is_dir() else ""
        raise ResourceNotFound(path, hint)
    checker = _URDFChecker(path)
    text = checker.run()
    try:
        model = pin.buildModelFromXML(text)
    except (ValueError, RuntimeError) as exc:  # checked above: should not happen
        raise URDFError(path, "", f"Pinocchio cannot build the model: {exc}") from exc
    try:
        collision = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
        visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    except (ValueError, RuntimeError) as exc:  # Coal could not parse a mesh
        raise checker.mesh_error(exc) from exc
    _name_pieces(collision, model)
    _name_pieces(visual, model)
    _convexify(collision)
    params = _joint_params(model)
    model.armature = params.armature.copy()
    model.gravity.linear = np.array([0.0, 0.0, -P.GRAVITY])
    poses = {name: np.zeros(model.nq) for name in P.POSES}
    for name, values in P.POSES.items():
        for joint, val in values.items():
            poses[name][params.index(joint)] = val
    log.debug("loaded %s: nq=%d, %d collision pieces", path, model.nq, collision.ngeoms)
    return Robot(model, collision, visual, poses, params, path)


_SHIPPED: list[Robot] = []


def _shipped_robot() -> Robot:
    """The shipped robot, loaded once (for reading: frames, kinematics, collision pieces)."""
    if not _SHIPPED:
        _SHIPPED.append(load_robot())
    return _SHIPPED[0]


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
