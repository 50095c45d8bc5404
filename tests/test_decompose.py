"""Convex decomposition of a concave collision mesh (packbot.decompose, CoACD).

A one-joint arm whose link is a fork (a U of three boxes: 0.30 m wide, 0.30 m tall, prongs
6 cm thick) spins about the vertical axis through its notch, where a cube stands. Its convex
hull fills the notch and holds the cube; the decomposed pieces leave it clear.
"""

from __future__ import annotations

import itertools
import struct
from pathlib import Path

import numpy as np
import pytest

import packbot
from packbot.collision import CollisionWorld

pytest.importorskip("coacd")

#: The fork's boxes (min corner, max corner) in its link frame [m]: the bar, then the prongs.
BOXES = [
    ((-0.15, -0.03, 0.00), (0.15, 0.03, 0.04)),
    ((-0.15, -0.03, 0.04), (-0.09, 0.03, 0.30)),
    ((0.09, -0.03, 0.04), (0.15, 0.03, 0.30)),
]
#: The mesh's volume [m^3] and its hull's (0.30 x 0.06 x 0.30).
VOLUME = sum(np.prod(np.subtract(hi, lo)) for lo, hi in BOXES)
HULL = 0.30 * 0.06 * 0.30
#: A cube in the notch, on the spin axis (world; the joint is 0.5 m up).
CUBE = packbot.Obstacle(name="cube", kind="box", size=(0.06, 0.06, 0.06), xyz=(0.0, 0.0, 0.67))

URDF = """<robot name="fork_arm">
  <link name="base"><inertial><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="fork"><inertial><origin xyz="0 0 0.1"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <collision><geometry><mesh filename="fork.stl"/></geometry></collision></link>
  <joint name="spin" type="continuous"><parent link="base"/><child link="fork"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit effort="10" velocity="10"/></joint>
</robot>
"""


def _box_triangles(lo, hi) -> list[np.ndarray]:
    """The 12 outward triangles of an axis-aligned box."""
    c = np.array(list(itertools.product(*zip(lo, hi, strict=True))))  # corner k: bits x y z
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    centre = c.mean(axis=0)
    for a, b, d, e in quads:
        for tri in ((a, b, d), (a, d, e)):
            p = c[list(tri)]
            n = np.cross(p[1] - p[0], p[2] - p[0])
            tris.append(p if np.dot(n, p[0] - centre) > 0 else p[[0, 2, 1]])
    return tris


def _write_fork(folder: Path) -> Path:
    tris = [t for lo, hi in BOXES for t in _box_triangles(lo, hi)]
    rows = [struct.pack("<12fH", 0, 0, 0, *t.ravel(), 0) for t in tris]
    (folder / "fork.stl").write_bytes(
        b"fork".ljust(80) + struct.pack("<I", len(rows)) + b"".join(rows)
    )
    urdf = folder / "fork_arm.urdf"
    urdf.write_text(URDF)
    return urdf


@pytest.fixture(scope="module")
def decomposed(tmp_path_factory):
    from packbot.decompose import decompose_meshes

    folder = tmp_path_factory.mktemp("fork")
    urdf = _write_fork(folder)
    written, report = decompose_meshes(urdf, folder / "out")
    return urdf, written, report


def test_a_concave_mesh_is_split_into_tight_convex_pieces(decomposed) -> None:
    """The fork's hull adds 108 % of its volume; its pieces' hulls add under 25 % (CoACD's
    pieces are approximate, cut on its remeshed surface: measured 3 pieces, +14 %)."""
    urdf, written, report = decomposed
    (mesh,) = report
    assert mesh.link == "fork" and mesh.volume == pytest.approx(VOLUME, rel=1e-6)
    assert mesh.hull_excess == pytest.approx(HULL / VOLUME - 1.0, rel=1e-6)
    assert len(mesh.pieces) >= 3 and mesh.pieces_excess is not None
    assert abs(mesh.pieces_excess) < 0.25
    assert all((written.parent / p).is_file() for p in mesh.pieces)
    robot = packbot.load_robot(written)
    pieces = [g.name for g in robot.collision_model.geometryObjects]
    assert pieces == [f"fork/{k}" for k in range(len(mesh.pieces))]
    hull = packbot.load_robot(urdf)
    assert [g.name for g in hull.collision_model.geometryObjects] == ["fork/0"]


def test_the_cube_in_the_notch_touches_the_hull_but_not_the_pieces(decomposed) -> None:
    """Over a turn of the spin joint the cube stays inside the fork's hull (distance < 0) and
    more than 3 cm clear of the pieces (6 cm from each prong's box, 10 cm above the bar;
    measured 4.7 cm from CoACD's approximate pieces); a spinning fork runs round it without an
    impact, where the hull's start is refused."""
    urdf, written, _ = decomposed
    env = packbot.Environment().with_obstacles(CUBE)
    hull, pieces = packbot.load_robot(urdf), packbot.load_robot(written)
    angles = np.linspace(0.0, 2 * np.pi, 13)
    for robot, inside in ((hull, True), (pieces, False)):
        world = CollisionWorld(robot, env)
        dist = [float(world.closest(np.array([a])).distance) for a in angles]
        assert (max(dist) < 0.0) if inside else (min(dist) > 0.03), dist
    res = packbot.simulate(pieces, np.zeros(1), np.array([3.0]), 1.0, environment=env)
    assert not [e for e in res.events if e.kind == "impact"]
    assert res.q[-1, 0] > 2.9  # (it turned, unhindered)
    with pytest.raises(packbot.errors.PackbotError, match="cube"):
        packbot.simulate(hull, np.zeros(1), np.array([3.0]), 1.0, environment=env)


def test_the_cli_decomposes_and_names_bad_options(tmp_path, capsys) -> None:
    from packbot.cli import main

    urdf = _write_fork(tmp_path)
    out = tmp_path / "out"
    # the decomposition itself is the fixture's (CoACD, 9 s): here the command's path, with an
    # excess no hull reaches (every mesh kept as its hull, the URDF still written)
    assert main(["decompose", "--urdf", str(urdf), "--out", str(out), "--excess", "10"]) == 0
    text = capsys.readouterr().out
    assert "fork" in text and (out / "fork_arm.urdf").is_file()
    assert main(["decompose", "--urdf", str(urdf), "--out", str(out)]) == 2  # not empty
    assert "--out" in capsys.readouterr().err
    bad = ["decompose", "--urdf", str(urdf), "--out", str(tmp_path / "o2"), "--threshold", "0"]
    assert main(bad) == 2
    assert "threshold" in capsys.readouterr().err
    assert main(["decompose", "--urdf", str(urdf), "--out", str(tmp_path)]) == 2  # its own folder


def test_a_run_that_fails_half_way_leaves_the_folder_as_it_found_it(tmp_path, monkeypatch) -> None:
    """The first piece written, the second fails (a full disk, Ctrl-C): no piece and no URDF
    stay in the folder, a folder the call created is removed, a user's file kept."""
    import packbot.decompose as dec

    cube = np.array([[x, y, z] for x in (0, 0.1) for y in (0, 0.1) for z in (0, 0.1)], float)

    class FakeCoacd:  # two pieces at once (no CoACD run: the failure is what is tested)
        Mesh = staticmethod(lambda vertices, tris: (vertices, tris))

        @staticmethod
        def run_coacd(mesh, threshold, seed):
            return [(cube, None), (cube + 0.2, None)]

    real_write = dec._write_stl
    written: list[Path] = []

    def write_then_fail(path, points):
        if written:
            raise OSError("No space left on device")
        written.append(path)
        return real_write(path, points)

    monkeypatch.setattr(dec, "_coacd", lambda: FakeCoacd)
    monkeypatch.setattr(dec, "_write_stl", write_then_fail)
    urdf = _write_fork(tmp_path)
    for out, keep in ((tmp_path / "new", None), (tmp_path / "mine", "notes.txt")):
        if keep:
            out.mkdir()
            (out / keep).write_text("the user's")
        written.clear()
        with pytest.raises(OSError, match="No space"):
            dec.decompose_meshes(urdf, out)
        assert written and not written[0].exists()  # the first piece was written, then removed
        if keep is None:
            assert not out.exists()
        else:
            assert [p.name for p in out.iterdir()] == [keep]
