"""load_robot checks the URDF first: each bad model is a ModelError naming the element."""

import re
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import packbot
from packbot.cli import main
from packbot.errors import (
    ConfigurationError,
    InertialError,
    JointError,
    JointMismatchError,
    MeshError,
    ModelError,
    PackbotError,
    ResourceNotFound,
    URDFError,
    URDFSyntaxError,
)
from packbot.model import check_urdf
from packbot.resources import data_dir
from packbot.urdfgen import URDF_NAME

TUBE = "package://packbot/meshes/link1__tube.stl"


def broken_copy(
    tmp_path: Path,
    edit: Callable[[str], str] | None = None,
    meshes: Callable[[Path], None] | None = None,
) -> Path:
    """A copy of urdf/ (URDF and meshes) in tmp_path, its text passed through ``edit``."""
    folder = tmp_path / "urdf"
    shutil.copytree(data_dir("urdf"), folder)
    path = folder / URDF_NAME
    if edit is not None:
        text = path.read_text()
        new = edit(text)
        assert new != text, "the edit changed nothing"
        path.write_text(new)
    if meshes is not None:
        meshes(folder / "meshes")
    return path


def load_error(path: Path, kind: type[ModelError]) -> ModelError:
    with pytest.raises(kind) as info:
        packbot.load_robot(path)
    err = info.value
    assert isinstance(err, ModelError)
    msg = str(err)
    assert str(path) in msg  # the file is named
    assert "data file not found" not in msg
    return err


# --- the file itself --------------------------------------------------------------------------


def test_empty_file(tmp_path):
    path = broken_copy(tmp_path, lambda t: "")
    err = load_error(path, URDFSyntaxError)
    assert "empty" in str(err)


def test_whitespace_only_file_is_empty(tmp_path):
    path = broken_copy(tmp_path, lambda t: "\n  \n")
    assert "empty" in str(load_error(path, URDFSyntaxError))


def test_truncated_file_names_the_line(tmp_path):
    path = broken_copy(tmp_path, lambda t: t[: len(t) // 2])
    err = load_error(path, URDFSyntaxError)
    assert err.line is not None and err.line > 100
    assert f"line {err.line}" in str(err)
    assert "truncated" in str(err)


def test_malformed_xml_names_the_line(tmp_path):
    def edit(t: str) -> str:
        return t.replace('<link name="link1">', '<link name="link1"', 1)

    path = broken_copy(tmp_path, edit)
    bad_line = 1 + path.read_text().split("\n").index('  <link name="link1"')
    err = load_error(path, URDFSyntaxError)
    assert err.line in (bad_line, bad_line + 1)  # expat reports where it notices
    assert re.search(rf"line {err.line}: not well-formed XML", str(err))


def test_not_a_urdf(tmp_path):
    def edit(t: str) -> str:
        return t.replace('<robot name="packbot_eod">', '<sdf version="1.6">').replace(
            "</robot>", "</sdf>"
        )

    err = load_error(broken_copy(tmp_path, edit), URDFSyntaxError)
    assert "<sdf>" in str(err) and "not a URDF" in str(err) and "<robot" in str(err)


# --- meshes -----------------------------------------------------------------------------------


def test_missing_mesh_names_uri_resolved_path_and_link(tmp_path):
    path = broken_copy(tmp_path, meshes=lambda d: (d / "link1__tube.stl").unlink())
    err = load_error(path, MeshError)
    assert isinstance(err, MeshError)
    expected = path.parent.resolve() / "meshes" / "link1__tube.stl"
    assert err.link == "link1" and err.uri == TUBE and err.mesh_path == expected
    msg = str(err)
    assert TUBE in msg and str(expected) in msg and "'link1'" in msg and "does not exist" in msg


def test_missing_mesh_with_a_relative_path(tmp_path):
    def edit(t: str) -> str:
        return t.replace(TUBE, "parts/tube.stl")

    path = broken_copy(tmp_path, edit)
    err = load_error(path, MeshError)
    assert isinstance(err, MeshError)
    assert err.mesh_path == path.parent.resolve() / "parts" / "tube.stl"
    assert "'parts/tube.stl'" in str(err) and str(err.mesh_path) in str(err)


def test_unresolvable_mesh_uri(tmp_path):
    def edit(t: str) -> str:
        return t.replace(TUBE, "package://other_robot/meshes/tube.stl")

    err = load_error(broken_copy(tmp_path, edit), MeshError)
    assert "package://other_robot/meshes/tube.stl" in str(err) and "'link1'" in str(err)


def test_corrupt_binary_mesh(tmp_path):
    def cut(d: Path) -> None:
        f = d / "link1__tube.stl"
        f.write_bytes(f.read_bytes()[:500])  # truncated: fewer triangles than announced

    err = load_error(broken_copy(tmp_path, meshes=cut), MeshError)
    assert "'link1'" in str(err) and TUBE in str(err) and "not an STL file" in str(err)


def test_empty_mesh(tmp_path):
    path = broken_copy(tmp_path, meshes=lambda d: (d / "link1__tube.stl").write_bytes(b""))
    assert "empty" in str(load_error(path, MeshError))


def test_corrupt_ascii_mesh_error_from_coal_names_the_mesh(tmp_path):
    def garble(d: Path) -> None:
        (d / "link1__tube.stl").write_bytes(b"solid x\n facet garbage\nendsolid x\n")

    err = load_error(broken_copy(tmp_path, meshes=garble), MeshError)
    assert isinstance(err, MeshError)
    assert err.link == "link1" and "Coal cannot load the mesh" in str(err)
    assert err.__cause__ is not None  # Pinocchio's own error kept as the cause


def test_unreadable_mesh(tmp_path):
    def make_dir(d: Path) -> None:  # tests may run as root: a directory cannot be read as a file
        (d / "link1__tube.stl").unlink()
        (d / "link1__tube.stl").mkdir()

    err = load_error(broken_copy(tmp_path, meshes=make_dir), MeshError)
    assert "directory" in str(err) and "'link1'" in str(err)


# --- masses and inertias ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "words"),
    [("-3.05", "not positive"), ("0", "not positive"), ("nan", "finite"), ("abc", "not a number")],
)
def test_bad_mass_names_the_link_and_value(tmp_path, value, words):
    def edit(t: str) -> str:
        return t.replace('<mass value="3.05"/>', f'<mass value="{value}"/>')

    err = load_error(broken_copy(tmp_path, edit), InertialError)
    assert isinstance(err, InertialError)
    assert err.link == "link1"
    assert "link 'link1' <mass>" in str(err) and value in str(err) and words in str(err)


@pytest.mark.parametrize(
    ("ixx", "words"),
    [
        ("-1", "not positive definite"),
        ("0", "not positive definite"),
        ("0.5", "triangle inequality"),  # 0.5 > 0.1626 + 0.1631
        ("inf", "not a finite number"),
    ],
)
def test_unphysical_inertia_names_the_link_and_value(tmp_path, ixx, words):
    def edit(t: str) -> str:
        return t.replace('ixx="0.00441725822407"', f'ixx="{ixx}"')

    err = load_error(broken_copy(tmp_path, edit), InertialError)
    assert isinstance(err, InertialError)
    assert err.link == "link1"
    assert "link 'link1' <inertia>" in str(err) and ixx in str(err) and words in str(err)


def test_inertia_check_eigenvalues_not_just_diagonal(tmp_path):
    # positive diagonal, but the off-diagonal term makes the tensor indefinite
    def edit(t: str) -> str:
        return t.replace('ixy="-4.66502003005e-19"', 'ixy="0.1"')

    err = load_error(broken_copy(tmp_path, edit), InertialError)
    assert "not positive definite" in str(err) and "principal moments -" in str(err)


# --- joints -----------------------------------------------------------------------------------

SHOULDER_LIMIT = '<limit lower="-1.3" upper="2.1" effort="156" velocity="0.8"/>'


@pytest.mark.parametrize(
    ("limit", "words"),
    [
        ('lower="2.1" upper="-1.3" effort="156" velocity="0.8"', "inverted"),
        ('lower="0.5" upper="0.5" effort="156" velocity="0.8"', "no range"),
        ('lower="-inf" upper="2.1" effort="156" velocity="0.8"', "not a finite number"),
        ('lower="-1.3" upper="nan" effort="156" velocity="0.8"', "not a finite number"),
        ('lower="-1.3" upper="2.1" effort="-156" velocity="0.8"', "effort limit -156 N*m"),
        ('lower="-1.3" upper="2.1" effort="156" velocity="-0.8"', "velocity limit -0.8 rad/s"),
        ('lower="-1.3" upper="2.1" effort="156" velocity="0"', "not positive"),
        ('lower="-1.3" upper="2.1" velocity="0.8"', "no effort"),
    ],
)
def test_bad_joint_limits_name_the_joint(tmp_path, limit, words):
    def edit(t: str) -> str:
        return t.replace(SHOULDER_LIMIT, f"<limit {limit}/>")

    err = load_error(broken_copy(tmp_path, edit), JointError)
    assert isinstance(err, JointError)
    assert err.joint == "shoulder"
    assert "joint 'shoulder' <limit>" in str(err) and words in str(err)


def test_missing_limit_on_a_revolute_joint(tmp_path):
    err = load_error(broken_copy(tmp_path, lambda t: t.replace(SHOULDER_LIMIT, "")), JointError)
    assert "joint 'shoulder' <limit>" in str(err) and "needs a <limit>" in str(err)


def test_renamed_joint_says_which_is_missing_and_which_the_file_has(tmp_path):
    def edit(t: str) -> str:
        return t.replace('<joint name="elbow1"', '<joint name="elbow_one"')

    err = load_error(broken_copy(tmp_path, edit), JointMismatchError)
    assert isinstance(err, JointMismatchError)
    assert err.missing == ("elbow1",) and err.unexpected == ("elbow_one",)
    assert "elbow_one" in err.found and "shoulder" in err.found
    msg = str(err)
    assert "no joint named 'elbow1'" in msg and "elbow_one" in msg and "packbot/params.py" in msg


def test_arm_joint_of_the_wrong_type(tmp_path):
    def edit(t: str) -> str:
        return t.replace(
            '<joint name="elbow2" type="revolute">', '<joint name="elbow2" type="fixed">'
        )

    err = load_error(broken_copy(tmp_path, edit), JointError)
    assert "joint 'elbow2'" in str(err) and "'fixed'" in str(err) and "revolute" in str(err)


def test_extra_movable_joint(tmp_path):
    def edit(t: str) -> str:
        return t.replace(
            '<joint name="gripper_tool_joint" type="fixed">',
            '<joint name="gripper_tool_joint" type="revolute"><axis xyz="0 0 1"/>'
            '<limit lower="0" upper="1" effort="1" velocity="1"/>',
        )

    err = load_error(broken_copy(tmp_path, edit), JointMismatchError)
    assert isinstance(err, JointMismatchError)
    assert err.missing == () and err.unexpected == ("gripper_tool_joint",)


def test_joint_to_an_undefined_link(tmp_path):
    def edit(t: str) -> str:
        return t.replace('<parent link="link1"/>', '<parent link="link_one"/>')

    err = load_error(broken_copy(tmp_path, edit), JointError)
    assert "joint 'elbow1' <parent>" in str(err) and "'link_one' is not defined" in str(err)


def test_zero_joint_axis(tmp_path):
    def edit(t: str) -> str:
        return t.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>')

    err = load_error(broken_copy(tmp_path, edit), JointError)
    assert "joint 'gripper_jaw' <axis>" in str(err)


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda t: t.replace('name="elbow2" type', 'name="elbow1" type'), "defined twice"),
        (lambda t: t.replace('<link name="link3">', '<link name="link2">'), "defined twice"),
        (
            lambda t: t.replace('<origin xyz="0.44 0 0" rpy="0 0 0"/>', '<origin xyz="0.44 0"/>'),
            "joint 'elbow2' <origin> xyz='0.44 0'",
        ),
        (lambda t: t.replace('<child link="link1"/>', '<child link="link2"/>'), "already the"),
    ],
)
def test_structural_errors(tmp_path, edit, words):
    err = load_error(broken_copy(tmp_path, edit), URDFError)
    assert words in str(err)


# --- what still loads, and the entry points ---------------------------------------------------


def test_shipped_model_passes_and_loads_unchanged(robot):
    text = check_urdf(robot.urdf_path)
    assert "package://" not in text  # mesh names made absolute for Pinocchio
    assert str(robot.urdf_path.resolve().parent / "meshes" / "link1__tube.stl") in text


@pytest.mark.parametrize("style", ["relative", "file"])
def test_other_mesh_uri_styles_load_the_same_model(tmp_path, robot, style):
    def edit(t: str) -> str:
        prefix = "meshes/" if style == "relative" else f"file://{tmp_path.resolve()}/urdf/meshes/"
        return t.replace("package://packbot/meshes/", prefix)

    other = packbot.load_robot(broken_copy(tmp_path, edit))
    assert [i.mass for i in other.model.inertias] == [i.mass for i in robot.model.inertias]
    a = [np.asarray(g.geometry.points()) for g in other.collision_model.geometryObjects]
    b = [np.asarray(g.geometry.points()) for g in robot.collision_model.geometryObjects]
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_urdf_argument_that_is_not_a_path():
    with pytest.raises(ConfigurationError, match="urdf"):
        packbot.load_robot(42)  # type: ignore[arg-type]


def test_urdf_argument_that_is_a_directory(tmp_path):
    with pytest.raises(ResourceNotFound, match="directory"):
        packbot.load_robot(tmp_path)


def test_cli_info_with_a_malformed_urdf_is_a_packbot_error(tmp_path, capsys):
    path = broken_copy(tmp_path, lambda t: t[: len(t) // 2])
    try:
        code = main(["info", "--urdf", str(path)])
    except PackbotError as exc:  # cli.py maps PackbotError to exit 2 (another change)
        assert isinstance(exc, URDFSyntaxError) and str(path) in str(exc)
    else:
        assert code == 2
        assert str(path) in capsys.readouterr().err
