"""The PackBot collapse in Drake: an independent Coulomb-sliding reference for the normal mode.

Why: MuJoCo's soft contact lifts a sliding contact off its surface (docs/contact.md, "MuJoCo as
a reference"), so its rest pose is a reference only in settings where that lift is small. Drake's
discrete point contact (compliant normal force, regularised Coulomb friction) has no such lift:
this script runs the same collapse there as a third opinion.

The collapse: pose "drive", zero torque, gravity, the wrist joints of
:data:`packbot.mujoco_model.WRIST_JOINTS` (camera_tilt, camera_pan, gripper_roll, gripper_jaw)
welded at their drive angles, our convex collision pieces, floor half-space z <= 0, Coulomb
mu = 0.5 (static = dynamic).

Model choices:

- Geometry: every collision STL of the URDF becomes an OBJ with ``<drake:declare_convex/>`` (the
  pieces are convex, so Drake's hull is the piece); visuals are dropped.
- Contact: ``ContactModel.kPoint``, discrete ``MultibodyPlant``, approximation ``--approx``
  (default ``lagged``, Drake's preferred one for sliding: no "gliding" artefact). Every
  geometry (and the floor) gets ``point_contact_stiffness`` 2 k: two geometries act in series,
  so a contact pair has stiffness k (``--stiffness``, default 1e6 N/m). Hunt-Crossley
  dissipation d (``--dissipation``, default 20 s/m; normal force k x (1 + d x_dot)).
- Friction: Coulomb mu (``--mu``) regularised below the stiction tolerance (``--stiction``,
  default 1e-4 m/s). ``sap`` ignores both d and the stiction tolerance (linear Kelvin-Voigt
  dissipation with Drake's default relaxation time, numerical regularisation); ``tamsi`` is
  deprecated in Drake.
- Joints: URDF limits (Drake's joint limit constraints), no ``<dynamics>`` (no joint damping or
  friction: the collapse has none), our armature (reflected rotor inertia, [kg*m^2]) as the
  actuator's rotor inertia with gear ratio 1, zero actuation on every free joint.
- Self-collision: the link pairs of the shipped SRDF are filtered (Drake also filters bodies
  joined by a joint and merges welded ones).

Output, one row per ``--dt``: rest time (first 2 ms sample after the last one with a joint speed
>= 1e-3 rad/s; "-": still moving at the end), shoulder, elbow1, elbow2 at the end [rad], deepest
point-contact penetration over the 2 ms samples [m], wall time of the stepping [s].

Usage, two steps with two Pythons (Drake is not a packbot dependency; tested with drake 1.51.1):

    /tmp/venv/bin/python benchmarks/drake_reference.py export /tmp/drake_ref
    /tmp/venv-drake/bin/python benchmarks/drake_reference.py run /tmp/drake_ref \\
        --approx lagged --dt 1e-4 5e-5 --duration 3

``export`` (packbot's Python) writes DIR/packbot_drake.urdf, the OBJ meshes and
DIR/packbot_drake.json (joint names, drive q, armature, welded angles, SRDF pairs, gravity);
``run`` (a Python with pydrake, which it imports only there) reads them and prints the table.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

log = logging.getLogger("drake_reference")

URDF_NAME = "packbot_drake.urdf"
JSON_NAME = "packbot_drake.json"
#: The collapse's initial pose.
POSE = "drive"
#: Joints printed in the table.
ARM_JOINTS = ("shoulder", "elbow1", "elbow2")
#: Drake's discrete contact approximations, by command-line name.
APPROXIMATIONS = ("lagged", "similar", "sap", "tamsi")
#: Sampling interval of the rest and penetration checks [s].
SAMPLE_DT = 2e-3
#: Joint speed below which the arm counts as at rest [rad/s].
REST_SPEED = 1e-3

_DRAKE_NS = "http://drake.mit.edu"
_D = "{" + _DRAKE_NS + "}"
#: Drake's note on every floor registration (no deformable bodies here): not shown.
_HALF_SPACE_NOTE = "half spaces are not currently supported for deformable contact"
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


# ----------------------------------------------------------------------------------------------
# export (packbot's Python)


def _stl_triangles(path: Path) -> NDArray[np.float64]:
    """Triangles (T, 3, 3) [m] of a binary STL file.

    Raises:
        ModelError: The file is not a binary STL.
    """
    from packbot.errors import ModelError

    data = path.read_bytes()
    count = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0]) if len(data) >= 84 else -1
    if count < 0 or len(data) != 84 + _STL_RECORD.itemsize * count:
        raise ModelError(f"{path}: not a binary STL ({len(data)} bytes, header count {count})")
    records = np.frombuffer(data, dtype=_STL_RECORD, count=count, offset=84)
    return records["vertices"].astype(float)


def _write_obj(triangles: NDArray[np.float64], path: Path) -> None:
    """Write triangles (T, 3, 3) [m] as an OBJ with shared vertices."""
    verts, inverse = np.unique(np.round(triangles.reshape(-1, 3), 9), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3) + 1
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in verts.tolist()]
    lines += [f"f {a} {b} {c}" for a, b, c in faces.tolist()]
    path.write_text("\n".join(lines) + "\n")


def _weld(joint: ET.Element, angle: float) -> None:
    """Make a revolute URDF joint fixed at ``angle`` [rad] (rotation folded into its origin)."""
    import pinocchio as pin

    origin = joint.find("origin")
    if origin is None:
        origin = ET.SubElement(joint, "origin")
    rpy = [float(x) for x in origin.attrib.get("rpy", "0 0 0").split()]
    axis_el = joint.find("axis")
    xyz = axis_el.attrib.get("xyz", "1 0 0") if axis_el is not None else "1 0 0"
    axis = np.array([float(x) for x in xyz.split()])
    rot = pin.rpy.rpyToMatrix(*rpy) @ pin.exp3(axis / np.linalg.norm(axis) * angle)
    origin.attrib["rpy"] = " ".join(repr(float(x)) for x in pin.rpy.matrixToRpy(rot))
    joint.attrib["type"] = "fixed"
    for tag in ("axis", "limit", "mimic", "safety_controller", "calibration"):
        for el in joint.findall(tag):
            joint.remove(el)


def drake_urdf(urdf: Path, out: Path, welded: dict[str, float]) -> str:
    """Drake's copy of a packbot URDF; writes the collision meshes as OBJ files into ``out``.

    Args:
        urdf: Our URDF (meshes in ``urdf.parent / "meshes"``).
        out: Output folder of the OBJ files.
        welded: Joint name -> angle [rad] of the joints made fixed.

    Returns:
        The URDF text: no visuals, no ``<dynamics>``, no transmissions, collision meshes as
        convex OBJ files named relative to ``out``, unique collision names ``link__part``.

    Raises:
        ModelError: A collision that is not a mesh, or a mesh that is not a binary STL.
    """
    from packbot.errors import ModelError

    ET.register_namespace("drake", _DRAKE_NS)
    root = ET.fromstring(urdf.read_text())
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        for col in link.findall("collision"):
            mesh = col.find("geometry/mesh")
            if mesh is None:
                raise ModelError(f"{urdf}: link {link.attrib['name']}: collision is not a mesh")
            stl = urdf.parent / "meshes" / Path(mesh.attrib["filename"]).name
            obj = out / (stl.stem + ".obj")
            _write_obj(_stl_triangles(stl), obj)
            mesh.attrib["filename"] = obj.name
            ET.SubElement(mesh, _D + "declare_convex")
            col.attrib["name"] = f"{link.attrib['name']}__{col.attrib.get('name', 'collision')}"
    for joint in root.iter("joint"):
        for dyn in joint.findall("dynamics"):
            joint.remove(dyn)
        if joint.attrib["name"] in welded:
            _weld(joint, welded[joint.attrib["name"]])
    for transmission in root.findall("transmission"):
        root.remove(transmission)
    return ET.tostring(root, encoding="unicode")


def srdf_pairs(path: Path) -> list[tuple[str, str]]:
    """Link pairs of an SRDF's ``<disable_collisions>`` elements."""
    root = ET.parse(path).getroot()
    return [(e.attrib["link1"], e.attrib["link2"]) for e in root.iter("disable_collisions")]


def export(out: Path) -> None:
    """Write the Drake URDF, its OBJ meshes and the JSON sidecar into ``out``."""
    import packbot
    from packbot.collision import SRDF_NAME
    from packbot.mujoco_model import WRIST_JOINTS

    robot = packbot.load_robot()
    q0 = robot.pose(POSE)
    names = list(robot.joint_names)
    welded = {j: float(q0[names.index(j)]) for j in WRIST_JOINTS}
    out.mkdir(parents=True, exist_ok=True)
    (out / URDF_NAME).write_text(drake_urdf(robot.urdf_path, out, welded) + "\n")
    sidecar = {
        "source_urdf": str(robot.urdf_path),
        "pose": POSE,
        "joint_names": names,
        "q0": q0.tolist(),
        "armature": robot.params.armature.tolist(),
        "welded": welded,
        "gravity": robot.model.gravity.linear.tolist(),
        "srdf_pairs": srdf_pairs(robot.urdf_path.parent / SRDF_NAME),
    }
    (out / JSON_NAME).write_text(json.dumps(sidecar, indent=1) + "\n")
    n_obj = len(list(out.glob("*.obj")))
    print(f"wrote {out / URDF_NAME}, {out / JSON_NAME} and {n_obj} OBJ meshes")


# ----------------------------------------------------------------------------------------------
# run (Drake's Python)


@dataclass(kw_only=True)
class ContactSettings:
    """Drake contact settings of one run.

    Attributes:
        approx: Discrete contact approximation, one of :data:`APPROXIMATIONS`.
        dt: Plant time step [s].
        mu: Coulomb friction coefficient (static = dynamic).
        stiffness: Point-contact stiffness of a pair [N/m].
        dissipation: Hunt-Crossley dissipation [s/m].
        stiction: Stiction tolerance (friction regularisation speed) [m/s].
    """

    approx: str
    dt: float
    mu: float
    stiffness: float
    dissipation: float
    stiction: float


@dataclass(kw_only=True)
class Row:
    """Result of one collapse.

    Attributes:
        rest: Rest time [s], None if still moving at the end.
        q_arm: Final shoulder, elbow1, elbow2 [rad].
        penetration: Deepest point-contact penetration over the samples [m].
        wall: Wall time of the stepping [s].
    """

    rest: float | None
    q_arm: tuple[float, ...]
    penetration: float
    wall: float


def _contact_urdf(folder: Path, s: ContactSettings) -> str:
    """The exported URDF with absolute mesh paths and proximity properties on every collision."""
    root = ET.parse(folder / URDF_NAME).getroot()
    for mesh in root.iter("mesh"):
        mesh.attrib["filename"] = (folder / mesh.attrib["filename"]).resolve().as_uri()
    for col in root.iter("collision"):
        props = ET.SubElement(col, _D + "proximity_properties")
        for tag, value in (
            ("mu_dynamic", s.mu),
            ("mu_static", s.mu),
            ("point_contact_stiffness", 2.0 * s.stiffness),
            ("hunt_crossley_dissipation", s.dissipation),
        ):
            ET.SubElement(props, _D + tag, {"value": repr(value)})
    ET.register_namespace("drake", _DRAKE_NS)
    return ET.tostring(root, encoding="unicode")


def collapse(folder: Path, side: dict[str, Any], s: ContactSettings, duration: float) -> Row:
    """Build the Drake model from an export folder and run the collapse.

    Args:
        folder: Folder written by ``export``.
        side: Its JSON sidecar.
        s: Contact settings.
        duration: Simulated time [s].

    Returns:
        The table row.
    """
    from pydrake.geometry import (
        AddContactMaterial,
        CollisionFilterDeclaration,
        GeometrySet,
        HalfSpace,
        ProximityProperties,
    )
    from pydrake.math import RigidTransform
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import (
        AddMultibodyPlantSceneGraph,
        ContactModel,
        CoulombFriction,
        DiscreteContactApproximation,
    )
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    approx = {
        "lagged": DiscreteContactApproximation.kLagged,
        "similar": DiscreteContactApproximation.kSimilar,
        "sap": DiscreteContactApproximation.kSap,
        "tamsi": DiscreteContactApproximation.kTamsi,
    }[s.approx]
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=s.dt)
    plant.set_contact_model(ContactModel.kPoint)
    plant.set_discrete_contact_approximation(approx)
    plant.set_stiction_tolerance(s.stiction)
    plant.mutable_gravity_field().set_gravity_vector(np.asarray(side["gravity"], dtype=float))
    Parser(plant).AddModelsFromString(_contact_urdf(folder, s), "urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
    floor = ProximityProperties()
    AddContactMaterial(
        dissipation=s.dissipation,
        point_stiffness=2.0 * s.stiffness,
        friction=CoulombFriction(s.mu, s.mu),
        properties=floor,
    )
    plant.RegisterCollisionGeometry(
        plant.world_body(), RigidTransform(), HalfSpace(), "floor", floor
    )
    names: list[str] = side["joint_names"]
    free = [n for n in names if n not in side["welded"]]
    for name in free:
        actuator = plant.AddJointActuator(f"{name}_actuator", plant.GetJointByName(name))
        actuator.set_default_rotor_inertia(side["armature"][names.index(name)])
        actuator.set_default_gear_ratio(1.0)
    plant.Finalize()
    filters = scene_graph.collision_filter_manager()
    n_filtered = 0
    for a, b in side["srdf_pairs"]:
        ga = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(a))
        gb = plant.GetCollisionGeometriesForBody(plant.GetBodyByName(b))
        if ga and gb:
            filters.Apply(
                CollisionFilterDeclaration().ExcludeBetween(GeometrySet(ga), GeometrySet(gb))
            )
            n_filtered += 1
    log.info(
        "%s, dt %g s: %d free joints, %d SRDF pairs filtered",
        s.approx,
        s.dt,
        len(free),
        n_filtered,
    )
    zero = builder.AddSystem(ConstantVectorSource(np.zeros(plant.num_actuated_dofs())))
    builder.Connect(zero.get_output_port(), plant.get_actuation_input_port())
    diagram = builder.Build()

    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    index = [plant.GetJointByName(n).position_start() for n in free]
    q = np.zeros(plant.num_positions())
    q[index] = [side["q0"][names.index(n)] for n in free]
    plant.SetPositions(plant_context, q)
    plant.SetVelocities(plant_context, np.zeros(plant.num_velocities()))
    simulator = Simulator(diagram, context)
    simulator.Initialize()
    contacts = plant.get_contact_results_output_port()

    n_samples = max(1, round(duration / SAMPLE_DT))
    last_moving = 0.0
    penetration = 0.0
    start = time.perf_counter()
    for i in range(1, n_samples + 1):
        t = i * SAMPLE_DT
        simulator.AdvanceTo(t)
        if np.abs(plant.GetVelocities(plant_context)).max() >= REST_SPEED:
            last_moving = t
        results = contacts.Eval(plant_context)
        for c in range(results.num_point_pair_contacts()):
            depth = results.point_pair_contact_info(c).point_pair().depth
            penetration = max(penetration, depth)
    wall = time.perf_counter() - start
    q = plant.GetPositions(plant_context)
    q_arm = tuple(float(q[index[free.index(n)]]) for n in ARM_JOINTS)
    t_end = n_samples * SAMPLE_DT
    rest = None if last_moving >= t_end - 0.5 * SAMPLE_DT else last_moving + SAMPLE_DT
    return Row(rest=rest, q_arm=q_arm, penetration=penetration, wall=wall)


def run(folder: Path, settings: Sequence[ContactSettings], duration: float) -> None:
    """Print the table of collapses, one row per settings."""
    side = json.loads((folder / JSON_NAME).read_text())
    s0 = settings[0]
    print(
        f"Drake collapse from {side['pose']!r}, {duration:g} s: mu {s0.mu:g}, k {s0.stiffness:g}"
        f" N/m, d {s0.dissipation:g} s/m, stiction {s0.stiction:g} m/s"
        f" (load {os.getloadavg()[0]:.2f})"
    )
    head = (
        f"{'approx':<8}{'dt[s]':>9}{'rest[s]':>9}{'shoulder':>9}{'elbow1':>8}{'elbow2':>8}"
        f"{'pen[m]':>10}{'wall[s]':>8}"
    )
    print(head)
    print("-" * len(head))
    for s in settings:
        row = collapse(folder, side, s, duration)
        rest = "-" if row.rest is None else f"{row.rest:.3f}"
        shoulder, elbow1, elbow2 = row.q_arm
        print(
            f"{s.approx:<8}{s.dt:>9.2g}{rest:>9}{shoulder:9.4f}{elbow1:8.4f}{elbow2:8.4f}"
            f"{row.penetration:10.2e}{row.wall:8.2f}",
            flush=True,
        )


# ----------------------------------------------------------------------------------------------
# command line


def _positive(text: str) -> float:
    value = float(text)
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite positive number")
    return value


def _non_negative(text: str) -> float:
    value = float(text)
    if not np.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number >= 0")
    return value


def main(argv: list[str] | None = None) -> None:
    """Command line: ``export DIR`` or ``run DIR [options]`` (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-v", "--verbose", action="store_true", help="log model details")
    sub = ap.add_subparsers(dest="command", required=True)
    p_export = sub.add_parser("export", help="write the Drake model (packbot's Python)")
    p_export.add_argument("dir", type=Path, help="output folder")
    p_run = sub.add_parser("run", help="run the collapse (Drake's Python)")
    p_run.add_argument("dir", type=Path, help="folder written by export")
    p_run.add_argument("--approx", choices=APPROXIMATIONS, default="lagged")
    p_run.add_argument(
        "--dt", type=_positive, nargs="+", default=[1e-4], help="time step(s) [s], one row each"
    )
    p_run.add_argument("--mu", type=_non_negative, default=0.5, help="Coulomb friction")
    p_run.add_argument("--stiffness", type=_positive, default=1e6, help="pair stiffness [N/m]")
    p_run.add_argument(
        "--dissipation", type=_non_negative, default=20.0, help="Hunt-Crossley d [s/m]"
    )
    p_run.add_argument("--stiction", type=_positive, default=1e-4, help="stiction tol. [m/s]")
    p_run.add_argument("--duration", type=_positive, default=3.0, help="simulated time [s]")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING)
    logging.getLogger("drake").addFilter(lambda r: _HALF_SPACE_NOTE not in r.getMessage())

    if args.command == "export":
        try:
            import packbot  # noqa: F401
        except ImportError:
            p_export.error("needs packbot: run it with packbot's Python")
        export(args.dir)
        return
    try:
        import pydrake  # noqa: F401
    except ImportError:
        p_run.error("needs pydrake: run it with a Python where Drake is installed")
    for name in (URDF_NAME, JSON_NAME):
        if not (args.dir / name).is_file():
            p_run.error(f"DIR {args.dir}: no {name}; write it first with `export {args.dir}`")
    settings = [
        ContactSettings(
            approx=args.approx,
            dt=dt,
            mu=args.mu,
            stiffness=args.stiffness,
            dissipation=args.dissipation,
            stiction=args.stiction,
        )
        for dt in args.dt
    ]
    run(args.dir, settings, args.duration)


if __name__ == "__main__":
    main()
