"""The shipped description package opens in other tools with no packbot code but the path helpers.

Plain Pinocchio reads the URDF (``package://packbot/...`` meshes through ``package_dirs``) and the
SRDF; the SRDF follows MoveIt's rules for groups and named states; plain MuJoCo reads the MJCF.
"""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.resources import DESCRIPTION_PACKAGE, mjcf_path, srdf_path

URDF_JOINTS = (
    "turret",
    "shoulder",
    "elbow1",
    "elbow2",
    "camera_tilt",
    "camera_pan",
    "gripper_roll",
    "gripper_jaw",
)


def _plain_pinocchio(urdf: Path, dirs: list[str]) -> tuple[pin.Model, pin.GeometryModel]:
    model, collision, _visual = pin.buildModelsFromUrdf(str(urdf), package_dirs=dirs)
    return model, collision


# ------------------------------------------------------------------------------ the package


def test_package_xml_names_the_package_as_the_mesh_uris_do():
    pkg = packbot.urdf_path().parent
    assert pkg.name == DESCRIPTION_PACKAGE
    manifest = ET.parse(pkg / "package.xml").getroot()
    assert manifest.tag == "package" and manifest.attrib["format"] == "3"
    assert manifest.findtext("name") == DESCRIPTION_PACKAGE
    uris = {m.attrib["filename"] for m in ET.parse(packbot.urdf_path()).getroot().iter("mesh")}
    assert uris and all(u.startswith(f"package://{DESCRIPTION_PACKAGE}/meshes/") for u in uris)
    for d in packbot.package_dirs():  # package://packbot/X is <dir>/packbot/X
        for uri in uris:
            assert (Path(d) / uri.removeprefix("package://")).is_file(), uri


def test_plain_pinocchio_loads_the_urdf_like_load_robot():
    model, collision = _plain_pinocchio(packbot.urdf_path(), packbot.package_dirs())
    robot = packbot.load_robot()
    assert tuple(model.names)[1:] == URDF_JOINTS == tuple(robot.joint_names)
    assert collision.ngeoms == robot.collision_model.ngeoms == 25
    for i in range(model.njoints):
        assert model.inertias[i] == robot.model.inertias[i]
        assert model.jointPlacements[i] == robot.model.jointPlacements[i]
    np.testing.assert_array_equal(model.lowerPositionLimit, robot.model.lowerPositionLimit)
    np.testing.assert_array_equal(model.upperPositionLimit, robot.model.upperPositionLimit)
    for go, ours in zip(
        collision.geometryObjects, robot.collision_model.geometryObjects, strict=True
    ):
        assert go.parentJoint == ours.parentJoint and go.placement == ours.placement
        assert Path(go.meshPath).is_file()


def test_plain_pinocchio_without_package_dirs_reports_the_missing_mesh():
    """The failure the package fixes: the package's own folder is not a package directory."""
    with pytest.raises((ValueError, RuntimeError), match="could not be found"):
        _plain_pinocchio(packbot.urdf_path(), [str(packbot.urdf_path().parent)])


def test_a_copied_package_loads_from_its_new_parent(tmp_path):
    """robot_descriptions-style: copy the package folder anywhere, pass its parent."""
    shutil.copytree(packbot.urdf_path().parent, tmp_path / DESCRIPTION_PACKAGE)
    urdf = tmp_path / DESCRIPTION_PACKAGE / packbot.urdf_path().name
    _, collision = _plain_pinocchio(urdf, [str(tmp_path)])
    assert all(Path(go.meshPath).is_relative_to(tmp_path) for go in collision.geometryObjects)


def test_plain_pinocchio_reads_the_srdf_pairs_and_named_poses():
    model, collision = _plain_pinocchio(packbot.urdf_path(), packbot.package_dirs())
    collision.addAllCollisionPairs()
    before = len(collision.collisionPairs)
    pin.removeCollisionPairs(model, collision, str(srdf_path()))
    assert 0 < len(collision.collisionPairs) < before
    pin.loadReferenceConfigurations(model, str(srdf_path()), False)
    robot = packbot.load_robot()
    loaded = {item.key(): np.array(item.data()) for item in model.referenceConfigurations}
    assert set(loaded) == set(robot.poses)
    for name, q in robot.poses.items():  # the whole-body state comes first, Pinocchio keeps it
        np.testing.assert_array_equal(loaded[name], q)


# ------------------------------------------------------------------------ SRDF (MoveIt rules)


def _groups(root: ET.Element) -> dict[str, set[str]]:
    """Group name -> its joints, subgroups expanded (MoveIt's semantics)."""
    direct = {g.attrib["name"]: g for g in root.findall("group")}

    def joints(name: str, seen: frozenset[str] = frozenset()) -> set[str]:
        assert name in direct and name not in seen, f"undefined or cyclic group {name!r}"
        g = direct[name]
        out = {j.attrib["name"] for j in g.findall("joint")}
        for sub in g.findall("group"):
            out |= joints(sub.attrib["name"], seen | {name})
        return out

    return {name: joints(name) for name in direct}


def test_srdf_groups_exist_and_name_urdf_joints():
    root = ET.parse(srdf_path()).getroot()
    groups = _groups(root)
    assert {"arm", "gripper", "camera"} <= set(groups)
    assert groups["arm"] == {"turret", "shoulder", "elbow1", "elbow2"}
    assert groups["gripper"] == {"gripper_roll", "gripper_jaw"}
    assert groups["camera"] == {"camera_tilt", "camera_pan"}
    urdf_joints = {j.attrib["name"] for j in ET.parse(packbot.urdf_path()).getroot().iter("joint")}
    for name, joints in groups.items():
        assert joints and joints <= urdf_joints, name


def test_every_srdf_state_sets_only_and_all_joints_of_a_defined_group():
    root = ET.parse(srdf_path()).getroot()
    groups = _groups(root)
    robot = packbot.load_robot()
    states = root.findall("group_state")
    assert {s.attrib["name"] for s in states} == set(robot.poses)
    for state in states:
        group = state.attrib["group"]
        assert group in groups, f"state {state.attrib['name']} uses undefined group {group}"
        values = {j.attrib["name"]: float(j.attrib["value"]) for j in state.findall("joint")}
        assert set(values) == groups[group], (state.attrib["name"], group)
        q = robot.poses[state.attrib["name"]]
        for joint, v in values.items():
            assert v == pytest.approx(q[robot.joint_names.index(joint)], abs=1e-12)
    for group in ("arm", "gripper", "camera"):  # every pose is reachable by every group
        names = {s.attrib["name"] for s in states if s.attrib["group"] == group}
        assert names == set(robot.poses), group


def test_srdf_disabled_pairs_name_urdf_links():
    root = ET.parse(srdf_path()).getroot()
    links = {e.attrib["name"] for e in ET.parse(packbot.urdf_path()).getroot().iter("link")}
    pairs = root.findall("disable_collisions")
    assert pairs
    for p in pairs:
        assert {p.attrib["link1"], p.attrib["link2"]} <= links


# --------------------------------------------------------------------------------- MJCF


def test_plain_mujoco_loads_the_mjcf_with_our_joints_armature_and_pairs():
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(mjcf_path()))
    robot = packbot.load_robot()
    names = tuple(model.joint(i).name for i in range(model.njnt))
    assert names == tuple(robot.joint_names)
    assert all(model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE for i in range(model.njnt))
    np.testing.assert_allclose(model.dof_armature, robot.params.armature, rtol=1e-12)
    np.testing.assert_allclose(model.dof_damping, robot.params.viscous, rtol=1e-12)
    np.testing.assert_allclose(model.dof_frictionloss, robot.params.coulomb, rtol=1e-12)
    np.testing.assert_allclose(model.jnt_range[:, 0], robot.params.lower, rtol=1e-12)
    np.testing.assert_allclose(model.jnt_range[:, 1], robot.params.upper, rtol=1e-12)
    body = {model.body(i).name: i for i in range(model.nbody)}
    excluded = {
        frozenset((int(model.exclude_signature[k]) >> 16, int(model.exclude_signature[k]) & 0xFFFF))
        for k in range(model.nexclude)
    }
    srdf = ET.parse(srdf_path()).getroot().findall("disable_collisions")
    assert excluded == {frozenset((body[p.attrib["link1"]], body[p.attrib["link2"]])) for p in srdf}
    child = {  # moving joint -> its child link
        j.attrib["name"]: j.find("child").attrib["link"]  # type: ignore[union-attr]
        for j in ET.parse(packbot.urdf_path()).getroot().iter("joint")
        if j.attrib["type"] != "fixed"
    }
    assert model.body_mass[body["base_link"]] == pytest.approx(robot.model.inertias[0].mass)
    for i, joint in enumerate(robot.joint_names, start=1):  # each link's mass equals the URDF's
        mass = robot.model.inertias[i].mass
        assert model.body_mass[body[child[joint]]] == pytest.approx(mass, rel=1e-9)


def test_the_mjcf_has_a_torque_motor_per_joint_at_its_effort_limit():
    """nu = 8 motors named as their joints, gear 1, ctrl and force within +/- the effort limit;
    a ctrl on the turret (vertical axis: no gravity torque) turns it, a zero ctrl does not, a
    ctrl beyond the limit applies the limit."""
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(mjcf_path()))
    robot = packbot.load_robot()
    effort = np.asarray(robot.params.effort, dtype=float)
    assert model.nu == model.njnt == len(robot.joint_names)
    assert "<motor " in mjcf_path().read_text()
    for i, name in enumerate(robot.joint_names):
        a = model.actuator(name)
        assert model.actuator_trntype[a.id] == mujoco.mjtTrn.mjTRN_JOINT
        assert model.actuator_trnid[a.id, 0] == model.joint(name).id
        assert model.actuator_gear[a.id, 0] == 1.0
        assert model.actuator_gaintype[a.id] == mujoco.mjtGain.mjGAIN_FIXED
        assert model.actuator_gainprm[a.id, 0] == 1.0  # ctrl is the joint torque [N*m]
        assert model.actuator_biastype[a.id] == mujoco.mjtBias.mjBIAS_NONE
        np.testing.assert_allclose(model.actuator_ctrlrange[a.id], [-effort[i], effort[i]])
        np.testing.assert_allclose(model.actuator_forcerange[a.id], [-effort[i], effort[i]])
    turret = model.joint("turret").dofadr[0]

    def spin(torque: float) -> tuple[float, float]:
        data = mujoco.MjData(model)
        data.qpos[:] = robot.pose("stand")
        data.ctrl[model.actuator("turret").id] = torque
        for _ in range(200):  # 0.1 s
            mujoco.mj_step(model, data)
        return float(data.qvel[turret]), float(data.actuator_force[model.actuator("turret").id])

    speed, force = spin(30.0)
    assert speed > 0.1 and force == pytest.approx(30.0)  # [rad/s] after 0.1 s at 30 N*m
    # no torque: held by its friction (1.5 N*m, MuJoCo's soft frictionloss creeps a little
    # while the arm above it falls)
    assert abs(spin(0.0)[0]) < 0.01 * speed
    assert spin(1e4)[1] == pytest.approx(effort[0])  # clamped to ctrlrange: the limit


RENDER = """
import sys
import mujoco
m = mujoco.MjModel.from_xml_path(sys.argv[1])
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
with mujoco.Renderer(m, 240, 320) as r:
    r.update_scene(d)
    img = r.render()
print(img.shape[0], img.shape[1], float(img.std()), float(img.mean()))
"""


def test_the_mjcf_has_lights_and_renders_where_opengl_is():
    """A headlight and a directional sun; mujoco.Renderer draws a lit, non-blank image with
    the first OpenGL backend that works here (osmesa, then egl: skipped without either)."""
    import os
    import subprocess
    import sys

    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_path(str(mjcf_path()))
    assert model.vis.headlight.active == 1 and model.vis.headlight.diffuse[0] > 0
    assert model.nlight >= 1 and model.light_dir[0][2] < 0  # shining down
    reasons = []
    for backend in ("osmesa", "egl"):
        env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
        done = subprocess.run(
            [sys.executable, "-c", RENDER, str(mjcf_path())],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        if done.returncode == 0:
            h, w, std, mean = (float(x) for x in done.stdout.split())
            assert (h, w) == (240, 320)
            assert std > 5.0 and 10.0 < mean < 245.0, (std, mean)  # not blank, not black
            return
        reasons.append(f"{backend}: {done.stderr.strip().splitlines()[-1:]}")
    pytest.skip(f"no OpenGL backend for mujoco.Renderer here ({'; '.join(reasons)})")


def test_generate_model_writes_the_package_and_its_mjcf(tmp_path):
    pytest.importorskip("mujoco")
    from packbot.urdfgen import generate

    pkg = tmp_path / "urdf" / DESCRIPTION_PACKAGE
    pkg.mkdir(parents=True)
    shutil.copy(srdf_path(), pkg)  # the MJCF needs the SRDF (generate-srdf writes it)
    written = generate(tmp_path)
    assert {"package.xml", "CMakeLists.txt", "packbot_eod.urdf", "packbot_eod.xml"} <= {
        p.name for p in written
    }
    shipped = packbot.urdf_path().parent
    for name in ("package.xml", "CMakeLists.txt", "packbot_eod.urdf"):
        assert (pkg / name).read_bytes() == (shipped / name).read_bytes(), name
    # The MJCF is MuJoCo's own text: another MuJoCo release writes the same model in other words
    # (its version in the header first), so the shipped one is compared as a compiled model, as
    # `packbot generate-model --check` does.
    assert shipped / "packbot_eod.xml" not in generate(shipped.parents[1], check=True)
    assert generate(tmp_path, check=True) == []
    mjcf = pkg / "packbot_eod.xml"
    text = mjcf.read_text()
    # Another MuJoCo release may word the same model differently: the check compiles both.
    mjcf.write_text(text.replace("<mujoco", "<!-- written by another MuJoCo -->\n<mujoco", 1))
    assert generate(tmp_path, check=True) == []
    assert 'armature="0.132"' in text
    mjcf.write_text(text.replace('armature="0.132"', 'armature="0.1"'))
    assert generate(tmp_path, check=True) == [mjcf]


def test_generate_model_skips_the_mjcf_without_an_srdf(tmp_path, caplog):
    from packbot.urdfgen import generate

    written = generate(tmp_path)
    assert (tmp_path / "urdf" / DESCRIPTION_PACKAGE / "package.xml") in written
    assert not (tmp_path / "urdf" / DESCRIPTION_PACKAGE / "packbot_eod.xml").exists()
    assert "generate-srdf" in caplog.text
