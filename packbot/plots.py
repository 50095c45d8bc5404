"""Plots of a simulation result: joint trajectories, signed distance and energy against time.

The functions draw on a fresh :class:`matplotlib.figure.Figure` with the Agg canvas attached
(no pyplot, so no global figure state is created or leaked), return it, and optionally save it:
with ``path="out/collapse_joints"`` (any suffix is replaced) they write ``out/collapse_joints.png``
and ``out/collapse_joints.svg`` (see ``formats``).

- :func:`plot_joints`: the 2010 report's Figures 9 and 10, planar joint positions [rad] and
  velocities [rad/s] against time [s];
- :func:`plot_distance`: the smallest signed distance over the tested pairs [m] against time,
  with the contact tolerance band;
- :func:`plot_energy`: total mechanical energy [J] against time, with the jumps of the events;
- :func:`plot_torques`: applied (and commanded) joint torques [N*m], scaled to the effort limits;
- :func:`plot_tracking`: joint positions against a controller's reference, and the error [rad];
- :func:`plot_tool_path`: the path of a frame (the tool) [m] in the x-z and x-y planes, with
  a controller's target;
- :func:`plot_occlusion`: whether the camera's view of target points is blocked, and by what
  (:func:`sample_occlusion`).

The time plots show the action: the time axis is zoomed to the motion and the events (first
to last marked event, moving sample and the rest time, plus a margin; the start of the run is
kept when it is near) and a strip at the bottom shows the whole run with the zoomed interval
shaded (see :func:`time_window`).
Every marked event is a vertical line coloured by kind and is labelled, in a lane above the
panels, with its kind and its joint or pair (:func:`event_label`; a failure names the joint and
the failure's kind); labels never overlap (they stack in rows; repeats of one label close in
time share one, counted). The rest time is a dashed black line, labelled too.

The figures are laid out with fixed margins (no layout pass measuring every text at each save).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from numpy.typing import ArrayLike, NDArray

from packbot.collision import CollisionWorld
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.labels import event_label, plain_text
from packbot.model import Robot
from packbot.outputs import IMAGE_FORMATS
from packbot.result import SimResult

__all__ = [
    "EVENT_COLORS",
    "MARKED_EVENTS",
    "MOVING_FRACTION",
    "PLANAR_JOINTS",
    "TORQUE_AXIS",
    "event_label",
    "plot_contacts",
    "plot_distance",
    "plot_energy",
    "plot_joints",
    "plot_occlusion",
    "plot_tool_path",
    "plot_torques",
    "plot_tracking",
    "sample_distances",
    "sample_occlusion",
    "time_window",
]

#: The arm's pitch joints: the report's "planar" joints.
PLANAR_JOINTS: tuple[str, ...] = ("shoulder", "elbow1", "elbow2")
#: Event kinds marked by default (lock engage/disengage are left out: they are mode changes
#: without a velocity jump).
MARKED_EVENTS: tuple[str, ...] = (
    "impact",
    "limit",
    "release",
    "secondary_intersection",
    "handoff",
    "failure",
    "freeze",
    "pick",
    "drop",
)
#: Line colour of each event kind.
EVENT_COLORS: dict[str, str] = {
    "impact": "tab:red",
    "limit": "tab:purple",
    "release": "tab:green",
    "secondary_intersection": "tab:orange",
    "handoff": "gold",
    "engage": "tab:gray",
    "disengage": "tab:brown",
    "failure": "black",
    "freeze": "tab:cyan",
    "pick": "tab:olive",
    "drop": "tab:pink",
    "stick": "tab:gray",
    "slip": "tab:brown",
}
# Label colours where the line colour is too light for text.
_TEXT_COLORS = {"handoff": "darkgoldenrod", "freeze": "darkcyan"}
#: The torque axes span this multiple of the joint's largest effort limit [-].
TORQUE_AXIS = 1.15
_JOINT_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
_FORMATS = IMAGE_FORMATS  # the image formats a plot is written in

# Fixed layout [in]: figure width, margins, title block, one label row of the event lane, gap
# between stacked panels, room under the last panel (tick labels + axis label), whole-run strip.
_WIDTH = 8.0
_LEFT = 0.95
_RIGHT = 0.22
_TITLE = 0.5
_ROW = 0.19
_GAP = 0.12
_XLABEL = 0.55
_STRIP = 0.55
_STRIP_TITLE = 0.22
_STRIP_BOTTOM = 0.3
_LABEL_PT = 7.5  # event label font size [pt]
# The zoom: shown when the events' interval is under this fraction of the run.
_ZOOM_BELOW = 0.6
#: A joint moves, for the zoom, above this fraction of the run's peak joint speed [-].
MOVING_FRACTION = 0.02


def _new_figure(height: float, nrows: int = 1) -> tuple[Figure, list[Axes]]:
    fig = Figure(figsize=(8.0, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, list(axes)


def _save(fig: Figure, path: str | Path | None, formats: Sequence[str], dpi: int) -> None:
    if path is None:
        return
    base = Path(path)
    for fmt in formats:
        if fmt not in _FORMATS:
            raise ConfigurationError("formats", tuple(formats), _FORMATS)
    base.parent.mkdir(parents=True, exist_ok=True)
    # A constrained layout (a pass measuring every text; only the occlusion plot has one) is
    # solved once, then frozen for every format: it is in figure fractions, so the same for any
    # dpi (to a pixel of rounding).
    engine = fig.get_layout_engine()
    if engine is not None and len(formats) > 1:
        engine.execute(fig)
        fig.set_layout_engine("none")
    try:
        for fmt in formats:
            if fmt == "svg":  # no date, fixed ids: regenerating an unchanged figure is no diff
                with rc_context({"svg.hashsalt": "packbot"}):
                    fig.savefig(base.with_suffix(".svg"), format="svg", metadata={"Date": None})
            else:
                fig.savefig(base.with_suffix(".png"), format="png", dpi=dpi)
    finally:
        fig.set_layout_engine(engine)


# --------------------------------------------------------------------------- events and zoom
@checked_arguments
def time_window(
    result: SimResult, event_kinds: Iterable[str] = MARKED_EVENTS
) -> tuple[float, float]:
    """The time interval [s] the plots zoom to: where the arm moves and the events happen.

    From the first to the last of: the events of ``event_kinds``, the motion (the first and
    the last sample where a joint moves faster than :data:`MOVING_FRACTION` of the run's
    peak joint speed, and at least ``config.rest_speed``: a controlled reach is framed whole,
    not only around its events) and the rest time (when the arm never comes to rest, the end
    of the run); plus a margin of a tenth of that span (at least 2 % of the run); widened to
    the start (end) of the run when that is less than half the span away. The whole run when
    these fill most of it (the zoom would show little more than 60 % of it) or when there is
    no event, no motion and no rest.

    Args:
        result: A simulation result.
        event_kinds: The event kinds that count.

    Returns:
        ``(start, end)`` [s], within the run.
    """
    t = np.asarray(result.t, dtype=float)
    t0, t1 = float(t[0]), float(t[-1])
    kinds = set(event_kinds)
    times = [e.t for e in result.events if e.kind in kinds and t0 <= e.t <= t1]
    v = np.asarray(result.v, dtype=float)
    speed = np.abs(v).max(axis=1) if v.size else np.zeros(len(t))
    peak = float(speed.max()) if len(speed) else 0.0
    moving = np.flatnonzero(speed >= max(MOVING_FRACTION * peak, result.config.rest_speed))
    if len(moving):
        times += [float(t[moving[0]]), float(t[moving[-1]])]
    if (not times and result.rest_time is None) or t1 <= t0:
        return t0, t1
    if not times:  # no event, no motion: from the start to the rest
        times.append(t0)
    times.append(t1 if result.rest_time is None else float(result.rest_time))
    first, last = min(times), max(times)
    margin = max(0.1 * (last - first), 0.02 * (t1 - t0))
    a, b = max(t0, first - margin), min(t1, last + margin)
    if a - t0 < 0.5 * (b - a):
        a = t0
    if t1 - b < 0.5 * (b - a):
        b = t1
    if b - a > _ZOOM_BELOW * (t1 - t0):
        return t0, t1
    return a, b


@dataclass(frozen=True)
class _Label:
    """An event label placed in the lane: the events' times, its text, row and alignment."""

    times: tuple[float, ...]
    text: str
    color: str
    row: int
    left: bool  # text to the right of the first event (else to the left)


@dataclass(frozen=True)
class _Timeline:
    """What a time plot shows: the run, the zoomed interval and the placed event labels."""

    t0: float
    t1: float
    x0: float
    x1: float
    labels: tuple[_Label, ...]
    rows: int

    @property
    def zoomed(self) -> bool:
        return (self.x0, self.x1) != (self.t0, self.t1)


def _text_width(text: str, span: float) -> float:
    """A label's width in data units of a lane spanning ``span`` [s] (a generous estimate)."""
    inches = (0.62 * _LABEL_PT * len(text) + 6.0) / 72.0
    return inches / (_WIDTH - _LEFT - _RIGHT) * span


def _timeline(
    result: SimResult,
    event_kinds: Iterable[str],
    zoom: bool,
    extra: dict[int, str] | None = None,
) -> _Timeline:
    """Zoom interval and label rows (``extra``: text appended to the label of event i)."""
    kinds = tuple(event_kinds)
    t0, t1 = float(result.t[0]), float(result.t[-1])
    x0, x1 = time_window(result, kinds) if zoom else (t0, t1)
    span = max(x1 - x0, 1e-12)
    # (time, kind, text, colour) of each event; repeats close in time merged: one label, counted
    entries: list[tuple[float, str, str, str]] = []
    for i, ev in enumerate(result.events):
        if ev.kind in kinds and x0 <= ev.t <= x1:
            text = event_label(ev) + (extra or {}).get(i, "")
            color = _TEXT_COLORS.get(ev.kind, EVENT_COLORS.get(ev.kind, "black"))
            entries.append((ev.t, ev.kind, text, color))
    if result.rest_time is not None and x0 <= result.rest_time <= x1:
        rest = float(result.rest_time)
        entries.append((rest, "", f"at rest {rest:.3f} s", "black"))
    groups: dict[str, list[list[float]]] = {}
    style: dict[str, tuple[str, str]] = {}  # text -> (kind, colour)
    for t, kind, text, color in sorted(entries, key=lambda e: e[0]):
        runs = groups.setdefault(text, [])
        style[text] = (kind, color)
        # a repeat that its label would cover joins it (the label then counts them)
        if runs and t - runs[-1][0] < _text_width(f"{text} x99", span):
            runs[-1].append(t)
        else:
            runs.append([t])
    # Labels of one kind at the same instant (within 0.2 % of the shown time: a pixel or two)
    # share one: "release elbow2 upper, shoulder lower" (not a failure: each has its own).
    same = 0.002 * span
    merged: list[tuple[list[float], str, list[str], str]] = []  # times, kind, parts, colour
    for ts, text in sorted(
        ((ts, text) for text, runs in groups.items() for ts in runs), key=lambda g: g[0][0]
    ):
        kind, color = style[text]
        part = text if len(ts) == 1 else f"{text} \u00d7{len(ts)}"
        target = None
        if kind not in ("", "failure") and text.startswith(kind + " "):
            for m in reversed(merged):
                if ts[0] - m[0][0] >= same:
                    break
                if m[1] == kind:
                    target = m
                    break
        if target is None:
            merged.append((list(ts), kind, [part], color))
        else:
            target[0].extend(ts)
            target[2].append(part[len(kind) + 1 :])
    items = [(tuple(sorted(ts)), ", ".join(parts), color) for ts, _, parts, color in merged]
    pad = _text_width("", span) * 0.5
    # Latest first, each in the lowest row where it overlaps no label and where neither its
    # leader (a vertical line from the lane's bottom) nor the leaders of the rows above cross
    # a label: the labels stack like stairs, the earliest on top. A label near the right end
    # is written to the left of its line; those go last, earliest first (the mirror image),
    # above the leaders they would cover.
    placed: list[tuple[int, float, float, float]] = []  # (row, left, right, leader x)
    labels = []
    widths = [_text_width(full, span) for _, full, _ in items]
    lefts = [
        when[0] + w + pad <= x1 or when[0] - w - pad < x0
        for (when, _, _), w in zip(items, widths, strict=True)
    ]
    order = [k for k in reversed(range(len(items))) if lefts[k]]
    order += [k for k in range(len(items)) if not lefts[k]]  # the mirror image: earliest first
    for k in order:
        when, full, color = items[k]
        w, left, x = widths[k], lefts[k], when[0]
        lo, hi = (x, x + w + pad) if left else (x - w - pad, x)

        def overlaps(row: int, lo: float = lo, hi: float = hi) -> bool:
            return any(r == row and lo < b and a < hi for r, a, b, _ in placed)

        def crosses(row: int, lo: float = lo, hi: float = hi, x: float = x) -> bool:
            return any(
                (r < row and a < x < b) or (r > row and lo < lx < hi) for r, a, b, lx in placed
            )

        free = [row for row in range(len(placed) + 1) if not overlaps(row)]
        row = next((r for r in free if not crosses(r)), free[0])
        placed.append((row, lo, hi, x))
        labels.append(_Label(when, full, color, row, left))
    rows = 1 + max((lb.row for lb in labels), default=-1)
    return _Timeline(t0, t1, x0, x1, tuple(labels), rows)


class _TimeFigure:
    """A time plot with fixed margins: title, event lane, stacked panels, whole-run strip."""

    def __init__(self, tl: _Timeline, heights: Sequence[float], title: str) -> None:
        self.tl = tl
        lane = tl.rows * _ROW + 0.08 if tl.rows else 0.0
        strip = _STRIP_TITLE + _STRIP + _STRIP_BOTTOM if tl.zoomed else 0.0
        panels = sum(heights) + _GAP * (len(heights) - 1)
        height = _TITLE + lane + panels + _XLABEL + strip
        fig = Figure(figsize=(_WIDTH, height))
        FigureCanvasAgg(fig)
        self.fig = fig
        w = (_WIDTH - _LEFT - _RIGHT) / _WIDTH

        def rect(top: float, h: float) -> tuple[float, float, float, float]:
            return (_LEFT / _WIDTH, 1.0 - (top + h) / height, w, h / height)

        fig.text(0.5, 1.0 - 0.08 / height, title, ha="center", va="top", fontsize="large")
        top = _TITLE
        self.lane: Axes | None = None
        if tl.rows:
            self.lane = fig.add_axes(rect(top, lane - 0.04))
            top += lane
        self.panels: list[Axes] = []
        for k, h in enumerate(heights):
            ax = fig.add_axes(rect(top, h), sharex=self.panels[0] if self.panels else None)
            if k < len(heights) - 1:
                ax.tick_params(labelbottom=False)
            ax.grid(True, alpha=0.3)
            self.panels.append(ax)
            top += h + _GAP
        top += _XLABEL - _GAP
        self.strip: Axes | None = None
        if tl.zoomed:
            self.strip = fig.add_axes(rect(top + _STRIP_TITLE, _STRIP))
        self.panels[0].set_xlim(tl.x0, tl.x1)
        self.panels[-1].set_xlabel("time [s]")
        if self.lane is not None:
            self.lane.sharex(self.panels[0])
            self._draw_lane(self.lane)

    def _draw_lane(self, ax: Axes) -> None:
        tl = self.tl
        ax.set_ylim(0.0, tl.rows)
        ax.set_axis_off()
        ax.set_xlim(tl.x0, tl.x1)
        pad = 0.5 * _text_width("", tl.x1 - tl.x0)
        for lb in tl.labels:
            x, y = lb.times[0], lb.row + 0.5
            ls = "--" if lb.text.startswith("at rest") else "-"
            ax.plot([x, x], [0.0, y], color=lb.color, lw=0.8, ls=ls, alpha=0.8)
            if len(lb.times) > 1:
                # the repeats' span, under the label (within its box: it overlaps nothing)
                yb = lb.row + 0.1
                ax.plot([lb.times[0], lb.times[-1]], [yb, yb], color=lb.color, lw=1.6)
                ax.plot(lb.times, [yb] * len(lb.times), "|", color=lb.color, ms=4, mew=0.8)
            ax.text(
                x + pad if lb.left else x - pad,
                y,
                plain_text(lb.text),  # names drawn as they are (no TeX math)
                ha="left" if lb.left else "right",
                va="center",
                fontsize=_LABEL_PT,
                color=lb.color,
            )

    def mark_events(self, result: SimResult, kinds: Iterable[str]) -> None:
        """Vertical lines at the marked events and the rest time, on every panel."""
        kinds = tuple(kinds)
        times: dict[str, list[float]] = {}
        for ev in result.events:
            if ev.kind in kinds:
                times.setdefault(ev.kind, []).append(ev.t)
        for ax in self.panels:
            if result.rest_time is not None:
                ax.axvline(result.rest_time, color="black", lw=1.1, ls=(0, (4, 3)), zorder=1)
            for kind, ts in times.items():
                color = EVENT_COLORS.get(kind, "black")
                ax.vlines(
                    ts,
                    0,
                    1,
                    transform=ax.get_xaxis_transform(),
                    colors=color,
                    lw=0.9,
                    alpha=0.6,
                    zorder=1.5,
                )

    def context(
        self,
        result: SimResult,
        traces: Sequence[tuple[NDArray[np.float64], str]],
        kinds: Iterable[str],
    ) -> None:
        """The whole-run strip: ``traces`` (values, colour) thin, events ticked, zoom shaded."""
        ax = self.strip
        if ax is None:
            return
        tl = self.tl
        for y, color in traces:
            ax.plot(result.t, y, color=color, lw=0.8)
        kinds = tuple(kinds)
        marked = [ev for ev in result.events if ev.kind in kinds]
        if marked:  # ticks along the top
            ax.vlines(
                [ev.t for ev in marked],
                0.75,
                1.0,
                transform=ax.get_xaxis_transform(),
                colors=[EVENT_COLORS.get(ev.kind, "black") for ev in marked],
                lw=0.9,
            )
        ax.axvspan(tl.x0, tl.x1, color="gold", alpha=0.2, lw=0)
        ax.set_xlim(tl.t0, tl.t1)
        ax.set_yticks([])
        ax.tick_params(labelsize="small")
        ax.set_title(
            f"the whole run ({tl.t1 - tl.t0:.3g} s); shaded: the time shown above",
            loc="left",
            fontsize="small",
            pad=3.0,
        )


def _title(result: SimResult) -> str:
    c = result.config
    if c.contact_mode == "none":
        return "contact_mode=none"
    return f"{c.contact_mode}, reset_rule={c.reset_rule}, clamp_rule={c.clamp_rule}"


def _in_window(result: SimResult, tl: _Timeline) -> NDArray[np.bool_]:
    t = np.asarray(result.t)
    return (t >= tl.x0) & (t <= tl.x1)


def _fit_y(ax: Axes, values: Sequence[NDArray[np.float64]], mask: NDArray[np.bool_]) -> None:
    """Y limits fitting ``values`` over the shown samples (``mask``), with a 5 % margin."""
    shown = [np.asarray(v)[mask] for v in values]
    shown = [v[np.isfinite(v)] for v in shown if len(v)]
    shown = [v for v in shown if len(v)]
    if not shown:
        return
    lo = min(float(v.min()) for v in shown)
    hi = max(float(v.max()) for v in shown)
    pad = 0.05 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.05
    ax.set_ylim(lo - pad, hi + pad)


@checked_arguments
def plot_joints(
    result: SimResult,
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Joint positions [rad] and velocities [rad/s] against time [s] (report Figures 9, 10).

    Two stacked axes sharing the time axis, zoomed to the events (:func:`time_window`) with
    the whole run's positions in a strip below. Events are vertical lines coloured by kind and
    labelled above the axes, the rest time a dashed black line. The samples include the
    instants just before and after every event, so velocity jumps show as vertical segments.

    Args:
        result: A simulation result.
        joints: Joint names to plot (default: the planar joints shoulder, elbow1, elbow2).
        path: Where to save, without suffix (any suffix is replaced by each format's); None
            saves nothing.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure (not registered with pyplot).

    Raises:
        UnknownNameError: A joint name that the result does not have.
    """
    idx = _joint_columns(result, joints)
    tl = _timeline(result, event_kinds, zoom)
    tf = _TimeFigure(tl, (2.3, 2.3), f"Joint positions and velocities\n({_title(result)})")
    ax_q, ax_v = tf.panels
    colors = [_JOINT_COLORS[k % len(_JOINT_COLORS)] for k in range(len(idx))]
    for name, j, color in zip(joints, idx, colors, strict=True):
        ax_q.plot(result.t, result.q[:, j], color=color, lw=1.5, label=name)
        ax_v.plot(result.t, result.v[:, j], color=color, lw=1.5, label=name)
    tf.mark_events(result, event_kinds)
    shown = _in_window(result, tl)
    _fit_y(ax_q, [result.q[:, j] for j in idx], shown)
    _fit_y(ax_v, [result.v[:, j] for j in idx], shown)
    ax_q.set_ylabel("joint position [rad]")
    ax_v.set_ylabel("joint velocity [rad/s]")
    ax_q.legend(loc="best", fontsize="small", framealpha=0.85)
    tf.context(result, [(result.q[:, j], c) for j, c in zip(idx, colors, strict=True)], event_kinds)
    _save(tf.fig, path, formats, dpi)
    return tf.fig


def _tested_pairs(result: SimResult, world: CollisionWorld) -> NDArray[np.intp]:
    """Pairs of ``world`` that the simulation itself tests.

    A locked joint merges its child body into its parent (``pin.buildReducedModel``); pairs of
    bodies that become one body, or adjacent bodies, are not tested by the simulation (their
    distance is constant, or they touch at a joint by construction), so they are left out here.
    """
    model = world.robot.model
    locked = {model.getJointId(name) for name in result.config.locked_joints}
    if not locked:
        return np.arange(len(world.pairs), dtype=np.intp)
    parents = [int(p) for p in model.parents]

    def merged(j: int) -> int:
        while j in locked:
            j = parents[j]
        return j

    obstacles = {ob.name for ob in world.environment.obstacles}
    keep = []
    for p in world.pairs:
        if p.link2 in obstacles:
            keep.append(p.index)
            continue
        b1, b2 = merged(p.joint1), merged(p.joint2)
        if b1 == b2 or merged(parents[b1]) == b2 or (b2 > 0 and merged(parents[b2]) == b1):
            continue
        keep.append(p.index)
    return np.array(keep, dtype=np.intp)


@checked_arguments
def sample_distances(result: SimResult, world: CollisionWorld) -> NDArray[np.float64]:
    """Smallest signed distance [m] at every sample of a result, over the tested pairs.

    Args:
        result: A simulation result (full coordinates).
        world: A collision world of the same (full) robot and environment.

    Returns:
        Shape (N,): the minimum over the pairs the simulation tests (pairs of bodies that the
        run's locked joints weld together are left out), unpruned.

    Raises:
        ConfigurationError: The world's robot does not have the result's joints.
    """
    nq = world.robot.model.nq
    if result.q.ndim != 2 or result.q.shape[1] != nq:
        raise ConfigurationError(
            "world", f"a world of a robot with nq={nq}", "a world built on the full robot"
        )
    pairs = _tested_pairs(result, world)
    if len(pairs) == 0:
        return np.full(len(result.t), np.inf)
    return np.array([float(world.all_distances(q)[pairs].min()) for q in result.q])


@checked_arguments
def plot_distance(
    result: SimResult,
    world: CollisionWorld,
    path: str | Path | None = None,
    *,
    distances: NDArray[np.float64] | None = None,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Minimum signed distance [m] against time [s], with the contact tolerance band.

    The distance is recomputed at every sample with ``world`` (see :func:`sample_distances`),
    so the plot also works for a run with ``contact_mode="none"``. Two stacked axes: the whole
    range, and a zoom on the contact tolerance band (-3 tol to +6 tol, widened to show the
    minimum if it lies within 10 tol). Negative values are penetration depths. The time axis
    is zoomed to the events (:func:`time_window`), the whole run in a strip below.

    Args:
        result: A simulation result.
        world: A collision world of the full robot and the run's environment (for a run with
            locked joints, build it on the full robot: the result is in full coordinates).
        path: Where to save, without suffix; None saves nothing.
        distances: Precomputed :func:`sample_distances` (saves the recomputation).
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure.
    """
    d = sample_distances(result, world) if distances is None else np.asarray(distances)
    tol = result.config.contact_tolerance
    tl = _timeline(result, event_kinds, zoom)
    title = f"Smallest signed distance over the tested pairs\n({_title(result)})"
    tf = _TimeFigure(tl, (2.3, 2.0), title)
    ax_all, ax_zoom = tf.panels
    k = int(np.argmin(d))
    for ax in (ax_all, ax_zoom):
        ax.plot(result.t, d, color="tab:blue", lw=1.5, label="min signed distance")
        ax.axhline(tol, color="tab:gray", ls=":", lw=1.3, label=f"+tol = {tol:g} m")
        ax.axhline(-tol, color="black", ls=":", lw=1.3, label=f"-tol = {-tol:g} m")
        ax.axhline(0.0, color="black", lw=0.6)
        ax.plot([result.t[k]], [d[k]], "v", color="tab:blue", ms=7)
    tf.mark_events(result, event_kinds)
    shown = _in_window(result, tl)
    _fit_y(ax_all, [d, np.where(shown, tol, np.nan), np.where(shown, -tol, np.nan)], shown)
    if tl.x0 <= result.t[k] <= tl.x1:
        right = result.t[k] > 0.5 * (tl.x0 + tl.x1)
        ax_all.annotate(
            f"min {d[k]:.3g} m at {result.t[k]:.3f} s",
            (float(result.t[k]), float(d[k])),
            xytext=(-8 if right else 8, 8),
            textcoords="offset points",
            ha="right" if right else "left",
            fontsize="small",
        )
    lo = min(-3.0 * tol, float(d.min()) - tol) if d.min() > -10 * tol else -3.0 * tol
    ax_zoom.set_ylim(lo, 6.0 * tol)
    ax_all.set_ylabel("min signed distance [m]")
    ax_zoom.set_ylabel("zoom on the tolerance [m]")
    ax_all.legend(loc="best", fontsize="small", framealpha=0.85)
    tf.context(result, [(d, "tab:blue")], event_kinds)
    _save(tf.fig, path, formats, dpi)
    return tf.fig


@checked_arguments
def plot_energy(
    result: SimResult,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    jump_threshold: float = 1e-3,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Total mechanical energy [J] against time [s], with the events' energy jumps.

    Every event that logs its energy before and after (impacts, limit stops, secondary
    intersections) and changes it by more than ``jump_threshold`` is drawn as a vertical
    segment from the energy before (circle) to after (triangle), and its label gives the
    change: a jump up is energy the impact law added. The time axis is zoomed to the events
    (:func:`time_window`), the whole run in a strip below.

    Args:
        result: A simulation result.
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark with vertical lines.
        jump_threshold: Smallest |energy change| labelled [J].
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure.
    """
    jumps: dict[int, str] = {}
    for i, ev in enumerate(result.events):
        e0, e1 = ev.energy_before, ev.energy_after
        if np.isfinite(e0) and np.isfinite(e1) and abs(e1 - e0) > jump_threshold:
            jumps[i] = f" {e1 - e0:+.3g} J"
    tl = _timeline(result, event_kinds, zoom, jumps)
    tf = _TimeFigure(tl, (3.0,), f"Total energy, kinetic + potential\n({_title(result)})")
    (ax,) = tf.panels
    ax.plot(result.t, result.energy, color="tab:blue", lw=1.5, label="total energy")
    tf.mark_events(result, event_kinds)
    ends = []
    for i in jumps:
        ev = result.events[i]
        e0, e1 = ev.energy_before, ev.energy_after
        color = EVENT_COLORS.get(ev.kind, "black")
        ax.plot([ev.t, ev.t], [e0, e1], color=color, lw=2.5)
        ax.plot([ev.t], [e0], "o", color=color, ms=5, mfc="white")
        ax.plot([ev.t], [e1], "^" if e1 > e0 else "v", color=color, ms=6)
        if tl.x0 <= ev.t <= tl.x1:
            ends.append(np.array([e0, e1]))
    _fit_y(ax, [result.energy], _in_window(result, tl))
    if ends:
        lo, hi = ax.get_ylim()
        e = np.concatenate(ends)
        ax.set_ylim(min(lo, float(e.min())), max(hi, float(e.max())))
    ax.set_ylabel("total energy [J]")
    ax.legend(loc="best", fontsize="small", framealpha=0.85)
    tf.context(result, [(result.energy, "tab:blue")], event_kinds)
    _save(tf.fig, path, formats, dpi)
    return tf.fig


@checked_arguments
def plot_contacts(
    result: SimResult,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Each pair's contact force [N] against time [s]: normal (solid) and friction (dashed).

    Per pair in contact, the sum of its points' normal forces and the magnitude of its summed
    friction force (:attr:`SimResult.contacts`, docs/contact.md); a pair's line has a gap where
    it carries no force (released, or a time-stepping window, whose forces are not recorded).
    The time axis is zoomed to the events, the whole run in a strip below.

    Args:
        result: A simulation result.
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark with vertical lines.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure.
    """
    tl = _timeline(result, event_kinds, zoom)
    tf = _TimeFigure(tl, (3.0,), f"Contact forces per pair\n({_title(result)})")
    (ax,) = tf.panels
    tab = result.contacts
    n = len(result.t)
    t = np.asarray(result.t)
    normal = tab.pair_normal_force(n)
    total = np.zeros((len(tab.pairs), n, 3))
    np.add.at(total, (tab.pair, tab.sample), tab.force)
    fn = np.zeros((len(tab.pairs), n, 3))
    along = np.einsum("ij,ij->i", tab.force, tab.normal)[:, None] * tab.normal
    np.add.at(fn, (tab.pair, tab.sample), along)
    friction = np.linalg.norm(total - fn, axis=2)
    touching = np.zeros((len(tab.pairs), n), dtype=bool)
    touching[tab.pair, tab.sample] = True
    traces: list[NDArray[np.float64]] = []
    for k, (_, piece1, _, piece2) in enumerate(tab.pairs):
        color = f"C{k % 10}"
        yn = np.where(touching[k], normal[k], np.nan)
        yf = np.where(touching[k], friction[k], np.nan)
        ax.plot(t, yn, color=color, lw=1.5, label=plain_text(f"{piece1} - {piece2}"))
        ax.plot(t, yf, color=color, lw=1.0, ls="--")
        traces += [yn, yf]
    if not tab.pairs:
        text = (
            "no contact forces: the arm touched nothing"
            if result.config.contact_mode == "normal"
            else f"no contact forces: contact_mode={result.config.contact_mode} records none"
        )
        ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.4")
    tf.mark_events(result, event_kinds)
    _fit_y(ax, traces, _in_window(result, tl))
    ax.set_ylabel("force [N]")
    if tab.pairs:
        ax.plot([], [], color="0.3", lw=1.5, label="normal force (solid)")
        ax.plot([], [], color="0.3", lw=1.0, ls="--", label="friction force (dashed)")
        ax.legend(loc="best", fontsize="small", framealpha=0.85)
    strip = normal.sum(axis=0) if tab.pairs else np.zeros(n)
    tf.context(result, [(strip, "tab:blue")], event_kinds)
    _save(tf.fig, path, formats, dpi)
    return tf.fig


def _joint_columns(result: SimResult, joints: Sequence[str]) -> list[int]:
    idx = []
    for name in joints:
        if name not in result.joint_names:
            raise UnknownNameError("joint", name, result.joint_names)
        idx.append(result.joint(name))
    return idx


def _runs_beyond(values: NDArray[np.float64], edge: float) -> list[tuple[int, int]]:
    """(start, end) index ranges (end exclusive) where |values| > edge (NaN: not beyond)."""
    out = np.abs(np.nan_to_num(values, nan=0.0)) > edge
    if not out.any():
        return []
    d = np.diff(np.concatenate([[0], out.astype(np.int8), [0]]))
    return [
        (int(a), int(b))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True)
    ]


@checked_arguments
def plot_torques(
    result: SimResult,
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    effort: NDArray[np.float64] | Sequence[float] | None = None,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Applied joint torques [N*m] against time [s], one axis per joint, scaled to its limits.

    The applied torque (``result.tau``) is solid; the commanded one (``result.tau_cmd``) dashed;
    the effort limits +/- (``result.effort`` per sample, else the constant ``effort``) are
    dash-dotted grey lines. Each axis spans :data:`TORQUE_AXIS` times the joint's largest
    effort limit: a command beyond is clipped at the axis' edge and marked there (a triangle at
    its peak, the largest peak given in numbers). The time axis is zoomed to the events
    (:func:`time_window`), the whole run's applied torques in a strip below.

    Args:
        result: A simulation result.
        joints: Joint names to plot.
        path: Where to save, without suffix; None saves nothing.
        effort: Constant effort limits [N*m], shape (nv,) (e.g. ``robot.params.effort``), used
            when the result has no per-sample ``effort``; None and no ``result.effort``: no
            limit lines, the axes fit the torques.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure.

    Raises:
        UnknownNameError: A joint name that the result does not have.
    """
    idx = _joint_columns(result, joints)
    tl = _timeline(result, event_kinds, zoom)
    tf = _TimeFigure(tl, [1.7] * len(idx), f"Joint torques\n({_title(result)})")
    tau_cmd = getattr(result, "tau_cmd", None)
    limits = getattr(result, "effort", None)
    if limits is None and effort is not None:
        limits = np.broadcast_to(np.asarray(effort, dtype=float), result.tau.shape)
    shown = _in_window(result, tl)
    colors = [_JOINT_COLORS[k % len(_JOINT_COLORS)] for k in range(len(idx))]
    for ax, name, j, color in zip(tf.panels, joints, idx, colors, strict=True):
        lim = None if limits is None else np.asarray(limits, dtype=float)[:, j]
        if lim is not None:
            ax.plot(result.t, lim, color="tab:gray", lw=1.0, ls="-.", label="effort limit")
            ax.plot(result.t, -lim, color="tab:gray", lw=1.0, ls="-.")
        cmd = None if tau_cmd is None else np.asarray(tau_cmd, dtype=float)[:, j]
        if cmd is not None:
            ax.plot(result.t, cmd, color=color, lw=1.0, ls="--", label="commanded")
        ax.plot(result.t, result.tau[:, j], color=color, lw=1.5, label="applied")
        top = float(np.max(np.abs(lim))) if lim is not None and len(lim) else 0.0
        if top > 0.0 and math.isfinite(top):
            edge = TORQUE_AXIS * top
            ax.set_ylim(-edge, edge)
            if cmd is not None:
                _mark_clipped(ax, result, cmd, edge, color)
        else:
            _fit_y(ax, [result.tau[:, j]] + ([] if cmd is None else [cmd]), shown)
        ax.set_ylabel(f"{name} [N*m]")
    tf.mark_events(result, event_kinds)
    tf.panels[0].legend(loc="best", fontsize="small", framealpha=0.85)
    tf.context(
        result, [(result.tau[:, j], c) for j, c in zip(idx, colors, strict=True)], event_kinds
    )
    _save(tf.fig, path, formats, dpi)
    return tf.fig


def _mark_clipped(
    ax: Axes, result: SimResult, cmd: NDArray[np.float64], edge: float, color: str
) -> None:
    """Triangles at the axis' edge at each peak of a command beyond it (in the shown time).

    The largest peak is also given in words.
    """
    t = np.asarray(result.t)
    x0, x1 = ax.get_xlim()
    shown = np.where((t >= x0) & (t <= x1), cmd, np.nan)
    runs = _runs_beyond(shown, edge)
    if not runs:
        return
    peaks = np.array([a + int(np.argmax(np.abs(cmd[a:b]))) for a, b in runs])
    style: dict[str, Any] = {
        "ls": "none",
        "ms": 7,
        "color": color,
        "mec": "black",
        "mew": 0.6,
        "zorder": 5,
    }
    for sign, marker, label in ((1, "^", "commanded, beyond the axis"), (-1, "v", None)):
        ks = peaks[np.sign(cmd[peaks]) == sign]
        if len(ks) or label:
            ax.plot(
                t[ks],
                np.full(len(ks), sign * edge),
                marker=marker,
                clip_on=False,
                label=label,
                **style,
            )
    k = peaks[int(np.argmax(np.abs(cmd[peaks])))]
    x0, x1 = ax.get_xlim()
    right = t[k] > 0.5 * (x0 + x1)  # the words go toward the middle
    ax.annotate(
        f"commanded {cmd[k]:+.4g} N*m at {t[k]:.3f} s, beyond the axis",
        (float(t[k]), float(np.sign(cmd[k]) * edge)),
        xytext=(-8 if right else 8, -9 if cmd[k] > 0 else 9),
        textcoords="offset points",
        ha="right" if right else "left",
        va="top" if cmd[k] > 0 else "bottom",
        fontsize="x-small",
        bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1.0},
        zorder=6,
    )


@checked_arguments
def plot_tracking(
    result: SimResult,
    q_ref: NDArray[np.float64],
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
    zoom: bool = True,
) -> Figure:
    """Joint positions against their reference [rad], and the tracking error q - q_ref [rad].

    The time axis is zoomed to the events (:func:`time_window`), the whole run's errors in a
    strip below.

    Args:
        result: A simulation result.
        q_ref: The reference joint positions at the result's samples [rad], shape (N, nq).
        joints: Joint names to plot.
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].
        zoom: Zoom the time axis to the events (False: the whole run, no strip).

    Returns:
        The figure.

    Raises:
        UnknownNameError: A joint name that the result does not have.
        ConfigurationError: ``q_ref`` not of the shape of ``result.q``.
    """
    idx = _joint_columns(result, joints)
    ref = np.asarray(q_ref, dtype=float)
    if ref.shape != result.q.shape:
        raise ConfigurationError("q_ref", ref.shape, f"shape {result.q.shape} (as result.q)")
    tl = _timeline(result, event_kinds, zoom)
    tf = _TimeFigure(tl, (2.3, 2.3), f"Tracking\n({_title(result)})")
    ax_q, ax_e = tf.panels
    colors = [_JOINT_COLORS[k % len(_JOINT_COLORS)] for k in range(len(idx))]
    for name, j, color in zip(joints, idx, colors, strict=True):
        ax_q.plot(result.t, result.q[:, j], color=color, lw=1.5, label=name)
        ax_q.plot(result.t, ref[:, j], color=color, lw=1.0, ls="--")
        ax_e.plot(result.t, result.q[:, j] - ref[:, j], color=color, lw=1.5, label=name)
    ax_q.plot([], [], color="black", lw=1.0, ls="--", label="reference")
    tf.mark_events(result, event_kinds)
    ax_e.axhline(0.0, color="black", lw=0.6)
    shown = _in_window(result, tl)
    _fit_y(ax_q, [result.q[:, j] for j in idx] + [ref[:, j] for j in idx], shown)
    _fit_y(ax_e, [result.q[:, j] - ref[:, j] for j in idx] + [np.zeros(len(shown))], shown)
    ax_q.set_ylabel("joint position [rad]")
    ax_e.set_ylabel("error q - q_ref [rad]")
    ax_q.legend(loc="best", fontsize="small", framealpha=0.85)
    errors = [(result.q[:, j] - ref[:, j], c) for j, c in zip(idx, colors, strict=True)]
    tf.context(result, errors, event_kinds)
    _save(tf.fig, path, formats, dpi)
    return tf.fig


#: Event kinds placed on a tool path: where the tool was when they happened.
_PATH_EVENTS: tuple[str, ...] = ("impact", "failure", "freeze", "pick", "drop")


@checked_arguments
def plot_tool_path(
    result: SimResult,
    path: str | Path | None = None,
    *,
    frame: str = "gripper_tool",
    robot: Robot | None = None,
    target: ArrayLike | None = None,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """The path of a frame's origin [m]: side view (x-z plane) and top view (x-y plane).

    World frame (``base_link``'s: x forward, y left, z up), equal scales on both axes. The
    start is a green circle, the end a black square, the target (if given) a red star with
    the final distance to it [mm]; impacts, failures, freezes and payload changes are placed
    where the tool was when they happened; the floor (z = 0) is a grey line in the side view.

    Args:
        result: A simulation result.
        path: Where to save, without suffix; None saves nothing.
        frame: The frame whose path is drawn (:meth:`SimResult.frame_positions`).
        robot: The robot the run simulated (None: the shipped one).
        target: The frame's target [m], world frame, shape (3,), or None.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure.

    Raises:
        UnknownNameError: ``frame`` is not a frame of the model.
        ConfigurationError: ``target`` is not 3 finite coordinates [m].
    """
    xyz = result.frame_positions(frame, robot)
    goal = None
    if target is not None:
        goal = np.asarray(target, dtype=float)
        if goal.shape != (3,) or not np.all(np.isfinite(goal)):
            raise ConfigurationError("target", target, "None or 3 finite coordinates [m]")
    fig = Figure(figsize=(_WIDTH, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax_side, ax_top = fig.subplots(1, 2)
    t = np.asarray(result.t, dtype=float)
    marks: dict[str, list[int]] = {}
    for ev in result.events:
        if ev.kind in _PATH_EVENTS and len(t):
            i = min(int(np.searchsorted(t, ev.t)), len(t) - 1)
            marks.setdefault(ev.kind, []).append(i)
    for ax, (a, b), names in ((ax_side, (0, 2), ("x", "z")), (ax_top, (0, 1), ("x", "y"))):
        ax.plot(xyz[:, a], xyz[:, b], color="tab:blue", lw=1.5, label=f"{plain_text(frame)} path")
        ax.plot(xyz[0, a], xyz[0, b], "o", color="tab:green", ms=7, label="start")
        ax.plot(xyz[-1, a], xyz[-1, b], "s", color="black", ms=6, label="end")
        if goal is not None:
            ax.plot(goal[a], goal[b], "*", color="tab:red", ms=13, label="target")
        for kind, idx in marks.items():
            ax.plot(
                xyz[idx, a],
                xyz[idx, b],
                {"impact": "x", "failure": "v"}.get(kind, "^"),
                color=EVENT_COLORS.get(kind, "black"),
                ms=7,
                mew=1.5,
                ls="none",
                label=f"{kind} ({len(idx)})",
            )
        ax.set_xlabel(f"{names[0]} [m]")
        ax.set_ylabel(f"{names[1]} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
    ax_side.axhline(0.0, color="grey", lw=1.5, zorder=0, label="floor")
    ax_side.set_title("side view (x-z)", fontsize="medium")
    ax_top.set_title("top view (x-y)", fontsize="medium")
    ax_side.legend(loc="best", fontsize="small", framealpha=0.85)
    title = f"Path of {plain_text(frame)}\n({_title(result)})"
    if goal is not None:
        miss = 1000.0 * float(np.linalg.norm(xyz[-1] - goal))
        title = f"Path of {plain_text(frame)}: {miss:.1f} mm from the target at the end\n"
        title += f"({_title(result)})"
    fig.suptitle(title)
    _save(fig, path, formats, dpi)
    return fig


def _mark_events(ax: Axes, result: SimResult, kinds: Iterable[str]) -> list[tuple[str, str]]:
    """Vertical lines at the events of the given kinds; returns the (kind, colour) drawn."""
    drawn: dict[str, str] = {}
    kinds = tuple(kinds)
    for ev in result.events:
        if ev.kind not in kinds:
            continue
        color = EVENT_COLORS.get(ev.kind, "black")
        ax.axvline(ev.t, color=color, lw=0.9, ls="-", alpha=0.55, zorder=0)
        drawn[ev.kind] = color
    if result.rest_time is not None:
        ax.axvline(result.rest_time, color="black", lw=1.1, ls="--", zorder=0)
    return list(drawn.items())


@checked_arguments
def sample_occlusion(
    result: SimResult,
    world: CollisionWorld,
    targets: Sequence[Sequence[float]],
    *,
    frame: str = "camera_optical",
    radius: float = 0.0,
    ignore: tuple[str, ...] = ("camera_head",),
) -> list[list[str | None]]:
    """What blocks the view from ``frame`` to each target at every sample.

    Args:
        result: A simulation result (full coordinates).
        world: A collision world of the full robot and the run's environment.
        targets: World points [m], each (x, y, z).
        frame: The eye frame.
        radius: Corridor radius [m] (see :meth:`CollisionWorld.line_of_sight`).
        ignore: Links not tested.

    Returns:
        One list per target, one entry per sample: the blocking link or obstacle nearest the
        eye, or None when the view is clear.
    """
    pts = [np.asarray(p, dtype=float) for p in targets]
    return [
        [world.line_of_sight(q, p, frame=frame, radius=radius, ignore=ignore) for q in result.q]
        for p in pts
    ]


def _runs(values: Sequence[str | None]) -> list[tuple[int, int, str]]:
    """(start, end, value) of the runs of equal, non-None values (end exclusive)."""
    out: list[tuple[int, int, str]] = []
    start = 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            v = values[start]
            if v is not None:
                out.append((start, i, v))
            start = i
    return out


@checked_arguments
def plot_occlusion(
    result: SimResult,
    blocked: Sequence[Sequence[str | None]],
    targets: Sequence[Sequence[float]],
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """The camera's view of each target against time: one row per target, a bar where blocked.

    Bars are coloured by the blocking link or obstacle; the fraction of the time the view is
    clear is given per target.

    Args:
        result: A simulation result.
        blocked: :func:`sample_occlusion`'s output: per target, per sample, the blocker or None.
        targets: The target points [m] (for the labels).
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure.
    """
    if len(blocked) != len(targets):
        raise ConfigurationError("blocked", len(blocked), f"{len(targets)} rows (one per target)")
    t = np.asarray(result.t, dtype=float)
    fig, (ax,) = _new_figure(max(3.0, 1.8 + 0.6 * len(targets)))
    colors: dict[str, str] = {}
    palette = ("tab:red", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive")
    # each sample stands for the time until the next one
    edges = np.append(t, t[-1] + (t[-1] - t[-2] if len(t) > 1 else 1.0))
    labels = []
    for k, (row, target) in enumerate(zip(blocked, targets, strict=True)):
        if len(row) != len(t):
            raise ConfigurationError(f"blocked[{k}]", len(row), f"{len(t)} samples")
        ax.broken_barh([(t[0], edges[-1] - t[0])], (k - 0.35, 0.7), color="tab:green", alpha=0.25)
        for i0, i1, name in _runs(list(row)):
            color = colors.setdefault(name, palette[len(colors) % len(palette)])
            ax.broken_barh([(t[i0], edges[i1] - t[i0])], (k - 0.35, 0.7), color=color)
        clear = float(np.mean([b is None for b in row])) if len(row) else 0.0
        xyz = ", ".join(f"{c:g}" for c in target)
        labels.append(f"({xyz}) m\nclear {100 * clear:.0f}%")
    drawn = _mark_events(ax, result, event_kinds)
    handles = [Line2D([], [], color="tab:green", alpha=0.4, lw=6, label="clear view")]
    handles += [
        Line2D([], [], color=c, lw=6, label=plain_text(f"blocked by {n}"))
        for n, c in colors.items()
    ]
    for kind, color in drawn:
        handles.append(Line2D([], [], color=color, lw=1.2, label=kind))
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize="small",
        framealpha=0.85,
    )
    ax.set_yticks(range(len(targets)), labels)
    ax.set_ylim(len(targets) - 0.4, -0.6)  # the first target on top
    ax.set_xlim(float(t[0]), float(t[-1]))
    ax.set_xlabel("time [s]")
    ax.set_title(f"Camera view of the targets\n({_title(result)})")
    ax.grid(True, axis="x", alpha=0.3)
    _save(fig, path, formats, dpi)
    return fig
