"""Convex decomposition of an arm's concave collision meshes, written as a new URDF.

:func:`packbot.load_robot` simulates each ``<collision>`` as one convex piece: a mesh is its
convex hull. For most links that is close (Panda: every hull within 0.1 % of its mesh's volume;
UR5: 6 to 18 % on the small links), but a long link with wider ends is not: the UR5's upper arm
and forearm hulls are 46 % and 55 % larger than their meshes, filling the waist between the
joint housings. :func:`decompose_meshes` splits each mesh whose hull adds more than ``excess``
of its volume into convex pieces by CoACD (approximate convex decomposition, Wei et al., SIGGRAPH
2022; the ``decompose`` extra), writes each piece's hull as an STL file and a copy of the URDF
whose ``<collision>`` holds the pieces, one ``<collision>`` each (same origin). Loading that
copy gives the link several convex pieces, each an ordinary packbot piece.

It is an offline step, as a MuJoCo model's decomposition is (``packbot decompose --urdf ARM
--out DIR``): CoACD takes seconds per mesh (7 s for the UR5's forearm), and the written files
are the user's to keep, check and ship. Measured on the UR5 at CoACD's concavity threshold 0.05
(``docs/model.md``, "Other arms"): upper arm 3 pieces, +15.5 % volume; forearm 3 pieces,
+20.4 %.
"""

from __future__ import annotations

import logging
import os
import shutil
import struct
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull

from packbot.errors import ConfigurationError, PackbotError, ResourceNotFound
from packbot.resources import resolve_mesh_uri, search_package_dirs
from packbot.robots import ROBOTS, robot_files
from packbot.urdf_check import URDFChecker
from packbot.validation import finite_number, integer

__all__ = ["DEFAULT_EXCESS", "DEFAULT_THRESHOLD", "DecomposedMesh", "decompose_meshes"]

log = logging.getLogger(__name__)

#: A mesh is decomposed when its hull's volume exceeds the mesh's by more than this fraction.
DEFAULT_EXCESS = 0.25
#: CoACD's concavity threshold [-]: smaller gives more, tighter pieces (0.05: its default).
DEFAULT_THRESHOLD = 0.05
#: The folder of the pieces' STL files, inside the output folder.
MESH_FOLDER = "meshes"


@dataclass(frozen=True)
class DecomposedMesh:
    """One collision mesh of the arm and what was done with it.

    Attributes:
        link: The link it belongs to.
        index: Its position among the link's ``<collision>`` elements.
        uri: Its ``filename`` (a relative path made absolute, as in the written copy).
        volume: The mesh's volume [m^3] (scale applied).
        hull_excess: (hull volume - volume) / volume [-].
        pieces: The pieces' STL files written (relative to the output folder); empty: kept as
            its hull.
        pieces_excess: (sum of the pieces' volumes - volume) / volume [-], or None if kept.
        seconds: CoACD's wall time [s] (0 if kept).
    """

    link: str
    index: int
    uri: str
    volume: float
    hull_excess: float
    pieces: tuple[str, ...] = ()
    pieces_excess: float | None = None
    seconds: float = 0.0


def _mesh_arrays(path: Path, scale: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Vertices [m] (scale applied) and triangles of a mesh file, through Coal's loader."""
    mesh = coal.MeshLoader().load(str(path), scale)
    vertices = np.array(mesh.vertices(), dtype=float)
    tris = np.array(
        [[mesh.tri_indices(i)[k] for k in range(3)] for i in range(mesh.num_tris)], dtype=np.int64
    )
    return vertices, tris


def _volume(vertices: NDArray, tris: NDArray) -> float:
    """The enclosed volume [m^3] of a closed triangle mesh (the divergence theorem)."""
    a, b, c = vertices[tris[:, 0]], vertices[tris[:, 1]], vertices[tris[:, 2]]
    return abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)


def _write_stl(path: Path, points: NDArray) -> float:
    """The convex hull of ``points`` as a binary STL file; returns its volume [m^3]."""
    hull = ConvexHull(points)
    centre = points[hull.vertices].mean(axis=0)
    rows = []
    for tri in hull.simplices:
        p = points[tri]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        if np.dot(n, p[0] - centre) < 0:  # outward, as STL readers expect
            p, n = p[[0, 2, 1]], -n
        n = n / (np.linalg.norm(n) or 1.0)
        rows.append(struct.pack("<12fH", *n, *p.ravel(), 0))
    path.write_bytes(
        b"packbot convex piece".ljust(80, b" ") + struct.pack("<I", len(rows)) + b"".join(rows)
    )
    return float(hull.volume)


def _coacd() -> Any:
    try:
        import coacd
    except ImportError:
        raise PackbotError(
            'convex decomposition needs CoACD: pip install "packbot[decompose]" (coacd)'
        ) from None
    coacd.set_log_level("error")
    return coacd


def decompose_meshes(
    urdf: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    package_dirs: Sequence[str | os.PathLike[str]] | None = None,
    excess: float = DEFAULT_EXCESS,
    threshold: float = DEFAULT_THRESHOLD,
    seed: int = 0,
) -> tuple[Path, list[DecomposedMesh]]:
    """Decompose the arm's concave collision meshes; write the pieces and a URDF using them.

    Args:
        urdf: The arm's URDF file, or a name of :data:`packbot.robots.ROBOTS` (its meshes'
            packages found as :func:`packbot.load_robot` finds them).
        out_dir: The folder to write into (created): ``<urdf's name>`` there and the pieces
            in its ``meshes/``. Nothing is written elsewhere, and a run that fails (or is
            interrupted) leaves the folder as it found it: the pieces are written into a
            folder of its own first and moved into ``meshes/`` once every mesh is done.
        package_dirs: Folders of the URDF's ``package://`` meshes (and ``ROS_PACKAGE_PATH``).
        excess: Decompose a mesh whose hull is larger than the mesh by more than this fraction
            of its volume [-], in [0, 10].
        threshold: CoACD's concavity threshold [-], in [0.01, 1].
        seed: CoACD's random seed (the same seed, the same pieces).

    Returns:
        The written URDF and one :class:`DecomposedMesh` per collision mesh. The new URDF
        keeps every other element as it was; relative mesh paths become absolute, so that
        the copy loads from ``out_dir`` (``package://`` URIs stay: pass the same
        ``package_dirs`` to :func:`packbot.load_robot`).

    Raises:
        ConfigurationError: ``excess`` or ``threshold`` out of range.
        PackbotError: CoACD is not installed.
        URDFError: The URDF fails :func:`packbot.check_urdf`'s checks.
    """
    integer("seed", seed, low=0, what="a random seed (an integer >= 0)")
    excess = finite_number("excess", excess, low=0.0, high=10.0)
    threshold = finite_number("threshold", threshold, low=0.01, high=1.0)
    dirs_given = [Path(d) for d in package_dirs or []]
    if isinstance(urdf, str) and urdf in ROBOTS and not Path(urdf).is_file():
        named = robot_files(urdf)
        if named.urdf is None:  # (PackBot: its shipped file)
            raise ConfigurationError("urdf", urdf, "a URDF file or the name of another arm")
        path = named.urdf
        dirs_given += named.package_dirs
    else:
        path = Path(urdf)
    if not path.is_file():
        raise ResourceNotFound(path, "pass the arm's .urdf file")
    out = Path(out_dir)
    if out.resolve() == path.resolve().parent:
        raise ConfigurationError("out_dir", str(out), "a folder other than the URDF's own")
    dirs = search_package_dirs(dirs_given or None)
    URDFChecker(path, dirs).run()  # the same checks (and mesh resolution) as load_robot
    tree = ET.parse(path)
    here = path.resolve().parent
    for mesh_el in tree.getroot().iter("mesh"):  # relative paths: absolute, for the copy
        uri = mesh_el.get("filename", "")
        if "://" not in uri and not Path(uri).is_absolute():
            mesh_el.set("filename", str(here / uri))
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    # the pieces go to a folder of out's own first and move into place once every mesh is
    # done: a run that fails (CoACD, a bad mesh, Ctrl-C) leaves out as it found it
    stage = Path(tempfile.mkdtemp(prefix=".decompose-", dir=out))
    (stage / MESH_FOLDER).mkdir()
    try:
        report = _decompose_tree(tree, here, dirs, stage, excess, threshold, seed)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise
    pieces = sorted((stage / MESH_FOLDER).iterdir())
    if pieces:
        (out / MESH_FOLDER).mkdir(exist_ok=True)
    for piece in pieces:
        os.replace(piece, out / MESH_FOLDER / piece.name)
    shutil.rmtree(stage, ignore_errors=True)
    written = out / path.name
    ET.indent(tree)
    tree.write(written, encoding="utf-8", xml_declaration=True)
    return written, report


def _decompose_tree(
    tree: ET.ElementTree[ET.Element],
    here: Path,
    dirs: Sequence[Path],
    stage: Path,
    excess: float,
    threshold: float,
    seed: int,
) -> list[DecomposedMesh]:
    """Each concave collision mesh of ``tree`` split, its pieces written into ``stage``."""
    coacd = None
    report: list[DecomposedMesh] = []
    root = tree.getroot()
    assert root is not None  # (a parsed file has its root)
    for link in root.iter("link"):
        name = link.get("name", "")
        for index, col in enumerate(list(link.iter("collision"))):
            mesh = col.find("geometry/mesh")
            if mesh is None:
                continue
            uri = mesh.get("filename", "")
            file = resolve_mesh_uri(uri, here, dirs)
            assert file is not None  # (the checker resolved every mesh)
            scale = np.array([float(x) for x in mesh.get("scale", "1 1 1").split()])
            vertices, tris = _mesh_arrays(file, scale)
            volume = _volume(vertices, tris)
            hull_excess = ConvexHull(vertices).volume / volume - 1.0
            if hull_excess <= excess:
                report.append(DecomposedMesh(name, index, uri, volume, hull_excess))
                continue
            coacd = coacd or _coacd()
            start = time.perf_counter()
            parts = coacd.run_coacd(coacd.Mesh(vertices, tris), threshold=threshold, seed=seed)
            seconds = time.perf_counter() - start
            files, total = [], 0.0
            for k, (points, _faces) in enumerate(parts):
                rel = f"{MESH_FOLDER}/{name}_{index}_{k}.stl"
                total += _write_stl(stage / rel, np.asarray(points, dtype=float))
                files.append(rel)
            position = list(link).index(col)
            link.remove(col)
            for k, rel in enumerate(files):
                piece = ET.fromstring(ET.tostring(col))
                piece.set("name", f"{name}_{index}_{k}")
                piece_mesh = piece.find("geometry/mesh")
                assert piece_mesh is not None
                piece_mesh.set("filename", rel)
                piece_mesh.attrib.pop("scale", None)  # (the pieces are written scaled)
                link.insert(position + k, piece)
            report.append(
                DecomposedMesh(
                    name,
                    index,
                    uri,
                    volume,
                    hull_excess,
                    tuple(files),
                    total / volume - 1.0,
                    seconds,
                )
            )
            log.info(
                "%s collision %d: hull +%.1f %% -> %d pieces +%.1f %% (%.1f s)",
                name,
                index,
                100 * hull_excess,
                len(files),
                100 * (total / volume - 1),
                seconds,
            )
    return report
