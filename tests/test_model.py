"""The model: URDF, inertias, kinematics against the DH tables, poses, generator round trip."""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot import params as P
from packbot.cli import main
from packbot.dh import chain_fk
from packbot.geometry import hull_triangles, part_inertia, stl_bytes
from packbot.params import Part
from packbot.resources import data_dir
from packbot.urdfgen import URDF_NAME, build, generate

REPO = Path(__file__).resolve().parents[1]

JOINT_NAMES = (
    "turret",
    "shoulder",
    "elbow1",
    "elbow2",
    "camera_tilt",
    "camera_pan",
    "gripper_roll",
    "gripper_jaw",
)


def test_urdf_loads_with_the_contract_joint_names(robot):
    assert robot.joint_names == JOINT_NAMES
    assert robot.model.nq == robot.model.nv == 8
    for name in JOINT_NAMES:
        assert robot.model.existJointName(name)
    assert robot.model.existFrame("gripper_tool")
    assert robot.model.existFrame("camera_optical")
    # several convex pieces per major link, each a coal.Convex
    per_link: dict[int, int] = {}
    for go in robot.collision_model.geometryObjects:
        assert type(go.geometry).__name__ == "Convex"
        per_link[go.parentJoint] = per_link.get(go.parentJoint, 0) + 1
    for joint in ("shoulder", "elbow1", "elbow2"):
        assert per_link[robot.model.getJointId(joint)] >= 3
    assert per_link[0] >= 6  # chassis: body, tracks, flippers, arm plate


def test_inertias_are_physical(robot):
    for i, inertia in enumerate(robot.model.inertias):
        if i == 0:
            continue
        assert inertia.mass > 0
        Ic = inertia.inertia
        np.testing.assert_allclose(Ic, Ic.T, atol=1e-15)
        ev = np.linalg.eigvalsh(Ic)
        assert ev.min() > 0, robot.model.names[i]
        a, b, c = ev
        assert a + b >= c * (1 - 1e-12), robot.model.names[i]  # triangle inequality


def test_part_inertia_matches_closed_forms():
    box = Part("b", "box", 2.0, (0.1, -0.2, 0.3), (0.3, 0.2, 0.1))
    inertia = part_inertia(box)
    np.testing.assert_allclose(inertia.lever, box.center, atol=1e-12)
    x, y, z = box.size
    expected = 2.0 / 12 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])
    np.testing.assert_allclose(inertia.inertia, expected, atol=1e-12)
    # hollow tube along x: closed form of a hollow cylinder, up to the 16-gon prism (< 3 %)
    ro, length, wall, m = 0.03, 0.5, 0.003, 0.45
    tube = part_inertia(Part("t", "tube", m, (0.0, 0.0, 0.0), (ro, length, wall), "x"))
    ri = ro - wall
    axial = m / 2 * (ro**2 + ri**2)
    transverse = m / 12 * (3 * (ro**2 + ri**2) + length**2)
    assert tube.mass == pytest.approx(m)
    np.testing.assert_allclose(np.diag(tube.inertia), [axial, transverse, transverse], rtol=0.03)


def test_total_mass_and_link_masses_match_table(robot):
    table_total = sum(part.mass for link in P.LINKS for part in link.parts)
    model_total = sum(inertia.mass for inertia in robot.model.inertias)
    assert model_total == pytest.approx(table_total, rel=1e-9)
    assert 29.0 <= model_total <= 31.5  # ~30 kg robot, 30.8 kg press figure
    arm = table_total - sum(p.mass for p in P.LINKS[0].parts)
    assert 10.0 <= arm + P.M_PLATE <= 13.0  # arm plus kit ~12 kg


def test_reach_matches_table(robot):
    data = robot.model.createData()
    q = np.zeros(robot.nq)  # arm straight out, horizontal
    pin.framesForwardKinematics(robot.model, data, q)
    tool = data.oMf[robot.model.getFrameId("gripper_tool")].translation
    turret_axis_x = P.MOUNT_X
    reach = tool[0] - turret_axis_x
    assert reach == pytest.approx(P.A_TURRET + P.L1 + P.L2 + P.L3, abs=1e-12)
    assert 1.83 <= reach <= 2.1  # > 6 ft (press), about 2 m (spec)
    assert P.L3 > P.L2  # the report's collapse result depends on it


def test_dh_forward_kinematics_equals_pinocchio(robot, rng):
    data = robot.model.createData()
    lo, hi = robot.params.lower, robot.params.upper
    for _ in range(100):
        q = rng.uniform(lo, hi)
        pin.framesForwardKinematics(robot.model, data, q)
        qd = dict(zip(robot.joint_names, q, strict=True))
        for chain, frame in P.TOOL_FRAMES.items():
            T = chain_fk(chain, qd)
            M = data.oMf[robot.model.getFrameId(frame)]
            np.testing.assert_allclose(T[:3, :3], M.rotation, atol=1e-9)
            np.testing.assert_allclose(T[:3, 3], M.translation, atol=1e-9)


def test_dh_check_can_fail(robot):
    """A perturbed DH table must disagree with the model (the comparison is not vacuous)."""
    from dataclasses import replace

    rows = list(P.CHAINS["gripper"])
    rows[1] = replace(rows[1], a=rows[1].a + 1e-3)
    data = robot.model.createData()
    q = robot.pose("stand")
    pin.framesForwardKinematics(robot.model, data, q)
    T = chain_fk("gripper", q, rows=rows)
    M = data.oMf[robot.model.getFrameId("gripper_tool")]
    assert np.abs(T[:3, 3] - M.translation).max() > 1e-4


def test_named_poses_within_limits(robot):
    assert {"drive", "stow", "stand", "high", "low"} <= set(robot.poses)
    for name in robot.poses:
        robot.check_within_limits(robot.pose(name), name)


def test_check_within_limits_names_the_joint(robot):
    q = robot.pose("drive")
    q[robot.params.index("elbow1")] = 4.0
    with pytest.raises(packbot.ConfigurationError, match="elbow1=4.0000"):
        robot.check_within_limits(q)


def test_unknown_pose_and_joint_list_valid_names(robot):
    with pytest.raises(packbot.UnknownNameError, match="valid pose names are: drive, high"):
        robot.pose("parked")
    with pytest.raises(packbot.UnknownNameError, match="elbow1, elbow2"):
        robot.q_from({"elbow3": 0.1})


def test_armature_reaches_the_mass_matrix(robot):
    arm = robot.params.armature
    np.testing.assert_allclose(arm, robot.params.gear_ratio**2 * robot.params.rotor_inertia)
    np.testing.assert_allclose(robot.model.armature, arm)
    q = robot.pose("stand")
    M = pin.crba(robot.model, robot.model.createData(), q)
    bare = robot.model.copy()
    bare.armature = np.zeros(robot.nq)
    M0 = pin.crba(bare, bare.createData(), q)
    M, M0 = np.triu(M) + np.triu(M, 1).T, np.triu(M0) + np.triu(M0, 1).T
    np.testing.assert_allclose(M - M0, np.diag(arm), atol=1e-12)


def test_urdf_dynamics_carry_friction_for_the_actuator_model(robot):
    np.testing.assert_allclose(robot.model.damping, robot.params.viscous)
    np.testing.assert_allclose(robot.model.friction, robot.params.coulomb)


def test_generated_files_match_committed():
    """The committed URDF, meshes and docs table equal the generator's output, and so do the
    files packbot actually loads (the installed wheel's copy, or the checkout's)."""
    gen = build()
    for urdf_dir in {REPO / "urdf" / "packbot", data_dir("urdf")}:
        assert (urdf_dir / URDF_NAME).read_text() == gen.urdf
        shipped = {p.name for p in (urdf_dir / "meshes").glob("*.stl")}
        assert shipped == set(gen.meshes)
        for name, data in gen.meshes.items():
            assert (urdf_dir / "meshes" / name).read_bytes() == data, name
    assert (REPO / "docs" / "parameters.md").read_text() == gen.parameters_md


def test_round_trip_check_detects_a_stale_file(tmp_path):
    generate(tmp_path)
    assert generate(tmp_path, check=True) == []
    urdf = tmp_path / "urdf" / "packbot" / URDF_NAME
    urdf.write_text(urdf.read_text().replace('effort="156"', 'effort="150"'))
    assert generate(tmp_path, check=True) == [urdf]
    assert main(["generate-model", "--check", "--root", str(tmp_path)]) == 1


def test_every_collision_piece_equals_its_hull(robot):
    from scipy.spatial import ConvexHull

    for go in robot.collision_model.geometryObjects:
        hull = go.geometry
        pts = np.array(hull.points())
        assert ConvexHull(pts).volume == pytest.approx(hull.computeVolume(), rel=1e-9)


def _write_robot_with_mesh(tmp_path: Path, tris: np.ndarray) -> Path:
    src = data_dir("urdf")
    (tmp_path / "meshes").mkdir()
    for f in (src / "meshes").glob("*.stl"):
        (tmp_path / "meshes" / f.name).write_bytes(f.read_bytes())
    (tmp_path / "meshes" / "link1__tube.stl").write_bytes(stl_bytes(tris))
    (tmp_path / URDF_NAME).write_text((src / URDF_NAME).read_text())
    return tmp_path / URDF_NAME


def test_non_convex_mesh_is_rejected_with_volumes(tmp_path):
    # an L-shaped prism: union of two boxes, not convex
    a = hull_triangles(np.array([[x, y, z] for x in (0, 2) for y in (0, 1) for z in (0, 1)], float))
    b = hull_triangles(np.array([[x, y, z] for x in (0, 1) for y in (1, 2) for z in (0, 1)], float))

    # stitch them into one closed surface: drop the shared-face triangles (on y = 1, x <= 1)
    def on_shared(t):
        return np.allclose(t[:, 1], 1.0) and t[:, 0].max() <= 1.0 + 1e-12

    tris = np.array([t for t in a if not on_shared(t)] + [t for t in b if not on_shared(t)])
    # the remaining part of a's y = 1 face (1 <= x <= 2) stays; the surface is closed
    path = _write_robot_with_mesh(tmp_path, tris * 0.05)
    with pytest.raises(packbot.ConvexityError, match="link1.*not convex.*differs from its hull"):
        packbot.load_robot(path)


def test_degenerate_mesh_is_rejected(tmp_path):
    flat = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [0, 1, 0], [1, 1, 0]]], float)
    path = _write_robot_with_mesh(tmp_path, flat)
    with pytest.raises(packbot.ConvexityError, match="link1"):
        packbot.load_robot(path)


def test_missing_urdf_is_a_resource_error(tmp_path):
    with pytest.raises(packbot.ResourceNotFound, match="nothing.urdf"):
        packbot.load_robot(tmp_path / "nothing.urdf")


def test_cli_info_and_help(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    for name in JOINT_NAMES:
        assert name in out
    assert "drive" in out and "total" in out
    assert main([]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0


def test_cli_generate_model_check():
    assert main(["generate-model", "--check", "--root", str(REPO)]) == 0


def test_system_energy_is_half_v_m_v_plus_potential(robot, rng):
    """System.energy (Pinocchio's O(n) kinetic energy) is 0.5 v^T M v with the armature in M,
    plus the potential energy, on the full and on a reduced model."""
    from packbot.system import System

    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    for locked in ((), ("gripper_jaw", "camera_pan")):
        cfg = packbot.SimConfig(locked_joints=locked)
        sysm = System(robot, robot.pose("drive"), cfg, None)
        assert float(np.abs(sysm.model.armature).max()) > 0.0
        for _ in range(20):
            q = sysm.reduce(rng.uniform(lo, hi))
            v = rng.standard_normal(sysm.nv)
            M = sysm.mass_matrix(q)
            ref = 0.5 * v @ M @ v + pin.computePotentialEnergy(sysm.model, sysm.data, q)
            assert sysm.energy(q, v) == pytest.approx(ref, rel=1e-12, abs=1e-12)


def test_system_mass_matrix_and_inverse_are_full_symmetric_matrices(robot, rng):
    """System.mass_matrix and System.minv fill the lower triangle that Pinocchio leaves out,
    from the upper one: M^T = M, M^-1 M = I, on the full and on reduced models (nv 8, 6, 1)."""
    from packbot.system import System

    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    names = robot.joint_names
    for locked in ((), ("gripper_jaw", "camera_pan"), tuple(names[1:])):
        sysm = System(robot, robot.pose("drive"), packbot.SimConfig(locked_joints=locked), None)
        for _ in range(10):
            q = sysm.reduce(rng.uniform(lo, hi))
            M, Mi = sysm.mass_matrix(q), sysm.minv(q)
            upper = pin.crba(sysm.model, sysm.data, q)
            iu = np.triu_indices(sysm.nv)
            np.testing.assert_array_equal(M[iu], np.asarray(upper).reshape(sysm.nv, -1)[iu])
            np.testing.assert_array_equal(M, M.T)
            np.testing.assert_array_equal(Mi, Mi.T)
            np.testing.assert_allclose(Mi @ M, np.eye(sysm.nv), atol=1e-9)
