"""Check a URDF file before Pinocchio reads it, so that every error names its element.

:class:`URDFChecker` parses the file with :mod:`xml.etree` and checks its links (names, inertias,
geometry, meshes); :class:`JointChecks`, which it composes, checks the joints: types, axes,
limits, dynamics, the tree they make and the arm's joint names of :mod:`packbot.params`. Each
failure is a :class:`packbot.errors.URDFError` (or a subclass) naming the file, the element and
the fix. The public entry points are :func:`packbot.model.check_urdf` and
:func:`packbot.model.load_robot`.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from packbot import params as P
from packbot.errors import (
    InertialError,
    JointError,
    JointMismatchError,
    MeshError,
    URDFError,
    URDFSyntaxError,
)
from packbot.resources import resolve_mesh_uri

__all__ = ["INERTIA_RTOL", "JointChecks", "URDFChecker"]

#: Relative tolerance on principal moments of inertia a <= b <= c: a > rtol * c (positive
#: definite) and a + b >= c (1 - rtol) (triangle inequality: a thin plate has a + b = c exactly;
#: the URDF prints 12 significant digits).
INERTIA_RTOL = 1e-9

_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: The movable joint types of an arm other than PackBot (one coordinate each, nq == nv).
_ARM_JOINT_TYPES = ("revolute", "continuous", "prismatic")
#: ``<robot name=...>`` of PackBot's URDF: its joints are the parameter table's.
PACKBOT_ROBOT = "packbot_eod"
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
    are left to Coal's loader (whose errors :func:`packbot.model.load_robot` maps back to the mesh).
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


def _check_origin(path: Path, element: str, el: ET.Element | None) -> None:
    """Check that an ``<origin>``'s ``xyz`` and ``rpy``, where given, are 3 finite numbers."""
    for attr in ("xyz", "rpy"):
        raw = el.get(attr) if el is not None else None
        if raw is not None and _numbers(raw, 3) is None:
            raise URDFError(
                path,
                f"{element} <origin> {attr}={raw!r}",
                "is not 3 finite numbers",
                "write 3 numbers",
            )


class URDFChecker:
    """Parse and check one URDF file; see :func:`packbot.model.check_urdf`.

    Args:
        path: The URDF file.
    """

    def __init__(self, path: Path, package_dirs: Sequence[Path] = ()) -> None:
        self.path = path
        self.dir = path.resolve().parent
        self.package_dirs = tuple(package_dirs)
        self.meshes: list[_MeshRef] = []
        self.joint_checks = JointChecks(path)
        #: Whether the file describes PackBot (``<robot name="packbot_eod">``): its joints must
        #: then be the parameter table's (set by :meth:`run`).
        self.is_packbot = True

    # -- helpers -------------------------------------------------------------------------------

    def _error(self, element: str, problem: str, fix: str = "") -> URDFError:
        return URDFError(self.path, element, problem, fix)

    def _origin(self, element: str, el: ET.Element | None) -> None:
        _check_origin(self.path, element, el)

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
        inertia_el = inertial.find("inertia")
        if mass == 0.0 and all(
            _number(inertia_el.get(k, "0") if inertia_el is not None else "0") == 0.0
            for k in _INERTIA_KEYS
        ):
            return  # a massless frame written out (mass 0, no inertia): as none at all
        if not (math.isfinite(mass) and mass > 0):
            raise InertialError(
                self.path, link, "mass", mass, f"mass {raw} kg is not positive and finite", fix
            )
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
            resolved = resolve_mesh_uri(uri, self.dir, self.package_dirs)
            if resolved is None:
                searched = ", ".join(map(str, self.package_dirs)) or "none"
                raise MeshError(
                    self.path,
                    link,
                    uri,
                    None,
                    f"packbot cannot resolve this URI (package folders searched: {searched})",
                    "pass the folder holding the package in load_robot(package_dirs=...) or "
                    "ROS_PACKAGE_PATH; or write package://packbot/<path relative to the URDF's "
                    "folder>, a path relative to that folder, or an absolute path",
                )
            shape.set("filename", str(resolved))
            self.meshes.append(_MeshRef(link, uri, resolved))
        else:
            raise self._error(
                where, "is not a URDF shape", "use <mesh>, <box>, <cylinder> or <sphere>"
            )

    def run(self) -> str:
        """All checks; the URDF text for Pinocchio, mesh file names made absolute."""
        root = self.parse()
        self.is_packbot = root.get("name") == PACKBOT_ROBOT
        links = self.links(root)
        self.joint_checks.check(root, links, P.ARM_JOINTS if self.is_packbot else None)
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


class JointChecks:
    """Check a URDF's joints: types, ends, axes, limits, dynamics, their tree, the arm's names.

    Args:
        path: The URDF file (named in the errors).
    """

    def __init__(self, path: Path) -> None:
        self.path = path

    def check(
        self,
        root: ET.Element,
        links: Mapping[str, ET.Element],
        arm_joints: Sequence[str] | None = P.ARM_JOINTS,
    ) -> list[str]:
        """Check the joints and the tree they make; return the movable joints in file order.

        ``arm_joints``: the movable joints the file must have, each revolute (PackBot's); None:
        any revolute and prismatic joints (another arm).
        """
        seen: set[str] = set()
        parent_of: dict[str, tuple[str, str]] = {}  # child link -> (joint, parent link)
        movable: list[str] = []
        types: dict[str, str] = {}
        for el in root.findall("joint"):
            name = el.get("name")
            if not name:
                raise URDFError(
                    self.path, "<joint>", "a joint has no name", "give every <joint> a name"
                )
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
            _check_origin(self.path, f"joint {name!r}", el.find("origin"))
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
        if arm_joints is None:
            for name in movable:
                if types[name] not in _ARM_JOINT_TYPES:
                    raise JointError(
                        self.path,
                        name,
                        "",
                        types[name],
                        f"type is {types[name]!r}: packbot simulates fixed-base arms of "
                        "revolute, continuous and prismatic joints (one coordinate each)",
                        "make it revolute with <limit lower upper>, continuous, or fixed",
                    )
            if not movable:
                raise URDFError(
                    self.path, "joints", "the robot has no movable joint", "describe an arm"
                )
            return movable
        for name in arm_joints:
            if name in types and types[name] != "revolute":
                raise JointError(
                    self.path,
                    name,
                    "",
                    types[name],
                    f"type is {types[name]!r}",
                    "packbot's arm joints are 'revolute' (with limits)",
                )
        missing = [n for n in arm_joints if n not in movable]
        unexpected = [n for n in movable if n not in arm_joints]
        if missing or unexpected:
            raise JointMismatchError(self.path, missing, unexpected, movable, arm_joints)
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
            raise URDFError(
                self.path,
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
            raise URDFError(
                self.path,
                "links",
                f"links {', '.join(cut)} form a cycle, not reachable from the root {roots[0]!r}",
                "a URDF is a tree: remove the joint that closes the loop",
            )
