"""Browser visualisation with meshcat: self-contained HTML animations and a live viewer.

Both draw the same scene through Pinocchio's ``MeshcatVisualizer``: the robot's visual geometry
(the URDF's STL meshes and colours) and its convex collision pieces (hidden unless asked for;
every node can be toggled in the page's "Scene" panel), the environment (the floor as a slab
under ``z = 0``, boxes, convex obstacles) and, while a contact is active (from its ``impact`` to
its ``release`` in the result's event log), a red marker at the pair's witness points and the
touching pieces turned red. A result plays as one meshcat animation clip: keyframes every
1/:data:`FPS` s of simulated time plus the event instants, scaled by ``speed`` (1 = real time).

- :func:`write_html` writes a page that needs no server and no network: meshcat's bundled
  viewer (three.js) is inlined, the scene and the clip are embedded as the viewer's own msgpack
  commands, recorded in-process by :class:`SceneRecorder` (meshcat 0.3.2's
  ``Visualizer.static_html()`` would ask a running server for them). Open it with
  ``file://...``; a fragment ``#t=0.4`` shows the pose at 0.4 s of simulated time, paused.
- :func:`start_viewer` serves the live viewer on 127.0.0.1 only (meshcat's bridge binds its
  web server to every interface whatever its ``host``; ours passes the loopback address to
  tornado) and returns a :class:`LiveViewer`.
"""

from __future__ import annotations

import asyncio
import base64
import json
import logging
import math
import os
import tempfile
import threading
import webbrowser
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import tornado.web
import umsgpack
from meshcat.animation import Animation
from meshcat.servers.tree import SceneTree, find_node, walk
from meshcat.servers.zmqserver import (
    VIEWER_ROOT,
    StaticFileHandlerNoCache,
    WebSocketHandler,
    ZMQWebSocketBridge,
)
from meshcat.visualizer import ViewerWindow
from numpy.typing import NDArray
from pinocchio.visualize import MeshcatVisualizer
from scipy.spatial import ConvexHull

from packbot.collision import CollisionWorld
from packbot.environment import Environment, Obstacle
from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.model import Robot
from packbot.result import SimResult

__all__ = [
    "CONTACT_COLOR",
    "FPS",
    "LOOPBACK",
    "ContactSpan",
    "LiveViewer",
    "SceneRecorder",
    "contact_spans",
    "html_page",
    "start_viewer",
    "write_html",
]

log = logging.getLogger(__name__)

#: Keyframes per second of simulated time [1/s].
FPS = 60.0
#: The only address the live viewer listens on.
LOOPBACK = "127.0.0.1"
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
#: Camera: the point it orbits, in the world [m] (the scene is shifted to put it at meshcat's
#: origin), and the camera's offset from it [m].
CAMERA_TARGET = (0.0, 0.0, 0.5)
CAMERA_OFFSET = (1.05, -1.3, 0.5)

_ROOT = "packbot"  # meshcat node of the robot: /meshcat/packbot/{visuals,collisions}
_ENV = "environment"
_CONTACTS = "contacts"
# Colours change this long [s] before and after an active span (a colour track interpolates).
_EDGE = 1e-4
# A keyframe is dropped where interpolating its neighbours misses it by less than this [rad].
_STILL = 1e-4


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (min(255, max(0, round(255 * float(c)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


# --------------------------------------------------------------------------- recording
class SceneRecorder:
    """A meshcat window that records commands into a scene tree instead of sending them.

    Plug it into ``meshcat.Visualizer(window=SceneRecorder())``. Every command replaces or
    extends the state of its node exactly as meshcat's server does (``set_object`` resets the
    node's properties, ``delete`` drops the subtree), so :meth:`commands` replays the final
    scene. Floats are packed in single precision (the viewer uses 32-bit floats anyway).

    Attributes:
        tree: meshcat's ``SceneTree`` of packed commands.
        web_url: Empty: nothing is served.
    """

    web_url = ""

    def __init__(self) -> None:
        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        """Record one meshcat command (``SetObject``, ``SetTransform``, ...)."""
        data = command.lower()
        kind = data["type"]
        packed = umsgpack.packb(data, force_float_precision="single")
        path = [p for p in str(data.get("path", "")).split("/") if p]
        node = find_node(self.tree, path)
        if kind == "set_object":
            node.object = packed
            node.properties = []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        elif kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree = SceneTree()
        else:
            raise ConfigurationError("meshcat command", kind, "a scene command")

    def commands(self) -> list[bytes]:
        """The packed commands that rebuild the scene: objects first, animations last."""
        out: list[bytes] = []
        animations: list[bytes] = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
            if node.animation is not None:
                animations.append(node.animation)
        return out + animations

    def open(self) -> SceneRecorder:
        """Nothing to open (meshcat's window interface)."""
        return self


# --------------------------------------------------------------------------- scene
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
        pviz = MeshcatVisualizer(robot.model, robot.collision_model, robot.visual_model)
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


def _keyframes(result: SimResult, fps: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Keyframe times [s] and q [rad] there.

    Every 1/fps s, the end and the event instants, less the keyframes that the linear
    interpolation between their kept neighbours reproduces within :data:`_STILL` (an arm at
    rest or turning steadily needs two keyframes, not one every 1/fps s).
    """
    t = np.asarray(result.t, dtype=float)
    if len(t) == 0:
        raise ConfigurationError("result.t", "empty", "a result with at least one sample")
    t0, t1 = float(t[0]), float(t[-1])
    grid = t0 + np.arange(math.floor((t1 - t0) * fps) + 1) / fps
    ev = [e.t for e in result.events if t0 <= e.t <= t1]
    t_keys = np.unique(np.concatenate([grid[grid <= t1], [t1], ev]))
    q = np.column_stack([np.interp(t_keys, t, result.q[:, j]) for j in range(result.q.shape[1])])
    # Greedy: extend the segment from the last kept key while interpolating across it
    # reproduces every key inside (the events are always kept).
    fixed = np.isin(t_keys, ev)
    keep = [0]
    for k in range(1, len(t_keys) - 1):
        a = keep[-1]
        w = (t_keys[a + 1 : k + 1] - t_keys[a]) / (t_keys[k + 1] - t_keys[a])
        err = q[a] + w[:, None] * (q[k + 1] - q[a]) - q[a + 1 : k + 1]
        if fixed[k] or np.abs(err).max() > _STILL:
            keep.append(k)
    keep.append(len(t_keys) - 1)
    return t_keys[keep], q[keep]


@dataclass(frozen=True)
class ContactSpan:
    """A time span over which a pair of pieces is in contact.

    Attributes:
        link1: Body 1 of the pair (distal link).
        link2: Body 2 (proximal link, chassis or obstacle).
        piece1: Convex piece on body 1.
        piece2: Convex piece on body 2.
        start: Time of the impact [s].
        end: Time of the release, or the end of the result [s].
    """

    link1: str
    link2: str
    piece1: str
    piece2: str
    start: float
    end: float

    @property
    def key(self) -> tuple[str, str, str, str]:
        """(link1, link2, piece1, piece2)."""
        return (self.link1, self.link2, self.piece1, self.piece2)


def contact_spans(result: SimResult) -> list[ContactSpan]:
    """The contact spans of a result's event log, in order of start.

    Each runs from an ``impact`` of a pair of pieces to the next ``release`` of that pair, or
    to the end of the result.
    """
    end = float(result.t[-1]) if len(result.t) else 0.0
    open_: dict[tuple[str, str, str, str], float] = {}
    spans: list[ContactSpan] = []
    for e in result.events:
        key = (e.link1, e.link2, e.piece1, e.piece2)
        if e.kind == "impact" and e.piece1 and e.piece2:
            open_.setdefault(key, e.t)
        elif e.kind == "release" and key in open_:
            spans.append(ContactSpan(*key, start=open_.pop(key), end=e.t))
    spans += [ContactSpan(*key, start=t, end=end) for key, t in open_.items()]
    return sorted(spans, key=lambda s: s.start)


def _merge(spans: Sequence[ContactSpan]) -> list[ContactSpan]:
    """Union of spans as spans (their pair fields are those of the first of each union)."""
    out: list[ContactSpan] = []
    for s in sorted(spans, key=lambda s: s.start):
        if out and s.start <= out[-1].end:
            last = out[-1]
            out[-1] = ContactSpan(*last.key, start=last.start, end=max(last.end, s.end))
        else:
            out.append(s)
    return out


def _check_speed(speed: float) -> float:
    if not (isinstance(speed, (int, float)) and math.isfinite(speed) and speed > 0):
        raise ConfigurationError("speed", speed, "a finite playback rate > 0 (1 = real time)")
    return float(speed)


# --------------------------------------------------------------------------- HTML
_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#packbot-caption {{ position: absolute; left: 8px; bottom: 8px; font: 13px sans-serif;
  color: #222; background: rgba(255, 255, 255, 0.7); padding: 3px 6px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="packbot-caption">{caption}</div>
<script>
{viewer_js}
</script>
<script>
// packbot: the scene and the animation clip as meshcat msgpack commands, replayed in order.
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var packbot = {settings};
packbot.commands.forEach(function (b64) {{
  var bin = atob(b64), bytes = new Uint8Array(bin.length);
  for (var i = 0; i < bin.length; i++) {{ bytes[i] = bin.charCodeAt(i); }}
  viewer.handle_command_bytearray(bytes);
}});
// "#t=0.4": show the pose at 0.4 s of simulated time, paused.
var match = /(?:^#|&)t=([0-9.eE+-]+)/.exec(window.location.hash);
if (match && viewer.animator.actions.length) {{
  var t = (parseFloat(match[1]) - packbot.t0) / packbot.speed;
  viewer.animator.pause();
  viewer.animator.seek(t);
  viewer.animator.display_progress(t);
}}
</script>
</body>
</html>
"""


def html_page(commands: Sequence[bytes], *, title: str, caption: str = "", **settings: Any) -> str:
    """A self-contained meshcat page replaying packed commands (see :class:`SceneRecorder`).

    Args:
        commands: msgpack-packed meshcat commands, replayed in order.
        title: The page title.
        caption: A line of text shown at the bottom left.
        **settings: JSON values exposed to the page as ``packbot.<name>`` (the page reads
            ``t0`` [s] and ``speed`` [-] for the ``#t=`` fragment).

    Returns:
        The HTML text, with meshcat's ``main.min.js`` (three.js included) inlined.
    """
    viewer_js = (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    if "</script" in viewer_js.lower():  # would close the inline <script> early
        raise PackbotError("meshcat's main.min.js contains '</script': cannot inline it")
    data = {"t0": 0.0, "speed": 1.0, **settings}
    data["commands"] = [base64.b64encode(c).decode("ascii") for c in commands]
    esc = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
    return _PAGE.format(
        title="".join(esc.get(c, c) for c in title),
        caption="".join(esc.get(c, c) for c in caption),
        viewer_js=viewer_js,
        settings=json.dumps(data, separators=(",", ":")),
    )


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; a page is for sharing
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_html(
    robot: Robot,
    result: SimResult,
    path: str | os.PathLike[str],
    *,
    environment: Environment | None = None,
    collision: bool = False,
    speed: float = 1.0,
) -> Path:
    """Write a self-contained HTML animation of a result (no server, no network).

    Args:
        robot: The robot the result was simulated with.
        result: The simulation result (its samples and event log).
        path: The HTML file to write (parent folders are created; written atomically).
        environment: The obstacles of the run; None means the floor alone.
        collision: Show the convex collision pieces instead of the visual meshes (both are
            in the page's scene panel).
        speed: Playback rate: 1 plays at real time, 0.25 four times slower [-].

    Returns:
        The path written.

    Raises:
        ConfigurationError: A bad ``speed`` or an empty result.
    """
    speed = _check_speed(speed)
    recorder = SceneRecorder()
    viewer = meshcat.Visualizer(window=recorder)
    scene = _Scene.load(robot, viewer, environment, collision)
    scene.place(np.asarray(result.q[0], dtype=float))
    viewer.set_animation(scene.animation(result, speed), play=True, repetitions=1)
    t0, t1 = float(result.t[0]), float(result.t[-1])
    n_contacts = len(contact_spans(result))
    caption = (
        f"packbot: {t1 - t0:.3g} s simulated, played at {speed:g}x real time; "
        f"{len(result.events)} events, {n_contacts} contact spans (red). "
        "Open 'Animations' to replay or scrub."
    )
    out = Path(path)
    html = html_page(recorder.commands(), title="packbot", caption=caption, t0=t0, speed=speed)
    _write_atomic(out, html)
    log.info("wrote %s (%.1f MB)", out, len(html) / 1e6)
    return out


# --------------------------------------------------------------------------- live viewer
class _LoopbackApplication(tornado.web.Application):
    """A tornado application whose ``listen`` binds the loopback address only."""

    server: Any = None

    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
        """Listen on ``LOOPBACK``:port, whatever address is asked for."""
        self.server = super().listen(port, address=LOOPBACK, **kwargs)
        return self.server


class _QuietWebSocketHandler(WebSocketHandler):
    """meshcat's websocket handler, logging instead of printing."""

    def open(self) -> None:
        self.bridge.websocket_pool.add(self)
        log.info("browser connected to the viewer")
        self.bridge.send_scene(self)

    def on_close(self) -> None:
        self.bridge.websocket_pool.discard(self)
        log.info("browser disconnected from the viewer")


def _log_request(handler: tornado.web.RequestHandler) -> None:
    log.debug("%d %s", handler.get_status(), handler.request.uri)


class _LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's ZMQ-to-websocket bridge, serving on 127.0.0.1 only.

    Its ZMQ socket binds ``tcp://{host}:port``, with host 127.0.0.1 already.
    """

    def make_app(self) -> _LoopbackApplication:
        return _LoopbackApplication(
            [
                (
                    r"/static/(.*)",
                    StaticFileHandlerNoCache,
                    {"path": VIEWER_ROOT, "default_filename": "index.html"},
                ),
                (r"/", _QuietWebSocketHandler, {"bridge": self}),
            ],
            log_function=_log_request,
        )


class _Window(ViewerWindow):
    """meshcat's ZMQ client window for a bridge already running (prints nothing)."""

    def __init__(self, zmq_url: str, web_url: str) -> None:
        self.server_proc = None
        self.zmq_url = zmq_url
        self.web_url = web_url
        self.connect_zmq()

    def close(self) -> None:
        self.zmq_socket.close(linger=0)


class LiveViewer:
    """A meshcat viewer served on 127.0.0.1, its server running in a background thread.

    Use :func:`start_viewer` to make one; close it (or use it as a context manager) to stop
    the server. A browser that connects late receives the whole scene, animation included.

    Attributes:
        url: The page to open, ``http://127.0.0.1:PORT/static/``.
        port: The web server's TCP port.
        zmq_url: The bridge's ZMQ endpoint (``tcp://127.0.0.1:...``).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        environment: Environment | None = None,
        port: int | None = None,
        collision: bool = False,
    ) -> None:
        self._bridge: _LoopbackBridge | None = None
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        ready = threading.Event()
        self._thread = threading.Thread(
            target=self._serve, args=(port, ready), name="packbot-meshcat", daemon=True
        )
        self._thread.start()
        ready.wait(30.0)
        if self._error is not None or self._bridge is None:
            self._thread.join(5.0)
            if isinstance(self._error, OSError):
                raise ConfigurationError(
                    "port", port, f"a free TCP port on {LOOPBACK} ({self._error})"
                ) from self._error
            raise PackbotError(f"the meshcat server did not start: {self._error!r}")
        bridge = self._bridge
        self.port: int = int(bridge.fileserver_port)
        self.zmq_url: str = str(bridge.zmq_url)
        self.url: str = str(bridge.web_url)
        self._window: _Window = _Window(self.zmq_url, self.url)
        self.viewer: meshcat.Visualizer = meshcat.Visualizer(window=self._window)
        self._scene: _Scene = _Scene.load(robot, self.viewer, environment, collision)
        self._robot: Robot = robot
        self.display(robot.pose("drive") if "drive" in robot.poses else np.zeros(robot.nq))

    def _serve(self, port: int | None, ready: threading.Event) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._loop = loop

        async def make() -> _LoopbackBridge:
            return _LoopbackBridge(host=LOOPBACK, port=port)

        try:
            self._bridge = loop.run_until_complete(make())
        except BaseException as exc:  # reported to the caller's thread
            self._error = exc
            ready.set()
            loop.close()
            return
        ready.set()
        bridge = self._bridge
        try:
            loop.run_forever()
        finally:
            bridge.app.server.stop()
            for ws in list(bridge.websocket_pool):
                ws.close()
            bridge.zmq_stream.close()
            bridge.zmq_socket.close(linger=0)
            loop.run_until_complete(asyncio.sleep(0))
            loop.close()

    def display(self, q: Sequence[float] | NDArray[np.float64]) -> None:
        """Show the robot at configuration q [rad] (shape (nq,))."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self._robot.nq,):
            raise ConfigurationError("q", q.shape, f"shape ({self._robot.nq},)")
        self._scene.place(q)

    def play(self, result: SimResult, speed: float = 1.0) -> None:
        """Send a result as an animation clip; connected browsers play it at once.

        Args:
            result: The simulation result.
            speed: Playback rate: 1 is real time, 0.25 four times slower [-].
        """
        speed = _check_speed(speed)
        self.display(result.q[0])
        anim = self._scene.animation(result, speed)
        self.viewer.set_animation(anim, play=True, repetitions=1)

    def open(self) -> None:
        """Open the viewer's page in the default web browser."""
        webbrowser.open(self.url, new=2)

    def close(self) -> None:
        """Stop the server and release its ports (idempotent)."""
        if self._thread.is_alive() and self._loop is not None:
            self._window.close()
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10.0)

    def __enter__(self) -> LiveViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def start_viewer(
    robot: Robot,
    *,
    environment: Environment | None = None,
    port: int | None = None,
    open_browser: bool = False,
    collision: bool = False,
) -> LiveViewer:
    """Start a live meshcat viewer listening on 127.0.0.1 only, showing the robot.

    Args:
        robot: The robot to show (drawn in its ``drive`` pose).
        environment: The obstacles; None means the floor alone.
        port: The web server's TCP port; None takes the first free one from 7000.
        open_browser: Open the page in the default browser.
        collision: Show the convex collision pieces instead of the visual meshes.

    Returns:
        The running viewer; its ``url`` is the page to open.

    Raises:
        ConfigurationError: The port is taken.
    """
    viewer = LiveViewer(robot, environment=environment, port=port, collision=collision)
    if open_browser:
        viewer.open()
    return viewer
