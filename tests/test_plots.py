"""Plots of a simulation result and the ``packbot collapse`` command."""

import csv

import numpy as np
import pytest
from matplotlib import _pylab_helpers
from matplotlib.figure import Figure
from matplotlib.image import imread

import packbot
from packbot.cli import main
from packbot.plots import plot_distance, plot_energy, plot_joints, sample_distances

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def short_collapse(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST)
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


def test_cli_collapse_writes_its_files(tmp_path, capsys):
    out = tmp_path / "collapse"
    assert main(["collapse", "--out", str(out), "--duration", "1"]) == 0
    for stem in ("joints", "distance", "energy"):
        assert_not_blank(out / f"collapse_{stem}.png")
        assert (out / f"collapse_{stem}.svg").is_file()
    data = np.load(out / "collapse.npz")
    assert set(data.files) == {"t", "q", "v", "tau", "energy", "joint_names"}
    assert data["q"].shape == (len(data["t"]), 8) == data["v"].shape
    assert data["t"][-1] == pytest.approx(1.0)
    assert list(data["joint_names"])[:4] == ["turret", "shoulder", "elbow1", "elbow2"]
    with (out / "collapse_events.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows and rows[0]["kind"] == "impact"
    assert {"time_s", "relevant_joints", "energy_before_J", "energy_after_J"} <= set(rows[0])
    text = capsys.readouterr().out
    for word in ("rest time", "final angles", "events", "min distance", "real time"):
        assert word in text


def test_cli_collapse_without_contact(tmp_path):
    out = tmp_path / "none"
    assert main(["collapse", "--out", str(out), "--mode", "none", "--duration", "0.5"]) == 0
    assert (out / "collapse_distance.png").is_file()


def test_cli_collapse_bad_mode_names_the_choices(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["collapse", "--out", str(tmp_path), "--mode", "bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "bogus" in err and "joint_clamp" in err and "none" in err


@pytest.mark.parametrize("duration", ["0", "-1", "nan", "inf"])
def test_cli_collapse_bad_duration(tmp_path, capsys, duration):
    assert main(["collapse", "--out", str(tmp_path), "--duration", duration]) == 2
    assert "--duration" in capsys.readouterr().err


def test_cli_collapse_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["collapse", "--out", str(f), "--duration", "1"]) == 2
    assert "not a directory" in capsys.readouterr().err
