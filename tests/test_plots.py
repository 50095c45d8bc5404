"""Plots of a simulation result (the command line is tested in test_cli.py)."""

import numpy as np
import pytest
from matplotlib import _pylab_helpers
from matplotlib.figure import Figure
from matplotlib.image import imread

import packbot
from packbot.plots import (
    plot_distance,
    plot_energy,
    plot_joints,
    plot_occlusion,
    plot_torques,
    plot_tracking,
    sample_distances,
    sample_occlusion,
)

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def short_collapse(robot):
    """The report's collapse (its law: at rest with all its events within 1 s)."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)


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
    assert len(fig.axes) == 2
    assert_not_blank(tmp_path / "joints.png")
    svg = (tmp_path / "joints.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    assert _pylab_helpers.Gcf.get_num_fig_managers() == 0  # nothing left in pyplot


def test_plot_joints_marks_the_events_and_rest(short_collapse):
    fig = plot_joints(short_collapse)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["shoulder", "elbow1", "elbow2"]
    n_impacts = len(short_collapse.events_of("impact"))
    assert n_impacts >= 2
    assert f"impact ({n_impacts})" in legend
    assert any(t.startswith("at rest") for t in legend)


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
    assert len(fig.axes) == 3
    assert_not_blank(tmp_path / "torques.png")
    ax = fig.axes[0]
    limit = next(ln for ln in ax.get_lines() if ln.get_label() == "effort limit")
    assert limit.get_ydata()[0] == robot.params.effort[robot.params.index("shoulder")]
    applied = next(ln for ln in ax.get_lines() if ln.get_label() == "applied")
    np.testing.assert_array_equal(applied.get_ydata(), short_collapse.tau[:, 1])


def test_plot_tracking_draws_the_error(short_collapse, tmp_path):
    q_ref = np.repeat(short_collapse.q[:1], len(short_collapse.t), axis=0)  # hold the start
    fig = plot_tracking(short_collapse, q_ref, ("shoulder", "elbow1"), path=tmp_path / "tr")
    assert_not_blank(tmp_path / "tr.png")
    err = fig.axes[1].get_lines()[0].get_ydata()
    np.testing.assert_allclose(err, short_collapse.q[:, 1] - short_collapse.q[0, 1])
    with pytest.raises(packbot.ConfigurationError, match="q_ref"):
        plot_tracking(short_collapse, q_ref[:, :3])


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
