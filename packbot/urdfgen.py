"""Generate the URDF, its convex collision meshes and the parameter document from the table.

``packbot generate-model`` (or :func:`generate`) writes:

- ``urdf/packbot_eod.urdf``: links with inertias computed from their parts, revolute joints with
  limits and ``<dynamics>`` (viscous damping, Coulomb friction), fixed tool frames;
- ``urdf/meshes/<link>__<part>.stl``: one convex piece per collision part (binary STL);
- ``docs/parameters.md``: the parameter table with sources, the derived link inertias, effort
  limits and armatures, and both DH tables.

Joint frames follow the DH tables (:mod:`packbot.dh`): the frame of the link after joint *i* is
DH frame *i-1* (z along the joint axis) shifted by ``axis_shift`` along that axis and turned by
``q_i``. ``tests/test_model.py`` fails when the committed files differ from what this writes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot import params as P
from packbot.dh import dh_transform, translation
from packbot.geometry import hull_triangles, part_inertia, part_vertices, stl_bytes

__all__ = ["URDF_NAME", "GeneratedModel", "build", "generate", "mesh_filename"]

log = logging.getLogger(__name__)

URDF_NAME = "packbot_eod.urdf"
MESH_URI = "package://packbot/meshes/"


def mesh_filename(link: str, part: str) -> str:
    """File name of a collision piece's mesh inside ``urdf/meshes``."""
    return f"{link}__{part}.stl"


@dataclass(frozen=True)
class GeneratedModel:
    """Everything the generator writes, in memory.

    Attributes:
        urdf: The URDF text.
        meshes: Mesh file name -> binary STL bytes.
        parameters_md: Text of ``docs/parameters.md``.
        effort: Joint name -> effort limit [N*m] (derived ones included).
    """

    urdf: str
    meshes: dict[str, bytes]
    parameters_md: str
    effort: dict[str, float]


def _fmt(x: float) -> str:
    s = f"{x:.12g}"
    return "0" if s == "-0" else s


def _origin(T: NDArray[np.float64]) -> str:
    xyz = " ".join(_fmt(v) for v in T[:3, 3])
    rpy = " ".join(_fmt(v) for v in pin.rpy.matrixToRpy(T[:3, :3]))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _row_of(chain: str, joint: str) -> P.DHRow:
    for row in P.CHAINS[chain]:
        if row.joint == joint:
            return row
    raise KeyError(joint)


def _joint_spec(name: str) -> P.JointSpec:
    return next(j for j in P.JOINTS if j.name == name)


def joint_origins() -> dict[str, NDArray[np.float64]]:
    """Placement of every joint frame (and tool frame) in its parent link's frame."""
    # Chain through which each joint is reached from its parent joint.
    origins: dict[str, NDArray[np.float64]] = {}
    shift = {j.name: j.axis_shift for j in P.JOINTS}
    origins["turret"] = translation(*P.DH_BASE) @ translation(0, 0, shift["turret"])
    for chain, rows in P.CHAINS.items():
        for prev, row in pairwise(rows):
            T = translation(0, 0, -shift[prev.joint]) @ dh_transform(prev, 0.0)
            origins[row.joint] = T @ translation(0, 0, shift[row.joint])
        last = rows[-1]
        origins[P.TOOL_FRAMES[chain]] = translation(0, 0, -shift[last.joint]) @ dh_transform(
            last, 0.0
        )
    origins["gripper_jaw"] = translation(*P.JAW_PIVOT)
    return origins


def _link_inertia(link: P.LinkSpec) -> pin.Inertia:
    total = pin.Inertia.Zero()
    for part in link.parts:
        total = total + part_inertia(part)
    return total


def _inertial_xml(inertia: pin.Inertia) -> str:
    c = inertia.lever
    Ic = inertia.inertia
    return (
        "    <inertial>\n"
        f'      <origin xyz="{" ".join(_fmt(v) for v in c)}" rpy="0 0 0"/>\n'
        f'      <mass value="{_fmt(inertia.mass)}"/>\n'
        f'      <inertia ixx="{_fmt(Ic[0, 0])}" ixy="{_fmt(Ic[0, 1])}" ixz="{_fmt(Ic[0, 2])}" '
        f'iyy="{_fmt(Ic[1, 1])}" iyz="{_fmt(Ic[1, 2])}" izz="{_fmt(Ic[2, 2])}"/>\n'
        "    </inertial>\n"
    )


def _link_xml(link: P.LinkSpec) -> str:
    out = [f'  <link name="{link.name}">\n', _inertial_xml(_link_inertia(link))]
    rgba = " ".join(_fmt(v) for v in link.color)
    for part in link.parts:
        if not part.collision:
            continue
        uri = MESH_URI + mesh_filename(link.name, part.name)
        geom = f'<geometry><mesh filename="{uri}"/></geometry>'
        out.append(
            f'    <visual name="{part.name}">\n      <origin xyz="0 0 0" rpy="0 0 0"/>\n'
            f'      {geom}\n      <material name="{link.name}_color"><color rgba="{rgba}"/>'
            "</material>\n    </visual>\n"
        )
        out.append(
            f'    <collision name="{part.name}">\n      <origin xyz="0 0 0" rpy="0 0 0"/>\n'
            f"      {geom}\n    </collision>\n"
        )
    out.append("  </link>\n")
    return "".join(out)


def _joint_xml(j: P.JointSpec, origin: NDArray[np.float64], effort: float) -> str:
    axis = "0 1 0" if j.name == "gripper_jaw" else "0 0 1"
    return (
        f'  <joint name="{j.name}" type="revolute">\n'
        f'    <parent link="{j.parent}"/>\n    <child link="{j.child}"/>\n'
        f"    {_origin(origin)}\n"
        f'    <axis xyz="{axis}"/>\n'
        f'    <limit lower="{_fmt(j.lower)}" upper="{_fmt(j.upper)}" effort="{_fmt(effort)}" '
        f'velocity="{_fmt(j.velocity)}"/>\n'
        f'    <dynamics damping="{_fmt(j.viscous)}" friction="{_fmt(j.coulomb)}"/>\n'
        "  </joint>\n"
    )


def _tool_xml(name: str, parent: str, origin: NDArray[np.float64]) -> str:
    return (
        f'  <link name="{name}"/>\n'
        f'  <joint name="{name}_joint" type="fixed">\n'
        f'    <parent link="{parent}"/>\n    <child link="{name}"/>\n'
        f"    {_origin(origin)}\n  </joint>\n"
    )


def _urdf(effort: dict[str, float]) -> str:
    origins = joint_origins()
    parts = [
        '<?xml version="1.0"?>\n',
        "<!-- GENERATED by `packbot generate-model` from packbot/params.py: do not edit. -->\n",
        "<!-- Mesh URIs package://packbot/ resolve to this urdf/ directory. -->\n",
        '<robot name="packbot_eod">\n',
    ]
    parts += [_link_xml(link) for link in P.LINKS]
    parts += [_joint_xml(j, origins[j.name], effort[j.name]) for j in P.JOINTS]
    tool_parent = {"gripper": "gripper_link", "camera": "camera_head"}
    for chain, frame in P.TOOL_FRAMES.items():
        parts.append(_tool_xml(frame, tool_parent[chain], origins[frame]))
    parts.append("</robot>\n")
    return "".join(parts)


def derived_efforts() -> dict[str, float]:
    """Effort limits [N*m]: given ones, and for the pitch joints derived from the lift capacity.

    For each joint with no given limit: the gravity torque of the arm held straight out
    horizontally (the worst case of its own weight) plus ``lift.mass * gravity * lift.lever``
    (the rated payload "close in"), rounded up to the next N*m.
    """
    provisional = {j.name: (j.effort if j.effort is not None else 1.0) for j in P.JOINTS}
    model = pin.buildModelFromXML(_urdf(provisional))
    model.gravity.linear = np.array([0.0, 0.0, -P.GRAVITY])
    data = model.createData()
    q_straight = np.zeros(model.nq)
    g = pin.computeGeneralizedGravity(model, data, q_straight)
    effort = {}
    for j in P.JOINTS:
        if j.effort is not None:
            effort[j.name] = j.effort
        else:
            idx = model.joints[model.getJointId(j.name)].idx_v
            effort[j.name] = float(math.ceil(abs(g[idx]) + P.LIFT_MASS * P.GRAVITY * P.LIFT_LEVER))
    return effort


def build() -> GeneratedModel:
    """Generate the URDF text, the mesh files and the parameter document in memory."""
    effort = derived_efforts()
    meshes = {}
    for link in P.LINKS:
        for part in link.parts:
            if part.collision:
                name = mesh_filename(link.name, part.name)
                tris = hull_triangles(part_vertices(part), name)
                meshes[name] = stl_bytes(tris, f"packbot {link.name}/{part.name}")
    urdf = _urdf(effort)
    return GeneratedModel(urdf, meshes, _parameters_md(urdf, effort), effort)


def _table(header: Iterable[str], rows: Iterable[Iterable[object]]) -> str:
    header = list(header)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _parameters_md(urdf: str, effort: dict[str, float]) -> str:
    model = pin.buildModelFromXML(urdf)
    out = [
        "# Model parameters (generated)\n\n",
        "GENERATED by `packbot generate-model` from `packbot/params.py`; do not edit by hand. "
        "`docs/model.md` explains the model and its sources.\n\n",
        "## Sources\n\n",
        _table(["key", "source"], ((f"`{k}`", escape(v)) for k, v in P.SOURCES.items())),
        "\n## Parameter table\n\n",
        _table(
            ["name", "value", "unit", "source", "note"],
            (
                (f"`{p.name}`", _fmt(p.value), p.unit, f"`{p.source}`", p.note)
                for p in P.TABLE.values()
            ),
        ),
        "\n## Links (derived: parts of uniform density, inertia at the centre of mass)\n\n",
    ]
    rows = []
    total = 0.0
    for link in P.LINKS:
        inertia = _link_inertia(link)
        total += inertia.mass
        c = ", ".join(f"{v:.4f}" for v in inertia.lever)
        Ic = inertia.inertia
        diag = ", ".join(f"{Ic[i, i]:.5f}" for i in range(3))
        names = ", ".join(p.name + ("" if p.collision else "*") for p in link.parts)
        rows.append((f"`{link.name}`", f"{inertia.mass:.3f}", c, diag, names))
    out.append(
        _table(
            ["link", "mass [kg]", "CoM in link frame [m]", "Ixx, Iyy, Izz [kg m^2]", "parts"], rows
        )
    )
    out.append(f"\nTotal mass {total:.3f} kg (parts marked * are internal: no collision piece).\n")
    out.append("\n## Joints (derived: effort limits, armature = gear_ratio^2 * rotor_inertia)\n\n")
    jrows = []
    for j in P.JOINTS:
        arm = j.gear_ratio**2 * j.rotor_inertia
        jrows.append(
            (
                f"`{j.name}`",
                f"`{j.parent}` -> `{j.child}`",
                f"[{_fmt(j.lower)}, {_fmt(j.upper)}]",
                _fmt(j.velocity),
                _fmt(effort[j.name]),
                _fmt(j.gear_ratio),
                f"{arm:.5g}",
                _fmt(j.viscous),
                _fmt(j.coulomb),
            )
        )
    out.append(
        _table(
            [
                "joint",
                "links",
                "limits [rad]",
                "vel. [rad/s]",
                "effort [N*m]",
                "ratio",
                "armature [kg m^2]",
                "viscous [N*m*s/rad]",
                "Coulomb [N*m]",
            ],
            jrows,
        )
    )
    out.append("\n## DH tables (standard DH: A = Rz(q + offset) Tz(d) Tx(a) Rx(alpha))\n\n")
    base = ", ".join(_fmt(v) for v in P.DH_BASE)
    out.append(f"Base transform of both chains: translation ({base}) m in `base_link`.\n")
    for chain, rows_ in P.CHAINS.items():
        out.append(f"\nChain `{chain}`, tool frame `{P.TOOL_FRAMES[chain]}`:\n\n")
        out.append(
            _table(
                ["i", "joint", "offset [rad]", "d [m]", "a [m]", "alpha [rad]"],
                (
                    (
                        i + 1,
                        f"`{r.joint}`",
                        f"{r.offset:.6f}",
                        _fmt(r.d),
                        _fmt(r.a),
                        f"{r.alpha:.6f}",
                    )
                    for i, r in enumerate(rows_)
                ),
            )
        )
    out.append("\n## Named poses [rad] (joints not listed are 0)\n\n")
    out.append(
        _table(
            ["pose", *P.ARM_JOINTS],
            ((f"`{n}`", *(_fmt(p.get(j, 0.0)) for j in P.ARM_JOINTS)) for n, p in P.POSES.items()),
        )
    )
    del model
    return "".join(out)


def generate(root: Path, check: bool = False) -> list[Path]:
    """Write (or with ``check``, compare) the generated files under the repository ``root``.

    Args:
        root: Repository root holding ``urdf/`` and ``docs/``.
        check: Do not write; return the files whose content differs from what would be written.

    Returns:
        The paths written (or, with ``check``, the ones that differ or are missing).
    """
    gen = build()
    files: dict[Path, bytes] = {
        root / "urdf" / URDF_NAME: gen.urdf.encode(),
        root / "docs" / "parameters.md": gen.parameters_md.encode(),
    }
    for name, data in gen.meshes.items():
        files[root / "urdf" / "meshes" / name] = data
    out = []
    for path, data in files.items():
        if check:
            if not path.exists() or path.read_bytes() != data:
                out.append(path)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        out.append(path)
    if not check:
        stale = set((root / "urdf" / "meshes").glob("*.stl")) - set(files)
        for path in stale:
            log.info("removing stale mesh %s", path)
            path.unlink()
    return out
