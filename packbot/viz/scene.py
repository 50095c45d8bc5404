"""The scene drawn in a meshcat visualizer: the robot, its environment and its contacts.

The robot's visual geometry (the URDF's STL meshes and colours) and its convex collision pieces
(hidden unless asked for) go through Pinocchio's ``MeshcatVisualizer``; the environment is the
floor as a slab under ``z = 0``, boxes and convex obstacles. :meth:`_Scene.animation` turns a
result into one meshcat animation clip, with a red marker at each touching pair's witness points
and the touching pieces turned red while a contact is active.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation
from numpy.typing import NDArray
from pinocchio.visualize import MeshcatVisualizer
from scipy.spatial import ConvexHull

from packbot.collision import CollisionWorld
from packbot.environment import Environment, Obstacle
from packbot.errors import UnknownNameError
from packbot.model import Robot
from packbot.result import SimResult
from packbot.viz.contacts import ContactSpan, _merge, contact_spans
from packbot.viz.keyframes import FPS, _keyframes

__all__ = [
    "CAMERA_FOV",
    "CAMERA_OFFSET",
    "CAMERA_TARGET",
    "COLLISION_RGBA",
    "CONTACT_COLOR",
    "FLOOR_COLOR",
    "FORCE_COLOR",
    "FORCE_RADIUS",
    "FORCE_SCALE",
    "MARKER_RADIUS",
    "OBSTACLE_COLOR",
    "SLAB_GAP",
    "SLAB_HALF",
    "SLAB_THICKNESS",
]

log = logging.getLogger(__name__)

#: Colour of contact markers and of touching pieces (RGB in [0, 1]).
CONTACT_COLOR = (0.9, 0.05, 0.05)
#: Colour of collision pieces when shown (RGBA).
COLLISION_RGBA = (0.3, 0.6, 0.95, 0.85)
#: Colour of obstacles (RGB); the floor is neutral grey.
OBSTACLE_COLOR = (0.45, 0.55, 0.75)
FLOOR_COLOR = (0.78, 0.78, 0.78)
#: Half extent of the slab drawn for a halfspace [m], and its thickness [m].
SLAB_HALF = 3.0
SLAB_THICKNESS = 0.02
#: Gap between a halfspace's surface and the slab's top [m] (keeps meshcat's grid visible).
SLAB_GAP = 0.002
#: Contact marker radius [m].
MARKER_RADIUS = 0.025
#: Contact force bars: length per newton [m/N], radius [m] and colour (RGB in [0, 1]).
FORCE_SCALE = 2e-3
FORCE_RADIUS = 0.006
FORCE_COLOR = (1.0, 0.55, 0.0)
#: Camera: the point it orbits, in the world [m] (the scene is shifted to put it at meshcat's
#: origin), and the camera's offset from it [m] (the live viewer's; a page fits its camera to
#: the motion, looking from the same direction: :meth:`_Scene.frame`).
CAMERA_TARGET = (0.0, 0.0, 0.5)
CAMERA_OFFSET = (1.05, -1.3, 0.5)
#: meshcat's camera: vertical field of view [deg].
CAMERA_FOV = 75.0

_ROOT = "packbot"  # meshcat node of the robot: /meshcat/packbot/{visuals,collisions}
_ENV = "environment"
_CONTACTS = "contacts"
_FORCES = "contact_forces"
# Colours change this long [s] before and after an active span (a colour track interpolates).
_EDGE = 1e-4


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (min(255, max(0, round(255 * float(c)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def _slab(ob: Obstacle) -> tuple[mg.Geometry, NDArray[np.float64]]:
    """A thin box under a halfspace's surface, and its pose (4x4) in the world."""
    n = np.asarray(ob.normal, dtype=float)
    nn = float(np.linalg.norm(n))
    n = n / nn
    centre = n * (ob.offset / nn - SLAB_GAP - SLAB_THICKNESS / 2)
    R = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), n).toRotationMatrix()
    return mg.Box([2 * SLAB_HALF, 2 * SLAB_HALF, SLAB_THICKNESS]), pin.SE3(R, centre).homogeneous


def _obstacle_geometry(ob: Obstacle) -> tuple[mg.Geometry, NDArray[np.float64]]:
    """The meshcat geometry of an obstacle and its pose (4x4) in the world."""
    if ob.kind == "halfspace":
        return _slab(ob)
    M = ob.placement().homogeneous
    if ob.kind == "box":
        return mg.Box(list(ob.size)), M
    pts = np.asarray(ob.points, dtype=float)
    hull = ConvexHull(pts)
    # Orient every face outward (Qhull's simplices have no consistent winding).
    faces = hull.simplices.copy()
    centre = pts[hull.vertices].mean(axis=0)
    for k, f in enumerate(faces):
        a, b, c = pts[f]
        if np.dot(np.cross(b - a, c - a), a - centre) < 0:
            faces[k] = f[[0, 2, 1]]
    return mg.TriangularMeshGeometry(pts, faces), M


def _obstacle_color(ob: Obstacle) -> tuple[float, float, float]:
    return FLOOR_COLOR if ob.kind == "halfspace" else OBSTACLE_COLOR


def _camera_offset(radius: float, aspect: float) -> NDArray[np.float64]:
    """The camera's offset [m] from the centre of a sphere of ``radius`` [m] that it frames.

    Along :data:`CAMERA_OFFSET`, at the distance where the sphere fits the narrower of the
    vertical field of view (:data:`CAMERA_FOV`) and the horizontal one at ``aspect`` (width /
    height) [-]. The page redoes this for its window (the same formula in JavaScript).
    """
    half = np.radians(CAMERA_FOV) / 2
    half = min(half, float(np.arctan(np.tan(half) * aspect)))
    direction = np.asarray(CAMERA_OFFSET, dtype=float)
    return direction / np.linalg.norm(direction) * (radius / np.sin(half))


@dataclass
class _Scene:
    """The robot, its environment and where each piece is drawn in a meshcat visualizer."""

    robot: Robot
    environment: Environment
    viewer: meshcat.Visualizer
    pviz: MeshcatVisualizer

    @classmethod
    def load(
        cls,
        robot: Robot,
        viewer: meshcat.Visualizer,
        environment: Environment | None,
        collision: bool,
    ) -> _Scene:
        env = Environment() if environment is None else environment
        env.validate()
        # An arm whose URDF has no <visual> is shown by its collision pieces.
        visual = robot.visual_model if robot.visual_model.ngeoms else robot.collision_model
        pviz = MeshcatVisualizer(robot.model, robot.collision_model, visual)
        pviz.initViewer(viewer=viewer)
        pviz.loadViewerModel(rootNodeName=_ROOT, collision_color=list(COLLISION_RGBA))
        pviz.displayCollisions(collision)
        pviz.displayVisuals(not collision)
        for ob in env.obstacles:
            geom, M = _obstacle_geometry(ob)
            node = viewer[f"{_ENV}/{ob.name}"]
            node.set_object(geom, mg.MeshPhongMaterial(color=_hex(_obstacle_color(ob))))
            node.set_transform(M)
        # The floor slab replaces meshcat's grid; the world axes would hide in the chassis.
        viewer["/Grid"].set_property("visible", False)
        viewer["/Axes"].set_property("visible", False)
        # The camera orbits the world origin: shift the scene so that CAMERA_TARGET is there.
        # The camera node is y-up: (x, y, z) there is (x, z, -y) in the world.
        viewer.set_transform(pin.SE3(np.eye(3), -np.asarray(CAMERA_TARGET)).homogeneous)
        x, y, z = CAMERA_OFFSET
        viewer["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])
        return cls(robot, env, viewer, pviz)

    def motion_bounds(
        self, q_keys: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The world box [m] holding every visual piece at every configuration of ``q_keys``.

        Each piece's local bounding box (of its mesh as loaded, scale included) placed at each
        configuration: its eight corners.

        Returns:
            ``(lo, hi)``, each shape (3,).
        """
        gm, gd = self.pviz.visual_model, self.pviz.visual_data
        corners = []
        for go in gm.geometryObjects:
            go.geometry.computeLocalAABB()
            box = go.geometry.aabb_local
            corners.append(np.array(list(itertools.product(*zip(box.min_, box.max_, strict=True)))))
        data = self.robot.model.createData()
        pts = []
        for q in np.atleast_2d(q_keys):
            pin.updateGeometryPlacements(self.robot.model, data, gm, gd, q)
            for k, c in enumerate(corners):
                M = gd.oMg[k]
                pts.append(c @ M.rotation.T + M.translation)
        allpts = np.concatenate(pts)
        return allpts.min(axis=0), allpts.max(axis=0)

    def frame(self, lo: NDArray[np.float64], hi: NDArray[np.float64], aspect: float) -> float:
        """Aim the camera at the box [lo, hi] [m], from :data:`CAMERA_OFFSET`'s direction.

        The scene is shifted to put the box's centre at the point the camera orbits, and the
        camera backed off until the box's bounding sphere fits its field of view at the given
        width/height ``aspect`` [-].

        Returns:
            The sphere's radius [m].
        """
        centre = 0.5 * (np.asarray(lo) + np.asarray(hi))
        radius = max(0.5 * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))), 0.05)
        self.viewer.set_transform(pin.SE3(np.eye(3), -centre).homogeneous)
        x, y, z = _camera_offset(radius, aspect)
        self.viewer["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])
        return radius

    def geometry_nodes(self) -> list[tuple[pin.GeometryModel, pin.GeometryData, str]]:
        """(model, data, meshcat group) of the visual and the collision geometry."""
        return [
            (self.pviz.visual_model, self.pviz.visual_data, self.pviz.viewerVisualGroupName),
            (
                self.pviz.collision_model,
                self.pviz.collision_data,
                self.pviz.viewerCollisionGroupName,
            ),
        ]

    def piece_nodes(self, piece: str) -> list[tuple[str, tuple[float, float, float]]]:
        """Mesh nodes (visual and collision) drawing a moving robot piece, with their colours.

        None for the chassis and obstacles (large and static: the marker suffices).
        """
        out: list[tuple[str, tuple[float, float, float]]] = []
        for gm, _, group in self.geometry_nodes():
            if gm.existGeometryName(piece):
                go = gm.geometryObjects[gm.getGeometryId(piece)]
                if go.parentJoint == 0:
                    continue
                c = COLLISION_RGBA if group.endswith("collisions") else go.meshColor
                out.append((f"{group}/{piece}/<object>", (float(c[0]), float(c[1]), float(c[2]))))
        return out

    def place(self, q: NDArray[np.float64]) -> None:
        """Place every visual and collision node at configuration q [rad]."""
        pin.forwardKinematics(self.robot.model, self.pviz.data, q)
        for gm, gd, group in self.geometry_nodes():
            pin.updateGeometryPlacements(self.robot.model, self.pviz.data, gm, gd)
            for k, go in enumerate(gm.geometryObjects):
                self.viewer[f"{group}/{go.name}"].set_transform(gd.oMg[k].homogeneous)

    def animation(self, result: SimResult, speed: float) -> Animation:
        """The result as a meshcat animation clip (time scaled by 1/speed)."""
        t_keys, q_keys = _keyframes(result, FPS)
        anim = Animation(default_framerate=FPS * speed)
        frames = (t_keys - t_keys[0]) * FPS
        model, data = self.robot.model, self.pviz.data
        geoms = self.geometry_nodes()
        for frame, q in zip(frames, q_keys, strict=True):
            pin.forwardKinematics(model, data, q)
            with anim.at_frame(self.viewer, float(frame)) as fv:
                for gm, gd, group in geoms:
                    pin.updateGeometryPlacements(model, data, gm, gd)
                    for k, go in enumerate(gm.geometryObjects):
                        if go.parentJoint > 0:  # the chassis pieces stay where place() put them
                            node = fv[f"{group}/{go.name}"]
                            M = gd.oMg[k]
                            # meshcat's set_transform, with Pinocchio's faster quaternion
                            node.set_property("position", "vector3", M.translation.tolist())
                            xyzw = pin.Quaternion(M.rotation).coeffs().tolist()
                            node.set_property("quaternion", "quaternion", xyzw)
        self._animate_contacts(anim, result, t_keys, q_keys)
        self._animate_forces(anim, result, t_keys)
        return anim

    def _animate_contacts(
        self,
        anim: Animation,
        result: SimResult,
        t_keys: NDArray[np.float64],
        q_keys: NDArray[np.float64],
    ) -> None:
        spans = contact_spans(result)
        if not spans:
            return
        world = CollisionWorld(self.robot, self.environment)
        t0 = float(t_keys[0])
        by_pair: dict[tuple[str, str, str, str], list[ContactSpan]] = {}
        for s in spans:
            by_pair.setdefault(s.key, []).append(s)
        by_piece: dict[str, list[ContactSpan]] = {}
        for k, (key, pair_spans) in enumerate(by_pair.items()):
            for piece in (key[2], key[3]):
                by_piece.setdefault(piece, []).extend(pair_spans)
            try:
                index = world.pair_index(key[0], key[1], key[2], key[3])[0]
            except (UnknownNameError, IndexError):
                log.warning("contact %s is not a pair of this environment: no marker", key)
                continue
            node = f"{_CONTACTS}/{k}"
            # Drawn through the bodies around it (no depth test; transparent: drawn last).
            marker = mg.MeshPhongMaterial(
                color=_hex(CONTACT_COLOR), opacity=0.9, transparent=True, depthTest=False
            )
            self.viewer[node].set_object(mg.Sphere(MARKER_RADIUS), marker)
            self.viewer[node].set_property("visible", False)
            active = np.zeros(len(t_keys), dtype=bool)
            for s in pair_spans:
                active |= (t_keys >= s.start) & (t_keys <= s.end)
            for t, q in zip(t_keys[active], q_keys[active], strict=True):
                c = world.pair_contact(q, index)
                M = np.eye(4)
                M[:3, 3] = (c.p1 + c.p2) / 2
                anim.at_frame(self.viewer, (t - t0) * FPS)[node].set_transform(M)
            vis = anim.at_frame(self.viewer, 0.0)[node]
            vis.set_property("visible", "boolean", False)
            for s in _merge(pair_spans):
                anim.at_frame(self.viewer, (s.start - t0) * FPS)[node].set_property(
                    "visible", "boolean", True
                )
                if s.end < float(t_keys[-1]):
                    anim.at_frame(self.viewer, (s.end - t0) * FPS + _EDGE)[node].set_property(
                        "visible", "boolean", False
                    )
        for piece, piece_spans in by_piece.items():
            for path, rgb in self.piece_nodes(piece):
                track = [(0.0, rgb)]
                for s in _merge(piece_spans):
                    a, b = (s.start - t0) * FPS, (s.end - t0) * FPS
                    track += [(max(a - _EDGE, 0.0), rgb), (a, CONTACT_COLOR)]
                    track += [(b, CONTACT_COLOR), (b + _EDGE, rgb)]
                for frame, colour in track:
                    anim.at_frame(self.viewer, frame)[path].set_property(
                        "material.color", "color", list(colour)
                    )

    def _animate_forces(
        self, anim: Animation, result: SimResult, t_keys: NDArray[np.float64]
    ) -> None:
        """Each pair's contact force on the arm as a bar from its contact (``FORCE_SCALE``).

        At each keyframe the last sample's forces (:attr:`SimResult.contacts`): the pair's
        summed force on body 1 (the arm's distal body: the opposite of the recorded force on
        body 2), drawn from the mean of its points, its length FORCE_SCALE per newton; hidden
        while the pair carries no force.
        """
        tab = result.contacts
        if not len(tab):
            return
        t = np.asarray(result.t)
        t0 = float(t_keys[0])
        at = np.clip(np.searchsorted(t, t_keys + 1e-12, side="right") - 1, 0, len(t) - 1)
        n = len(t)
        total = np.zeros((len(tab.pairs), n, 3))
        np.add.at(total, (tab.pair, tab.sample), -tab.force)
        where = np.zeros((len(tab.pairs), n, 3))
        np.add.at(where, (tab.pair, tab.sample), tab.point)
        count = np.zeros((len(tab.pairs), n))
        np.add.at(count, (tab.pair, tab.sample), 1.0)
        material = mg.MeshPhongMaterial(
            color=_hex(FORCE_COLOR), opacity=0.95, transparent=True, depthTest=False
        )
        for k in range(len(tab.pairs)):
            node = f"{_FORCES}/{k}"
            self.viewer[node].set_object(mg.Cylinder(1.0, FORCE_RADIUS), material)
            self.viewer[node].set_property("visible", False)
            shown = None
            for key, s in zip(t_keys, at.tolist(), strict=True):
                frame = anim.at_frame(self.viewer, (float(key) - t0) * FPS)[node]
                F = total[k, s]
                length = float(np.linalg.norm(F)) * FORCE_SCALE
                on = count[k, s] > 0 and length > 1e-6
                if on != shown:
                    frame.set_property("visible", "boolean", bool(on))
                    shown = on
                if on:
                    centre = where[k, s] / count[k, s] + 0.5 * length * F / np.linalg.norm(F)
                    position, xyzw = _bar(centre, F)
                    frame.set_property("position", "vector3", position)
                    frame.set_property("quaternion", "quaternion", xyzw)
                    frame.set_property("scale", "vector3", [1.0, length, 1.0])


def _bar(start: NDArray[np.float64], force: NDArray[np.float64]) -> tuple[list[float], list[float]]:
    """A unit cylinder's position and quaternion (x, y, z, w) for a bar along ``force``.

    meshcat's cylinder lies along y, centred at ``start`` here; its length is the y scale.
    """
    d = force / np.linalg.norm(force)
    # a rotation taking y to d (the other axes any orthonormal completion)
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(d, a)
    x /= np.linalg.norm(x)
    z = np.cross(x, d)
    R = np.column_stack([x, d, z])
    return start.tolist(), pin.Quaternion(R).coeffs().tolist()
