"""The parameter table's tolerances and the arms drawn within them (packbot.sample_robots)."""

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot import params as P
from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.geometry import part_inertia, part_volume
from packbot.model import INERTIA_RTOL
from packbot.resources import SRDF_NAME, srdf_path
from packbot.uncertainty import MAX_SAMPLED_ROBOTS, robot_from_values

REPO = Path(__file__).resolve().parents[1]
WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: Entries that are capacity figures, not dimensions or masses of a body: no tolerance.
CAPACITY = ("lift.mass", "lift.lever")


@pytest.fixture(scope="module")
def arms() -> packbot.SampledRobots:
    return packbot.sample_robots(6, seed=11)


def _link(robot: packbot.Robot, name: str) -> pin.Inertia:
    return robot.model.inertias[robot.model.getJointId(name)]


# ------------------------------------------------------------------------------- the table


def test_every_geometric_and_inertial_entry_has_a_tolerance_and_basis():
    for p in P.TABLE.values():
        if p.unit not in ("m", "kg") or p.name in CAPACITY:
            continue
        tol = p.tolerance
        assert tol is not None, p.name
        assert tol.basis in P.BASES and tol.reason, p.name
        if tol.basis == "measured":
            assert tol.plus_minus == pytest.approx(0.005) and p.unit == "m"
        if tol.basis == "weighed":
            assert 0.0 < tol.plus_minus <= 0.1 and p.unit == "kg"
        if tol.basis in ("measured", "weighed", "estimated"):
            assert tol.line is not None and 313 <= tol.line <= 341, p.name  # Appendix A
        if p.unit == "kg" or p.name != "chassis.arm_mount_x":
            assert tol.plus_minus < abs(p.value), p.name  # the box stays positive
    # The report's own "estimates and memory" are wider than its measurements.
    assert P.TABLE["link.tube_wall"].tolerance.basis == "estimated"
    assert P.TABLE["mass.link1_tube"].tolerance.basis == "estimated"
    assert P.TABLE["mass.link1_motor"].tolerance.basis == "weighed"
    assert P.TABLE["link1.motor_length"].tolerance.basis == "estimated"


def test_parameters_md_shows_every_tolerance():
    text = (REPO / "docs" / "parameters.md").read_text()
    section = text.split("## Tolerances", 1)[1].split("\n## ", 1)[0]
    assert "| parameter | value | tolerance | basis | report line |" in section
    for name in P.toleranced():
        assert f"| `{name}` |" in section, name


def test_the_nominal_values_are_the_centres_of_the_boxes():
    sample = packbot.sample_values(1, seed=0)
    centres = sample.bounds.mean(axis=1)
    nominal = np.array([P.value(n) for n in sample.names])
    np.testing.assert_allclose(centres, nominal, rtol=1e-12, atol=1e-15)
    assert P.design(P.nominal_values()) == P.NOMINAL  # the nominal model is the design's


def test_draws_stay_in_their_boxes_and_fill_them():
    for method in packbot.uncertainty.METHODS:
        sample = packbot.sample_values(256, seed=5, method=method)
        lo, hi = sample.bounds.T
        half = (hi - lo) / 2
        assert np.all(sample.values >= lo) and np.all(sample.values <= hi)
        # Quasi-random: every entry spreads over its whole box, centred on the nominal value.
        assert np.all(sample.values.min(axis=0) < lo + 0.05 * half)
        assert np.all(sample.values.max(axis=0) > hi - 0.05 * half)
        assert np.all(np.abs(sample.values.mean(axis=0) - (lo + hi) / 2) < 0.05 * half)


def test_the_same_seed_gives_the_same_values_another_seed_others():
    a = packbot.sample_values(16, seed=3)
    b = packbot.sample_values(16, seed=3)
    c = packbot.sample_values(16, seed=4)
    np.testing.assert_array_equal(a.values, b.values)
    assert np.max(np.abs(a.points - c.points)) > 0.1
    some = packbot.sample_values(8, seed=3, vary=["link1.length", "mass.link1_tube"])
    assert some.names == ("link1.length", "mass.link1_tube")
    arm = some.arm(0)
    assert arm["link2.length"] == P.value("link2.length")  # not drawn: nominal
    assert arm["link1.length"] == some.column("link1.length")[0]


# ------------------------------------------------------------------------------- the arms


def test_sampled_arms_are_robots_like_the_nominal(arms, robot):
    assert len(arms) == 6 and len(arms.sample) == 6
    names = [go.name for go in robot.collision_model.geometryObjects]
    for k, arm in enumerate(arms):
        assert arm.joint_names == robot.joint_names
        assert arm.nq == robot.nq and set(arm.poses) == set(robot.poses)
        np.testing.assert_array_equal(arm.pose("drive"), robot.pose("drive"))
        np.testing.assert_array_equal(arm.params.armature, robot.params.armature)
        np.testing.assert_array_equal(arm.params.effort, robot.params.effort)
        assert [go.name for go in arm.collision_model.geometryObjects] == names
        values = arms.values(k)
        assert {n: p.value for n, p in arm.params.table.items()} == values
        assert arms[k] is arm


def test_sampled_arms_differ_and_follow_their_values(arms, robot):
    masses = [sum(_link(a, j).mass for j in robot.joint_names) for a in arms]
    assert np.ptp(masses) > 0.05  # [kg]: the arms differ
    for k, arm in enumerate(arms):
        v = arms.values(k)
        # Link lengths move the joints and the collision pieces together.
        elbow1 = arm.model.jointPlacements[arm.model.getJointId("elbow1")]
        assert elbow1.translation[0] == pytest.approx(v["link1.length"], abs=1e-12)
        go = arm.collision_model.geometryObjects[
            arm.collision_model.getGeometryId("link1/elbow1_casing")
        ]
        centre = np.asarray(go.geometry.points(), dtype=float).mean(axis=0)
        assert centre[0] == pytest.approx(v["link1.length"], abs=1e-6)  # STL: float32
        # Each part's mass: drawn (weighed parts) or drawn times its volume ratio (the others).
        assert arms.part_masses[k]["link1/motor"] == pytest.approx(v["mass.link1_motor"])
        assert arms.part_masses[k]["link1/tube"] != pytest.approx(v["mass.link1_tube"], rel=1e-6)


def test_masses_are_positive_and_inertias_physical(arms):
    for arm in arms:
        for inertia in arm.model.inertias[1:]:
            assert inertia.mass > 0.0
            a, b, c = np.linalg.eigvalsh(inertia.inertia)
            assert a > INERTIA_RTOL * c  # positive definite
            assert a + b >= c * (1 - INERTIA_RTOL)  # triangle inequality


def test_a_thicker_tube_is_heavier_with_more_inertia_by_the_same_geometry_code():
    wall = P.TABLE["link.tube_wall"]
    lo, hi = wall.tolerance.bounds(wall.value)
    thin = robot_from_values({"link.tube_wall": lo})
    thick = robot_from_values({"link.tube_wall": hi})
    m_thin, m_thick = _link(thin, "shoulder"), _link(thick, "shoulder")  # link 1's body
    assert m_thick.mass > m_thin.mass
    assert m_thick.inertia[1, 1] > m_thin.inertia[1, 1]
    # Mass and inertia are the nominal code's: the tube's mass is its density times its volume.
    for v, arm in ((lo, thin), (hi, thick)):
        values = P.nominal_values() | {"link.tube_wall": v}
        link1 = next(link for link in P.design(values).links if link.name == "link1")
        nominal = next(link for link in P.LINKS if link.name == "link1")
        tube0 = nominal.parts[1]
        density = tube0.mass / part_volume(tube0)
        scaled = [
            p if p.name != "tube" else replace(p, mass=density * part_volume(p))
            for p in link1.parts
        ]
        total = sum((part_inertia(p) for p in scaled), pin.Inertia.Zero())
        got = _link(arm, "shoulder")
        assert got.mass == pytest.approx(total.mass, rel=1e-9)
        np.testing.assert_allclose(got.lever, total.lever, atol=1e-9)
        np.testing.assert_allclose(got.inertia, total.inertia, rtol=1e-8, atol=1e-12)


def test_a_weighed_part_keeps_its_mass_when_it_grows():
    r = P.TABLE["casing.shoulder_radius"]
    big = robot_from_values({"casing.shoulder_radius": r.tolerance.bounds(r.value)[1]})
    nominal = packbot.load_robot()
    assert _link(big, "shoulder").mass == pytest.approx(_link(nominal, "shoulder").mass)
    assert _link(big, "shoulder").inertia[2, 2] > _link(nominal, "shoulder").inertia[2, 2]


def test_each_arm_simulates_the_collapse_and_its_world_builds(arms):
    config = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    for arm in arms:
        world = packbot.CollisionWorld(arm)
        for pose in arm.poses:  # every named pose starts apart (the nominal: 2 cm or more)
            assert world.closest(arm.pose(pose)).distance > 0.0, pose
        result = packbot.simulate(arm, arm.pose("drive"), [0.0] * 8, 0.3, config=config)
        assert result.t[-1] == pytest.approx(0.3)
        assert np.all(np.isfinite(result.q))
        assert result.diagnostics.min_distance > -1e-3  # [m]: no piece sunk into another


def test_the_srdf_never_pairs_stay_apart_on_every_arm(arms, robot):
    # The shipped SRDF's "Never" pairs (never within 5 cm on the nominal arm) are not tested in
    # a sampled arm's world either: they must stay apart on it too.
    text = srdf_path().read_text()
    never = {frozenset(m) for m in re.findall(r'link1="(\w+)" link2="(\w+)" reason="Never"', text)}
    assert never
    rng = np.random.default_rng(7)
    lo, hi = robot.params.lower, robot.params.upper
    qs = lo + rng.random((300, robot.nq)) * (hi - lo)
    for arm in arms:
        world = packbot.CollisionWorld(arm, srdf=False)
        idx = [i for i, p in enumerate(world.pairs) if frozenset((p.link1, p.link2)) in never]
        assert len(idx) >= len(never)
        closest = min(float(world.all_distances(q)[idx].min()) for q in qs)
        assert closest > 0.02  # [m] (the nominal arm: 7.1 cm over 3,000 configurations)


def test_an_arm_simulates_in_the_contact_normal_mode(arms):
    config = packbot.SimConfig(locked_joints=WRIST)
    arm = arms[0]
    result = packbot.simulate(arm, arm.pose("drive"), [0.0] * 8, 0.3, config=config)
    assert result.t[-1] == pytest.approx(0.3) and np.all(np.isfinite(result.q))


def test_the_arms_packages_go_to_the_given_folder(tmp_path):
    arms = packbot.sample_robots(2, seed=1, directory=tmp_path, method="lhs")
    for k, arm in enumerate(arms):
        folder = tmp_path / f"arm_{k:04d}" / "packbot"
        assert arm.urdf_path == folder / "packbot_eod.urdf"
        assert (folder / SRDF_NAME).is_file() and any((folder / "meshes").glob("*.stl"))
    again = packbot.sample_robots(2, seed=1, method="lhs")
    for a, b in zip(arms, again, strict=True):
        np.testing.assert_array_equal(a.model.inertias[3].inertia, b.model.inertias[3].inertia)


# ------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"n": 0}, "n"),
        ({"n": 2.0}, "n"),
        ({"n": True}, "n"),
        ({"n": "4"}, "n"),
        ({"n": MAX_SAMPLED_ROBOTS + 1}, "n"),
        ({"n": 2, "seed": -1}, "seed"),
        ({"n": 2, "seed": 1.5}, "seed"),
        ({"n": 2, "seed": None}, "seed"),
        ({"n": 2, "method": "halton"}, "method"),
        ({"n": 2, "vary": "link1.length"}, "vary"),
        ({"n": 2, "vary": []}, "vary"),
        ({"n": 2, "directory": 3}, "directory"),
    ],
)
def test_bad_arguments_name_the_field_value_and_choices(kwargs, field):
    with pytest.raises(ConfigurationError) as info:
        packbot.sample_robots(**kwargs)
    assert info.value.field == field
    assert str(info.value).startswith(f"invalid {field}=")
    assert info.value.expected


def test_unknown_or_untoleranced_names_are_refused_with_the_valid_ones():
    with pytest.raises(UnknownNameError, match="did you mean 'link1.length'") as info:
        packbot.sample_values(4, vary=["link1.lenght"])
    assert "link1.length" in info.value.valid
    with pytest.raises(UnknownNameError, match="unknown toleranced parameter 'gravity'"):
        robot_from_values({"gravity": 9.8})


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"mass.board": -0.1}, "mass.board"),
        ({"link1.length": float("nan")}, "link1.length"),
        ({"link1.length": "0.5"}, "link1.length"),
        ({"link.tube_wall": 0.05}, "link.tube_wall"),
        (["link1.length"], "values"),
    ],
)
def test_bad_values_name_the_entry(values, field):
    with pytest.raises(PackbotError) as info:
        robot_from_values(values)
    assert isinstance(info.value, ConfigurationError) and info.value.field == field


def test_a_file_is_not_a_directory(tmp_path):
    path = tmp_path / "file"
    path.write_text("")
    with pytest.raises(ConfigurationError, match="a folder"):
        packbot.sample_robots(1, directory=path)
