"""Plots of a simulation result (the command line is tested in test_cli.py)."""

import dataclasses

import numpy as np
import pytest
from matplotlib import _pylab_helpers
from matplotlib.figure import Figure
from matplotlib.image import imread

import packbot
from packbot.plots import (
    MARKED_EVENTS,
    MOVING_FRACTION,
    TORQUE_AXIS,
    event_label,
    plot_distance,
    plot_energy,
    plot_joints,
    plot_occlusion,
    plot_tool_path,
    plot_torques,
    plot_tracking,
    sample_distances,
    sample_occlusion,
    time_window,
)
from packbot.result import Event

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def short_collapse(robot):
    """Two seconds of the report's collapse (its law): impacts at 0.15, 0.17 and 0.59 s, at rest
    from 0.59 s."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)


def panel(fig, ylabel):
    """The axes of a figure with this y label."""
    return next(ax for ax in fig.axes if ax.get_ylabel() == ylabel)


def lane_texts(fig):
    """The event labels of a time plot (the lane: the axes drawn without axis)."""
    lane = next(ax for ax in fig.axes if not ax.axison)
    return lane.texts


def strip(fig):
    """The whole-run strip of a zoomed time plot."""
    return next(ax for ax in fig.axes if ax.get_title(loc="left").startswith("the whole run"))


@pytest.fixture(scope="module")
def world(robot):
    return packbot.CollisionWorld(robot)


def assert_not_blank(path):
    assert path.is_file() and path.stat().st_size > 1000, path
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    assert float(img[..., :3].std()) > 0.02, f"{path} is (nearly) a single colour"


def test_plot_joints_writes_png_and_svg(short_collapse, tmp_path):
    fig = plot_joints(short_collapse, path=tmp_path / "joints")
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 4  # the event lane, positions, velocities, the whole run
    assert_not_blank(tmp_path / "joints.png")
    svg = (tmp_path / "joints.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    assert _pylab_helpers.Gcf.get_num_fig_managers() == 0  # nothing left in pyplot


def test_plot_joints_labels_the_events_and_rest(short_collapse):
    fig = plot_joints(short_collapse)
    ax = panel(fig, "joint position [rad]")
    assert ax.get_legend_handles_labels()[1] == ["shoulder", "elbow1", "elbow2"]
    impacts = short_collapse.events_of("impact")
    assert len(impacts) == 3
    texts = [t.get_text() for t in lane_texts(fig)]
    for e in impacts:  # each impact labelled with its pair
        assert f"impact {e.link1}\u2013{e.link2}" in texts
    assert f"at rest {short_collapse.rest_time:.3f} s" in texts
    assert len(texts) == 4


def test_time_axis_zooms_to_the_events_with_the_whole_run_below(short_collapse):
    res = short_collapse
    marked = [e.t for e in res.events if e.kind in MARKED_EVENTS] + [res.rest_time]
    t0, t1 = time_window(res)
    assert t0 == res.t[0]  # the start is near: kept
    assert max(marked) < t1 < max(marked) + 0.1 and t1 < 0.5 * res.t[-1]
    for plot in (plot_joints, plot_energy):
        fig = plot(res)
        ax = fig.axes[1]  # the first panel, under the event lane
        lo, hi = ax.get_xlim()
        assert (lo, hi) == (t0, t1)
        assert all(lo <= t <= hi for t in marked)
        # the strip shows the whole run, the zoomed interval shaded
        whole = strip(fig)
        assert whole.get_xlim() == (res.t[0], res.t[-1])
        (span,) = whole.patches
        box = span.get_bbox()  # x in data units
        assert (box.x0, box.x1) == pytest.approx((t0, t1))
    fig = plot_joints(res, zoom=False)
    assert fig.axes[1].get_xlim() == (res.t[0], res.t[-1])
    assert not any(ax.get_title(loc="left") for ax in fig.axes)


def test_time_window_frames_the_motion_of_a_controlled_run(robot):
    """A computed-torque reach whose elbow freezes at 1 s: the zoom was on the failure and the
    rest (0.9-2.1 s of 3 s) and cut the first second of the reach; now every moving sample is
    shown."""
    from packbot.scenario import load_scenario, run_scenario

    res = run_scenario(load_scenario("frozen_elbow_reach"), robot)
    a, b = time_window(res)
    speed = np.abs(res.v).max(axis=1)
    moving = res.t[speed >= max(MOVING_FRACTION * speed.max(), res.config.rest_speed)]
    assert moving[0] < 0.5 < moving[-1]  # the reach starts at once, before the failure
    assert a <= moving[0] and moving[-1] <= b


def test_time_window_zooms_to_late_motion_without_events(short_collapse):
    """The arm still for most of a run, moving from 1.4 s to 1.6 s alone: the zoom frames that
    motion (plus its margin), as it frames events."""
    t = short_collapse.t
    v = np.zeros_like(short_collapse.v)
    move = (t >= 1.4) & (t <= 1.6)
    v[move, 1] = 0.5 * np.sin(np.pi * (t[move] - 1.4) / 0.2)
    rest = float(t[np.flatnonzero(move)[-1] + 1])  # the first still sample after the motion
    quiet = dataclasses.replace(short_collapse, v=v, events=[], rest_time=rest)
    a, b = time_window(quiet)
    assert 1.2 < a < 1.42 and 1.58 < b < 1.8, (a, b)


def test_time_window_whole_run_when_events_fill_it(short_collapse):
    res = short_collapse
    late = dataclasses.replace(res.events[0], t=1.9)
    assert time_window(dataclasses.replace(res, events=[*res.events, late])) == (0.0, 2.0)
    quiet = dataclasses.replace(res, events=[], rest_time=None)
    assert time_window(quiet) == (0.0, 2.0)
    v = np.where((res.t > 0.3)[:, None], 0.0, res.v)  # at rest from 0.3 s
    still = dataclasses.replace(res, v=v, events=[], rest_time=0.3)  # no event: start to rest
    t0, t1 = time_window(still)
    assert t0 == 0.0 and 0.3 < t1 < 0.4


@pytest.mark.parametrize("zoom", [True, False])
def test_event_labels_never_overlap(short_collapse, zoom):
    """Dense events: every one labelled (repeats close in time counted), no two labels overlap,
    no leader runs through a label (zoom=False: labels near the right end, written leftward)."""
    res = short_collapse
    base = res.events_of("impact")[0]
    dense = [dataclasses.replace(base, t=0.15 + 0.004 * k) for k in range(5)]  # repeats
    others = [
        Event(t=0.16 + 0.01 * k, kind=kind, link1=joint, link2=what)
        for k, (kind, joint, what) in enumerate(
            [
                ("limit", "elbow1", "upper"),
                ("failure", "shoulder", "loose"),
                ("freeze", "elbow2", ""),
                ("release", "link3", "link1"),
                ("limit", "shoulder", "lower"),
            ]
        )
    ]
    late = [
        Event(t=t, kind="limit", link1=joint, link2="upper")
        for t, joint in ((1.8, "turret"), (1.9, "shoulder"), (1.95, "elbow1"), (1.97, "elbow2"))
    ]
    events = sorted([*res.events, *dense, *others, *late], key=lambda e: e.t)
    fig = plot_joints(dataclasses.replace(res, events=events), zoom=zoom)
    texts = lane_texts(fig)
    words = [t.get_text() for t in texts]
    for e in [*others, *late]:
        assert event_label(e) in words
    assert f"{event_label(base)} \u00d76" in words  # the first impact and its 5 repeats
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in texts]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b), (a, b)
    # no leader (the vertical line from an event up to its label) runs through a label
    lane = texts[0].axes
    leaders = [ln for ln in lane.get_lines() if len(ln.get_xdata()) == 2]
    leaders = [ln for ln in leaders if ln.get_xdata()[0] == ln.get_xdata()[1]]
    assert len(leaders) == len(texts)
    for ln in leaders:
        (x, y0), (_, y1) = lane.transData.transform(np.column_stack(ln.get_data()))
        for b in boxes:
            assert not (b.x0 + 0.5 < x < b.x1 - 0.5 and y0 < b.y1 - 0.5 and b.y0 + 0.5 < y1), (
                ln.get_xdata(),
                b,
            )
    # each label in the figure, below the title
    title_box = fig.texts[0].get_window_extent(renderer)
    for b in boxes:
        assert b.x0 >= 0 and b.x1 <= fig.bbox.width and b.y1 < title_box.y0


def test_simultaneous_events_of_a_kind_share_a_label(short_collapse):
    both = [
        Event(t=0.3, kind="release", link1="elbow2", link2="upper"),
        Event(t=0.3, kind="release", link1="shoulder", link2="lower"),
        Event(t=0.3, kind="failure", link1="elbow1", link2="loose"),
        Event(t=0.3, kind="failure", link1="turret", link2="frozen"),
    ]
    events = sorted([*short_collapse.events, *both], key=lambda e: e.t)
    fig = plot_joints(dataclasses.replace(short_collapse, events=events))
    words = [t.get_text() for t in lane_texts(fig)]
    assert "release elbow2 upper, shoulder lower" in words
    # failures are never merged: each names its joint and kind
    assert {"failure: elbow1 loose", "failure: turret frozen"} <= set(words)


def test_failure_label_names_the_joint_and_the_kind(short_collapse):
    fail = Event(t=0.3, kind="failure", link1="elbow1", link2="frozen")
    assert event_label(fail) == "failure: elbow1 frozen"
    assert event_label(Event(t=0.3, kind="limit", link1="elbow1", link2="upper")) == (
        "limit elbow1 upper"
    )
    assert event_label(Event(t=0.3, kind="freeze", link1="elbow1")) == "freeze elbow1"
    events = sorted([*short_collapse.events, fail], key=lambda e: e.t)
    fig = plot_torques(dataclasses.replace(short_collapse, events=events))
    assert "failure: elbow1 frozen" in [t.get_text() for t in lane_texts(fig)]


def test_plot_joints_unknown_joint_lists_the_joints(short_collapse):
    with pytest.raises(packbot.UnknownNameError, match="shoulder"):
        plot_joints(short_collapse, joints=("shoulder", "wrist"))


def test_plot_distance_writes_png(short_collapse, world, tmp_path):
    plot_distance(short_collapse, world, path=tmp_path / "distance", formats=("png",))
    assert_not_blank(tmp_path / "distance.png")
    assert not (tmp_path / "distance.svg").exists()


def test_sample_distances_agree_with_the_simulation(short_collapse, world):
    d = sample_distances(short_collapse, world)
    assert d.shape == short_collapse.t.shape
    tol = short_collapse.config.contact_tolerance
    assert d.min() >= -tol
    # the run's own minimum is over the samples and the accepted steps, a superset
    assert d.min() >= short_collapse.diagnostics.min_distance - 1e-9
    assert d.min() == pytest.approx(short_collapse.diagnostics.min_distance, abs=1e-5)
    assert d[0] > 0.01  # the drive pose is clear


def test_plot_energy_writes_png(short_collapse, tmp_path):
    plot_energy(short_collapse, path=tmp_path / "energy.png")
    assert_not_blank(tmp_path / "energy.png")
    assert (tmp_path / "energy.svg").is_file()


def test_bad_format_is_refused(short_collapse, tmp_path):
    with pytest.raises(packbot.ConfigurationError, match="formats"):
        plot_energy(short_collapse, path=tmp_path / "energy", formats=("pdf",))


def test_plot_torques_shows_torques_and_limits(short_collapse, robot, tmp_path):
    fig = plot_torques(short_collapse, path=tmp_path / "torques", effort=robot.params.effort)
    assert_not_blank(tmp_path / "torques.png")
    ax = panel(fig, "shoulder [N*m]")
    limit = next(ln for ln in ax.get_lines() if ln.get_label() == "effort limit")
    assert limit.get_ydata()[0] == robot.params.effort[robot.params.index("shoulder")]
    applied = next(ln for ln in ax.get_lines() if ln.get_label() == "applied")
    np.testing.assert_array_equal(applied.get_ydata(), short_collapse.tau[:, 1])


def test_torque_axes_fit_the_limits_and_mark_clipped_commands(short_collapse, robot):
    res = short_collapse
    j = res.joint("shoulder")
    cmd = res.tau_cmd.copy()
    k = int(np.searchsorted(res.t, 0.3))
    cmd[k : k + 5, j] = 2800.0  # far beyond the 156 N*m limit
    cmd[k + 20, j] = -1000.0
    fig = plot_torques(dataclasses.replace(res, tau_cmd=cmd))
    for name in ("shoulder", "elbow1", "elbow2"):
        ax = panel(fig, f"{name} [N*m]")
        top = float(np.max(res.effort[:, res.joint(name)]))
        assert ax.get_ylim() == pytest.approx((-TORQUE_AXIS * top, TORQUE_AXIS * top))
    ax = panel(fig, "shoulder [N*m]")
    edge = TORQUE_AXIS * float(np.max(res.effort[:, j]))
    marks = [ln for ln in ax.get_lines() if ln.get_marker() in ("^", "v") and len(ln.get_xdata())]
    xs = sorted(float(x) for ln in marks for x in ln.get_xdata())
    ys = sorted(float(y) for ln in marks for y in ln.get_ydata())
    assert xs == pytest.approx([res.t[k], res.t[k + 20]])
    assert ys == pytest.approx([-edge, edge])
    assert all(not ln.get_clip_on() for ln in marks)  # drawn on the edge, not clipped away
    (note,) = [t for t in ax.texts if "beyond the axis" in t.get_text()]
    assert "+2800 N*m" in note.get_text()
    assert not any(ln.get_marker() in ("^", "v") for ln in panel(fig, "elbow1 [N*m]").get_lines())


def test_plot_tracking_draws_the_error(short_collapse, tmp_path):
    q_ref = np.repeat(short_collapse.q[:1], len(short_collapse.t), axis=0)  # hold the start
    fig = plot_tracking(short_collapse, q_ref, ("shoulder", "elbow1"), path=tmp_path / "tr")
    assert_not_blank(tmp_path / "tr.png")
    err = panel(fig, "error q - q_ref [rad]").get_lines()[0].get_ydata()
    np.testing.assert_allclose(err, short_collapse.q[:, 1] - short_collapse.q[0, 1])
    with pytest.raises(packbot.ConfigurationError, match="q_ref"):
        plot_tracking(short_collapse, q_ref[:, :3])


def test_plot_tool_path_side_and_top_views_with_the_target(short_collapse, tmp_path):
    target = (1.0, 0.2, 0.3)
    fig = plot_tool_path(short_collapse, path=tmp_path / "tp", target=target)
    assert_not_blank(tmp_path / "tp.png")
    assert (tmp_path / "tp.svg").is_file()
    side, top = panel(fig, "z [m]"), panel(fig, "y [m]")
    xyz = short_collapse.frame_positions("gripper_tool")
    path = side.get_lines()[0]
    np.testing.assert_allclose(path.get_xdata(), xyz[:, 0])
    np.testing.assert_allclose(path.get_ydata(), xyz[:, 2])
    np.testing.assert_allclose(top.get_lines()[0].get_ydata(), xyz[:, 1])
    labels = [line.get_label() for line in side.get_lines()]
    assert {"start", "end", "target", "floor"} <= set(labels)
    impacts = len(short_collapse.events_of("impact"))
    assert f"impact ({impacts})" in labels
    miss = 1000 * np.linalg.norm(xyz[-1] - np.array(target))
    assert f"{miss:.1f} mm from the target" in fig.get_suptitle()
    no_target = plot_tool_path(short_collapse, frame="camera_optical")
    assert "target" not in [line.get_label() for line in panel(no_target, "z [m]").get_lines()]
    with pytest.raises(packbot.ConfigurationError, match="target"):
        plot_tool_path(short_collapse, target=(1.0, 2.0))
    with pytest.raises(packbot.UnknownNameError, match="gripper_tool"):
        plot_tool_path(short_collapse, frame="tool")


def test_sample_and_plot_occlusion(short_collapse, world, tmp_path):
    targets = [(2.0, 0.0, 0.0), (0.0, 0.0, -0.5)]
    blocked = sample_occlusion(short_collapse, world, targets)
    assert [len(b) for b in blocked] == [len(short_collapse.t)] * 2
    assert None not in blocked[1]  # a point under the floor is never seen
    k = len(short_collapse.t) // 2
    assert blocked[0][k] == world.line_of_sight(short_collapse.q[k], np.array(targets[0]))
    fig = plot_occlusion(short_collapse, blocked, targets, path=tmp_path / "occ")
    assert_not_blank(tmp_path / "occ.png")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert f"blocked by {blocked[1][0]}" in labels
    with pytest.raises(packbot.ConfigurationError, match="blocked"):
        plot_occlusion(short_collapse, blocked[:1], targets)
