"""Self-contained HTML animations: a page replaying recorded meshcat commands offline.

The page needs no server and no network: meshcat's bundled viewer (three.js) is inlined, the
scene and the clip are embedded as the viewer's own msgpack commands, recorded in-process by
:class:`~packbot.viz.recorder.SceneRecorder` (meshcat 0.3.2's ``Visualizer.static_html()``
would ask a running server for them). Open it with ``file://...``: it plays the run once from
its start, with play/pause, speed, a time slider and the list of events to jump to; a fragment
``#t=0.4`` shows the pose at 0.4 s of simulated time, paused.
"""

from __future__ import annotations

import base64
import html as html_lib
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
from packbot.labels import event_label
from packbot.model import Robot
from packbot.result import SimResult
from packbot.viz.contacts import contact_spans
from packbot.viz.keyframes import FPS, _check_speed, _keyframes
from packbot.viz.recorder import SceneRecorder
from packbot.viz.scene import CAMERA_FOV, CAMERA_OFFSET, _Scene

__all__ = [
    "EVENT_CSS",
    "html_page",
    "screenshot_command",
    "script_json",
    "write_html",
]

log = logging.getLogger(__name__)

# The window shape [-] (width / height) the recorded camera is fitted for; the page refits it
# to its own window.
_ASPECT = 4.0 / 3.0

_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; font: 13px sans-serif; color: #222; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
.packbot-box {{ background: rgba(255, 255, 255, 0.85); border-radius: 4px;
  box-shadow: 0 1px 3px rgba(0, 0, 0, 0.25); }}
#packbot-side {{ position: absolute; left: 8px; top: 8px; max-width: 40vw;
  max-height: calc(100vh - 80px); display: flex; flex-direction: column; gap: 6px; }}
#packbot-caption {{ padding: 4px 8px; }}
#packbot-events {{ overflow-y: auto; min-height: 0; max-height: 45vh; padding: 4px 0;
  align-self: flex-start; }}
#packbot-events summary {{ font-weight: bold; margin: 2px 8px 4px; cursor: pointer; }}
#packbot-events ol {{ list-style: none; margin: 0; padding: 0; }}
#packbot-events button {{ display: block; width: 100%; text-align: left; border: 0;
  background: none; padding: 2px 8px; font: 12px monospace; cursor: pointer;
  white-space: nowrap; }}
#packbot-events button:hover {{ background: rgba(0, 0, 0, 0.08); }}
#packbot-events button.current {{ background: rgba(255, 215, 0, 0.45); }}
#packbot-events .kind {{ display: inline-block; width: 9px; height: 9px; margin-right: 5px;
  border-radius: 2px; vertical-align: middle; }}
#packbot-bar {{ position: absolute; left: 8px; right: 8px; bottom: 8px; padding: 6px 10px;
  display: flex; align-items: center; gap: 10px; }}
#packbot-play {{ width: 34px; height: 28px; font-size: 16px; cursor: pointer; }}
#packbot-track {{ position: relative; flex: 1; height: 28px; }}
#packbot-slider {{ position: absolute; left: 0; right: 0; top: 8px; width: 100%; margin: 0; }}
#packbot-ticks {{ position: absolute; left: 8px; right: 8px; top: 0; height: 8px; }}
#packbot-ticks span {{ position: absolute; top: 0; width: 2px; height: 8px;
  margin-left: -1px; cursor: pointer; }}
#packbot-time {{ font: 12px monospace; min-width: 150px; text-align: right; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="packbot-side">
<div id="packbot-caption" class="packbot-box">{caption}</div>
<details id="packbot-events" class="packbot-box" open>
<summary id="packbot-events-title">Events</summary><ol id="packbot-event-list"></ol></details>
</div>
<div id="packbot-bar" class="packbot-box">
<button id="packbot-play" type="button" title="play / pause (space)">&#10074;&#10074;</button>
<label>speed <select id="packbot-speed" title="playback rate (1 = real time)"></select></label>
<div id="packbot-track"><div id="packbot-ticks"></div>
<input id="packbot-slider" type="range" min="0" max="1" step="any" value="0"
 title="simulated time"></div>
<span id="packbot-time"></span>
</div>
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
(function () {{
  var el = function (id) {{ return document.getElementById(id); }};
  // The camera frames the motion: the sphere around it fits the window's field of view.
  function fitCamera() {{
    var cam = packbot.camera;
    if (!cam) {{ return; }}
    var aspect = window.innerWidth / Math.max(window.innerHeight, 1);
    var half = cam.fov * Math.PI / 360;
    half = Math.min(half, Math.atan(Math.tan(half) * aspect));
    var d = cam.radius / Math.sin(half), u = cam.direction;
    viewer.set_property(["Cameras", "default", "rotated", "<object>"], "position",
                        [u[0] * d, u[2] * d, -u[1] * d]);
    viewer.set_dirty();
  }}
  fitCamera();
  window.addEventListener("resize", fitCamera);
  var anim = viewer.animator;
  var duration = packbot.t1 - packbot.t0;  // simulated [s]
  if (!anim.actions.length || !(duration > 0)) {{
    el("packbot-bar").style.display = "none";
    return;
  }}
  anim.pause();  // the page drives the clip: clip time = simulated time / packbot.speed
  if (anim.folder && anim.folder.domElement) {{ anim.folder.domElement.style.display = "none"; }}
  var state = {{ t: 0, playing: false, rate: packbot.speed, last: null }};
  var slider = el("packbot-slider"), play = el("packbot-play"), speed = el("packbot-speed");
  slider.max = duration;
  var rates = [0.05, 0.1, 0.25, 0.5, 1, 2];
  if (rates.indexOf(packbot.speed) < 0) {{
    rates.push(packbot.speed);
    rates.sort(function (a, b) {{ return a - b; }});
  }}
  rates.forEach(function (r) {{
    var o = document.createElement("option");
    o.value = r; o.textContent = r + "x"; o.selected = r === packbot.speed;
    speed.appendChild(o);
  }});
  speed.addEventListener("change", function () {{ state.rate = parseFloat(speed.value); }});
  // The event list and the ticks over the slider: a click jumps there (paused).
  var items = [];
  el("packbot-events-title").textContent = "Events (" + packbot.events.length + ")";
  packbot.events.forEach(function (ev) {{
    var li = document.createElement("li"), b = document.createElement("button");
    var dot = document.createElement("span");
    dot.className = "kind"; dot.style.background = ev.color;
    b.appendChild(dot);
    b.appendChild(document.createTextNode(ev.t.toFixed(3) + " s  " + ev.label));
    b.title = "jump to " + ev.t.toFixed(4) + " s";
    b.addEventListener("click", function () {{
      b.blur();  // the space key stays play/pause
      setPlaying(false);
      show(ev.t - packbot.t0);
    }});
    li.appendChild(b);
    el("packbot-event-list").appendChild(li);
    items.push({{ t: ev.t - packbot.t0, button: b }});
    var tick = document.createElement("span");
    tick.style.left = (100 * (ev.t - packbot.t0) / duration) + "%";
    tick.style.background = ev.color;
    tick.title = ev.t.toFixed(3) + " s " + ev.label;
    tick.addEventListener("click", function () {{ setPlaying(false); show(ev.t - packbot.t0); }});
    el("packbot-ticks").appendChild(tick);
  }});
  if (!packbot.events.length) {{ el("packbot-events").style.display = "none"; }}
  function show(t) {{
    state.t = Math.max(0, Math.min(duration, t));
    anim.seek(state.t / packbot.speed);
    anim.display_progress(state.t / packbot.speed);
    slider.value = state.t;
    el("packbot-time").textContent = "t = " + (packbot.t0 + state.t).toFixed(3) + " / " +
      packbot.t1.toFixed(3) + " s";
    var current = -1;
    items.forEach(function (it, k) {{ if (it.t <= state.t + 1e-9) {{ current = k; }} }});
    items.forEach(function (it, k) {{ it.button.className = k === current ? "current" : ""; }});
    document.body.dataset.time = (packbot.t0 + state.t).toFixed(6);
  }}
  function setPlaying(p) {{
    if (p && state.t >= duration) {{ show(0); }}  // play again from the start
    state.playing = p;
    state.last = null;
    play.innerHTML = p ? "&#10074;&#10074;" : "&#9654;";
    document.body.dataset.playing = p ? "true" : "false";
  }}
  play.addEventListener("click", function () {{
    play.blur();
    setPlaying(!state.playing);
  }});
  document.addEventListener("keydown", function (e) {{
    if (e.key === " " && e.target.tagName !== "SELECT" && e.target.tagName !== "BUTTON") {{
      e.preventDefault();
      setPlaying(!state.playing);
    }}
  }});
  slider.addEventListener("input", function () {{
    setPlaying(false);
    show(parseFloat(slider.value));
  }});
  function frame(now) {{
    if (state.playing) {{
      if (state.last !== null) {{
        // at most 0.25 s of wall time per frame: a stalled page does not skip the action
        var t = state.t + Math.min((now - state.last) / 1000, 0.25) * state.rate;
        if (t >= duration) {{ show(duration); setPlaying(false); }} else {{ show(t); }}
      }}
      state.last = now;
    }}
    requestAnimationFrame(frame);
  }}
  // Opens at the start, playing; "#t=0.4" shows the pose at 0.4 s of simulated time, paused.
  var match = /(?:^#|&)t=([0-9.eE+-]+)/.exec(window.location.hash);
  if (match) {{
    setPlaying(false);
    show(parseFloat(match[1]) - packbot.t0);
  }} else {{
    show(0);
    setPlaying(true);
  }}
  requestAnimationFrame(frame);
}})();
</script>
</body>
</html>
"""

#: CSS colour of each event kind in the page (the plots' colours).
EVENT_CSS: dict[str, str] = {
    "impact": "#d62728",
    "limit": "#9467bd",
    "release": "#2ca02c",
    "secondary_intersection": "#ff7f0e",
    "handoff": "#ffd700",
    "engage": "#7f7f7f",
    "disengage": "#8c564b",
    "failure": "#000000",
    "freeze": "#17becf",
    "pick": "#bcbd22",
    "drop": "#e377c2",
    "stick": "#7f7f7f",
    "slip": "#8c564b",
}


def html_page(commands: Sequence[bytes], *, title: str, caption: str = "", **settings: Any) -> str:
    """A self-contained meshcat page replaying packed commands (see :class:`SceneRecorder`).

    Args:
        commands: msgpack-packed meshcat commands, replayed in order.
        title: The page title.
        caption: A line of text shown at the bottom left.
        **settings: JSON values exposed to the page as ``packbot.<name>``; the page reads
            ``t0``, ``t1`` [s] (the simulated interval the clip plays), ``speed`` [-] (the
            clip's time is simulated time / speed), ``events`` (a list of ``{"t": [s],
            "label": str, "color": CSS colour}``) and ``camera`` (``{"radius": [m],
            "direction": unit vector, "fov": [deg]}``: the camera backs off along the
            direction until a sphere of that radius around the orbit point fits the window).

    Returns:
        The HTML text, with meshcat's ``main.min.js`` (three.js included) inlined.
    """
    viewer_js = (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    if "</script" in viewer_js.lower():  # would close the inline <script> early
        raise PackbotError("meshcat's main.min.js contains '</script': cannot inline it")
    data = {"t0": 0.0, "t1": 0.0, "speed": 1.0, "events": [], "camera": None, **settings}
    data["commands"] = [base64.b64encode(c).decode("ascii") for c in commands]
    return _PAGE.format(
        title=html_lib.escape(title),
        caption=html_lib.escape(caption),
        viewer_js=viewer_js,
        settings=script_json(data),  # a label with "</script" cannot close the script early
    )


#: What :func:`script_json` writes as ``\\uXXXX`` escapes.
_SCRIPT_ESCAPES = {c: f"\\u{ord(c):04x}" for c in "<>&\u2028\u2029"}


def script_json(data: Any) -> str:
    r"""JSON to embed in an inline ``<script>``: data, never markup.

    ``<``, ``>``, ``&`` (and the line separators U+2028, U+2029) are written as ``\uXXXX``
    escapes, which JSON and JavaScript read back as the same characters: a string holding
    ``</script>`` or ``<!--`` cannot end the script or change how the page parses it. The page
    must then set such strings as text (``textContent``), never as ``innerHTML``.
    """
    text = json.dumps(data, separators=(",", ":"))
    return "".join(_SCRIPT_ESCAPES.get(c, c) for c in text)


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

    The page opens at the start of the run and plays it once; a bar at the bottom has
    play/pause (also the space key), the playback rate, a time slider with the events ticked
    over it, and the simulated time; the list of events at the left jumps to one when clicked.
    The camera frames the motion: it looks at the box holding every visual piece over the
    run, from far enough for the box's bounding sphere to fit the window (it orbits that
    box's centre with the mouse).

    Args:
        robot: The robot the result was simulated with.
        result: The simulation result (its samples, event log and environment).
        path: The HTML file to write (parent folders are created; written atomically).
        environment: The obstacles to draw; None: the result's own (``result.environment``;
            the floor alone for a result without one).
        collision: Show the convex collision pieces instead of the visual meshes (both are
            in the page's scene panel).
        speed: Playback rate the page starts with: 1 plays at real time, 0.25 four times
            slower [-] (the clip is recorded at this rate).

    Returns:
        The path written.

    Raises:
        ConfigurationError: A bad ``speed`` or an empty result.
    """
    speed = _check_speed(speed)
    if environment is None:
        environment = result.environment
    recorder = SceneRecorder()
    viewer = meshcat.Visualizer(window=recorder)
    scene = _Scene.load(robot, viewer, environment, collision)
    _, q_keys = _keyframes(result, FPS)
    lo, hi = scene.motion_bounds(q_keys)
    radius = scene.frame(lo, hi, _ASPECT)
    scene.place(np.asarray(result.q[0], dtype=float))
    viewer.set_animation(scene.animation(result, speed), play=True, repetitions=1)
    t0, t1 = float(result.t[0]), float(result.t[-1])
    n_contacts = len(contact_spans(result))
    caption = (
        f"packbot: {t1 - t0:.3g} s simulated; {len(result.events)} "
        f"event{'' if len(result.events) == 1 else 's'}, "
        f"{n_contacts} contact span{'' if n_contacts == 1 else 's'} (touching pieces turn red"
        + (
            "; orange bars: the contact forces on the arm, 2 mm per N)"
            if len(result.contacts)
            else ")"
        )
    )
    events = [
        {"t": e.t, "label": event_label(e), "color": EVENT_CSS.get(e.kind, "#000000")}
        for e in result.events
    ]
    direction = np.asarray(CAMERA_OFFSET, dtype=float)
    camera = {
        "radius": radius,
        "direction": (direction / np.linalg.norm(direction)).tolist(),
        "fov": CAMERA_FOV,
    }
    out = Path(path)
    html = html_page(
        recorder.commands(),
        title="packbot",
        caption=caption,
        t0=t0,
        t1=t1,
        speed=speed,
        events=events,
        camera=camera,
    )
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
