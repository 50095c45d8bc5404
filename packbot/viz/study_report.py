"""The failure study's report: ``study.json``, its figures and one self-contained ``report.html``.

:func:`write_study` writes, from a :class:`packbot.study.StudyResult`:

- ``study.json``: :meth:`StudyResult.summary` (keys ``runs`` -> ``healthy`` / ``failed`` /
  ``reconfigured`` -> metrics with their units in their names), plus the figures' file names;
- figures, each as PNG and SVG: ``study_task_error`` (task error against time, the failure and
  the detection marked, the tolerance drawn), ``study_joints`` (joint angles of the three runs
  against their limits), ``study_torques`` (applied torques against the effort limits),
  ``study_energy``, and for a loose joint ``study_equilibria`` (its gravity torque over its
  range with the other joints at their final angles, the predicted rest positions and where it
  came to rest);
- ``report.html``: one file that opens offline (meshcat's viewer, three.js included, inlined
  as :mod:`packbot.viz.html` does; the scenes and clips embedded as msgpack commands; the
  figures as inline PNG): the three runs' animations side by side, synchronised by one time
  slider with play/pause (``#t=1.2`` opens paused at 1.2 s), the verdict on recovery, a summary
  table per run, the figures, the loose joint's equilibria and the events and contacts table.
"""

from __future__ import annotations

import base64
import html as html_lib
import io
import json
import logging
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import numpy as np
from meshcat.servers.zmqserver import VIEWER_ROOT

from packbot.errors import ConfigurationError, PackbotError
from packbot.labels import plain_text
from packbot.study import RUN_NAMES, StudyResult, impact_speeds, verdict_lines
from packbot.viz.html import script_json
from packbot.viz.recorder import SceneRecorder
from packbot.viz.scene import _Scene

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["RUN_COLORS", "study_figures", "study_page", "write_study"]

log = logging.getLogger(__name__)

#: Line colour of each run in the figures and the page.
RUN_COLORS: dict[str, str] = {
    "healthy": "#2ca02c",
    "failed": "#d62728",
    "reconfigured": "#1f77b4",
}
_FORMATS = ("png", "svg")
#: Event kinds listed in the events table.
_TABLE_EVENTS = (
    "failure",
    "freeze",
    "impact",
    "release",
    "limit",
    "secondary_intersection",
    "handoff",
    "slip",
    "stick",
    "painleve",
)
#: Most rows of the events table.
MAX_EVENT_ROWS = 400


# ---------------------------------------------------------------------------------- writing
def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_study(
    result: StudyResult,
    out_dir: str | os.PathLike[str],
    *,
    formats: Sequence[str] = _FORMATS,
    html: bool = True,
) -> dict[str, Path]:
    """Write ``study.json``, the figures and ``report.html`` of a study into ``out_dir``.

    Args:
        result: The study.
        out_dir: The folder (created if missing).
        formats: Image formats of the figures (of "png", "svg").
        html: Whether to write ``report.html``.

    Returns:
        Name -> path of every file written.

    Raises:
        ConfigurationError: A bad format, or ``out_dir`` is a file.
    """
    if not isinstance(result, StudyResult):
        raise ConfigurationError("result", result, "a packbot.study.StudyResult")
    fmts = tuple(formats)
    for fmt in fmts:
        if fmt not in _FORMATS:
            raise ConfigurationError("formats", fmts, _FORMATS)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigurationError("out_dir", str(out), "a directory (this is a file)")
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    figures = study_figures(result)
    pngs: dict[str, bytes] = {}
    for name, fig in figures.items():
        for fmt in fmts:
            buf = io.BytesIO()
            if fmt == "svg":
                from matplotlib import rc_context

                with rc_context({"svg.hashsalt": "packbot"}):
                    fig.savefig(buf, format="svg", metadata={"Date": None})
            else:
                fig.savefig(buf, format="png", dpi=110)
                pngs[name] = buf.getvalue()
            path = out / f"{name}.{fmt}"
            _write_atomic(path, buf.getvalue())
            written[f"{name}.{fmt}"] = path
        if name not in pngs:  # the page shows PNGs
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=110)
            pngs[name] = buf.getvalue()
    summary = result.summary()
    summary["figures"] = sorted(p.name for p in written.values())
    path = out / "study.json"
    _write_atomic(path, (json.dumps(summary, indent=2, allow_nan=False) + "\n").encode())
    written["study.json"] = path
    if html:
        page = study_page(result, pngs)
        path = out / "report.html"
        _write_atomic(path, page.encode("utf-8"))
        written["report.html"] = path
        log.info("wrote %s (%.1f MB)", path, len(page) / 1e6)
    return written


# ---------------------------------------------------------------------------------- figures
def _figure(nrows: int, height: float) -> tuple[Figure, list[Any]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, list(axes)


def _mark_failure(ax: Any, result: StudyResult, label: bool) -> None:
    for k, f in enumerate(result.failures):
        ax.axvline(
            f.t,
            color="black",
            lw=1.1,
            label=f"failure: {f.joint} {f.kind} ({f.t:g} s)" if label and k == 0 else None,
        )
    m = result.reconfigured.metrics
    if m is not None and m.detect_time_s is not None:
        ax.axvline(
            m.detect_time_s,
            color=RUN_COLORS["reconfigured"],
            lw=1.1,
            ls="--",
            label=f"detected: {m.detected_joint} {m.detected_kind} ({m.detect_time_s:.3f} s)"
            if label
            else None,
        )


def study_figures(result: StudyResult) -> dict[str, Figure]:
    """The study's figures by name (``study_task_error``, ``study_joints``, ...)."""
    figs: dict[str, Figure] = {}
    robot = result.robot
    runs = [(n, r) for n, r in result.runs.items() if r.result is not None]
    title = plain_text(
        f"{result.scenario.name}: {result.controller or result.scenario.controller} controller, "
        f"{result.contact_mode}"
    )

    fig, (ax,) = _figure(1, 3.6)
    for name, run in runs:
        if run.task_error is not None and run.result is not None:
            ax.plot(run.result.t, 1000 * run.task_error, color=RUN_COLORS[name], lw=1.5, label=name)
    ax.axhline(1000 * result.tolerance_m, color="gray", ls=":", lw=1.0, label="tolerance")
    _mark_failure(ax, result, label=True)
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_ylim(bottom=0.0)
    ax.set_ylabel("task error |x - x*| [mm]")
    ax.set_xlabel("time [s]")
    ax.set_title(
        f"{title}: {result.robot.tool_frame} against the healthy run's path", fontsize="medium"
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    figs["study_task_error"] = fig

    joints = list(
        result.scenario.outputs.joints_of(result.robot.joint_names, result.robot.is_packbot)
    )
    for kind, caption in (
        ("joints", "angles against their limits (dashed)"),
        ("torques", "torques against their limits in force (dashed)"),
    ):
        fig, axes = _figure(len(joints), 1.6 * len(joints) + 0.8)
        for ax, joint in zip(axes, joints, strict=True):
            j = robot.params.index(joint)
            for name, run in runs:
                assert run.result is not None
                y = run.result.q[:, j] if kind == "joints" else run.result.tau[:, j]
                ax.plot(run.result.t, y, color=RUN_COLORS[name], lw=1.3, label=name)
            if kind == "joints":
                for lim in (robot.params.lower[j], robot.params.upper[j]):
                    ax.axhline(lim, color="gray", ls="--", lw=0.9)
                ax.set_ylabel(f"{joint} [rad]")
            else:
                # each run's limit as it is at each sample (a weak joint's drops at its failure)
                for name, run in runs:
                    assert run.result is not None
                    e = np.asarray(run.result.effort, dtype=float)[:, j]
                    for sign in (-1.0, 1.0):
                        ax.plot(
                            run.result.t,
                            sign * e,
                            color=RUN_COLORS[name],
                            ls="--",
                            lw=0.9,
                            alpha=0.8,
                            drawstyle="steps-post",
                        )
                ax.set_ylabel(f"{joint} [N*m]")
            _mark_failure(ax, result, label=False)
            ax.grid(alpha=0.3)
        if runs:
            axes[0].legend(fontsize="small", loc="best", ncol=3)
        axes[0].set_title(
            f"{title}: joint {caption}",
            fontsize="medium",
        )
        axes[-1].set_xlabel("time [s]")
        figs[f"study_{kind}"] = fig

    fig, (ax,) = _figure(1, 3.2)
    for name, run in runs:
        assert run.result is not None
        ax.plot(run.result.t, run.result.energy, color=RUN_COLORS[name], lw=1.4, label=name)
    _mark_failure(ax, result, label=True)
    ax.set_ylabel("total mechanical energy [J]")
    ax.set_xlabel("time [s]")
    ax.set_title(f"{title}: energy", fontsize="medium")
    ax.grid(alpha=0.3)
    if runs:
        ax.legend(fontsize="small", loc="best")
    figs["study_energy"] = fig

    if result.loose:
        fig, axes = _figure(len(result.loose), 2.6 * len(result.loose) + 0.6)
        for ax, s in zip(axes, result.loose, strict=True):
            ax.plot(s.angles_rad, s.gravity_torque_nm, color=RUN_COLORS[s.run], lw=1.4)
            ax.axhline(0.0, color="gray", lw=0.8)
            for eq in s.equilibria:
                ax.plot(
                    [eq.angle],
                    [eq.gravity_torque],
                    marker="o" if eq.stable else "s",
                    mfc=RUN_COLORS[s.run] if eq.stable else "white",
                    mec="black",
                    ms=8,
                    ls="none",
                )
            ax.axvline(s.settled_angle_rad, color="black", ls="--", lw=1.1)
            ax.set_ylabel(f"g({s.joint}) [N*m]")
            ax.set_title(
                f"{s.run}: {s.joint} came to rest at {s.settled_angle_rad:.3f} rad (dashed); "
                f"predicted rest positions: filled stable, open unstable",
                fontsize="small",
            )
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel(
            f"{result.loose[0].joint} angle [rad] (the others at their final angles)"
        )
        figs["study_equilibria"] = fig
    return figs


# ---------------------------------------------------------------------------------- page
#: Width / height of a pane the camera frames the motion for [-] (a pane is a third of the
#: page wide and 340 px high: about 1.2 on a laptop; the narrower 1.0 frames it on any).
PANE_ASPECT = 1.0


def _motion_box(result: StudyResult) -> tuple[Any, Any] | None:
    """The world box [m] holding the arm at every keyframe of every run (one framing)."""
    from packbot.viz.keyframes import FPS, _keyframes

    scene = _Scene.load(
        result.robot, meshcat.Visualizer(window=SceneRecorder()), result.scenario.environment, False
    )
    boxes = [
        scene.motion_bounds(_keyframes(run.result, FPS)[1])
        for run in result.runs.values()
        if run.result is not None and len(run.result.t)
    ]
    if not boxes:
        return None
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def _commands(result: StudyResult, name: str, box: tuple[Any, Any] | None = None) -> list[str]:
    run = result.runs[name]
    if run.result is None or len(run.result.t) == 0:
        return []
    recorder = SceneRecorder()
    viewer = meshcat.Visualizer(window=recorder)
    scene = _Scene.load(result.robot, viewer, result.scenario.environment, False)
    if box is not None:  # the whole motion in view (an outstretched gripper is not cut off)
        scene.frame(box[0], box[1], PANE_ASPECT)
    scene.place(np.asarray(run.result.q[0], dtype=float))
    viewer.set_animation(scene.animation(run.result, 1.0), play=True, repetitions=1)
    return [base64.b64encode(c).decode("ascii") for c in recorder.commands()]


def _fmt(x: Any, unit: str = "", scale: float = 1.0, digits: int = 3) -> str:
    if x is None:
        return "&mdash;"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, float):
        if not math.isfinite(x):
            return "&mdash;"
        return f"{x * scale:.{digits}g}{(' ' + unit) if unit else ''}"
    return html_lib.escape(str(x))


#: Summary rows: (label, metric, unit shown, scale).
_ROWS: tuple[tuple[str, str, str, float], ...] = (
    ("time to detect", "detect_time_s", "s", 1.0),
    ("detected joint", "detected_joint", "", 1.0),
    ("detected as", "detected_kind", "", 1.0),
    ("time to recover (within tolerance to the end)", "recover_time_s", "s", 1.0),
    ("recovered", "recovered", "", 1.0),
    ("final task error", "final_task_error_m", "mm", 1000.0),
    ("RMS task error after the failure", "rms_task_error_m", "mm", 1000.0),
    ("largest task error after the failure", "max_task_error_m", "mm", 1000.0),
    ("peak torque", "peak_torque_nm", "N*m", 1.0),
    ("at joint", "peak_torque_joint", "", 1.0),
    ("peak torque / effort limit in force", "peak_torque_ratio", "", 1.0),
    ("at joint", "peak_torque_ratio_joint", "", 1.0),
    ("detected weak scale", "detected_scale", "", 1.0),
    ("false detections", "false_detections", "", 1.0),
    ("contacts (impacts)", "contacts", "", 1.0),
    ("peak impact speed", "peak_impact_speed_m_s", "m/s", 1.0),
    ("joint-stop events", "limit_hits", "", 1.0),
    ("smallest signed distance", "min_distance_m", "mm", 1000.0),
    ("energy at the start", "energy_initial_j", "J", 1.0),
    ("energy at the end", "energy_final_j", "J", 1.0),
    ("events", "events", "", 1.0),
    ("wall time", "wall_time_s", "s", 1.0),
)


def _summary_table(result: StudyResult) -> str:
    head = "".join(f'<th style="color:{RUN_COLORS[n]}">{n}</th>' for n in RUN_NAMES)
    rows = [f"<tr><th></th>{head}</tr>"]
    status = "".join(
        "<td>" + html_lib.escape(r.status + (f": {r.reason}" if r.reason else "")) + "</td>"
        for r in result.runs.values()
    )
    rows.append(f"<tr><td>run</td>{status}</tr>")
    for label, key, unit, scale in _ROWS:
        cells = []
        for run in result.runs.values():
            m = None if run.metrics is None else getattr(run.metrics, key)
            cells.append(f"<td>{_fmt(m, unit, scale)}</td>")
        rows.append(f"<tr><td>{html_lib.escape(label)}</td>{''.join(cells)}</tr>")
    return '<table class="grid">' + "".join(rows) + "</table>"


def _events_table(result: StudyResult) -> str:
    from packbot.collision import CollisionWorld

    world = CollisionWorld(result.robot, result.scenario.environment)
    rows: list[tuple[float, str, str, str, str]] = []
    for name, run in result.runs.items():
        res = run.result
        if res is not None:
            speeds = iter(impact_speeds(result.robot, world, res))
            for e in res.events:
                if e.kind not in _TABLE_EVENTS:
                    continue
                if e.kind == "impact":
                    what = f"{e.link1}/{e.piece1} - {e.link2}/{e.piece2}"
                    detail = f"approach speed {next(speeds, 0.0):.3g} m/s"
                elif e.kind in ("failure", "freeze"):
                    what = f"{e.link1} {e.link2}".strip()
                    detail = "" if e.kind == "failure" else f"at {e.distance:.4g} rad"
                elif e.kind == "limit":
                    what = f"{e.link1} {e.link2} stop"
                    detail = ""
                else:
                    what = f"{e.link1} {e.link2}".strip()
                    detail = ""
                rows.append((e.t, name, e.kind, what, detail))
        for c in run.controller_log:
            rows.append((c.t, name, f"controller: {c.kind}", c.joint, c.detail))
    rows.sort(key=lambda r: (r[0], RUN_NAMES.index(r[1])))
    more = len(rows) - MAX_EVENT_ROWS
    rows = rows[:MAX_EVENT_ROWS]
    body = "".join(
        f'<tr><td>{t:.4f}</td><td style="color:{RUN_COLORS[n]}">{n}</td>'
        f"<td>{html_lib.escape(k)}</td><td>{html_lib.escape(w)}</td>"
        f"<td>{html_lib.escape(d)}</td></tr>"
        for t, n, k, w, d in rows
    )
    tail = (
        f"<p>{more} more rows not shown (study.json and the runs hold them).</p>"
        if more > 0
        else ""
    )
    return (
        '<table class="grid"><tr><th>time [s]</th><th>run</th><th>event</th><th>what</th>'
        f"<th>detail</th></tr>{body}</table>{tail}"
    )


def _loose_table(result: StudyResult) -> str:
    if not result.loose:
        return ""
    esc = html_lib.escape
    rows = []
    for s in result.loose:
        eqs = (
            "; ".join(
                f"{e.angle:.3f} rad ({e.kind}, {'stable' if e.stable else 'unstable'}"
                f"{', in collision' if e.in_collision else ''})"
                for e in s.equilibria
            )
            or "none (no gravity torque)"
        )
        rows.append(
            f'<tr><td style="color:{RUN_COLORS[s.run]}">{esc(s.run)}</td><td>{esc(s.joint)}</td>'
            f"<td>{s.settled_angle_rad:.4f}</td><td>{_fmt(s.final_speed_rad_s, 'rad/s')}</td>"
            f"<td>{_fmt(s.nearest_angle_rad)} ({html_lib.escape(s.nearest_kind)}"
            f"{', stable' if s.nearest_stable else ', unstable'})</td>"
            f"<td>{_fmt(s.offset_rad, 'rad')}</td><td>{_fmt(s.final_distance_m, 'mm', 1000.0)}</td>"
            f"<td>{html_lib.escape(eqs)}</td></tr>"
        )
    return (
        "<h2>Loose joint: where the arm settles against the predicted equilibria</h2>"
        "<p>Predicted rest positions: <code>packbot.analysis.loose_joint_equilibria</code> of the "
        "loose joint with the other joints held at their final angles in that run. A final "
        "distance near zero means the link rests on a contact, not on gravity alone.</p>"
        '<table class="grid"><tr><th>run</th><th>joint</th><th>final angle [rad]</th>'
        "<th>final speed</th><th>nearest predicted rest [rad]</th><th>offset</th>"
        "<th>smallest distance at the end</th><th>all predicted rest positions</th></tr>"
        + "".join(rows)
        + "</table>"
    )


_CSS = """
body { font: 14px sans-serif; margin: 12px 18px; color: #222; }
h1 { font-size: 20px; margin: 4px 0; } h2 { font-size: 16px; margin: 18px 0 6px; }
.panes { display: flex; gap: 6px; }
.pane { flex: 1; min-width: 0; }
.pane .label { font-weight: bold; padding: 2px 4px; }
.view { position: relative; height: 340px; border: 1px solid #999; overflow: hidden; }
.dg { display: none !important; }
#controls { margin: 8px 0; display: flex; align-items: center; gap: 10px; }
#slider { flex: 1; }
table.grid { border-collapse: collapse; margin: 4px 0; }
table.grid td, table.grid th { border: 1px solid #bbb; padding: 2px 6px; text-align: left;
  font-size: 13px; vertical-align: top; }
.verdict { padding: 6px 10px; border-left: 5px solid; margin: 8px 0; }
.verdict.yes { border-color: #2ca02c; background: #eef8ee; }
.verdict.no { border-color: #d62728; background: #fbeeee; }
.verdict.unknown { border-color: #999; background: #f4f4f4; }
img.fig { max-width: 100%; display: block; margin: 6px 0; }
"""

_JS = """
var study = STUDY_DATA;
var viewers = [];
study.runs.forEach(function (run, k) {
  var el = document.getElementById("view" + k);
  if (!run.commands.length) {
    // the reason quotes names (obstacles, joints): text, never markup
    var p = document.createElement("p");
    p.style.padding = "8px";
    p.textContent = "no animation: " + run.reason;
    el.appendChild(p);
    viewers.push(null);
    return;
  }
  var v = new MeshCat.Viewer(el);
  // meshcat sizes its canvas to the window's height: size it to its pane instead
  var size = v.set_3d_pane_size;
  v.set_3d_pane_size = function () { size.call(v, el.clientWidth, el.clientHeight); };
  v.set_3d_pane_size();
  run.commands.forEach(function (b64) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) { bytes[i] = bin.charCodeAt(i); }
    v.handle_command_bytearray(bytes);
  });
  v.animator.pause();
  viewers.push(v);
});
var slider = document.getElementById("slider"), label = document.getElementById("time");
var button = document.getElementById("play"), playing = false, last = null;
function seek(t) {
  t = Math.max(study.t0, Math.min(study.t1, t));
  slider.value = t;
  label.textContent = t.toFixed(3) + " s";
  viewers.forEach(function (v, k) {
    if (!v) { return; }
    v.animator.seek(t - study.runs[k].t0);
    v.animator.display_progress(t - study.runs[k].t0);
  });
}
slider.addEventListener("input", function () { seek(parseFloat(slider.value)); });
function frame(now) {
  if (!playing) { return; }
  if (last !== null) {
    var t = parseFloat(slider.value) + (now - last) / 1000 * study.speed;
    if (t >= study.t1) { t = study.t1; playing = false; button.textContent = "play"; }
    seek(t);
  }
  last = now;
  if (playing) { requestAnimationFrame(frame); }
}
button.addEventListener("click", function () {
  playing = !playing;
  button.textContent = playing ? "pause" : "play";
  if (playing) {
    if (parseFloat(slider.value) >= study.t1) { seek(study.t0); }
    last = null; requestAnimationFrame(frame);
  }
});
var match = /(?:^#|&)t=([0-9.eE+-]+)/.exec(window.location.hash);
seek(match ? parseFloat(match[1]) : study.t0);
window.addEventListener("load", function () { seek(parseFloat(slider.value)); });
"""


def _strategy(result: StudyResult) -> str:
    r = result.reconfiguration
    return "" if r is None else r.strategy


def study_page(result: StudyResult, pngs: dict[str, bytes] | None = None) -> str:
    """The self-contained report page (HTML text).

    Args:
        result: The study.
        pngs: Figure name -> PNG bytes to show (default: drawn here).

    Raises:
        PackbotError: meshcat's viewer script cannot be inlined.
    """
    if pngs is None:
        pngs = {}
        for name, fig in study_figures(result).items():
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=110)
            pngs[name] = buf.getvalue()
    viewer_js = (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    if "</script" in viewer_js.lower():
        raise PackbotError("meshcat's main.min.js contains '</script': cannot inline it")
    sc = result.scenario
    runs_data = []
    t0s, t1s = [], []
    box = _motion_box(result)
    for name in RUN_NAMES:
        run = result.runs[name]
        cmds = _commands(result, name, box)
        t0 = float(run.result.t[0]) if run.result is not None and len(run.result.t) else 0.0
        t1 = float(run.result.t[-1]) if run.result is not None and len(run.result.t) else 0.0
        if cmds:
            t0s.append(t0)
            t1s.append(t1)
        runs_data.append({"name": name, "commands": cmds, "t0": t0, "reason": run.reason})
    data = {
        "runs": runs_data,
        "t0": min(t0s, default=0.0),
        "t1": max(t1s, default=0.0),
        "speed": 1.0,
    }
    esc = html_lib.escape
    panes = []
    for k, name in enumerate(RUN_NAMES):
        run = result.runs[name]
        m = run.metrics
        extra = "" if m is None else f" &middot; final error {m.final_task_error_m * 1000:.1f} mm"
        if run.status != "ok":
            extra = f" &middot; {esc(run.status)}"
        panes.append(
            f'<div class="pane"><div class="label" style="color:{RUN_COLORS[name]}">{name}'
            f'{extra}</div><div class="view" id="view{k}"></div></div>'
        )
    rec = result.recovery
    cls = "yes" if rec.harmless else {True: "yes", False: "no", None: "unknown"}[rec.possible]
    head, lines = verdict_lines(result)
    verdict = head.split(": ", 1)[-1]
    verdict = verdict[:1].upper() + verdict[1:]
    reasons = "".join(f"<li>{esc(r)}</li>" for r in lines)
    fails = ", ".join(f"{f.joint} {f.kind} at {f.t:g} s" for f in result.failures)
    figs = "".join(
        f'<h3>{esc(name)}</h3><img class="fig" alt="{esc(name)}" '
        f'src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'
        for name, png in pngs.items()
    )
    settings = script_json(data)
    body = f"""<h1>Failure study: {esc(sc.name)}</h1>
<p>{esc(sc.description)}<br>controller <b>{esc(result.controller or sc.controller)}</b>,
recovery strategy <b>{esc(_strategy(result))}</b>, contact mode
<b>{esc(result.contact_mode)}</b>, failures: <b>{esc(fails)}</b>, {result.duration_s:g} s simulated,
tolerance {result.tolerance_m * 1000:g} mm. The task is the healthy run's
<code>{esc(result.robot.tool_frame)}</code> path.</p>
<div class="panes">{"".join(panes)}</div>
<div id="controls"><button id="play">play</button>
<input id="slider" type="range" min="{data["t0"]}" max="{data["t1"]}" step="0.001"
 value="{data["t0"]}"><span id="time"></span></div>
<div class="verdict {cls}"><b>{verdict}.</b><ul>{reasons}</ul></div>
<h2>Summary per run</h2>{_summary_table(result)}
{_loose_table(result)}
<h2>Figures</h2>{figs}
<h2>Events and contacts</h2>{_events_table(result)}
"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>packbot study: {esc(sc.name)}</title>
<style>{_CSS}</style>
</head>
<body>
{body}
<script>
{viewer_js}
</script>
<script>
{_JS.replace("STUDY_DATA", settings)}
</script>
</body>
</html>
"""
