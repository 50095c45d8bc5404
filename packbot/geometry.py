"""Convex pieces: vertex sets of the model's parts, their hulls, STL files and mass properties.

A part (:class:`packbot.params.Part`) becomes one convex polyhedron: boxes exactly, cylinders as
regular prisms with :data:`CYLINDER_SIDES` sides, stadiums (tracks, flippers) as the hull of two
such prisms. Hulls come from Qhull (``scipy.spatial.ConvexHull``); mass properties of a uniform
solid come from Coal's polyhedron integrals, so the inertia describes the very solid the
collision model uses.
"""

from __future__ import annotations

import struct

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConvexityError
from packbot.params import Part

__all__ = [
    "CYLINDER_SIDES",
    "SPHERE_RINGS",
    "convex_piece",
    "hull_triangles",
    "part_inertia",
    "part_vertices",
    "part_volume",
    "primitive_vertices",
    "solid_mass_properties",
    "stl_bytes",
]

#: Number of sides of the prisms that stand for cylinders.
CYLINDER_SIDES = 16
#: Latitude rings of the polyhedra that stand for spheres (each of 2 x this many points) [-].
SPHERE_RINGS = 8

_AXES = {"x": 0, "y": 1, "z": 2}


def _prism(radius: float, length: float, axis: str, n: int = CYLINDER_SIDES) -> NDArray[np.float64]:
    """Vertices of a regular n-gon prism centred at the origin along ``axis`` [m]."""
    ang = (np.arange(n) + 0.5) * 2 * np.pi / n
    ring = np.stack([radius * np.cos(ang), radius * np.sin(ang)], axis=1)
    k = _AXES[axis]
    others = [i for i in range(3) if i != k]
    pts = np.zeros((2 * n, 3))
    for side, h in enumerate((-length / 2, length / 2)):
        block = pts[side * n : (side + 1) * n]
        block[:, k] = h
        block[:, others[0]] = ring[:, 0]
        block[:, others[1]] = ring[:, 1]
    return pts


def _sphere_points(radius: float, rings: int = SPHERE_RINGS) -> NDArray[np.float64]:
    """Points on a sphere of ``radius`` [m]: the poles and ``rings`` rings of ``2 rings``."""
    pts = [[0.0, 0.0, radius], [0.0, 0.0, -radius]]
    for i in range(1, rings + 1):
        lat = np.pi * i / (rings + 1) - np.pi / 2
        ang = (np.arange(2 * rings) + 0.5 * (i % 2)) * np.pi / rings
        r, z = radius * np.cos(lat), radius * np.sin(lat)
        pts += [[r * np.cos(a), r * np.sin(a), z] for a in ang]
    return np.asarray(pts, dtype=np.float64)


def primitive_vertices(shape: coal.CollisionGeometry) -> NDArray[np.float64] | None:
    """Vertices of the convex piece that stands for a URDF primitive, its frame [m], (N, 3).

    A box is its 8 corners; a cylinder (axis z) a :data:`CYLINDER_SIDES`-gon prism with its
    vertices on the circle; a sphere :data:`SPHERE_RINGS` rings of points on it; a capsule two
    such half spheres. The polygonal pieces lie inside the round shapes (a modelling choice:
    a 16-gon's sides are 1.9 % of the radius inside the circle). None: not a primitive.
    """
    if isinstance(shape, coal.Box):
        half = np.asarray(shape.halfSide, dtype=float)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return np.asarray(signs * half, dtype=np.float64)
    if isinstance(shape, coal.Cylinder):
        return _prism(float(shape.radius), 2.0 * float(shape.halfLength), "z")
    if isinstance(shape, coal.Sphere):
        return _sphere_points(float(shape.radius))
    if isinstance(shape, coal.Capsule):
        ball = _sphere_points(float(shape.radius))
        h = float(shape.halfLength)
        top, bottom = ball[ball[:, 2] >= 0.0], ball[ball[:, 2] <= 0.0]
        lift = np.array([0.0, 0.0, h])
        return np.vstack([top + lift, bottom - lift])
    return None


def convex_piece(points: NDArray[np.float64]) -> coal.ConvexBase:
    """Coal's convex hull of ``points`` [m], (N, 3), with its faces (a ``coal.Convex``)."""
    vec = coal.StdVec_Vec3s()
    vec.extend(np.asarray(points, dtype=np.float64))
    return coal.Convex.convexHull(vec, True, "Qt")


def part_vertices(part: Part) -> NDArray[np.float64]:
    """Vertices of a part's convex collision piece in its link frame [m], shape (N, 3).

    A tube's collision piece is its solid outer cylinder.
    """
    c = np.asarray(part.center, dtype=float)
    if part.shape == "box":
        half = np.asarray(part.size) / 2
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return c + signs * half
    if part.shape in ("cylinder", "tube"):
        return c + _prism(part.size[0], part.size[1], part.axis)
    if part.shape == "stadium":
        x1, r1, x2, r2, width = part.size
        a = _prism(r1, width, "y") + np.array([x1, 0.0, 0.0])
        b = _prism(r2, width, "y") + np.array([x2, 0.0, 0.0])
        return c + np.vstack([a, b])
    raise ConvexityError(part.name, f"unknown shape {part.shape!r}")


def hull_triangles(points: NDArray[np.float64], name: str = "piece") -> NDArray[np.float64]:
    """Triangles of the convex hull of ``points``, outward-oriented, shape (T, 3, 3) [m].

    Raises:
        ConvexityError: The points are fewer than 4 or span no volume.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
        raise ConvexityError(name, f"needs at least 4 points in 3D, got shape {pts.shape}")
    from scipy.spatial import ConvexHull  # lazy: ~0.25 s of import, needed by generate only

    try:
        hull = ConvexHull(pts)
    except Exception as exc:  # scipy raises QhullError for flat or degenerate sets
        raise ConvexityError(name, f"degenerate point set: {exc}".splitlines()[0]) from exc
    tris = pts[hull.simplices]
    # Orient each triangle so that its normal points along the hull facet's outward normal.
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    flip = np.einsum("ij,ij->i", n, hull.equations[:, :3]) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    return tris


def stl_bytes(triangles: NDArray[np.float64], header: str = "packbot") -> bytes:
    """Binary STL of triangles (T, 3, 3), with unit normals; deterministic bytes."""
    tris = np.asarray(triangles, dtype=np.float64)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n
    rec["v"] = tris
    head = header.encode("ascii")[:80].ljust(80, b" ")
    return head + struct.pack("<I", len(tris)) + rec.tobytes()


def _coal_hull(points: NDArray[np.float64]) -> coal.ConvexBase:
    vec = coal.StdVec_Vec3s()
    for p in np.asarray(points, dtype=float):
        vec.append(p)
    return coal.Convex.convexHull(vec, True, None)


def solid_mass_properties(
    points: NDArray[np.float64],
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Volume [m^3], centroid [m] and inertia about the centroid per unit density [m^5].

    Computed by Coal on the convex hull of ``points``.
    """
    h = _coal_hull(points)
    vol = float(h.computeVolume())
    com = np.array(h.computeCOM(), dtype=float)
    inertia = np.array(h.computeMomentofInertiaRelatedToCOM(), dtype=float)
    return vol, com, inertia


def _solid_inertia(points: NDArray[np.float64], mass: float) -> pin.Inertia:
    vol, com, inertia = solid_mass_properties(points)
    rho = mass / vol
    return pin.Inertia(mass, com, rho * inertia)


def part_volume(part: Part) -> float:
    """Volume of a part's solid [m^3] (a tube's: the outer prism less the inner one), by Coal."""
    vol = solid_mass_properties(part_vertices(part))[0]
    if part.shape != "tube":
        return vol
    r_out, length, wall = part.size
    inner = np.asarray(part.center) + _prism(r_out - wall, length, part.axis)
    return vol - solid_mass_properties(inner)[0]


def part_inertia(part: Part) -> pin.Inertia:
    """Spatial inertia of a part of uniform density, in its link frame.

    A tube is the outer prism less the inner one, its mass split by volume; every other part is
    the solid of :func:`part_vertices`.
    """
    outer = part_vertices(part)
    if part.shape != "tube":
        return _solid_inertia(outer, part.mass)
    r_out, length, wall = part.size
    inner = np.asarray(part.center) + _prism(r_out - wall, length, part.axis)
    v_out = solid_mass_properties(outer)[0]
    v_in = solid_mass_properties(inner)[0]
    rho = part.mass / (v_out - v_in)
    return _solid_inertia(outer, rho * v_out) - _solid_inertia(inner, rho * v_in)
