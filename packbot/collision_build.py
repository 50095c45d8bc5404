"""The collision world's fixed parts: its geometry models, pieces, pairs and broadphase boxes.

Built once per robot, environment and SRDF (:func:`fixed_parts`, with a cache of the last few
built) and shared read-only by every :class:`~packbot.collision.CollisionWorld` of them (each
world has its own compiled sweep and data). The pair filters and the broadphase boxes are
described in :mod:`packbot.collision`.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.environment import Environment
from packbot.errors import ConfigurationError
from packbot.model import Robot

if TYPE_CHECKING:
    from packbot.collision_records import PairInfo

__all__ = [
    "BOX_PAD",
    "GJK_TOLERANCE",
    "HALFSPACE_BOX",
    "Built",
    "fixed_parts",
    "structure_key",
]

log = logging.getLogger("packbot.collision")  # (the SRDF's pairs: logged as before)

#: Padding of every piece's bounding box [m]: covers the rounding of the box arithmetic, so
#: that the pruned sweep never drops a pair that the unpruned one finds within the margin.
BOX_PAD = 1e-9
#: A halfspace's infinite box sides are clipped to +-HALFSPACE_BOX [m] in the broadphase (Coal's
#: broadphase inflates a box, not a halfspace; 1e6 m keeps the rounding of the finite face
#: under BOX_PAD).
HALFSPACE_BOX = 1e6
#: Absolute GJK and EPA tolerance [m].
GJK_TOLERANCE = 1e-10

#: A world's fixed parts (:func:`build`): geometry model with its pairs, the broadphase's
#: model, each piece's link and body, the links, the pairs, their flat indices.
Built = tuple[
    pin.GeometryModel,
    pin.GeometryModel,
    list[str],
    NDArray[np.intp],
    tuple[str, ...],
    tuple["PairInfo", ...],
]
#: The fixed parts of the worlds built so far, by :func:`structure_key` (the last few: a
#: simulation builds its world at every phase, a batch of runs the same worlds again).
_BUILT: dict[tuple[object, ...], Built] = {}
_BUILT_MAX = 16


def fixed_parts(robot: Robot, environment: Environment, srdf_path: Path | None) -> Built:
    """The fixed parts of a world of ``robot`` in ``environment``: built, or the cache's.

    Raises:
        ConfigurationError: An obstacle named like a link.
    """
    key = structure_key(robot, environment, srdf_path)
    built = _BUILT.get(key) if key is not None else None
    if built is None:
        built = build(robot, environment, srdf_path)
        if key is not None:
            if len(_BUILT) >= _BUILT_MAX:
                del _BUILT[next(iter(_BUILT))]
            _BUILT[key] = built
    return built


def structure_key(
    robot: Robot, environment: Environment, srdf: Path | None
) -> tuple[object, ...] | None:
    """What a world's fixed parts are made of, by value; None: not to be shared.

    Every robot piece (name, joint, frame and its link, placement, the convex's vertices), the
    model's joint names, the links joined by one joint, the environment (a frozen dataclass)
    and the SRDF file (path, modification time and size). Two worlds with equal keys have
    equal geometry models, pairs and broadphase boxes. Costs about 0.1 ms (the build, 3 to 4).
    """
    try:
        hash(environment)
    except TypeError:  # an environment with unhashable parts: built every time
        return None
    model = robot.model
    pieces = []
    for go in robot.collision_model.geometryObjects:
        geom = go.geometry
        if not isinstance(geom, coal.ConvexBase):
            return None
        pieces.append(
            (
                go.name,
                int(go.parentJoint),
                int(go.parentFrame),
                str(model.frames[go.parentFrame].name),
                go.placement.homogeneous.tobytes(),
                np.asarray(geom.points(), dtype=float).tobytes(),
            )
        )
    if srdf is None:
        srdf_id: tuple[object, ...] | None = None
    else:
        st = srdf.stat()
        srdf_id = (str(srdf.resolve()), st.st_mtime_ns, st.st_size)
    return (tuple(pieces), tuple(model.names), robot.adjacent_links, environment, srdf_id)


def _link_name(model: pin.Model, geom: pin.GeometryObject) -> str:
    return str(model.frames[geom.parentFrame].name)


def build(robot: Robot, environment: Environment, srdf_path: Path | None) -> Built:
    """The world's fixed parts: its geometry models, pieces and pairs (see structure_key).

    Read-only once built: the worlds of the same robot, environment and SRDF share them
    (each has its own compiled sweep and data).

    Raises:
        ConfigurationError: An obstacle named like a link.
    """
    model = robot.model
    gm = robot.collision_model.copy()
    link_of_geom = [_link_name(model, go) for go in gm.geometryObjects]
    # Obstacles: static, one "body" each (body id -1 - k).
    body_list = [int(go.parentJoint) for go in gm.geometryObjects]
    for k, ob in enumerate(environment.obstacles):
        if ob.name in set(link_of_geom):
            raise ConfigurationError("obstacle.name", ob.name, "a name that is not a link")
        go = pin.GeometryObject(f"{ob.name}", 0, 0, ob.placement(), ob.shape())
        gm.addGeometryObject(go)
        link_of_geom.append(ob.name)
        body_list.append(-1 - k)
    body_of_geom = np.array(body_list)
    links: tuple[str, ...] = tuple(dict.fromkeys(link_of_geom))
    for g1, g2 in candidate_geom_pairs(robot, gm.ngeoms, link_of_geom, body_of_geom):
        gm.addCollisionPair(pin.CollisionPair(g1, g2))
    if srdf_path is not None:
        n_before = len(gm.collisionPairs)
        pin.removeCollisionPairs(model, gm, str(srdf_path))
        log.debug(
            "SRDF %s removed %d of %d pairs",
            srdf_path,
            n_before - len(gm.collisionPairs),
            n_before,
        )
    pairs = pair_infos(gm, link_of_geom, body_of_geom)
    return (
        gm,
        broadphase_model(gm, body_of_geom, environment),
        link_of_geom,
        body_of_geom,
        links,
        pairs,
    )


# ---------------------------------------------------------------------- pairs
def _is_static(body: int) -> bool:
    return body <= 0


def _adjacent(
    robot: Robot, link_of_geom: list[str], body_of_geom: NDArray[np.intp], g1: int, g2: int
) -> bool:
    """Pieces on links joined by one joint of the healthy arm (see Robot.adjacent_links)."""
    if body_of_geom[g1] < 0 or body_of_geom[g2] < 0:
        return False  # obstacles
    link1, link2 = link_of_geom[g1], link_of_geom[g2]
    return frozenset((link1, link2)) in robot.adjacent_links


def candidate_geom_pairs(
    robot: Robot, n: int, link_of_geom: list[str], body_of_geom: NDArray[np.intp]
) -> list[tuple[int, int]]:
    """Geometry pairs on different, non-adjacent bodies, not both static; distal first.

    Args:
        robot: The robot (its links joined by one joint).
        n: Number of pieces (robot and obstacles).
        link_of_geom: Each piece's link or obstacle name.
        body_of_geom: Each piece's body: its joint index, ``-1 - k`` for obstacle k.
    """
    bodies = body_of_geom
    out = []
    for i in range(n):
        for j in range(i + 1, n):
            b_i, b_j = int(bodies[i]), int(bodies[j])
            if b_i == b_j or (_is_static(b_i) and _is_static(b_j)):
                continue
            if _adjacent(robot, link_of_geom, body_of_geom, i, j):
                continue
            # piece 1 on the more distal body; static bodies (<= 0) always second
            out.append((i, j) if b_i > b_j else (j, i))
    return out


def pair_infos(
    gm: pin.GeometryModel, link_of_geom: list[str], body_of_geom: NDArray[np.intp]
) -> tuple[PairInfo, ...]:
    """The pairs of the geometry model ``gm``, in its order (piece 1 distal)."""
    from packbot.collision_records import PairInfo

    gos = gm.geometryObjects
    out = []
    for index, cp in enumerate(gm.collisionPairs):
        g1, g2 = int(cp.first), int(cp.second)
        out.append(
            PairInfo(
                index=index,
                geom1=g1,
                geom2=g2,
                link1=link_of_geom[g1],
                link2=link_of_geom[g2],
                piece1=gos[g1].name,
                piece2=gos[g2].name,
                joint1=int(max(body_of_geom[g1], 0)),
                joint2=int(max(body_of_geom[g2], 0)),
            )
        )
    return tuple(out)


# ---------------------------------------------------------------------- broadphase
def broadphase_model(
    gm: pin.GeometryModel, body_of_geom: NDArray[np.intp], environment: Environment
) -> pin.GeometryModel:
    """The broadphase boxes as a geometry model (the compiled sweep's boxes are built from it).

    The broadphase model has one box per piece and the same pairs in the same order as
    ``gm``, so that its pair indices are the world's. A moving piece's box is the box of its
    vertices in its joint's frame, a static piece's (chassis, obstacles) in the world frame,
    padded by ``BOX_PAD``; a halfspace's is infinite on its open sides (clipped to
    :data:`HALFSPACE_BOX`) and on all sides unless it is axis-aligned. Coal takes the world
    box of that box (``R c + t +- |R| h``), which the sweep inflates by half the query
    margin.
    """
    bp_model = pin.GeometryModel()
    bodies = body_of_geom
    for g, go in enumerate(gm.geometryObjects):
        b = int(bodies[g])
        if b >= 0:  # the joint frame (the world frame for the chassis, on joint 0)
            M = go.placement
            pts = np.asarray(go.geometry.points(), dtype=float) @ M.rotation.T + M.translation
            lo, hi = pts.min(axis=0), pts.max(axis=0)
        else:
            lo, hi = environment.obstacles[-1 - b].world_aabb()
            lo = np.clip(lo, -HALFSPACE_BOX, HALFSPACE_BOX)
            hi = np.clip(hi, -HALFSPACE_BOX, HALFSPACE_BOX)
        lo, hi = lo - BOX_PAD, hi + BOX_PAD  # covers rounding: the boxes stay conservative
        box = coal.Box(*(hi - lo))  # a positive volume: the manager would skip a flat one
        box.computeLocalAABB()
        centre = pin.SE3(np.eye(3), (lo + hi) / 2)
        bp_model.addGeometryObject(
            pin.GeometryObject(go.name, go.parentJoint, go.parentFrame, centre, box)
        )
    for cp in gm.collisionPairs:
        bp_model.addCollisionPair(pin.CollisionPair(int(cp.first), int(cp.second)))
    assert [(c.first, c.second) for c in bp_model.collisionPairs] == [
        (c.first, c.second) for c in gm.collisionPairs
    ]  # Pinocchio appends pairs in order: a pair index means the same in both models
    return bp_model
