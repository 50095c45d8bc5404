"""Failure studies over a matrix (packbot.study_matrix, `packbot study MATRIX`).

The shipped example (sims/matrices/study-frozen-elbows.toml: 2 joints x 2 failure times, 2.5 s
runs) is studied once in this process; its summary is checked against the cells' study.json, its
heat map is read back pixel by pixel, a resume skips the finished cells and redoes a corrupted
one, and the report is screenshot in headless Chromium. The batch's hooks for runners other
than the simulation (files in the run's folder, metrics, no final state) are tested with a
cheap runner.
"""

from __future__ import annotations

import csv
import functools
import json
import pickle
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib import colormaps
from matplotlib.image import imread

from packbot.batch import RERUN_CORRUPT_FILE, RERUN_EDITED, read_records, run_batch
from packbot.cli import main
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.matrix import Run, parse_matrix
from packbot.study_matrix import (
    SUMMARY_FORMAT,
    StudyMatrix,
    StudyOptions,
    load_study_matrix,
    run_study_matrix,
    study_cell,
)
from packbot.viz.html import screenshot_command
from packbot.viz.study_matrix_report import _DPI, HEAT_MAP, PANELS, _norms, heat_map_figure

EXAMPLE = "study-frozen-elbows"


# --------------------------------------------------------------------------- the example
#: The runs the example's study simulated, by name (the fixture counts them).
SIMULATED: dict[str, int] = {}


@pytest.fixture(scope="module")
def studied(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any]:
    import importlib

    study_module = importlib.import_module("packbot.study")  # the package's `study` is the function
    study_matrix_module = importlib.import_module("packbot.study_matrix")

    out = tmp_path_factory.mktemp("study-matrix") / "out"
    real_run = study_module._run

    def counted(setup: Any, name: str, task: Any) -> Any:
        SIMULATED[name] = SIMULATED.get(name, 0) + 1
        return real_run(setup, name, task)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(study_module, "_run", counted)
        mp.setattr(study_matrix_module, "_HEALTHY_RUNS", {})
        report = run_study_matrix(EXAMPLE, out, workers=0)
    return out, report


def _without_wall_times(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _without_wall_times(v) for k, v in value.items() if "wall" not in k}
    if isinstance(value, list):
        return [_without_wall_times(v) for v in value]
    return value


def test_the_cells_share_one_healthy_run(studied: tuple[Path, Any]) -> None:
    """The four cells vary only the failure: one healthy run is simulated, not four, and the
    last cell's study (its healthy run given) is the study that simulates its own, to the last
    digit."""
    from packbot.scenario import scenario_robot
    from packbot.study import study

    out, report = studied
    assert SIMULATED["healthy"] == 1 and SIMULATED["failed"] == 4, SIMULATED
    run = report.study_matrix.runs()[-1]
    scenario = run.build_scenario()
    opts = report.study_matrix.options
    alone = study(
        scenario,
        robot=scenario_robot(scenario),
        tolerance=opts.tolerance,
        workspace_samples=opts.workspace_samples,
        seed=opts.seed,
    )
    data = json.loads((out / run.id / "study.json").read_text())
    data.pop("figures")  # the files write_study adds
    assert _without_wall_times(data) == _without_wall_times(json.loads(json.dumps(alone.summary())))


def test_a_healthy_run_of_another_start_or_length_is_refused(studied: tuple[Path, Any]) -> None:
    import dataclasses

    from packbot.scenario import scenario_robot
    from packbot.study import StudyRun, study

    _, report = studied
    run = report.study_matrix.runs()[0]
    scenario = run.build_scenario()
    robot = scenario_robot(scenario)
    from packbot.study_matrix import _HEALTHY_RUNS, _healthy_key

    assert _healthy_key(run, None) not in _HEALTHY_RUNS  # the fixture's memo was its own
    with pytest.raises(ConfigurationError, match="before the failure") as exc:
        study(scenario, robot=robot, duration=0.5)  # the failure is at 0.5 s
    assert exc.value.field == "duration"
    shorter = dataclasses.replace(scenario, duration=0.6)
    healthy = study(shorter, robot=robot, workspace_samples=100).healthy
    assert healthy.result is not None
    elsewhere = dataclasses.replace(healthy.result, q=healthy.result.q + 0.1)
    for bad, why in (
        (healthy, "study's 2.5 s"),
        (dataclasses.replace(healthy, result=elsewhere), "initial state"),
        (StudyRun(name="failed", status="ok"), "named 'healthy'"),
    ):
        with pytest.raises(ConfigurationError, match=why) as exc:
            study(scenario, robot=robot, workspace_samples=100, healthy=bad)
        assert exc.value.field == "healthy"


def test_example_is_a_study_matrix() -> None:
    sm = load_study_matrix(EXAMPLE)
    assert sm.failure_index == 0
    assert sm.options == StudyOptions(tolerance=0.01, workspace_samples=800)
    cells = sm.runs()
    assert [(c.params["failures.0.joint"], c.params["failures.0.t"]) for c in cells] == [
        ("elbow1", 0.5),
        ("elbow1", 1.5),
        ("elbow2", 0.5),
        ("elbow2", 1.5),
    ]
    assert all(c.scenario["failures"][0]["kind"] == "frozen" for c in cells)


def test_cells_and_files(studied: tuple[Path, Any]) -> None:
    out, report = studied
    assert report.batch.failed == [] and report.batch.missing == []
    assert sorted(report.batch.executed) == sorted(r.id for r in report.study_matrix.runs())
    for run in report.study_matrix.runs():
        folder = out / run.id
        for name in ("study.json", "report.html", "study_task_error.png", "study_joints.svg"):
            assert (folder / name).stat().st_size > 1000, (run.id, name)
        rec = report.batch.records[run.id]
        assert rec.files["report.html"] == f"{run.id}/report.html"
        assert rec.worker == "main" and rec.final_q == ()
    for name in ("study-matrix.json", "report.html", f"{HEAT_MAP}.png", f"{HEAT_MAP}.svg"):
        assert (out / name).stat().st_size > 1000, name
    assert not (out / "trajectories").exists()  # a study writes into its cells' folders


def test_summary_agrees_with_the_cells_study_json(studied: tuple[Path, Any]) -> None:
    out, report = studied
    summary = json.loads((out / "study-matrix.json").read_text())
    assert summary["format"] == SUMMARY_FORMAT
    assert summary["figures"] == [f"{HEAT_MAP}.png", f"{HEAT_MAP}.svg"]
    assert summary["failure"] == "failures.0" and summary["durations_s"] == [2.5]
    assert len(summary["cells"]) == 4
    for cell in summary["cells"]:
        data = json.loads((out / cell["study_json"]).read_text())
        failure = data["failures"][0]
        assert (cell["joint"], cell["kind"], cell["failure_time_s"]) == (
            failure["joint"],
            failure["kind"],
            failure["t_s"],
        )
        assert cell["report"] == f"{cell['id']}/report.html"
        assert cell["recovery_possible"] == data["recovery"]["possible"]
        assert cell["recovery_reasons"] == data["recovery"]["reasons"]
        for name in ("healthy", "failed", "reconfigured"):
            for key in ("status", "final_task_error_m", "rms_task_error_m", "recovered"):
                assert cell["runs"][name][key] == data["runs"][name][key], (cell["id"], key)
        assert cell["recovered"] == data["runs"]["reconfigured"]["recovered"]
        assert cell["detect_time_s"] == data["runs"]["reconfigured"]["detect_time_s"]
        # the record's metrics (and summary.csv) say the same
        rec = report.batch.records[cell["id"]]
        assert (
            rec.metrics["reconfigured_final_task_error_m"]
            == (data["runs"]["reconfigured"]["final_task_error_m"])
        )
        assert rec.metrics["recovery_possible"] == data["recovery"]["possible"]
    hm = summary["heat_map"]
    assert hm["joints"] == ["elbow1", "elbow2"] and hm["failure_times_s"] == [0.5, 1.5]
    by_bin = {(c["joint"], c["failure_time_s"]): c for c in summary["cells"]}
    for r, joint in enumerate(hm["joints"]):
        for k, t in enumerate(hm["failure_times_s"]):
            cell = by_bin[(joint, t)]
            assert hm["cells"][r][k] == [cell["id"]] and hm["studied"][r][k] == 1
            assert hm["recovery_rate"][r][k] == float(cell["recovered"])
            for name in ("reconfigured", "failed"):
                assert (
                    hm[f"{name}_final_task_error_m"][r][k]
                    == (cell["runs"][name]["final_task_error_m"])
                )
    # early (0.5 s) the task leaves the reduced arm's workspace; late (1.5 s) it is recovered
    assert hm["recovery_rate"] == [[0.0, 1.0], [0.0, 1.0]]
    for cell in summary["cells"]:
        early = cell["failure_time_s"] == 0.5
        assert cell["recovery_possible"] is (not early)
        if early:
            assert any("workspace" in r for r in cell["recovery_reasons"])
        reconf = cell["runs"]["reconfigured"]["final_task_error_m"]
        assert reconf <= cell["runs"]["failed"]["final_task_error_m"]
    assert summary["counts"] == {
        "cells": 4,
        "ok": 4,
        "failed": 0,
        "missing": 0,
        "studied": 4,
        "recovery_possible": 2,
        "recovered": 2,
    }
    with (out / "summary.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["metrics.reconfigured_recovered"] for r in rows] == ["False", "True"] * 2
    assert "q.elbow1" not in rows[0] and "rest_time" not in rows[0]


def _pixel(fig: Any, ax: Any, x: float, y: float, height: int) -> tuple[int, int]:
    px, py = ax.transData.transform((x, y)) * (_DPI / fig.dpi)  # saved at _DPI
    return round(float(height - py)), round(float(px))


def test_heat_map_png_shows_the_bins(studied: tuple[Path, Any]) -> None:
    out, _ = studied
    summary = json.loads((out / "study-matrix.json").read_text())
    img = np.asarray(imread(out / f"{HEAT_MAP}.png"))[..., :3]
    fig = heat_map_figure(summary)  # the same drawing: where its squares are
    fig.savefig(out / "layout.png", dpi=_DPI)
    assert np.asarray(imread(out / "layout.png")).shape[:2] == img.shape[:2]
    (out / "layout.png").unlink()
    axes = fig.axes[:3]
    hm = summary["heat_map"]
    rate_norm, err_norm = _norms(summary)
    h = img.shape[0]
    for ax, (key, _) in zip(axes, PANELS, strict=True):
        cmap = colormaps["RdYlGn" if key == "recovery_rate" else "viridis_r"]
        for r in range(2):
            for k in range(2):
                v = hm[key][r][k]
                want = cmap(rate_norm(v) if key == "recovery_rate" else err_norm(1000 * v))[:3]
                # a point of the square away from its annotation
                i, j = _pixel(fig, ax, k - 0.3, r - 0.3, h)
                assert np.abs(img[i, j] - np.asarray(want)).max() < 0.03, (key, r, k)
    # the recovery panel: red where not recovered (early), green where recovered (late)
    i, j = _pixel(fig, axes[0], 0 - 0.3, 0 - 0.3, h)
    assert img[i, j][0] > 0.5 and img[i, j][1] < 0.2
    i, j = _pixel(fig, axes[0], 1 - 0.3, 0 - 0.3, h)
    assert img[i, j][1] > 0.3 and img[i, j][0] < 0.1
    svg = (out / f"{HEAT_MAP}.svg").read_text()
    for cell in summary["cells"]:
        assert f'xlink:href="{cell["report"]}"' in svg


def test_resume_skips_finished_cells_and_redoes_a_corrupted_one(
    studied: tuple[Path, Any], tmp_path: Path
) -> None:
    out, first = studied
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    again = run_study_matrix(EXAMPLE, copy, workers=0)
    assert again.batch.executed == [] and sorted(again.batch.skipped) == sorted(first.batch.records)
    assert again.summary["cells"] == json.loads((out / "study-matrix.json").read_text())["cells"]
    # a cell's report changed on disk: its checksum no longer matches, that cell alone is redone
    victim = first.study_matrix.runs()[1].id
    (copy / victim / "report.html").write_text("<html>edited</html>")
    third = run_study_matrix(EXAMPLE, copy, workers=0)
    assert third.batch.executed == [victim]
    assert third.batch.rerun == {victim: RERUN_CORRUPT_FILE}
    assert (copy / victim / "report.html").stat().st_size > 1000
    new = json.loads((copy / victim / "study.json").read_text())
    old = json.loads((out / victim / "study.json").read_text())
    for name in ("failed", "reconfigured"):  # deterministic: the same study again
        assert new["runs"][name]["final_task_error_m"] == old["runs"][name]["final_task_error_m"]


# --------------------------------------------------------------------------- real browser
@pytest.fixture(scope="module")
def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("chromium is not installed: the real-browser test is skipped")


def test_browser_shows_the_heat_map_and_links(
    chromium: str, studied: tuple[Path, Any], tmp_path: Path
) -> None:
    out, report = studied
    page = out / "report.html"
    text = page.read_text()
    assert "<script" not in text and "http://" not in text and "<link" not in text
    for run in report.study_matrix.runs():
        assert f'href="{run.id}/report.html"' in text
    png = tmp_path / "matrix.png"
    cmd = screenshot_command(chromium, page.as_uri(), png, tmp_path / "profile")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0 and png.exists(), proc.stderr[-2000:]
    img = np.asarray(imread(png))[..., :3]
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = (r > 0.55) & (g < 0.1) & (b < 0.25)  # RdYlGn at 0: not recovered
    green = (r < 0.1) & (g > 0.3) & (g < 0.5) & (b < 0.3)  # RdYlGn at 1: recovered
    for mask in (red, green):
        assert mask.sum() > 0.005 * mask.size
    # both in the upper half: the heat map is the first thing the page shows
    top = img.shape[0] // 2
    assert red[:top].sum() > 0.9 * red.sum() and green[:top].sum() > 0.5 * green.sum()


# --------------------------------------------------------------------------- matrix files
_BASE = """
name = "m"
base = "frozen_elbow_reach"
[set]
duration = 0.6
"failures.0.t" = 0.3
[axes]
"failures.0.joint" = ["elbow1"]
"""


def _matrix(text: str, tmp_path: Path) -> Path:
    path = tmp_path / "m.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("extra", "error", "field"),
    [
        ("[study]\ncolour = 1\n", UnknownNameError, None),
        ("[study]\ntolerance = -0.01\n", ConfigurationError, "study.tolerance"),
        ('[study]\ntolerance = "1 cm"\n', ConfigurationError, "study.tolerance"),
        ("[study]\nworkspace_samples = 10\n", ConfigurationError, "study.workspace_samples"),
        ('[study]\nhtml = "yes"\n', ConfigurationError, "study.html"),
        ("[study]\nseed = -1\n", ConfigurationError, "study.seed"),
        ("", ConfigurationError, "study"),
    ],
)
def test_bad_study_tables_name_the_field(
    tmp_path: Path, extra: str, error: type[Exception], field: str | None
) -> None:
    with pytest.raises(error) as exc:
        load_study_matrix(_matrix(_BASE + extra, tmp_path))
    if field is not None:
        assert isinstance(exc.value, ConfigurationError) and exc.value.field == field
    else:
        assert "colour" in str(exc.value) and "tolerance" in str(exc.value)


@pytest.mark.parametrize(
    ("axes", "error", "field"),
    [
        ('"config.restitution" = [0.0, 0.5]', ConfigurationError, "axes"),
        ('"failures.0.t" = [0.2]\n"failures.1.t" = [0.3]', ConfigurationError, "axes"),
        ('"failures.0.colour" = ["red"]', UnknownNameError, None),
        ('"failures.x.t" = [0.2]', ConfigurationError, "axes.failures.x.t"),
    ],
)
def test_axes_must_vary_one_failure(
    tmp_path: Path, axes: str, error: type[Exception], field: str | None
) -> None:
    text = f'name = "m"\nbase = "frozen_elbow_reach"\n[axes]\n{axes}\n[study]\n'
    with pytest.raises(error) as exc:
        load_study_matrix(_matrix(text, tmp_path))
    if field is not None:
        assert isinstance(exc.value, ConfigurationError) and exc.value.field == field
    else:
        assert "colour" in str(exc.value) and "joint" in str(exc.value)


def test_a_bad_cell_is_refused_before_anything_runs(tmp_path: Path) -> None:
    text = _BASE.replace('["elbow1"]', '["elbow1", "elbow9"]') + "[study]\n"
    out = tmp_path / "out"
    with pytest.raises(ConfigurationError) as exc:
        run_study_matrix(_matrix(text, tmp_path), out, workers=0)
    assert "elbow9" in str(exc.value) and exc.value.field.startswith("run ")
    assert not out.exists()
    # a base without failures, no [set] creating one: the varied failure is missing
    text = 'name = "m"\nbase = "collapse"\n[axes]\n"failures.0.kind" = ["loose"]\n[study]\n'
    with pytest.raises(ConfigurationError) as exc:
        run_study_matrix(_matrix(text, tmp_path), out, workers=0)
    assert "failures" in exc.value.field
    assert not out.exists()
    # a cell whose runs end (0.6 s) before its failure (1 s)
    text = _BASE.replace('"failures.0.t" = 0.3', '"failures.0.t" = 1.0') + "[study]\n"
    with pytest.raises(ConfigurationError, match="before the failure") as exc:
        run_study_matrix(_matrix(text, tmp_path), out, workers=0)
    assert exc.value.field.startswith("run ") and exc.value.field.endswith("duration")
    assert not out.exists()


def test_timeout_fails_the_cell_on_a_local_worker(tmp_path: Path) -> None:
    path = _matrix(_BASE + "[study]\nhtml = false\n", tmp_path)
    out = tmp_path / "out"
    report = run_study_matrix(path, out, workers=1, timeout=0.05)
    (rid,) = report.batch.failed
    rec = report.batch.records[rid]
    assert rec.error.startswith("CellTimeout: wall-time limit of 0.05 s exceeded (")
    assert rec.worker.startswith("local:")
    summary = json.loads((out / "study-matrix.json").read_text())
    assert summary["counts"]["failed"] == 1 and summary["counts"]["studied"] == 0
    assert summary["heat_map"]["studied"] == [[0]]
    assert summary["heat_map"]["recovery_rate"] == [[None]]
    assert "CellTimeout" in (out / "report.html").read_text()
    # the runner is picklable (local pool, Dask)
    sm = load_study_matrix(path)
    runner = functools.partial(study_cell, options=sm.options)
    assert pickle.loads(pickle.dumps(runner)).keywords == {"options": sm.options}


# --------------------------------------------------------------------------- CLI
def test_cli(studied: tuple[Path, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, _ = studied
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    argv = ["study", EXAMPLE, "--out", str(copy), "--workers", "0", "--no-progress"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "4 finished before" in text and "recovery possible in 2" in text
    assert str(copy / "report.html") in text
    # a failed cell: exit 1
    path = _matrix(_BASE + "[study]\nhtml = false\n", tmp_path)
    argv = ["study", str(path), "--out", str(tmp_path / "t"), "--workers", "0", "--no-progress"]
    assert main([*argv, "--timeout", "0.05"]) == 1
    capsys.readouterr()
    # usage errors: one line, exit 2
    for argv in (
        ["study", EXAMPLE, "--out", str(tmp_path / "a"), "--tolerance", "0.02"],
        ["study", EXAMPLE, "--out", str(tmp_path / "a"), "--duration", "1"],
        ["study", "reconfig_elbow1", "--out", str(tmp_path / "b"), "--workers", "2"],
        ["study", "reconfig_elbow1", "--out", str(tmp_path / "b"), "--dask", "tcp://h:1"],
        ["study", "collapse-small", "--out", str(tmp_path / "c")],
        ["batch", EXAMPLE, "--out", str(tmp_path / "d")],
        ["study", EXAMPLE, "--out", str(tmp_path / "e"), "--workers", "-1"],
        ["study", EXAMPLE, "--out", str(copy / "report.html")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, (argv, err)
    assert not any((tmp_path / n).exists() for n in "abcde")


# --------------------------------------------------------------------------- batch hooks
def _cheap(run: Run, progress: Any) -> tuple[dict[str, Any], dict[str, tuple[str, bytes]]]:
    """A runner without a simulation: a file in the run's folder, metrics, no final state."""
    progress(0.0)
    x = run.params["x"]
    files = {"note": (f"{run.id}/note.txt", f"x = {x}\n".encode())}
    return {"metrics": {"double": 2 * x, "label": f"x{x}", "none": None}}, files


def test_batch_hooks_for_other_runners(tmp_path: Path) -> None:
    matrix = parse_matrix('name = "h"\nbase = "collapse"\n[axes]\nx = [1, 2]\n')
    out = tmp_path / "out"
    report = run_batch(matrix, out, workers=0, runner=_cheap)
    assert report.failed == []
    for run in report.runs:
        rec = report.records[run.id]
        assert rec.files == {"note": f"{run.id}/note.txt"}
        assert (out / run.id / "note.txt").read_text() == f"x = {run.params['x']}\n"
        assert rec.metrics == {
            "double": 2 * run.params["x"],
            "label": f"x{run.params['x']}",
            "none": None,
        }
    assert read_records(out)[report.runs[0].id].metrics["double"] == 2
    with (out / "summary.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["metrics.double"] for r in rows] == ["2", "4"]
    assert "n_impacts" not in rows[0]
    # resumed: verified and skipped; a record pointing outside its folders is redone
    again = run_batch(matrix, out, workers=0, runner=_cheap)
    assert again.executed == []
    rid = report.runs[0].id
    path = out / "runs" / f"{rid}.json"
    data = json.loads(path.read_text())
    data["files"]["note"] = f"{report.runs[1].id}/note.txt"
    data.pop("record_sha256")
    from packbot.batch import _sha256_json

    data["record_sha256"] = _sha256_json(data)
    path.write_text(json.dumps(data))
    third = run_batch(matrix, out, workers=0, runner=_cheap)
    assert third.rerun == {rid: RERUN_EDITED}

    # a file name outside the run's folder is refused
    def bad(run: Run, progress: Any) -> tuple[dict[str, Any], dict[str, tuple[str, bytes]]]:
        return {"metrics": {}}, {"x": ("../x.txt", b"")}

    with pytest.raises(ConfigurationError) as exc:
        run_batch(matrix, tmp_path / "bad", workers=0, runner=bad)
    assert exc.value.field == "files.x"


def test_a_study_matrix_is_not_run_as_simulations(tmp_path: Path) -> None:
    sm = load_study_matrix(EXAMPLE)
    with pytest.raises(ConfigurationError) as exc:
        run_batch(sm.matrix, tmp_path / "out", workers=0)
    assert exc.value.field == "matrix" and "study" in str(exc.value)
    assert not (tmp_path / "out").exists()
    # and the [study] table is part of the matrix's identity (not of a plain matrix's)
    assert "study" in sm.matrix.canonical()
    assert (
        "study" not in parse_matrix('name = "p"\nbase = "collapse"\n[axes]\nx = [1]\n').canonical()
    )
    assert isinstance(StudyMatrix.from_matrix(sm.matrix), StudyMatrix)


# --------------------------------------------------------------------------- aggregation
def _fake_study(joint: str, t: float, kind: str, recovered: bool, errors: tuple[float, float]):
    runs = {
        "healthy": {"status": "ok", "reason": "", "final_task_error_m": 0.0},
        "failed": {"status": "ok", "reason": "", "final_task_error_m": errors[0]},
        "reconfigured": {"status": "ok", "reason": "", "final_task_error_m": errors[1]},
    }
    for entry in runs.values():
        entry |= {"rms_task_error_m": entry["final_task_error_m"], "recovered": recovered}
    runs["reconfigured"] |= {"detect_time_s": t + 0.02, "recover_time_s": t if recovered else None}
    return {
        "duration_s": 2.0,
        "failures": [{"joint": joint, "kind": kind, "t_s": t}],
        "recovery": {"possible": recovered, "reasons": [] if recovered else ["out of reach"]},
        "runs": runs,
    }


def test_bins_aggregate_the_other_axes(tmp_path: Path) -> None:
    from packbot.batch import BatchReport, RunRecord
    from packbot.study_matrix import study_matrix_summary
    from packbot.viz.study_matrix_report import write_matrix_report

    text = (
        'name = "agg"\nbase = "frozen_elbow_reach"\n[axes]\n'
        '"failures.0.joint" = ["elbow1", "shoulder"]\n"failures.0.kind" = ["frozen", "loose"]\n'
        '"failures.0.t" = [0.5]\n[study]\n'
    )
    sm = StudyMatrix.from_matrix(parse_matrix(text))
    runs = sm.runs()
    assert len(runs) == 4
    outcome = {  # (joint, kind) -> recovered, (failed, reconfigured) final errors [m]
        ("elbow1", "frozen"): (True, (0.05, 0.002)),
        ("elbow1", "loose"): (False, (0.30, 0.100)),
        ("shoulder", "frozen"): (True, (0.02, 0.004)),
    }  # shoulder loose: the cell failed
    records = {}
    for run in runs:
        f = sm.failure_of(run)
        key = (f["joint"], f["kind"])
        if key not in outcome:
            records[run.id] = RunRecord(
                id=run.id, index=run.index, params=run.params, digest=run.digest,
                status="failed", error="CellTimeout: wall-time limit of 1 s exceeded",
            )  # fmt: skip
            continue
        (tmp_path / run.id).mkdir()
        data = _fake_study(f["joint"], f["t"], f["kind"], *outcome[key])
        (tmp_path / run.id / "study.json").write_text(json.dumps(data))
        records[run.id] = RunRecord(
            id=run.id, index=run.index, params=run.params, digest=run.digest, status="ok",
            files={"study.json": f"{run.id}/study.json"},
        )  # fmt: skip
    batch = BatchReport(out_dir=tmp_path, runs=runs, records=records)
    summary = study_matrix_summary(sm, tmp_path, runs, batch)
    hm = summary["heat_map"]
    assert hm["joints"] == ["elbow1", "shoulder"] and hm["failure_times_s"] == [0.5]
    assert hm["studied"] == [[2], [1]] and hm["recovered"] == [[1], [1]]
    assert hm["recovery_rate"] == [[0.5], [1.0]]
    assert hm["recovery_possible"] == [[1], [1]]
    assert hm["reconfigured_final_task_error_m"] == [[pytest.approx(0.051)], [0.004]]
    assert hm["failed_final_task_error_m"] == [[pytest.approx(0.175)], [0.02]]
    assert len(hm["cells"][1][0]) == 2  # the failed cell is in its bin, not studied
    c = summary["counts"]
    assert (c["cells"], c["studied"], c["failed"], c["recovered"]) == (4, 3, 1, 2)
    files = write_matrix_report(summary, tmp_path)
    page = files["report.html"].read_text()
    # no report.html in these cells: the links go to their study.json, labelled by the kind
    for run in runs:
        if run.id in records and records[run.id].status == "ok":
            assert f'href="{run.id}/study.json">kind {sm.failure_of(run)["kind"]}</a>' in page
    assert "CellTimeout: wall-time limit of 1 s exceeded" in page
    assert "other parameters" in page and "1 cell failed" in page
    svg = files[f"{HEAT_MAP}.svg"].read_text()
    assert 'xlink:href="report.html#bin-0-0"' in svg and 'id="bin-0-0"' in page
