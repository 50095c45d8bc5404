"""The collision world's queries outside the pair sweep: one pair, patches, line of sight.

One pair's distance and the contact patches are the compiled sweep's calls
(:mod:`packbot.native_sweep`); the line of sight calls Coal directly on the pieces placed at q
(:meth:`CollisionWorld.line_of_sight <packbot.collision.CollisionWorld.line_of_sight>`
delegates here; its docstring is the contract).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, UnknownNameError

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld
    from packbot.collision_records import Contact

__all__ = [
    "LOS_SHORTEN",
    "line_of_sight",
    "material_batch",
    "patch_batch",
    "point_contact",
]

#: The line of sight stops this short of the target [m], so that a target on a surface is seen.
LOS_SHORTEN = 1e-3


def point_contact(world: CollisionWorld, q: NDArray[np.float64], k: int) -> Contact:
    """One pair's signed distance, witness points and normal at q, in one native call.

    :meth:`CollisionWorld.pair_contact <packbot.collision.CollisionWorld.pair_contact>` of the
    tested pair ``k`` by the world's compiled sweep (``Sweep.point_distance``, with GJK warm
    starts of its own).

    Raises:
        ConfigurationError: A wrong-size q.
    """
    qa = np.ascontiguousarray(q, dtype=np.float64)
    try:
        d, p1, p2, normal = world._native.point_distance(qa, k)
    except (ValueError, TypeError) as exc:  # the extension's size/type check
        nq = world.robot.model.nq
        raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc
    dispatch = world.dispatch
    dispatch.pending = qa.tobytes()  # (the pieces owed at q, as after _place(q))
    return dispatch._contact(world.pairs[k], float(d), p1, p2, normal)


def patch_batch(
    world: CollisionWorld, q: NDArray[np.float64], pairs: list[int], tol: float
) -> tuple[NDArray[Any], ...]:
    """The contact patches of checked ``pairs`` at q (the compiled sweep's ``patches``).

    Returns:
        (sizes, normals, depths, points1, points2, rotations, translations): per pair its
        number of patch points K (-1: farther apart than ``tol``), normal, signed distance [m];
        the patches' points on pieces 1 and 2, pair after pair, (sum K, 3) [m]; the two pieces'
        world placements, rotations (n, 2, 3, 3) (each Fortran-ordered, as Pinocchio's) and
        translations (n, 2, 3) [m].

    Raises:
        ConfigurationError: A wrong-size q.
    """
    out = _native_query(world, q, "patches", pairs, float(tol))
    sizes, normals, depths, pts1, pts2, rot, trans = out
    return sizes, normals, depths, pts1, pts2, rot.swapaxes(2, 3), trans


def material_batch(
    world: CollisionWorld,
    q: NDArray[np.float64],
    pairs: list[int],
    tol: float,
    patch_tol: float,
    face_align: float,
    planes: Callable[[], tuple[NDArray[Any], ...]],
) -> tuple[NDArray[Any], ...]:
    """The contact patches of checked ``pairs`` at q as material points.

    The patches of :func:`patch_batch`, each made material points by the
    extension (``Sweep.materials``: the patch materials of ``src/native/material.hpp``)
    with the pieces' face planes (``planes() -> (N, o, start)``,
    loaded once per native sweep), the patch tolerance ``patch_tol`` [m], and whether nothing
    lags on the patch (its normal a face's within ``face_align``).

    Returns:
        (sizes, flags, normals, depths, rotations, translations, local1, local2, offset0,
        normal2, frame2, centres): see the extension's ``Sweep.materials``; the rotations
        Fortran-ordered, as :func:`patch_batch`'s.

    Raises:
        ConfigurationError: A wrong-size q.
    """
    out = _native_query(world, q, "materials", pairs, float(tol), patch_tol, face_align, planes)
    rot = out[4]
    return (*out[:4], rot.swapaxes(2, 3), *out[5:])


def _native_query(
    world: CollisionWorld, q: NDArray[np.float64], name: str, pairs: list[int], *args: Any
) -> tuple[NDArray[Any], ...]:
    """The world's compiled sweep's ``name(q, pairs, *args)``.

    The pieces of ``geom_data`` are then owed at q (placed on first read, as after a reused
    sweep).

    Raises:
        ConfigurationError: A wrong-size q.
    """
    qa = np.ascontiguousarray(q, dtype=np.float64)
    try:
        out = getattr(world._native, name)(qa, np.asarray(pairs, dtype=np.int64), *args)
    except (ValueError, TypeError) as exc:  # the extension's size/type check
        nq = world.robot.model.nq
        raise ConfigurationError("q", np.shape(q), f"a vector of shape ({nq},) [rad]") from exc
    world.dispatch.pending = qa.tobytes()
    return tuple(out)


def line_of_sight(
    world: CollisionWorld,
    q: NDArray[np.float64],
    target: NDArray[np.float64],
    frame: str,
    radius: float,
    ignore: tuple[str, ...],
) -> str | None:
    """The blocking link or obstacle nearest to the eye, or None (see the method).

    Raises:
        UnknownNameError: An unknown frame, or an unknown link or obstacle in ``ignore``.
        ConfigurationError: A target that is not 3 finite numbers, or a negative radius.
    """
    model = world.robot.model
    if not model.existFrame(frame):
        raise UnknownNameError("frame", frame, [f.name for f in model.frames])
    for name in ignore:
        if name not in world.links:
            raise UnknownNameError("link or obstacle", name, world.links)
    b = np.asarray(target, dtype=float)
    if b.shape != (3,) or not np.all(np.isfinite(b)):
        raise ConfigurationError("target", target, "a world point: 3 finite numbers [m]")
    if not radius >= 0.0:
        raise ConfigurationError("radius", radius, "a non-negative radius [m]")
    world._place(q)
    data = world._data
    fid = model.getFrameId(frame)
    pin.updateFramePlacement(model, data, fid)
    a = data.oMf[fid].translation.copy()
    seg = b - a
    full = float(np.linalg.norm(seg))
    reach = full - LOS_SHORTEN  # the capsule spans [a, a + reach * u]
    if reach <= 0.0:
        return None
    u = seg / full
    r = min(float(radius), reach / 2)
    R = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), u).matrix()
    T = coal.Transform3s(R, a + u * reach / 2)
    cap = coal.Capsule(r, reach - 2 * r)  # coal: full cylinder length, axis z, centred
    best: tuple[float, str] | None = None
    req = coal.DistanceRequest()
    res = coal.DistanceResult()
    ignored = set(ignore)
    link_of_geom = world._link_of_geom
    for g, go in enumerate(world.geom_model.geometryObjects):
        name = link_of_geom[g]
        if name in ignored:
            continue
        res.clear()
        d = coal.distance(cap, T, go.geometry, _to_coal(world.geom_data.oMg[g]), req, res)
        if d <= 0.0:
            dist_from_eye = float(np.dot(np.array(res.getNearestPoint2()) - a, u))
            if best is None or dist_from_eye < best[0]:
                best = (dist_from_eye, name)
    return None if best is None else best[1]


def _to_coal(M: pin.SE3) -> coal.Transform3s:
    return coal.Transform3s(M.rotation, M.translation)
