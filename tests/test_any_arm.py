"""Arms other than PackBot: loaded from their URDF (a two-link arm written here, UR5 and Panda
from example-robot-data), simulated, checked against an independent integration and physics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

import packbot
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.errors import (
    ConfigurationError,
    JointError,
    MeshError,
    ResourceNotFound,
    UnknownNameError,
)
from packbot.robots import ROBOTS, robot_files

LINK = """
  <link name="{name}">
    <inertial><origin xyz="0 0 {c}"/><mass value="{m}"/>
      <inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{j}"/></inertial>
    <collision><origin xyz="0 0 {c}"/><geometry>{shape}</geometry></collision>
  </link>"""

JOINT = """
  <joint name="{name}" type="{kind}">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="0 0 {z}"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="50" velocity="10"/>{dynamics}
  </joint>"""


def two_link_urdf(kind: str = "revolute", dynamics: str = "", mesh: str = "") -> str:
    """Two links of 0.4 m hanging from joint1 at 1 m (a box base, a cylinder, a sphere)."""
    base = '<box size="0.2 0.2 0.1"/>'
    links = [
        LINK.format(name="base", c=0.05, m=5.0, i=0.02, j=0.02, shape=base),
        LINK.format(
            name="upper",
            c=-0.2,
            m=2.0,
            i=0.03,
            j=0.004,
            shape=mesh or '<cylinder radius="0.04" length="0.4"/>',
        ),
        LINK.format(name="fore", c=-0.2, m=1.0, i=0.015, j=0.002, shape='<sphere radius="0.05"/>'),
        '\n  <link name="tip"/>',
    ]
    joints = [
        JOINT.format(
            name="joint1", kind=kind, parent="base", child="upper", z=1.0, dynamics=dynamics
        ),
        JOINT.format(
            name="joint2", kind="revolute", parent="upper", child="fore", z=-0.4, dynamics=""
        ),
        '\n  <joint name="tip_joint" type="fixed"><parent link="fore"/><child link="tip"/>'
        '<origin xyz="0 0 -0.4"/></joint>',
    ]
    return '<robot name="two_link">' + "".join(links) + "".join(joints) + "\n</robot>\n"


@pytest.fixture()
def two_link(tmp_path):
    path = tmp_path / "two_link.urdf"
    path.write_text(two_link_urdf(dynamics='\n    <dynamics damping="0.1" friction="0.2"/>'))
    return packbot.load_robot(path)


def test_a_two_link_arm_loads_with_its_urdf_data(two_link) -> None:
    r = two_link
    assert r.joint_names == ("joint1", "joint2")
    assert not r.is_packbot
    assert r.tool_frame == "tip"
    np.testing.assert_array_equal(r.params.lower, [-3.0, -3.0])
    np.testing.assert_array_equal(r.params.effort, [50.0, 50.0])
    np.testing.assert_array_equal(r.params.viscous, [0.1, 0.0])  # <dynamics damping>
    np.testing.assert_array_equal(r.params.coulomb, [0.2, 0.0])  # <dynamics friction>
    np.testing.assert_array_equal(r.params.armature, [0.0, 0.0])
    assert set(r.poses) == {"zero", "middle"}
    assert r.srdf_path is None


def test_primitives_become_convex_pieces_of_their_volume(two_link) -> None:
    vols = {
        str(g.name): float(g.geometry.computeVolume())
        for g in two_link.collision_model.geometryObjects
    }
    assert all(
        type(g.geometry).__name__ == "Convex" for g in two_link.collision_model.geometryObjects
    )
    assert vols["base/0"] == pytest.approx(0.2 * 0.2 * 0.1, rel=1e-9)
    n = 16  # a 16-gon prism inscribed in the cylinder: (n/2) r^2 sin(2 pi / n) h
    assert vols["upper/0"] == pytest.approx(n / 2 * 0.04**2 * np.sin(2 * np.pi / n) * 0.4, rel=1e-9)
    sphere = 4 / 3 * np.pi * 0.05**3
    assert 0.9 * sphere < vols["fore/0"] < sphere  # inside the sphere, close to it


def test_free_motion_matches_an_independent_integration_of_pinocchios_aba(two_link) -> None:
    """No contact, no limit reached: the arm swings as Pinocchio's ABA says, to 1e-6 rad (joint
    friction is off by default: the URDF's damping and friction act with joint_friction)."""
    r = two_link
    q0 = np.array([0.6, -0.4])
    cfg = packbot.SimConfig(contact_mode="none", rtol=1e-10, atol=1e-12, sample_dt=0.05)
    res = packbot.simulate(r, q0, np.zeros(2), 1.0, config=cfg)
    model = r.model.copy()
    data = model.createData()

    def f(_t, y):
        q, v = y[:2], y[2:]
        return np.concatenate([v, pin.aba(model, data, q, v, np.zeros(2))])

    y0 = np.concatenate([q0, np.zeros(2)])
    ref = solve_ivp(f, (0.0, 1.0), y0, dense_output=True, rtol=1e-12, atol=1e-12)
    assert np.abs(res.q - ref.sol(res.t)[:2].T).max() < 1e-6
    assert np.abs(res.q).max() < 3.0  # (no limit reached: the check is of free motion)


def test_armature_from_a_mapping_or_a_sidecar_file(tmp_path) -> None:
    """``armature=`` (joint -> kg*m^2, or a TOML sidecar's ``[armature]``) is added to M's
    diagonal, and the arm swings as Pinocchio's ABA with that armature says; bad values are
    named."""
    path = tmp_path / "arm.urdf"
    path.write_text(two_link_urdf())
    plain = packbot.load_robot(path)
    side = tmp_path / "arm.armature.toml"
    side.write_text("[armature]\njoint1 = 0.05\n")
    for spec in ({"joint1": 0.05}, side, str(side)):
        r = packbot.load_robot(path, armature=spec)
        np.testing.assert_array_equal(r.params.armature, [0.05, 0.0])
        q = np.array([0.3, -0.2])
        M = pin.crba(r.model, r.model.createData(), q)
        M0 = pin.crba(plain.model, plain.model.createData(), q)
        np.testing.assert_allclose(np.triu(M) - np.triu(M0), np.diag([0.05, 0.0]), atol=1e-15)
    q0 = np.array([0.6, -0.4])
    cfg = packbot.SimConfig(contact_mode="none", rtol=1e-10, atol=1e-12, sample_dt=0.05)
    res = packbot.simulate(r, q0, np.zeros(2), 1.0, config=cfg)
    slow = packbot.simulate(plain, q0, np.zeros(2), 1.0, config=cfg)
    model = r.model.copy()
    data = model.createData()

    def f(_t, y):
        return np.concatenate([y[2:], pin.aba(model, data, y[:2], y[2:], np.zeros(2))])

    ref = solve_ivp(f, (0.0, 1.0), np.concatenate([q0, np.zeros(2)]), dense_output=True,
                    rtol=1e-12, atol=1e-12)  # fmt: skip
    assert np.abs(res.q - ref.sol(res.t)[:2].T).max() < 1e-6
    assert np.abs(res.q - slow.q).max() > 1e-3  # (the armature changes the swing: a real test)
    with pytest.raises(UnknownNameError, match="armature joint"):
        packbot.load_robot(path, armature={"joint9": 0.1})
    with pytest.raises(ConfigurationError, match=r"armature\.joint1"):
        packbot.load_robot(path, armature={"joint1": -1.0})
    with pytest.raises(ConfigurationError, match="armature"):
        packbot.load_robot(path, armature=3)
    bad = tmp_path / "bad.toml"
    bad.write_text("joint1 = 0.1\n")
    with pytest.raises(ConfigurationError, match=r"\[armature\] table"):
        packbot.load_robot(path, armature=bad)
    with pytest.raises(ResourceNotFound):
        packbot.load_robot(path, armature=tmp_path / "missing.toml")


def test_a_scenario_names_its_arms_armature(tmp_path) -> None:
    from packbot.scenario_robot import load_spec_robot, robot_spec

    (tmp_path / "arm.urdf").write_text(two_link_urdf())
    (tmp_path / "arm.armature.toml").write_text("[armature]\njoint2 = 0.02\n")
    table = {"urdf": "arm.urdf", "armature": {"joint1": 0.05}}
    r = load_spec_robot(robot_spec(table), tmp_path / "s.toml")
    np.testing.assert_array_equal(r.params.armature, [0.05, 0.0])
    file = {"urdf": "arm.urdf", "armature": "arm.armature.toml"}  # (relative to the file)
    r = load_spec_robot(robot_spec(file), tmp_path / "s.toml")
    np.testing.assert_array_equal(r.params.armature, [0.0, 0.02])
    with pytest.raises(ConfigurationError, match="robot.armature"):
        robot_spec({"urdf": "arm.urdf", "armature": 3})


def test_a_planar_joint_is_refused_by_name(tmp_path) -> None:
    path = tmp_path / "arm.urdf"
    path.write_text(two_link_urdf(kind="planar"))
    with pytest.raises(JointError, match="joint1") as exc:
        packbot.load_robot(path)
    assert "revolute, continuous and prismatic" in str(exc.value)


def test_bad_loading_arguments_are_named(tmp_path, two_link) -> None:
    path = tmp_path / "arm.urdf"
    path.write_text(two_link_urdf(mesh='<mesh filename="package://nowhere/meshes/a.stl"/>'))
    with pytest.raises(MeshError, match="package folders searched"):
        packbot.load_robot(path, package_dirs=[tmp_path])
    with pytest.raises(ConfigurationError, match="package_dirs"):
        packbot.load_robot(path, package_dirs=[tmp_path / "missing"])
    with pytest.raises(ConfigurationError, match="package_dirs"):
        packbot.load_robot(path, package_dirs=3)
    good = tmp_path / "good.urdf"
    good.write_text(two_link_urdf())
    with pytest.raises(UnknownNameError, match="tool_frame"):
        packbot.load_robot(good, tool_frame="no_such_frame")
    with pytest.raises(ResourceNotFound):
        packbot.load_robot(good, srdf=tmp_path / "missing.srdf")


def test_a_package_uri_resolves_through_package_dirs(tmp_path) -> None:
    import coal

    from packbot.geometry import hull_triangles, primitive_vertices, stl_bytes

    mesh_dir = tmp_path / "my_arm" / "meshes"
    mesh_dir.mkdir(parents=True)
    corners = primitive_vertices(coal.Box(0.1, 0.1, 0.4))
    (mesh_dir / "upper.stl").write_bytes(stl_bytes(hull_triangles(corners)))
    path = tmp_path / "arm.urdf"
    path.write_text(two_link_urdf(mesh='<mesh filename="package://my_arm/meshes/upper.stl"/>'))
    r = packbot.load_robot(path, package_dirs=[tmp_path])
    vols = {
        str(g.name): float(g.geometry.computeVolume()) for g in r.collision_model.geometryObjects
    }
    assert vols["upper/0"] == pytest.approx(0.1 * 0.1 * 0.4, rel=1e-6)


# ------------------------------------------------------------------ UR5 and Panda
#: Start poses clear of the floor and of the arm itself [rad].
RAISED = {
    "ur5": {"shoulder_lift_joint": -1.2, "elbow_joint": 0.6, "wrist_1_joint": -1.0},
    "panda": {"panda_joint2": 0.3, "panda_joint4": -1.2, "panda_joint6": 1.5},
}


def _named(name: str) -> packbot.Robot:
    try:
        robot_files(name)
    except ResourceNotFound:
        pytest.skip("example-robot-data is not installed (the arms extra)")
    return packbot.load_robot(name)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_named_arm_loads(name) -> None:
    r = _named(name)
    assert not r.is_packbot and r.srdf_path is not None and r.srdf_path.is_file()
    assert r.model.existFrame(r.tool_frame)
    assert all(type(g.geometry).__name__ == "Convex" for g in r.collision_model.geometryObjects)
    assert r.nq == {"ur5": 6, "panda": 9}[name]


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_named_arm_collapses_onto_the_floor_without_penetrating_or_gaining_energy(name) -> None:
    """Zero torque from a raised pose, the contact-normal mode: the arm falls and comes to
    rest on the floor (or on itself); no pair passes below -PENETRATION_TOL at the samples,
    and no event adds energy beyond rounding."""
    r = _named(name)
    q0 = r.q_from(RAISED[name], base="zero")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, sample_dt=0.005)
    res = packbot.simulate(r, q0, np.zeros(r.nq), 2.0, config=cfg)
    assert res.diagnostics.min_distance > -PENETRATION_TOL
    gains = [e.energy_after - e.energy_before for e in res.events if e.kind == "impact"]
    assert max(gains, default=0.0) < 1e-9
    assert res.energy[-1] <= res.energy[0] + 1e-6
    # the tool's path by default: the arm's tool frame (placed by Pinocchio at each sample)
    tool = res.frame_positions(robot=r)
    data = r.model.createData()
    pin.framesForwardKinematics(r.model, data, res.q[-1])
    np.testing.assert_allclose(
        tool[-1], data.oMf[r.model.getFrameId(r.tool_frame)].translation, atol=1e-12
    )
    assert np.linalg.norm(tool[-1] - tool[0]) > 0.05  # (it fell: a real path)


#: The Panda's fingers (prismatic, 4 cm, 15 g each), locked where the hand-off runs: with a
#: free finger on the floor the hand-off's mixed problem cycles at one instant (Painleve, slip,
#: release, the clamps re-chosen; docs/contact.md, "The hand-off": a known limit).
_FINGERS = ("panda_finger_joint1", "panda_finger_joint2")


@pytest.mark.parametrize(
    ("mode", "extra"),
    [("none", {}), ("joint_clamp", {}), ("joint_clamp", {"handoff": True})],
    ids=["none", "joint_clamp", "handoff"],
)
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_named_arm_falls_in_every_other_contact_mode(name, mode, extra) -> None:
    """Zero torque from the raised pose for 2 s (the contact-normal mode: the test above): in
    the report's law (and its hand-off) the arm strikes the floor or itself, no pair passes
    below -PENETRATION_TOL at the samples, no impact adds energy (1e-9 J) and the energy rises
    at most 1e-6 J above its running minimum (the integrator's error at rtol 1e-6; measured
    1.5e-8 J). Without contact the arm falls through the floor and swings on its joint stops:
    no stop adds energy (1e-9 J), and between them the integrator's error stays within 1e-5 of
    the energy (measured 5e-6 on the UR5's 64 J: fast swings at rtol 1e-6)."""
    r = _named(name)
    q0 = r.q_from(RAISED[name], base="zero")
    locked = _FINGERS if name == "panda" and extra else ()
    cfg = packbot.SimConfig(contact_mode=mode, sample_dt=0.005, locked_joints=locked, **extra)
    res = packbot.simulate(r, q0, np.zeros(r.nq), 2.0, config=cfg)
    energy = np.asarray(res.energy)
    rise = float(np.max(energy - np.minimum.accumulate(energy)))
    if mode == "none":
        assert rise < 1e-5 * abs(energy[0])
        assert {e.kind for e in res.events} <= {"limit", "release", "disengage"}
        stops = [e.energy_after - e.energy_before for e in res.events if e.kind == "limit"]
        assert max(stops, default=0.0) < 1e-9
        return
    assert rise < 1e-6
    impacts = [e for e in res.events if e.kind in ("impact", "handoff")]
    assert impacts and res.diagnostics.min_distance > -PENETRATION_TOL
    assert max(e.energy_after - e.energy_before for e in impacts) < 1e-9


#: The collapses checked against MuJoCo: the joints locked (Panda: its plane of joints 2, 4 and 6;
#: the UR5 all free), and the big joints whose rest angles are compared.
_PEER_COLLAPSES = {
    "ur5": ((), ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint")),
    "panda": (
        ("panda_joint1", "panda_joint3", "panda_joint5", "panda_joint7",
         "panda_finger_joint1", "panda_finger_joint2"),
        ("panda_joint2", "panda_joint4"),
    ),
}  # fmt: skip


@pytest.mark.parametrize("name", list(_PEER_COLLAPSES))
def test_a_named_arm_collapses_to_mujocos_rest_pose(name) -> None:
    """Zero torque from a raised pose, mu 0.5, 4 s: packbot's contact-normal mode and MuJoCo
    (RK4, 0.5 ms: the integrator that keeps a sliding contact on its surface) loading the same
    URDF and SRDF come to rest within 0.02 rad of each other on the big joints (measured: UR5
    4e-3 rad, Panda 5e-3 rad); packbot penetrates no pair beyond PENETRATION_TOL (MuJoCo's soft
    contact about 1.2 mm)."""
    pytest.importorskip("mujoco")
    from packbot.mujoco_model import build_mujoco_model, run_collapse

    r = _named(name)
    locked, big = _PEER_COLLAPSES[name]
    q0 = r.q_from(RAISED[name], base="zero")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, sample_dt=0.01, locked_joints=locked)
    res = packbot.simulate(r, q0, np.zeros(r.nq), 4.0, config=cfg)
    assert res.rest_time is not None and res.diagnostics.min_distance > -PENETRATION_TOL
    arm = build_mujoco_model(
        r, integrator="rk4", timestep=5e-4, mu=0.5, locked_joints=locked, q_locked=q0
    )
    mj = run_collapse(arm, q0, 4.0)
    assert mj.rest_time is not None
    idx = [r.joint_names.index(j) for j in big]
    assert np.abs(res.q[-1][idx] - q0[idx]).max() > 0.3  # (it fell: a real collapse)
    np.testing.assert_allclose(res.q[-1][idx], mj.q_rest[idx], atol=0.02)


def test_the_registry_names_the_shipped_arm() -> None:
    assert ROBOTS["packbot"] is None
    assert packbot.load_robot("packbot").is_packbot


def test_info_prints_another_arm(tmp_path, capsys) -> None:
    from packbot.cli import main

    path = tmp_path / "two_link.urdf"
    path.write_text(two_link_urdf())
    assert main(["info", "--urdf", str(path)]) == 0
    out = capsys.readouterr().out
    assert "arm 'two_link'" in out and "joint2" in out and "tip position" in out
    assert main(["info", "--urdf", str(path), "--package-dir", str(tmp_path / "missing")]) == 2
    assert "package_dirs" in capsys.readouterr().err


def test_a_sampled_srdf_leaves_out_only_pairs_that_never_touch(tmp_path, capsys) -> None:
    """``packbot generate-srdf --urdf panda --out F`` samples the joint space (MoveIt's setup
    assistant's rule, a 5 cm clearance): the Panda loaded with that SRDF tests fewer pairs (16
    left out at 3000 samples; the UR5's full joint ranges leave none 5 cm clear), and on an
    independent sample of configurations every pair it leaves out stays clear."""
    from packbot.cli import main

    _named("panda")
    out = tmp_path / "panda.srdf"
    assert main(["generate-srdf", "--urdf", "panda", "--samples", "3000", "--out", str(out)]) == 0
    text = out.read_text()
    assert 'reason="Never"' in text and '<group name="arm">' in text
    files = robot_files("panda")
    full = packbot.load_robot("panda")
    sampled = packbot.load_robot(files.urdf, package_dirs=files.package_dirs, srdf=out)
    every = packbot.CollisionWorld(full, packbot.Environment.empty(), srdf=False)
    kept = packbot.CollisionWorld(sampled, packbot.Environment.empty())
    assert len(kept.pairs) < len(every.pairs)
    names = {(p.piece1, p.piece2) for p in kept.pairs}
    left_out = [k for k, p in enumerate(every.pairs) if (p.piece1, p.piece2) not in names]
    assert left_out
    rng = np.random.default_rng(11)
    lo, hi = full.params.lower, full.params.upper
    for _ in range(300):
        d = every.all_distances(rng.uniform(lo, hi))
        assert d[left_out].min() > 0.0
    # usage errors: exit 2 without a traceback
    assert main(["generate-srdf", "--urdf", "panda"]) == 2
    assert main(["generate-srdf", "--out", str(tmp_path / "no" / "x.srdf")]) == 2
    assert "--out" in capsys.readouterr().err


# ------------------------------------------------------------------ scenario files
def _arm_scenario(tmp_path, robot_line: str) -> object:
    (tmp_path / "arms").mkdir(exist_ok=True)
    (tmp_path / "arms" / "two_link.urdf").write_text(two_link_urdf())
    path = tmp_path / "swing.toml"
    path.write_text(
        f"duration = 0.5\n{robot_line}\n\n[initial]\nq = {{ joint1 = 0.6 }}\n\n"
        '[[failures]]\njoint = "joint2"\nkind = "frozen"\nt = 0.2\n'
    )
    return path


def test_a_scenario_runs_on_the_arm_it_names(tmp_path) -> None:
    from packbot.scenario import load_scenario, run_scenario, scenario_robot

    path = _arm_scenario(tmp_path, 'robot = "arms/two_link.urdf"')  # (relative to the file)
    scenario = load_scenario(path)
    assert scenario_robot(scenario).joint_names == ("joint1", "joint2")
    res = run_scenario(scenario)
    assert res.joint_names == ("joint1", "joint2")
    assert [e.kind for e in res.events if e.kind == "freeze"] == ["freeze"]
    table = _arm_scenario(tmp_path, '[robot]\nurdf = "arms/two_link.urdf"\ntool_frame = "fore"')
    assert scenario_robot(load_scenario(table)).tool_frame == "fore"


@pytest.mark.parametrize(
    ("line", "field"),
    [
        ("robot = 3", "robot"),
        ('robot = ""', "robot"),
        ('[robot]\nurdf = "arms/two_link.urdf"\ncolour = "red"', "robot.colour"),
        ('[robot]\ntool_frame = "fore"', "robot.urdf"),
        ('[robot]\nurdf = "arms/two_link.urdf"\npackage_dirs = "ros"', "robot.package_dirs"),
    ],
)
def test_a_bad_robot_key_is_named(tmp_path, line, field) -> None:
    from packbot.scenario import load_scenario

    with pytest.raises(ConfigurationError) as exc:
        load_scenario(_arm_scenario(tmp_path, line))
    assert exc.value.field == field


def test_the_cli_runs_a_scenario_of_another_arm(tmp_path) -> None:
    from packbot.cli import main

    path = _arm_scenario(tmp_path, 'robot = "arms/two_link.urdf"')
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--plot"]) == 0
    assert (out / "swing.npz").is_file() and (out / "swing_joints.png").is_file()


def test_an_uncertain_run_refuses_another_arm(tmp_path) -> None:
    path = _arm_scenario(tmp_path, 'robot = "arms/two_link.urdf"')
    with pytest.raises(ConfigurationError) as exc:
        packbot.uncertain_run(path, samples=2)
    assert exc.value.field == "scenario.robot"


def test_a_payload_is_held_in_the_arms_tool_frame_by_default(two_link) -> None:
    """Payload(frame=None) on the two-link arm: held at its tool frame ("tip", 0.8 m below the
    shoulder); the gravity torque at the shoulder grows by m g times the tip's horizontal lever
    (1e-9 N*m), and the pick event names the frame."""
    from packbot.system import with_payload

    r = two_link
    q = np.array([0.6, -0.4])
    heavy = with_payload(r, packbot.Payload(mass=2.0))
    data, hdata = r.model.createData(), heavy.model.createData()
    pin.framesForwardKinematics(r.model, data, q)
    tip = data.oMf[r.model.getFrameId("tip")].translation
    joint1 = data.oMi[r.model.getJointId("joint1")].translation
    extra = pin.computeGeneralizedGravity(heavy.model, hdata, q) - pin.computeGeneralizedGravity(
        r.model, data, q
    )
    # the weight's torque about joint1's axis (y): ((tip - joint1) x (-m g e_z))_y; g(q) is the
    # torque that balances gravity (M a + g = tau), its negative
    weight = np.cross(tip - joint1, [0.0, 0.0, -2.0 * 9.81])[1]
    assert abs(weight) > 1.0  # (a real lever)
    assert abs(extra[0] + weight) < 1e-9
    res = packbot.simulate(r, q, np.zeros(2), 0.2, payload=packbot.Payload(mass=2.0, t_pick=0.1))
    assert [(e.kind, e.link1) for e in res.events if e.kind == "pick"] == [("pick", "tip")]
