"""Browser visualisation: the recorded HTML page, the live viewer on 127.0.0.1, and a real
headless Chromium drawing both (skipped only where chromium could not be installed)."""

from __future__ import annotations

import asyncio
import base64
import dataclasses
import json
import math
import os
import re
import shutil
import socket
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from matplotlib.image import imread
from tornado.websocket import websocket_connect

import packbot
from packbot.errors import ConfigurationError
from packbot.labels import event_label
from packbot.result import Event
from packbot.viz import (
    CONTACT_COLOR,
    FPS,
    LOOPBACK,
    contact_spans,
    start_viewer,
    write_html,
)
from packbot.viz.html import screenshot_command
from packbot.viz.scene import CAMERA_FOV, CAMERA_OFFSET, _camera_offset

LOCKED = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def collapse(robot: packbot.Robot) -> packbot.SimResult:
    """One second of the report's collapse: two impacts before 0.2 s, at rest by 0.6 s."""
    config = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=LOCKED)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.0, config=config)


@pytest.fixture(scope="module")
def page(robot: packbot.Robot, collapse: packbot.SimResult, tmp_path_factory) -> Path:
    return write_html(robot, collapse, tmp_path_factory.mktemp("html") / "collapse.html")


def _settings(html: str) -> dict[str, Any]:
    """The page's embedded settings (``var packbot = {...}``)."""
    m = re.search(r"var packbot = (\{.*?\});\n", html)
    assert m is not None, "no embedded command list"
    return json.loads(m.group(1))


def _commands(html: str) -> list[dict[str, Any]]:
    """The meshcat commands embedded in a page, decoded."""
    return [umsgpack.unpackb(base64.b64decode(c)) for c in _settings(html)["commands"]]


def _clips(cmds: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Animation clips by node path: {path: {track name: (times [s], values)}}."""
    anims = [c for c in cmds if c["type"] == "set_animation"]
    assert len(anims) == 1
    out: dict[str, dict[str, Any]] = {}
    for a in anims[0]["animations"]:
        clip = a["clip"]
        out[a["path"]] = {
            t["name"]: (
                np.array([k["time"] for k in t["keys"]]) / clip["fps"],
                [k["value"] for k in t["keys"]],
            )
            for t in clip["tracks"]
        }
    return out


def _placements(robot: packbot.Robot, q: np.ndarray) -> tuple[pin.GeometryData, pin.GeometryModel]:
    data = robot.model.createData()
    gd = robot.visual_model.createData()
    pin.updateGeometryPlacements(robot.model, data, robot.visual_model, gd, q)
    return gd, robot.visual_model


# --------------------------------------------------------------------------- contact spans
def test_contact_spans_follow_the_event_log(collapse: packbot.SimResult) -> None:
    impacts = [e for e in collapse.events if e.kind == "impact"]
    assert len(impacts) >= 2
    spans = contact_spans(collapse)
    # No release in this run: one span per distinct pair, from its first impact to the end.
    pairs = {(e.link1, e.link2, e.piece1, e.piece2) for e in impacts}
    assert {s.key for s in spans} == pairs
    for s in spans:
        first = min(e.t for e in impacts if (e.link1, e.link2, e.piece1, e.piece2) == s.key)
        assert s.start == first
        assert s.end == collapse.t[-1]
    # A release closes its pair's span; a later impact of the pair opens a new one.
    e0 = impacts[0]
    rel = dataclasses.replace(e0, t=e0.t + 0.05, kind="release", relevant_joints=())
    again = dataclasses.replace(e0, t=e0.t + 0.1)
    # a clamp's release (it names its joint) leaves the pair in contact: it ends no span
    clamp = dataclasses.replace(e0, t=e0.t + 0.02, kind="release", relevant_joints=("elbow1",))
    events: list[Event] = sorted([*collapse.events, clamp, rel, again], key=lambda e: e.t)
    spans2 = [s for s in contact_spans(dataclasses.replace(collapse, events=events))]
    mine = [s for s in spans2 if s.key == (e0.link1, e0.link2, e0.piece1, e0.piece2)]
    assert [(s.start, s.end) for s in mine] == [
        (e0.t, e0.t + 0.05),
        (e0.t + 0.1, collapse.t[-1]),
    ]


# --------------------------------------------------------------------------- the HTML page
def test_page_is_self_contained(page: Path) -> None:
    html = page.read_text(encoding="utf-8")
    viewer_js = (
        Path(__import__("meshcat").__file__).parent / "viewer" / "dist" / "main.min.js"
    ).read_text(encoding="utf-8")
    assert viewer_js in html  # three.js and the meshcat viewer inlined
    # Nothing loaded from elsewhere: no external script, stylesheet, image, fetch or socket.
    assert not re.search(r"""<(script|link|img|iframe)[^>]+(src|href)\s*=""", html, re.I)
    assert not re.search(r"""fetch\(\s*["'`]https?:""", html)
    ours = html.replace(viewer_js, "")
    assert "http" not in ours and ".connect(" not in ours and "WebSocket" not in ours


def test_page_embeds_meshes_floor_and_a_real_time_clip(
    robot: packbot.Robot, collapse: packbot.SimResult, page: Path
) -> None:
    cmds = _commands(page.read_text(encoding="utf-8"))
    objects = {c["path"]: c for c in cmds if c["type"] == "set_object"}
    for go in robot.visual_model.geometryObjects:
        obj = objects[f"/meshcat/packbot/visuals/{go.name}"]["object"]
        stl = Path(go.meshPath).read_bytes()
        assert bytes(obj["geometries"][0]["data"].data) == stl  # the URDF's mesh, embedded
    for go in robot.collision_model.geometryObjects:
        assert f"/meshcat/packbot/collisions/{go.name}" in objects
    assert "/meshcat/environment/floor" in objects
    clips = _clips(cmds)
    duration = collapse.t[-1] - collapse.t[0]
    # Every moving visual piece is animated, at real time, ending on the result's last pose.
    gd, gm = _placements(robot, collapse.q[-1])
    moving = [k for k, go in enumerate(gm.geometryObjects) if go.parentJoint > 0]
    assert len(moving) >= 15
    for k in moving:
        tracks = clips[f"/meshcat/packbot/visuals/{gm.geometryObjects[k].name}"]
        times, values = tracks[".position"]
        assert times[0] == 0.0
        assert times[-1] == pytest.approx(duration, rel=1e-6)
        np.testing.assert_allclose(values[-1], gd.oMg[k].translation, atol=2e-6)
        _, qv = tracks[".quaternion"]
        quat = pin.Quaternion(gd.oMg[k].rotation)
        assert abs(float(np.dot(qv[-1], [quat.x, quat.y, quat.z, quat.w]))) == pytest.approx(
            1.0, abs=1e-5
        )
    # Between keyframes (every 1/FPS s while the arm moves, fewer where interpolation
    # reproduces the motion) the drawn gripper is within 1 mm of where the result has it.
    k = gm.getGeometryId("gripper_link/palm")
    times, values = clips["/meshcat/packbot/visuals/gripper_link/palm"][".position"]
    times = times + collapse.t[0]
    drawn = np.column_stack(
        [np.interp(collapse.t, times, np.array(values)[:, i]) for i in range(3)]
    )
    for i, q in enumerate(collapse.q):
        gd, _ = _placements(robot, q)
        assert np.linalg.norm(drawn[i] - gd.oMg[k].translation) < 1e-3, collapse.t[i]
    assert len(times) < 0.8 * duration * FPS  # the arm is at rest after 0.6 s
    assert np.diff(times[times < 0.55]).max() <= 1.0 / FPS + 1e-9
    for e in collapse.events:
        assert np.min(np.abs(times - e.t)) < 1e-5


def test_speed_slows_the_clip(
    robot: packbot.Robot, collapse: packbot.SimResult, tmp_path: Path
) -> None:
    slow = write_html(robot, collapse, tmp_path / "slow.html", speed=0.25)
    clips = _clips(_commands(slow.read_text(encoding="utf-8")))
    times = clips["/meshcat/packbot/visuals/link3/tube"][".position"][0]
    assert times[-1] == pytest.approx(4 * (collapse.t[-1] - collapse.t[0]), rel=1e-6)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ConfigurationError, match="speed"):
            write_html(robot, collapse, tmp_path / "bad.html", speed=bad)
    assert not (tmp_path / "bad.html").exists()


def test_contacts_marked_while_active(
    robot: packbot.Robot, collapse: packbot.SimResult, page: Path
) -> None:
    clips = _clips(_commands(page.read_text(encoding="utf-8")))
    world = packbot.CollisionWorld(robot)
    spans = contact_spans(collapse)
    for k, s in enumerate(spans):
        vis_t, vis_v = clips[f"/meshcat/contacts/{k}"][".visible"]
        assert vis_v[0] is False and vis_t[0] == 0.0
        on = np.flatnonzero(np.array(vis_v))
        assert vis_t[on[0]] == pytest.approx(s.start - collapse.t[0], abs=1e-6)
        # The marker sits between the pair's witness points at the impact.
        pos_t, pos_v = clips[f"/meshcat/contacts/{k}"][".position"]
        i = int(np.argmin(np.abs(pos_t - (s.start - collapse.t[0]))))
        q = collapse.q[int(np.flatnonzero(collapse.t == s.start)[-1])]
        c = world.pair_contact(q, world.pair_index(s.link1, s.link2, s.piece1, s.piece2)[0])
        np.testing.assert_allclose(pos_v[i], (c.p1 + c.p2) / 2, atol=1e-5)
        # The moving piece turns red at the impact; it had its own colour before.
        col_t, col_v = clips[f"/meshcat/packbot/visuals/{s.piece1}/<object>"][".material.color"]
        j = int(np.argmin(np.abs(col_t - (s.start - collapse.t[0]))))
        np.testing.assert_allclose(col_v[j], CONTACT_COLOR, atol=1e-6)
        assert not np.allclose(col_v[0], CONTACT_COLOR)


def test_obstacles_drawn(robot: packbot.Robot, collapse: packbot.SimResult, tmp_path: Path) -> None:
    box = packbot.Obstacle(name="crate", kind="box", size=(0.3, 0.2, 0.1), xyz=(0.8, 0, 0.05))
    pts = ((0.6, 0.4, 0), (0.9, 0.4, 0), (0.75, 0.7, 0), (0.75, 0.5, 0.3), (0.7, 0.5, 0.1))
    rock = packbot.Obstacle(name="rock", kind="convex", points=pts)
    env = packbot.Environment().with_obstacles(box, rock)
    path = write_html(robot, collapse, tmp_path / "env.html", environment=env, collision=True)
    cmds = _commands(path.read_text(encoding="utf-8"))
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    geom = objects["/meshcat/environment/crate"]["geometries"][0]
    assert geom["type"] == "BoxGeometry"
    sizes = [geom["width"], geom["height"], geom["depth"]]
    np.testing.assert_allclose(sizes, box.size, rtol=1e-6)  # float32
    assert "/meshcat/environment/rock" in objects
    props = {(c["path"], c["property"]): c["value"] for c in cmds if c["type"] == "set_property"}
    assert props[("/meshcat/packbot/collisions", "visible")] is True
    assert props[("/meshcat/packbot/visuals", "visible")] is False


def test_obstacles_come_with_the_result(
    robot: packbot.Robot, collapse: packbot.SimResult, tmp_path: Path
) -> None:
    """The result carries its environment: the page draws it without being told again."""
    box = packbot.Obstacle(name="crate", kind="box", size=(0.3, 0.2, 0.1), xyz=(0.8, 0, 0.05))
    env = packbot.Environment().with_obstacles(box)
    res = dataclasses.replace(collapse, environment=env)
    cmds = _commands(write_html(robot, res, tmp_path / "env.html").read_text(encoding="utf-8"))
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert {"/meshcat/environment/crate", "/meshcat/environment/floor"} <= objects
    # an environment passed explicitly still wins
    other = write_html(robot, res, tmp_path / "bare.html", environment=packbot.Environment())
    cmds = _commands(other.read_text(encoding="utf-8"))
    assert "/meshcat/environment/crate" not in {c.get("path") for c in cmds}


def test_page_has_controls_and_the_event_list(collapse: packbot.SimResult, page: Path) -> None:
    html = page.read_text(encoding="utf-8")
    for control in ("packbot-play", "packbot-speed", "packbot-slider", "packbot-event-list"):
        assert f'id="{control}"' in html
    data = _settings(html)
    assert (data["t0"], data["t1"], data["speed"]) == (collapse.t[0], collapse.t[-1], 1.0)
    assert [(e["t"], e["label"]) for e in data["events"]] == [
        (e.t, event_label(e)) for e in collapse.events
    ]
    assert "impact link3\u2013link1" in {e["label"] for e in data["events"]}


def test_camera_frames_the_motion(
    robot: packbot.Robot, collapse: packbot.SimResult, page: Path
) -> None:
    """The scene is centred on the motion's box; the camera backs off until it fits."""
    html = page.read_text(encoding="utf-8")
    cmds = _commands(html)
    cam = _settings(html)["camera"]
    # the last of each command wins (the scene's defaults come first)
    shift = [c for c in cmds if c["type"] == "set_transform" and c["path"] == "/meshcat"][-1]
    centre = -np.array(shift["matrix"]).reshape(4, 4).T[:3, 3]
    radius = cam["radius"]
    # every piece's origin stays inside the sphere over the whole clip, and the sphere is
    # snug: the pieces reach near its edge (within the pieces' own size, 0.35 m)
    clips = _clips(cmds)
    far = 0.0
    for go in robot.visual_model.geometryObjects:
        tracks = clips.get(f"/meshcat/packbot/visuals/{go.name}")
        if tracks is None:
            continue
        d = np.linalg.norm(np.array(tracks[".position"][1]) - centre, axis=1)
        assert d.max() <= radius
        far = max(far, float(d.max()))
    assert far > radius - 0.35
    # the recorded camera (a 4:3 window) at the distance where the sphere fits
    pos = [
        c["value"]
        for c in cmds
        if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"
    ][-1]
    expect = _camera_offset(radius, 4.0 / 3.0)
    np.testing.assert_allclose(pos, [expect[0], expect[2], -expect[1]], rtol=1e-6)  # float32
    half = np.radians(CAMERA_FOV) / 2
    assert np.linalg.norm(pos) == pytest.approx(radius / np.sin(half))
    u = np.asarray(CAMERA_OFFSET) / np.linalg.norm(CAMERA_OFFSET)
    np.testing.assert_allclose(cam["direction"], u)


# --------------------------------------------------------------------------- live viewer
def _listening_sockets() -> list[tuple[str, int]]:
    """(address, port) of this process's listening TCP sockets, from /proc."""
    if not Path("/proc/self/fd").is_dir():
        pytest.skip("no /proc: cannot list this process's sockets")
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            link = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    out = []
    for name, family in (("tcp", socket.AF_INET), ("tcp6", socket.AF_INET6)):
        table = Path(f"/proc/net/{name}")
        if not table.exists():
            continue
        for line in table.read_text().splitlines()[1:]:
            f = line.split()
            if f[3] != "0A" or f[9] not in inodes:  # 0A: LISTEN
                continue
            addr_hex, port_hex = f[1].split(":")
            raw = bytes.fromhex(addr_hex)
            raw = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
            out.append((socket.inet_ntop(family, raw), int(port_hex, 16)))
    return out


def test_live_viewer_listens_on_loopback_only(robot: packbot.Robot) -> None:
    with start_viewer(robot) as viewer:
        assert viewer.url == f"http://{LOOPBACK}:{viewer.port}/static/"
        zmq_port = int(viewer.zmq_url.rsplit(":", 1)[1])
        listening = _listening_sockets()
        ports = {p for _, p in listening}
        assert {viewer.port, zmq_port} <= ports
        assert all(addr == LOOPBACK for addr, _ in listening), listening
    # Closed: both ports released (libzmq closes its listener in its own thread, soon after).
    for _ in range(50):
        if not {viewer.port, zmq_port} & {p for _, p in _listening_sockets()}:
            break
        time.sleep(0.1)
    assert not {viewer.port, zmq_port} & {p for _, p in _listening_sockets()}


def test_live_viewer_streams_scene_poses_and_clip(
    robot: packbot.Robot, collapse: packbot.SimResult
) -> None:
    q = robot.pose("stand")
    gd, gm = _placements(robot, q)
    k = gm.getGeometryId("link3/tube")

    async def session(port: int, viewer) -> tuple[list[dict], dict, dict]:
        ws = await websocket_connect(f"ws://{LOOPBACK}:{port}/")
        scene = []
        while True:  # the scene replayed on connection
            try:
                msg = await asyncio.wait_for(ws.read_message(), 0.5)
            except asyncio.TimeoutError:
                break
            scene.append(umsgpack.unpackb(msg))
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(None, viewer.display, q)
        while True:
            pose = umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 5.0))
            if pose["path"] == "/meshcat/packbot/visuals/link3/tube":
                break
        await loop.run_in_executor(None, viewer.play, collapse, 0.5)
        while True:
            clip = umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 5.0))
            if clip["type"] == "set_animation":
                ws.close()
                return scene, pose, clip

    with start_viewer(robot) as viewer:
        scene, cmd, clip = asyncio.run(session(viewer.port, viewer))
    objects = {c["path"] for c in scene if c["type"] == "set_object"}
    assert {f"/meshcat/packbot/visuals/{go.name}" for go in gm.geometryObjects} <= objects
    M = np.array(cmd["matrix"]).reshape(4, 4).T
    np.testing.assert_allclose(M, gd.oMg[k].homogeneous, atol=1e-12)
    # play(): the result's clip, at half speed, for every moving piece.
    paths = {a["path"] for a in clip["animations"]}
    assert "/meshcat/packbot/visuals/link3/tube" in paths
    for a in clip["animations"]:
        if not a["path"].startswith("/meshcat/packbot/visuals/") or "<" in a["path"]:
            continue
        keys = next(t["keys"] for t in a["clip"]["tracks"] if t["name"] == ".position")
        assert keys[-1]["time"] / a["clip"]["fps"] == pytest.approx(2 * collapse.t[-1], rel=1e-6)


def test_live_viewer_port_taken(robot: packbot.Robot) -> None:
    with start_viewer(robot) as first:
        with pytest.raises(ConfigurationError, match="port"):
            start_viewer(robot, port=first.port)
        first.display(robot.pose("stow"))  # still serving


# --------------------------------------------------------------------------- real browser
@pytest.fixture(scope="module")
def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip(
        "chromium could not be installed on this machine (.ci/run installs Debian's chromium "
        "with apt-get): the real-browser tests are skipped"
    )


def _screenshot(chromium: str, url: str, out: Path) -> np.ndarray:
    profile = out.parent / f"profile-{out.stem}"
    cmd = screenshot_command(chromium, url, out, profile)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and out.exists(), proc.stderr[-2000:]
    return np.asarray(imread(out))[..., :3]


def _arm(img: np.ndarray) -> np.ndarray:
    """Pixels of the arm's yellow-tan (URDF colours of the turret and links 1-3)."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 0.35) & (r - b > 0.2) & (g - b > 0.15)


def _red(img: np.ndarray) -> np.ndarray:
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 0.5) & (g < 0.25) & (b < 0.25)


def _scene(img: np.ndarray) -> np.ndarray:
    """The 3D view of a page's screenshot, less the event list (left) and the bar (bottom)."""
    h, w = img.shape[:2]
    return img[: h - 70, int(0.3 * w) :]


def test_browser_draws_the_animation(
    chromium: str, collapse: packbot.SimResult, page: Path, tmp_path: Path
) -> None:
    t_contact = contact_spans(collapse)[0].start + 0.02
    start = _screenshot(chromium, f"{page.as_uri()}#t=0", tmp_path / "start.png")
    contact = _screenshot(chromium, f"{page.as_uri()}#t={t_contact:.3f}", tmp_path / "c.png")
    end = _screenshot(chromium, f"{page.as_uri()}#t={collapse.t[-1]:.3f}", tmp_path / "end.png")
    start, contact, end = _scene(start), _scene(contact), _scene(end)
    n_pixels = start.shape[0] * start.shape[1]
    for img in (start, contact, end):
        assert _arm(img).sum() > 0.004 * n_pixels  # the arm is drawn, in the view
        # framed: the arm's pixels do not touch the view's top or right edge
        assert not _arm(img)[:3].any() and not _arm(img)[:, -3:].any()
    # The arm moved between the two times; no contact at the start, red pieces during one.
    assert (_arm(start) ^ _arm(end)).sum() > 0.001 * n_pixels
    assert _red(start).sum() < 50
    assert _red(contact).sum() > 0.0005 * n_pixels


def _dom(chromium: str, url: str, tmp_path: Path, budget_ms: int) -> str:
    """The page's DOM after ``budget_ms`` of virtual time in a headless Chromium."""
    cmd = [
        c
        for c in screenshot_command(chromium, url, tmp_path / "x.png", tmp_path / "profile-dom")
        if not c.startswith(("--screenshot", "--virtual-time-budget"))
    ]
    cmd[-1:-1] = ["--dump-dom", f"--virtual-time-budget={budget_ms}"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def _body_data(dom: str) -> dict[str, str]:
    m = re.search(r"<body([^>]*)>", dom)
    assert m is not None
    return dict(re.findall(r'data-([a-z]+)="([^"]*)"', m.group(1)))


def test_browser_page_opens_at_the_start_and_plays(
    chromium: str, robot: packbot.Robot, collapse: packbot.SimResult, tmp_path: Path
) -> None:
    """Played at 1/100 of real time (the 1 s run lasts 100 s), a few seconds after opening it
    is a little past the start, playing; the event list is built, one entry per event; a
    fragment shows its time, paused."""
    slow = write_html(robot, collapse, tmp_path / "slow.html", speed=0.01)
    dom = _dom(chromium, slow.as_uri(), tmp_path, 3000)
    body = _body_data(dom)
    assert body["playing"] == "true"
    # the budget's 3 s of virtual time at 0.01x: 0.03 s of the run, well under 0.5 s, which a
    # page opening on its last pose would pass (1 s). Chromium can run well past the budget: at
    # 0.05x a loaded CI machine showed 0.69 s (about 14 s of virtual time)
    assert 0.0 < float(body["time"]) < 0.5
    assert dom.count('title="jump to ') == len(collapse.events)
    assert f"Events ({len(collapse.events)})" in dom
    body = _body_data(_dom(chromium, f"{slow.as_uri()}#t=0.4", tmp_path, 1000))
    assert body == {"time": "0.400000", "playing": "false"}


def test_browser_draws_the_live_viewer(chromium: str, robot: packbot.Robot, tmp_path: Path) -> None:
    with start_viewer(robot) as viewer:
        viewer.display(robot.pose("stand"))
        img = _screenshot(chromium, viewer.url, tmp_path / "live.png")
    assert _arm(img).sum() > 0.002 * img.shape[0] * img.shape[1]


# --------------------------------------------------------------------------- command line
def test_main_job_writes_the_animation(tmp_path: Path) -> None:
    """The README's first command (`packbot collapse --out DIR`) writes the page too."""
    from packbot.cli import main

    assert main(["collapse", "--duration", "0.3", "--out", str(tmp_path)]) == 0
    html = (tmp_path / "collapse.html").read_text(encoding="utf-8")
    cmds = _commands(html)
    assert any(c["type"] == "set_animation" for c in cmds)
    assert "/meshcat/packbot/visuals/link3/tube" in {c["path"] for c in cmds}
