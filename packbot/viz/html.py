"""Self-contained HTML animations: a page replaying recorded meshcat commands offline.

The page needs no server and no network: meshcat's bundled viewer (three.js) is inlined, the
scene and the clip are embedded as the viewer's own msgpack commands, recorded in-process by
:class:`~packbot.viz.recorder.SceneRecorder` (meshcat 0.3.2's ``Visualizer.static_html()``
would ask a running server for them). Open it with ``file://...``; a fragment ``#t=0.4`` shows
the pose at 0.4 s of simulated time, paused.
"""

from __future__ import annotations

import base64
import json
import logging
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import meshcat
import numpy as np
from meshcat.servers.zmqserver import VIEWER_ROOT

from packbot.environment import Environment
from packbot.errors import PackbotError
from packbot.model import Robot
from packbot.result import SimResult
from packbot.viz.contacts import contact_spans
from packbot.viz.keyframes import _check_speed
from packbot.viz.recorder import SceneRecorder
from packbot.viz.scene import _Scene

__all__ = ["html_page", "screenshot_command", "write_html"]

log = logging.getLogger(__name__)

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


def screenshot_command(browser: str, url: str, png: Path | str, profile: Path | str) -> list[str]:
    """The command line that screenshots ``url`` into ``png`` with a headless Chromium.

    Software WebGL (SwiftShader), a fresh profile directory ``profile``, no background
    networking (a closed network otherwise stalls the start), a 1024x768 window and 3 s of
    virtual time for the page's animation to reach the time in its URL fragment (``#t=...``).
    Used by the browser tests and ``benchmarks/readme_figures.py``.
    """
    return [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--window-size=1024,768",
        "--virtual-time-budget=3000",
        f"--screenshot={png}",
        url,
    ]
