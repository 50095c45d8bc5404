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
- :func:`plot_torques`: applied (and commanded) joint torques [N*m] with their effort limits;
- :func:`plot_tracking`: joint positions against a controller's reference, and the error [rad];
- :func:`plot_occlusion`: whether the camera's view of target points is blocked, and by what
  (:func:`sample_occlusion`).

Events are vertical lines coloured by kind; the rest time is a dashed black line.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from numpy.typing import NDArray

from packbot.collision import CollisionWorld
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.result import SimResult

__all__ = [
    "EVENT_COLORS",
    "MARKED_EVENTS",
    "PLANAR_JOINTS",
    "plot_distance",
    "plot_energy",
    "plot_joints",
    "plot_occlusion",
    "plot_torques",
    "plot_tracking",
    "sample_distances",
    "sample_occlusion",
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
_JOINT_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
_FORMATS = ("png", "svg")


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
    # The constrained layout (a pass measuring every text) is solved once, then frozen for every
    # format: it is in figure fractions, so the same for any dpi (to a pixel of rounding). This
    # makes a two-format figure ~12% faster.
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


def _mark_events(
    ax: Axes, result: SimResult, kinds: Iterable[str], label: bool
) -> list[tuple[str, str]]:
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
    if label:
        return list(drawn.items())
    return []


def _event_legend(ax: Axes, drawn: list[tuple[str, str]], result: SimResult) -> None:
    handles = ax.get_legend_handles_labels()[0]
    for kind, color in drawn:
        n = len(result.events_of(kind))
        handles.append(Line2D([], [], color=color, lw=1.2, label=f"{kind} ({n})"))
    if result.rest_time is not None:
        handles.append(
            Line2D(
                [], [], color="black", ls="--", lw=1.1, label=f"at rest {result.rest_time:.3f} s"
            )
        )
    ax.legend(handles=handles, loc="best", fontsize="small", framealpha=0.85)


def _title(result: SimResult) -> str:
    c = result.config
    if c.contact_mode == "none":
        return "contact_mode=none"
    return f"{c.contact_mode}, reset_rule={c.reset_rule}, clamp_rule={c.clamp_rule}"


def plot_joints(
    result: SimResult,
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """Joint positions [rad] and velocities [rad/s] against time [s] (report Figures 9, 10).

    Two stacked axes sharing the time axis. Events are marked as vertical lines coloured by
    kind, the rest time as a dashed black line. The samples include the instants just before
    and after every event, so velocity jumps show as vertical segments.

    Args:
        result: A simulation result.
        joints: Joint names to plot (default: the planar joints shoulder, elbow1, elbow2).
        path: Where to save, without suffix (any suffix is replaced by each format's); None
            saves nothing.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure (not registered with pyplot).

    Raises:
        UnknownNameError: A joint name that the result does not have.
    """
    idx = _joint_columns(result, joints)
    fig, (ax_q, ax_v) = _new_figure(6.5, 2)
    for k, (name, j) in enumerate(zip(joints, idx, strict=True)):
        color = _JOINT_COLORS[k % len(_JOINT_COLORS)]
        ax_q.plot(result.t, result.q[:, j], color=color, lw=1.5, label=name)
        ax_v.plot(result.t, result.v[:, j], color=color, lw=1.5, label=name)
    drawn = _mark_events(ax_q, result, event_kinds, label=True)
    _mark_events(ax_v, result, event_kinds, label=False)
    ax_q.set_ylabel("joint position [rad]")
    ax_v.set_ylabel("joint velocity [rad/s]")
    ax_v.set_xlabel("time [s]")
    ax_q.set_title(f"Joint positions and velocities\n({_title(result)})")
    _finish_two_panels(fig, ax_q, ax_v, result, drawn, path, formats, dpi)
    return fig


def _finish_two_panels(
    fig: Figure,
    top: Axes,
    bottom: Axes,
    result: SimResult,
    drawn: list[tuple[str, str]],
    path: str | Path | None,
    formats: Sequence[str],
    dpi: int,
) -> None:
    """Grid, time range and legends of a two-panel time plot (events on top), then save it."""
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
        ax.set_xlim(float(result.t[0]), float(result.t[-1]))
    _event_legend(top, drawn, result)
    bottom.legend(loc="best", fontsize="small", framealpha=0.85)
    _save(fig, path, formats, dpi)


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


def plot_distance(
    result: SimResult,
    world: CollisionWorld,
    path: str | Path | None = None,
    *,
    distances: NDArray[np.float64] | None = None,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """Minimum signed distance [m] against time [s], with the contact tolerance band.

    The distance is recomputed at every sample with ``world`` (see :func:`sample_distances`),
    so the plot also works for a run with ``contact_mode="none"``. Two stacked axes: the whole
    range, and a zoom on the contact tolerance band (-3 tol to +6 tol, widened to show the
    minimum if it lies within 10 tol). Negative values are penetration depths.

    Args:
        result: A simulation result.
        world: A collision world of the full robot and the run's environment (for a run with
            locked joints, build it on the full robot: the result is in full coordinates).
        path: Where to save, without suffix; None saves nothing.
        distances: Precomputed :func:`sample_distances` (saves the recomputation).
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure.
    """
    d = sample_distances(result, world) if distances is None else np.asarray(distances)
    tol = result.config.contact_tolerance
    fig, (ax_all, ax_zoom) = _new_figure(6.5, 2)
    k = int(np.argmin(d))
    for ax in (ax_all, ax_zoom):
        ax.plot(result.t, d, color="tab:blue", lw=1.5, label="min signed distance")
        ax.axhline(tol, color="tab:gray", ls=":", lw=1.3, label=f"+tol = {tol:g} m")
        ax.axhline(-tol, color="black", ls=":", lw=1.3, label=f"-tol = {-tol:g} m")
        ax.axhline(0.0, color="black", lw=0.6)
        ax.plot([result.t[k]], [d[k]], "v", color="tab:blue", ms=7)
        ax.set_xlim(float(result.t[0]), float(result.t[-1]))
        ax.grid(True, alpha=0.3)
    drawn = _mark_events(ax_all, result, event_kinds, label=True)
    _mark_events(ax_zoom, result, event_kinds, label=False)
    right = result.t[k] > 0.5 * (result.t[0] + result.t[-1])
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
    ax_zoom.set_xlabel("time [s]")
    ax_all.set_title(f"Smallest signed distance over the tested pairs\n({_title(result)})")
    _event_legend(ax_all, drawn, result)
    _save(fig, path, formats, dpi)
    return fig


def plot_energy(
    result: SimResult,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    jump_threshold: float = 1e-3,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """Total mechanical energy [J] against time [s], with the events' energy jumps.

    Every event that logs its energy before and after (impacts, limit stops, secondary
    intersections) and changes it by more than ``jump_threshold`` is drawn as a vertical
    segment from the energy before (circle) to after (triangle), labelled with the change:
    a jump up is energy the impact law added.

    Args:
        result: A simulation result.
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark with vertical lines.
        jump_threshold: Smallest |energy change| annotated [J].
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure.
    """
    fig, (ax,) = _new_figure(4.5)
    ax.plot(result.t, result.energy, color="tab:blue", lw=1.5, label="total energy")
    drawn = _mark_events(ax, result, event_kinds, label=True)
    for ev in result.events:
        e0, e1 = ev.energy_before, ev.energy_after
        if not (np.isfinite(e0) and np.isfinite(e1)) or abs(e1 - e0) <= jump_threshold:
            continue
        color = EVENT_COLORS.get(ev.kind, "black")
        ax.plot([ev.t, ev.t], [e0, e1], color=color, lw=2.5)
        ax.plot([ev.t], [e0], "o", color=color, ms=5, mfc="white")
        ax.plot([ev.t], [e1], "^" if e1 > e0 else "v", color=color, ms=6)
        ax.annotate(
            f"{e1 - e0:+.3g} J",
            (ev.t, 0.5 * (e0 + e1)),
            xytext=(5, 0),
            textcoords="offset points",
            fontsize="small",
            color=color,
            va="center",
        )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("total energy [J]")
    ax.set_title(f"Total energy, kinetic + potential\n({_title(result)})")
    ax.set_xlim(float(result.t[0]), float(result.t[-1]))
    ax.grid(True, alpha=0.3)
    _event_legend(ax, drawn, result)
    _save(fig, path, formats, dpi)
    return fig


def _joint_columns(result: SimResult, joints: Sequence[str]) -> list[int]:
    idx = []
    for name in joints:
        if name not in result.joint_names:
            raise UnknownNameError("joint", name, result.joint_names)
        idx.append(result.joint(name))
    return idx


def plot_torques(
    result: SimResult,
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    effort: NDArray[np.float64] | Sequence[float] | None = None,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """Applied joint torques [N*m] against time [s], one axis per joint, with their limits.

    The applied torque (``result.tau``) is solid; the commanded one (``result.tau_cmd``, when
    the result has it) dashed; the effort limits +/- (``result.effort`` per sample when the
    result has it, else the constant ``effort``) are grey bands' edges.

    Args:
        result: A simulation result.
        joints: Joint names to plot.
        path: Where to save, without suffix; None saves nothing.
        effort: Constant effort limits [N*m], shape (nv,) (e.g. ``robot.params.effort``), used
            when the result has no per-sample ``effort``; None: no limit lines.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

    Returns:
        The figure.

    Raises:
        UnknownNameError: A joint name that the result does not have.
    """
    idx = _joint_columns(result, joints)
    fig, axes = _new_figure(1.0 + 2.0 * len(idx), len(idx))
    tau_cmd = getattr(result, "tau_cmd", None)
    limits = getattr(result, "effort", None)
    if limits is None and effort is not None:
        limits = np.broadcast_to(np.asarray(effort, dtype=float), result.tau.shape)
    drawn: list[tuple[str, str]] = []
    for k, (ax, name, j) in enumerate(zip(axes, joints, idx, strict=True)):
        color = _JOINT_COLORS[k % len(_JOINT_COLORS)]
        if limits is not None:
            lim = np.asarray(limits)[:, j]
            ax.plot(result.t, lim, color="tab:gray", lw=1.0, ls="-.", label="effort limit")
            ax.plot(result.t, -lim, color="tab:gray", lw=1.0, ls="-.")
        if tau_cmd is not None:
            ax.plot(
                result.t, np.asarray(tau_cmd)[:, j], color=color, lw=1.0, ls="--", label="commanded"
            )
        ax.plot(result.t, result.tau[:, j], color=color, lw=1.5, label="applied")
        found = _mark_events(ax, result, event_kinds, label=k == 0)
        drawn = drawn or found
        ax.set_ylabel(f"{name} [N*m]")
        ax.grid(True, alpha=0.3)
        ax.set_xlim(float(result.t[0]), float(result.t[-1]))
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(f"Joint torques\n({_title(result)})")
    _event_legend(axes[0], drawn, result)
    _save(fig, path, formats, dpi)
    return fig


def plot_tracking(
    result: SimResult,
    q_ref: NDArray[np.float64],
    joints: Sequence[str] = PLANAR_JOINTS,
    path: str | Path | None = None,
    *,
    event_kinds: Iterable[str] = MARKED_EVENTS,
    formats: Sequence[str] = _FORMATS,
    dpi: int = 120,
) -> Figure:
    """Joint positions against their reference [rad], and the tracking error q - q_ref [rad].

    Args:
        result: A simulation result.
        q_ref: The reference joint positions at the result's samples [rad], shape (N, nq).
        joints: Joint names to plot.
        path: Where to save, without suffix; None saves nothing.
        event_kinds: Event kinds to mark.
        formats: File formats written when ``path`` is given ("png", "svg").
        dpi: Resolution of the PNG [dots per inch].

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
    fig, (ax_q, ax_e) = _new_figure(6.5, 2)
    for k, (name, j) in enumerate(zip(joints, idx, strict=True)):
        color = _JOINT_COLORS[k % len(_JOINT_COLORS)]
        ax_q.plot(result.t, result.q[:, j], color=color, lw=1.5, label=name)
        ax_q.plot(result.t, ref[:, j], color=color, lw=1.0, ls="--")
        ax_e.plot(result.t, result.q[:, j] - ref[:, j], color=color, lw=1.5, label=name)
    ax_q.plot([], [], color="black", lw=1.0, ls="--", label="reference")
    drawn = _mark_events(ax_q, result, event_kinds, label=True)
    _mark_events(ax_e, result, event_kinds, label=False)
    ax_e.axhline(0.0, color="black", lw=0.6)
    ax_q.set_ylabel("joint position [rad]")
    ax_e.set_ylabel("error q - q_ref [rad]")
    ax_e.set_xlabel("time [s]")
    ax_q.set_title(f"Tracking\n({_title(result)})")
    _finish_two_panels(fig, ax_q, ax_e, result, drawn, path, formats, dpi)
    return fig


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
    drawn = _mark_events(ax, result, event_kinds, label=True)
    handles = [Line2D([], [], color="tab:green", alpha=0.4, lw=6, label="clear view")]
    handles += [Line2D([], [], color=c, lw=6, label=f"blocked by {n}") for n, c in colors.items()]
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
