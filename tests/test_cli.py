"""The ``packbot`` command line: run, list, collapse; exit codes and messages."""

import csv

import numpy as np
import pytest
from matplotlib.image import imread

from packbot.cli import main
from packbot.scenario import list_scenarios, scenario_path


def assert_not_blank(path):
    assert path.is_file() and path.stat().st_size > 1000, path
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    assert float(img[..., :3].std()) > 0.02, f"{path} is (nearly) a single colour"


def test_run_collapse_writes_trajectory_events_and_plots(tmp_path, capsys):
    out = tmp_path / "collapse"
    assert main(["run", "collapse", "--out", str(out), "--plot", "--duration", "1"]) == 0
    for stem in ("joints", "distance", "energy"):
        assert_not_blank(out / f"collapse_{stem}.png")
        assert (out / f"collapse_{stem}.svg").is_file()
    data = np.load(out / "collapse.npz")
    assert {"t", "q", "v", "tau", "energy", "joint_names", "scenario_text"} <= set(data.files)
    assert data["q"].shape == (len(data["t"]), 8) == data["v"].shape
    assert data["t"][-1] == pytest.approx(1.0)
    assert list(data["joint_names"])[:4] == ["turret", "shoulder", "elbow1", "elbow2"]
    assert str(data["scenario_text"]) == scenario_path("collapse").read_text()
    with (out / "collapse_events.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows and rows[0]["kind"] == "impact"
    assert {"time_s", "relevant_joints", "energy_before_J", "energy_after_J"} <= set(rows[0])
    text = capsys.readouterr().out
    for word in ("rest time", "final angles", "events", "min distance", "real time"):
        assert word in text


def test_run_without_plot_writes_no_plot(tmp_path):
    out = tmp_path / "o"
    assert main(["run", "collapse", "--out", str(out), "--duration", "0.3"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["collapse.npz", "collapse_events.csv"]


def test_run_a_path_and_the_occlusion_table(tmp_path):
    src = scenario_path("camera_occlusion")
    mine = tmp_path / "occ.toml"
    mine.write_text(src.read_text())
    out = tmp_path / "o"
    assert main(["run", str(mine), "--out", str(out), "--duration", "0.3", "--plot"]) == 0
    assert (out / "occ_occlusion.csv").is_file()
    assert_not_blank(out / "occ_occlusion.png")


def test_collapse_alias_without_contact(tmp_path):
    out = tmp_path / "none"
    assert main(["collapse", "--out", str(out), "--mode", "none", "--duration", "0.5"]) == 0
    assert (out / "collapse_no_collisions_distance.png").is_file()
    cfg = str(np.load(out / "collapse_no_collisions.npz")["config_json"])
    assert '"contact_mode": "none"' in cfg


def test_collapse_bad_mode_names_the_choices(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["collapse", "--out", str(tmp_path), "--mode", "bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "bogus" in err and "joint_clamp" in err and "none" in err


@pytest.mark.parametrize("duration", ["0", "-1", "nan", "inf"])
def test_run_bad_duration(tmp_path, capsys, duration):
    assert main(["run", "collapse", "--out", str(tmp_path), "--duration", duration]) == 2
    assert "--duration" in capsys.readouterr().err


def test_run_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["run", "collapse", "--out", str(f), "--duration", "0.2"]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_run_unknown_scenario_lists_them(tmp_path, capsys):
    assert main(["run", "colapse", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "colapse" in err and "collapse_elastic" in err and "Traceback" not in err


def test_run_bad_file_names_the_field(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text("duration = 1.0\n[config]\nrestitution = 2.0\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "config.restitution" in err and "2.0" in err and "[0, 1]" in err
    assert "Traceback" not in err


def test_run_simulation_failure_exits_1_saying_what_and_when(tmp_path, capsys):
    p = tmp_path / "runaway.toml"
    p.write_text(
        scenario_path("collapse").read_text().replace("[config]", "[config]\nmax_events = 2")
    )
    out = tmp_path / "o"
    assert main(["run", str(p), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "runaway failed" in err and "t = " in err and "events" in err
    data = np.load(out / "runaway_partial.npz")
    assert 0 < data["t"][-1] < 1.0


def test_list_shows_scenarios_and_poses(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in list_scenarios():
        assert name in out
    for pose in ("drive", "stow", "stand", "high", "low"):
        assert pose in out
    assert "invalid" not in out


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "run" in capsys.readouterr().out


def test_generate_srdf_without_urdf_folder_names_the_option(tmp_path, capsys):
    assert main(["generate-srdf", "--root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--root" in err and "urdf/" in err
    assert not (tmp_path / "urdf").exists()
