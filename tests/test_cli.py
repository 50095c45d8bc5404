"""The ``packbot`` command line: run, list, collapse; exit codes and messages."""

import csv
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

import packbot
from packbot.cli import MANIFEST_NAME, build_parser, main
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
    assert sorted(p.name for p in out.iterdir()) == [
        "collapse.npz",
        "collapse_events.csv",
        MANIFEST_NAME,
    ]


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


def test_collapse_alias_in_the_contact_normal_mode(tmp_path):
    out = tmp_path / "physical"
    assert main(["collapse", "--out", str(out), "--mode", "normal", "--duration", "0.2"]) == 0
    assert (out / "collapse_physical_joints.png").is_file()
    cfg = str(np.load(out / "collapse_physical.npz")["config_json"])
    assert '"contact_mode": "normal"' in cfg and '"mu": 0.5' in cfg


def test_collapse_bad_mode_names_the_choices(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["collapse", "--out", str(tmp_path), "--mode", "bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "bogus" in err and "joint_clamp" in err and "normal" in err and "none" in err


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


def test_run_of_a_controlled_scenario_plots_the_tool_path(tmp_path):
    """A computed-torque reach: the tool's path, and the target (its last waypoint's tool)."""
    out = tmp_path / "o"
    assert (
        main(["run", "frozen_elbow_reach", "--out", str(out), "--plot", "--duration", "0.3"]) == 0
    )
    png = out / "frozen_elbow_reach_tool_path.png"
    assert png.is_file() and png.stat().st_size > 1000
    img = imread(png)
    assert img.ndim == 3 and float(img[..., :3].std()) > 0.02


def test_version_prints_the_package_version(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"packbot {packbot.__version__}"
    done = subprocess.run(
        [sys.executable, "-m", "packbot.cli", "--version"],
        capture_output=True,
        text=True,
        cwd=tmp_path,  # outside the checkout, whose packbot/ has no compiled extension
    )
    assert (done.returncode, done.stdout.strip()) == (0, f"packbot {packbot.__version__}")


def test_generate_srdf_without_urdf_folder_names_the_option(tmp_path, capsys):
    assert main(["generate-srdf", "--root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--root" in err and "urdf/" in err
    assert not (tmp_path / "urdf").exists()


# ---------------------------------------------------------------- issue 15: clean errors, no loss
def run_cli(argv, capsys):
    """main(argv) -> (exit code, stderr); an argparse error counts as its exit code."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def assert_one_line(err):
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err


def test_out_under_a_file_is_exit_2_in_one_line(tmp_path, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    code, err = run_cli(["run", "collapse", "--out", str(f / "sub"), "--duration", "0.2"], capsys)
    assert code == 2
    assert_one_line(err)
    assert "afile is a file" in err and f.read_text() == "x"


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")
def test_out_that_cannot_be_created_is_exit_2(capsys):
    code, err = run_cli(
        ["run", "collapse", "--out", "/proc/packbot-x", "--duration", "0.2"], capsys
    )
    assert code == 2
    assert_one_line(err)
    assert "/proc/packbot-x" in err and "cannot create" in err


@pytest.mark.parametrize("command", ["batch", "regress"])
@pytest.mark.parametrize("address", ["bogus://x", "tcp://host", "tcp://host:99999", "x y:1"])
def test_bad_scheduler_address_says_what_a_valid_one_looks_like(tmp_path, capsys, command, address):
    argv = [command, "collapse-small", "--scheduler", address, "--out", str(tmp_path / "b")]
    code, err = run_cli(argv, capsys)
    assert code == 2
    assert_one_line(err)
    assert repr(address) in err and "tcp://127.0.0.1:8786" in err
    assert not (tmp_path / "b").exists()  # refused before anything ran


@pytest.mark.parametrize(
    "address", ["local", "tcp://127.0.0.1:8786", "tls://sched.example:8786", "10.0.0.2:8786"]
)
def test_good_scheduler_addresses_are_accepted(address):
    args = build_parser().parse_args(["batch", "m", "--out", "o", "--scheduler", address])
    assert args.scheduler == address


def test_info_malformed_urdf_is_exit_2_naming_the_file(tmp_path, capsys):
    bad = tmp_path / "bad.urdf"
    bad.write_text('<robot name="x"><link name="a">')  # truncated
    code, err = run_cli(["info", "--urdf", str(bad)], capsys)
    assert code == 2
    assert_one_line(err)
    assert "bad.urdf" in err


def test_info_a_parser_error_from_the_loader_is_exit_2(tmp_path, capsys, monkeypatch):
    import packbot.model

    def broken(path=None, **_options):
        raise ValueError("Pinocchio could not parse it")

    monkeypatch.setattr(packbot.model, "load_robot", broken)
    code, err = run_cli(["info", "--urdf", str(tmp_path / "x.urdf")], capsys)
    assert code == 2
    assert_one_line(err)
    assert "x.urdf" in err and "Pinocchio could not parse it" in err


@pytest.mark.parametrize("port", ["99999", "0", "-1", "65536", "http"])
def test_show_port_out_of_range_is_exit_2(capsys, port):
    code, err = run_cli(["show", "--port", port], capsys)
    assert code == 2
    assert_one_line(err)
    assert "1..65535" in err


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _accepts(port):
    with socket.create_connection(("127.0.0.1", port), timeout=5):
        return True


def test_viewer_listens_on_the_port_it_reports(robot):
    from packbot.viz import start_viewer

    port = _free_port()
    with start_viewer(robot, port=port) as viewer:
        assert viewer.port == port and viewer.url == f"http://127.0.0.1:{port}/static/"
        assert _accepts(port)
    with start_viewer(robot) as viewer:  # the first free port from 7000
        assert viewer.url == f"http://127.0.0.1:{viewer.port}/static/"
        assert _accepts(viewer.port)


@pytest.mark.parametrize("port", [99999, 0, -5, True, 80.0, "7000"])
def test_viewer_refuses_a_bad_port(robot, port):
    from packbot.viz import start_viewer

    with pytest.raises(packbot.ConfigurationError, match="port"):
        start_viewer(robot, port=port)


# Bad input to every subcommand: exit 2, one line on stderr, no traceback, nothing written.
BAD_INPUTS = [
    ["run", "no_such_scenario"],
    ["run", "{tmp}/missing.toml"],
    ["run", "{tmp}/dir/"],
    ["run", "{tmp}/afile"],
    ["run", "{tmp}/empty.toml"],
    ["run", "collapse", "--duration", "abc"],
    ["run", "collapse", "--duration", "-1"],
    ["run", "collapse", "--duration", "0"],
    ["run", "collapse", "--duration", "inf"],
    ["run", "collapse", "--out", "{tmp}/afile"],
    ["run", "collapse", "--out", "{tmp}/afile/sub/deeper"],
    ["run", "collapse", "--bogus"],
    ["run"],
    ["collapse", "--out", "{tmp}/afile"],
    ["collapse", "--duration", "nan", "--out", "{tmp}/c"],
    ["collapse", "--mode", "elastic"],
    ["info", "--urdf", "{tmp}/missing.urdf"],
    ["info", "--urdf", "{tmp}/dir"],
    ["info", "--urdf", "{tmp}/afile"],
    ["info", "--urdf", "{tmp}/empty.toml"],
    ["generate-model", "--root", "{tmp}/afile", "--check"],
    ["generate-model", "--root", "{tmp}/missing"],
    ["generate-srdf", "--root", "{tmp}/dir", "--samples", "-5"],
    ["generate-srdf", "--root", "{tmp}/dir", "--samples", "0"],
    ["generate-srdf", "--root", "{tmp}/dir", "--samples", "1.5"],
    ["generate-srdf", "--root", "{tmp}/dir", "--clearance", "nan"],
    ["generate-srdf", "--root", "{tmp}/dir", "--clearance", "-0.1"],
    ["generate-srdf", "--root", "{tmp}/afile"],
    ["show", "no_such_pose"],
    ["show", "--port", "99999"],
    ["list", "extra"],
    ["batch", "no_such_matrix", "--out", "{tmp}/b"],
    ["batch", "{tmp}/afile", "--out", "{tmp}/b"],
    ["batch", "collapse-small"],
    ["batch", "collapse-small", "--out", "{tmp}/afile"],
    ["batch", "collapse-small", "--out", "{tmp}/b", "--workers", "-1"],
    ["batch", "collapse-small", "--out", "{tmp}/b", "--workers", "two"],
    ["batch", "collapse-small", "--out", "{tmp}/b", "--timeout", "-3"],
    ["batch", "collapse-small", "--out", "{tmp}/b", "--scheduler", "bogus://x"],
    ["regress", "no_such_matrix"],
    ["regress", "collapse-small", "--golden", "{tmp}/dir"],
    ["regress", "collapse-small", "--workers", "-2"],
    ["regress", "collapse-small", "--scheduler", "bogus://x"],
    ["no-such-command"],
    ["--bogus"],
]


@pytest.mark.parametrize("argv", BAD_INPUTS, ids=lambda a: " ".join(a) or "none")
def test_bad_input_is_exit_2_in_one_line(tmp_path, capsys, argv):
    (tmp_path / "afile").write_text("not toml, not xml, not a folder")
    (tmp_path / "empty.toml").write_text("")
    (tmp_path / "dir").mkdir()
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code, err = run_cli([a.format(tmp=tmp_path) for a in argv], capsys)
    assert code == 2, err
    assert_one_line(err)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written


def test_ctrl_c_during_run_saves_the_partial_result_and_exits_130(tmp_path):
    out = tmp_path / "o"
    manifest = out / MANIFEST_NAME
    # loose_shoulder runs at a few times real time: 300 s cannot finish before the signal
    cmd = [sys.executable, "-m", "packbot.cli", "run", "loose_shoulder", "--duration", "300"]
    # (cwd: not the checkout, whose source tree `python -m` would import, without the extensions)
    proc = subprocess.Popen(
        [*cmd, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        # the manifest is written once the Ctrl-C handler is in place, just before simulating
        deadline = time.monotonic() + 120
        while not manifest.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert manifest.exists(), proc.stderr.read() if proc.poll() is not None else "no start"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert_one_line(err)
    assert "interrupted at t = " in err and "loose_shoulder_partial.npz" in err
    data = np.load(out / "loose_shoulder_partial.npz")
    assert 0.0 <= data["t"][-1] < 300.0 and data["q"].shape == (len(data["t"]), 8)
    assert np.all(np.diff(data["t"]) >= 0)
    assert str(data["scenario_name"]) == "loose_shoulder"
    assert sorted(p.name for p in out.iterdir()) == [
        "loose_shoulder_partial.npz",
        "loose_shoulder_partial_events.csv",
        MANIFEST_NAME,
    ]
    m = json.loads(manifest.read_text())
    assert m["status"] == "interrupted" and m["scenario"] == "loose_shoulder"
    assert m["files"] == ["loose_shoulder_partial.npz", "loose_shoulder_partial_events.csv"]


def test_ctrl_c_inside_simulate_in_process_saves_the_partial_result(tmp_path, capsys, monkeypatch):
    """A Ctrl-C (SIGINT to this process) while the simulation runs: partial saved, exit 130."""
    import packbot.scenario

    real = packbot.scenario.run_scenario
    seen = []

    def progress_then_sigint(*args, progress, **kwargs):
        def p(t):
            seen.append(t)
            if len(seen) == 20:
                os.kill(os.getpid(), signal.SIGINT)  # handled by packbot run's handler
            progress(t)

        return real(*args, progress=p, **kwargs)

    monkeypatch.setattr(packbot.scenario, "run_scenario", progress_then_sigint)
    handler = signal.getsignal(signal.SIGINT)
    out = tmp_path / "o"
    code, err = run_cli(["run", "collapse", "--out", str(out), "--duration", "3"], capsys)
    assert code == 130
    assert_one_line(err)
    assert len(seen) == 20  # stopped at the step where the signal came
    data = np.load(out / "collapse_partial.npz")
    assert 0 < data["t"][-1] <= seen[-1] < 3.0
    assert not (out / "collapse.npz").exists()
    assert signal.getsignal(signal.SIGINT) is handler  # restored


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_rerun_into_the_same_out_leaves_only_the_new_run(tmp_path, capsys):
    out = tmp_path / "collapse"
    argv = ["run", "collapse", "--out", str(out), "--duration", "0.3"]
    assert main([*argv, "--plot"]) == 0
    assert "collapse_joints.svg" in _names(out)
    m = json.loads((out / MANIFEST_NAME).read_text())
    assert m["status"] == "ok" and m["scenario"] == "collapse"
    assert m["packbot_version"] == packbot.__version__
    assert set(m["files"]) == set(_names(out)) - {MANIFEST_NAME}
    assert main(argv) == 0  # no plots this time: the old ones are gone
    assert _names(out) == ["collapse.npz", "collapse_events.csv", MANIFEST_NAME]
    assert json.loads((out / MANIFEST_NAME).read_text())["files"] == _names(out)[:2]


def test_rerun_that_fails_leaves_no_old_trajectory_beside_the_partial_one(tmp_path, capsys):
    src = scenario_path("collapse").read_text()
    scenario = tmp_path / "c.toml"
    scenario.write_text(src)
    out = tmp_path / "o"
    assert main(["run", str(scenario), "--out", str(out), "--duration", "0.5", "--plot"]) == 0
    scenario.write_text(src.replace("[config]", "[config]\nmax_events = 2"))
    assert main(["run", str(scenario), "--out", str(out)]) == 1
    assert _names(out) == ["c_partial.npz", "c_partial_events.csv", MANIFEST_NAME]
    assert json.loads((out / MANIFEST_NAME).read_text())["status"] == "failed"
    scenario.write_text(src)  # and back: the partial files go
    assert main(["run", str(scenario), "--out", str(out), "--duration", "0.3"]) == 0
    assert _names(out) == ["c.npz", "c_events.csv", MANIFEST_NAME]


def test_out_with_foreign_files_is_refused_and_left_alone(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["run", "collapse", "--out", str(out), "--duration", "0.3"]
    assert main(argv) == 0
    (out / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    code, err = run_cli(argv, capsys)
    assert code == 2
    assert_one_line(err)
    assert "notes.txt" in err and "--overwrite" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing deleted


def test_out_without_manifest_is_refused_unless_overwrite(tmp_path, capsys):
    out = tmp_path / "o"
    (out / "sub").mkdir(parents=True)
    (out / "collapse_joints.png").write_text("an older tool's plot")
    argv = ["run", "collapse", "--out", str(out), "--duration", "0.3"]
    code, err = run_cli(argv, capsys)
    assert code == 2 and "--overwrite" in err
    assert_one_line(err)
    assert main([*argv, "--overwrite"]) == 0
    assert (out / "collapse_joints.png").read_text() == "an older tool's plot"  # kept
    assert (out / "sub").is_dir()
    assert json.loads((out / MANIFEST_NAME).read_text())["files"] == [
        "collapse.npz",
        "collapse_events.csv",
    ]


def test_overwrite_removes_the_earlier_runs_files_and_keeps_foreign_ones(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["collapse", "--out", str(out), "--duration", "0.3"]) == 0
    assert "collapse.html" in _names(out)
    (out / "notes.txt").write_text("mine")
    argv = ["run", "collapse", "--out", str(out), "--duration", "0.3", "--overwrite"]
    assert main(argv) == 0
    assert _names(out) == ["collapse.npz", "collapse_events.csv", "notes.txt", MANIFEST_NAME]


def test_empty_existing_out_is_fine(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    assert main(["run", "collapse", "--out", str(out), "--duration", "0.3"]) == 0
    assert _names(out) == ["collapse.npz", "collapse_events.csv", MANIFEST_NAME]


@pytest.mark.parametrize(
    "entry", ["../outside.txt", "{outside}", "sub/x.txt", "..", "", 7, None, "a\\b", "C:x"]
)
def test_manifest_entries_outside_the_folder_are_never_followed(tmp_path, capsys, entry):
    out = tmp_path / "o"
    out.mkdir()
    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    (out / "sub").mkdir()
    (out / "sub" / "x.txt").write_text("keep")
    if isinstance(entry, str):
        entry = entry.format(outside=outside)
    old = {"sha256": hashlib.sha256(b"old").hexdigest(), "size": 3}
    manifest = {"tool": "packbot", "format": 2, "files": [entry, "old.npz"]}
    manifest["checksums"] = {"old.npz": old, str(entry): old}
    (out / MANIFEST_NAME).write_text(json.dumps(manifest))
    (out / "old.npz").write_text("old")
    argv = ["run", "collapse", "--out", str(out), "--duration", "0.3", "--overwrite"]
    assert main(argv) == 0
    assert outside.read_text() == "keep" and (out / "sub" / "x.txt").read_text() == "keep"
    assert not (out / "old.npz").exists()  # the plain entry was the earlier run's (its SHA-256)


def test_an_older_manifest_without_checksums_deletes_nothing(tmp_path, capsys):
    # format 1 listed bare names: packbot cannot prove it wrote them, so they are foreign
    out = tmp_path / "o"
    out.mkdir()
    (out / MANIFEST_NAME).write_text(
        json.dumps({"tool": "packbot", "format": 1, "files": ["a.npz"]})
    )
    (out / "a.npz").write_text("whose?")
    code, err = run_cli(["run", "collapse", "--out", str(out), "--duration", "0.3"], capsys)
    assert code == 2 and "a.npz (listed without a checksum)" in err and "SHA-256" in err
    assert_one_line(err)
    assert main(["run", "collapse", "--out", str(out), "--duration", "0.3", "--overwrite"]) == 0
    assert (out / "a.npz").read_text() == "whose?"


def test_a_broken_manifest_counts_as_no_manifest(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / MANIFEST_NAME).write_text("{not json")
    (out / "collapse.npz").write_text("whose?")
    code, err = run_cli(["run", "collapse", "--out", str(out), "--duration", "0.3"], capsys)
    assert code == 2 and "collapse.npz" in err and "--overwrite" in err
    assert (out / "collapse.npz").read_text() == "whose?"


def test_help_explains_overwrite_and_exit_codes(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--overwrite" in text and MANIFEST_NAME in text and "are kept" in text
    assert "130" in text and "_partial.npz" in text
