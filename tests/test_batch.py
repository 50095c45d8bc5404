"""Scenario matrices, batch runs (in process, local pool, Dask), resume, kill, regression."""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import packbot.batch as batch_module
from packbot.batch import (
    LOCK_NAME,
    RERUN_CORRUPT_FILE,
    RERUN_EDITED,
    RERUN_FAILED,
    RERUN_MALFORMED,
    RERUN_MISSING_FILE,
    RERUN_OLD_FORMAT,
    RERUN_STALE,
    BatchLock,
    BatchLockedError,
    ProgressBar,
    RunRecord,
    execute,
    file_sha256,
    read_records,
    run_batch,
    scenario_runner,
)
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.matrix import (
    Matrix,
    Run,
    apply_overrides,
    expand,
    load_matrix,
    parse_matrix,
    run_id,
    set_dotted,
)
from packbot.regress import (
    Tolerances,
    compare,
    default_golden_dir,
    format_drifts,
    read_golden,
    read_trajectories,
    run_regression,
)

SMALL = "collapse-small"


# ---------------------------------------------------------------------------------- toy runners
# Module-level (picklable): the spawned workers import this module by name.
def toy_runner(run: Run, progress: Any) -> tuple[dict[str, Any], dict[str, tuple[str, bytes]]]:
    """A cheap deterministic run whose behaviour the scenario dict and marker files select."""
    x = float(run.scenario["x"])
    marker = Path(run.scenario["marker"])
    mode = run.scenario.get("mode", "ok")
    progress(0.0)
    if x == 2.0:
        if mode == "raise" and (marker / "fail").exists():
            raise ValueError("x = 2 is refused while the marker exists")
        if mode == "nan":
            x = math.nan
        if mode == "slow":
            while True:
                time.sleep(0.01)
                progress(0.5)
        if mode == "interrupt":
            raise KeyboardInterrupt
        if mode == "die" or (mode == "die_once" and not (marker / "died").exists()):
            (marker / "died").touch()
            os.kill(os.getpid(), signal.SIGKILL)
    quantities = {
        "joint_names": ("a", "b"),
        "final_q": (x, x * x),
        "rest_time": x / 3,
        "n_impacts": 1,
        "n_events": 1,
        "event_times": (x / 10,),
        "event_kinds": ("impact",),
        "min_distance": 1e-3 * x,
        "energy_change": -x,
        "t_end": 1.0,
    }
    return quantities, {"trajectory": (f"{run.id}.txt", repr(x).encode())}


def toy_runs(tmp_path: Path, mode: str = "ok", values: tuple[float, ...] = (1.0, 2.0, 3.0)):
    m = Matrix(name="toy", base="toy", axes={"x": list(values)})
    m.validate()
    return m, expand(m, {"x": 0.0, "mode": mode, "marker": str(tmp_path)})


# ---------------------------------------------------------------------------------- matrix
def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_matrix_expansion_ids_and_overrides(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "m.toml",
        """
        base = "collapse"
        [set]
        duration = 0.5
        [axes]
        config.restitution = [0.0, 0.5]
        "initial.pose" = ["drive", "stow", "high"]
        [[exclude]]
        "config.restitution" = 0.5
        "initial.pose" = "stow"
        [[include]]
        "failures.0" = {joint = "elbow1", kind = "frozen"}
        """,
    )
    m = load_matrix(path)
    assert m.name == "m" and list(m.axes) == ["config.restitution", "initial.pose"]
    runs = m.runs()
    assert len(runs) == 2 * 3 - 1 + 1
    params = [r.params for r in runs]
    assert {"config.restitution": 0.5, "initial.pose": "stow"} not in params
    assert runs[-1].scenario["failures"] == [{"joint": "elbow1", "kind": "frozen"}]
    assert all(r.scenario["duration"] == 0.5 for r in runs)
    assert runs[0].scenario["config"]["locked_joints"]  # the base's other fields are kept
    assert len({r.id for r in runs}) == len(runs)
    assert runs[0].id.startswith("restitution-0.0_pose-drive-")  # sorted names
    # Ids depend on the parameters only: reorder the axes, add a value: same ids.
    m2 = load_matrix(
        _write(
            tmp_path / "m2.toml",
            """
            base = "collapse"
            [set]
            duration = 2.0
            [axes]
            "initial.pose" = ["low", "high", "stow", "drive"]
            "config.restitution" = [0.5, 0.0]
            """,
        )
    )
    ids2 = {r.id: r for r in m2.runs()}
    for r in runs[:-1]:
        assert r.id in ids2
        assert ids2[r.id].digest != r.digest  # another duration: the results would be stale
    assert run_id({"a": 1}) != run_id({"a": 1.0})
    # Every resolved scenario loads.
    from packbot.scenario import scenario_from_dict

    for r in runs:
        s = scenario_from_dict(r.scenario, name=r.id)
        assert s.config.restitution == r.scenario["config"]["restitution"]


def test_set_dotted() -> None:
    data: dict[str, Any] = {"config": {"restitution": 0.0}, "failures": [{"joint": "shoulder"}]}
    out = apply_overrides(data, {"failures.0.kind": "loose", "failures.1.joint": "elbow1"})
    assert out["failures"] == [{"joint": "shoulder", "kind": "loose"}, {"joint": "elbow1"}]
    assert data["failures"] == [{"joint": "shoulder"}]  # a copy
    with pytest.raises(ConfigurationError, match=r"axes\.failures\.5\.kind"):
        apply_overrides(data, {"failures.5.kind": "loose"})
    with pytest.raises(ConfigurationError, match="config.restitution"):
        set_dotted(data, "config.restitution.x", 1.0)
    new: dict[str, Any] = {}
    set_dotted(new, "failures.0.kind", "frozen")
    assert new == {"failures": [{"kind": "frozen"}]}


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        ('base = "collapse"\nbogus = 1\n[axes]\nx = [1]', UnknownNameError, "matrix key 'bogus'"),
        ('base = "collapse"\n[axes]\nx = []', ConfigurationError, r"axes\.x"),
        ('base = "collapse"\n[axes]\n"a..b" = [1]', ConfigurationError, r"axes\.a\.\.b"),
        ('base = "collapse"\n[axes]\nx = [1, 1]', ConfigurationError, "distinct"),
        ('base = "collapse"', ConfigurationError, "axes"),
        ("[axes]\nx = [1]", ConfigurationError, "base"),
        ('base = "collapse"\n[axes]\nx = [1]\n[[exclude]]\ny = 1', UnknownNameError, "'y'"),
        ('base = "collapse"\n[axes]\nx = [1]\n[tolerances]\nq = -1', ConfigurationError, "q"),
        ("base = ", ConfigurationError, "TOML"),
        ('base = "collapse"\n[axes]\nx = [1979-05-27]', ConfigurationError, r"axes\.x.*date"),
        ('base = "collapse"\n[axes]\nx = [1.0, inf]', ConfigurationError, r"axes\.x.*inf"),
        ('base = "collapse"\n[set]\nx = nan\n[axes]\ny = [1]', ConfigurationError, r"set\.x"),
    ],
)
def test_matrix_errors(tmp_path: Path, text: str, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        load_matrix(_write(tmp_path / "bad.toml", text))


def test_unknown_matrix_lists_shipped() -> None:
    with pytest.raises(UnknownNameError, match=SMALL):
        load_matrix("no-such-matrix")


# ---------------------------------------------------------------------------------- failures
def test_failed_runs_are_recorded_and_the_batch_goes_on(tmp_path: Path) -> None:
    m, runs = toy_runs(tmp_path, "raise")
    (tmp_path / "fail").touch()
    out = tmp_path / "out"
    bar = io.StringIO()
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner, progress=ProgressBar(bar))
    status = {r.id: rep.records[r.id].status for r in runs}
    assert list(status.values()) == ["ok", "failed", "ok"]
    lines = bar.getvalue().splitlines()
    assert len(lines) == 4 and lines[0].startswith("[....")
    assert "2/3 runs (1 failed)" in lines[2] and lines[3].startswith("[" + "#" * 30 + "] 3/3")
    bad = rep.records[runs[1].id]
    assert bad.error == "ValueError: x = 2 is refused while the marker exists"
    assert "toy_runner" in bad.traceback
    assert not list((out / "trajectories").glob(f"{runs[1].id}*"))
    # The summary has one row per run; the failed one's message is in it.
    csv_rows = (out / "summary.csv").read_text().splitlines()
    assert len(csv_rows) == 4 and "refused" in csv_rows[2] and ",failed," in csv_rows[2]
    # Resume: the failed run only is redone; its fix shows.
    (tmp_path / "fail").unlink()
    before = {r.id: (out / "runs" / f"{r.id}.json").read_bytes() for r in runs}
    rep2 = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep2.executed == [runs[1].id]
    assert rep2.skipped == [runs[0].id, runs[2].id]
    assert rep2.failed == []
    for r in (runs[0], runs[2]):  # untouched
        assert (out / "runs" / f"{r.id}.json").read_bytes() == before[r.id]
    # A stale record (another scenario, same id) is redone.
    m3, runs3 = toy_runs(tmp_path, "ok")
    assert [r.id for r in runs3] == [r.id for r in runs]
    rep3 = run_batch(m3, out, runs=runs3, workers=0, runner=toy_runner)
    assert rep3.executed == [r.id for r in runs3]


def test_summary_csv_and_parquet_agree(tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    m, runs = toy_runs(tmp_path, "nan")
    rep = run_batch(m, tmp_path / "out", runs=runs, workers=0, runner=toy_runner)
    table = pq.read_table(tmp_path / "out" / "summary.parquet").to_pydict()
    assert table["id"] == [r.id for r in runs]
    assert table["status"] == ["ok", "failed", "ok"]
    assert table["q.b"] == [1.0, None, 9.0]
    assert table["x"] == [1.0, 2.0, 3.0]
    assert "diverged" in table["error"][1]
    csv = (tmp_path / "out" / "summary.csv").read_text().splitlines()
    head = csv[0].split(",")
    row = dict(zip(head, csv[3].split(","), strict=True))
    assert float(row["q.b"]) == rep.records[runs[2].id].final_q[1]
    assert float(row["min_distance"]) == table["min_distance"][2]


def test_diverged_and_timed_out_runs_fail(tmp_path: Path) -> None:
    _, runs = toy_runs(tmp_path, "nan")
    rec, files = execute(runs[1], toy_runner)
    assert rec.status == "failed" and "diverged" in rec.error and files == {}
    assert execute(runs[0], toy_runner)[0].status == "ok"
    _, runs = toy_runs(tmp_path, "slow")
    t0 = time.perf_counter()
    rec, _ = execute(runs[1], toy_runner, timeout=0.2)
    assert rec.status == "failed" and "wall-time limit of 0.2 s" in rec.error
    assert 0.2 <= time.perf_counter() - t0 < 5.0
    # The real simulator honours the limit at its next step.
    rec, _ = execute(load_matrix(SMALL).runs()[0], scenario_runner, timeout=1e-3)
    assert (
        rec.status == "failed" and "wall-time limit" in rec.error and "stopped at t =" in rec.error
    )
    # A bad override is a failed run naming the field, not a crash of the batch.
    run = load_matrix(SMALL).runs()[0]
    bad = dataclasses.replace(
        run, scenario=apply_overrides(run.scenario, {"config.restitution": 7})
    )
    rec, _ = execute(bad, scenario_runner)
    assert rec.status == "failed" and "restitution" in rec.error


def test_a_killed_worker_loses_nothing(tmp_path: Path) -> None:
    # The worker running x = 2 dies every time: the pool breaks, the runs in flight are made
    # again one at a time; x = 2 kills its worker again and is recorded as failed, the others
    # complete with the same results as in this process.
    m, runs = toy_runs(tmp_path, "die", values=(1.0, 2.0, 3.0, 4.0))
    rep = run_batch(m, tmp_path / "out", runs=runs, workers=2, runner=toy_runner)
    assert (tmp_path / "died").exists()
    status = [rep.records[r.id].status for r in runs]
    assert status == ["ok", "failed", "ok", "ok"]
    assert rep.records[runs[1].id].error.startswith("WorkerDied")
    for i in (0, 2, 3):
        assert rep.records[runs[i].id].quantities() == execute(runs[i], toy_runner)[0].quantities()


# ---------------------------------------------------------------------------------- real runs
@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory):
    """The small golden matrix, run in this process."""
    m = load_matrix(SMALL)
    out = tmp_path_factory.mktemp("reference")
    return run_batch(m, out, workers=0)


def _trajectory(out: Path, rec: RunRecord) -> dict[str, np.ndarray]:
    with np.load(out / rec.files["trajectory"]) as z:
        return {k: z[k] for k in ("t", "q", "v", "tau", "energy")}


def test_small_matrix_matches_golden(reference) -> None:
    """What CI checks: the small matrix's results against the committed golden results."""
    folder = default_golden_dir() / SMALL
    name, golden = read_golden(folder)
    assert name == SMALL
    assert [r.id for r in reference.runs] == list(golden)
    tol = Tolerances.from_mapping(load_matrix(SMALL).tolerances)
    trajectories = read_trajectories(reference.out_dir, reference.records)
    assert set(trajectories) == set(golden)  # the checkpoints are compared for every run
    assert all("checkpoints" in g and "sensitivity" in g for g in golden.values())
    drifts = compare(golden, reference.records, tol, trajectories)
    assert drifts == [], "\n" + format_drifts(drifts, len(golden))
    # The matrix exercises what it claims: impacts, a failure, runs not at rest.
    recs = list(reference.records.values())
    assert all(r.status == "ok" for r in recs)
    assert any(r.n_impacts > 0 for r in recs) and any(r.n_limits > 0 for r in recs)
    assert {r.rest_time is None for r in recs} == {True, False}
    assert all("failure" in r.event_kinds for r in recs)


def test_same_run_twice_in_one_process_is_bit_identical(reference) -> None:
    run = reference.runs[7]
    rec, files = execute(run)
    ref = reference.records[run.id]
    assert rec.quantities() == ref.quantities()
    assert rec.final_q == ref.final_q  # exact float equality
    name, _ = files["trajectory"]
    assert name == Path(ref.files["trajectory"]).name


def test_local_pool_matches_main_process(reference, tmp_path: Path) -> None:
    m = load_matrix(SMALL)
    rep = run_batch(m, tmp_path, runs=reference.runs, workers=2)
    assert {r.worker.split(":")[0] for r in rep.records.values()} == {"local"}
    assert len({r.worker for r in rep.records.values()}) == 2
    for run in reference.runs:
        a, b = reference.records[run.id], rep.records[run.id]
        assert a.worker == "main"
        assert a.quantities() == b.quantities(), run.id
        ta, tb = _trajectory(reference.out_dir, a), _trajectory(tmp_path, b)
        for key in ta:
            np.testing.assert_array_equal(ta[key], tb[key], err_msg=f"{run.id} {key}")
    assert (tmp_path / "summary.csv").read_text().count("\n") == len(reference.runs) + 1


def test_dask_worker_matches_main_process(reference, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    runs = reference.runs[::3]
    more = reference.runs[1::6]
    with (
        distributed.LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        rep = run_batch(load_matrix(SMALL), tmp_path, runs=runs, scheduler=client)
        # By address, as `packbot batch --scheduler tcp://...` does; the finished ones skipped.
        rep = run_batch(
            load_matrix(SMALL), tmp_path, runs=runs + more, scheduler=cluster.scheduler_address
        )
        assert rep.skipped == [r.id for r in runs]
        assert rep.executed == [r.id for r in more]
    for run in runs + more:
        a, b = reference.records[run.id], rep.records[run.id]
        assert b.worker.startswith("dask:tcp://127.0.0.1:")
        assert a.quantities() == b.quantities(), run.id
        np.testing.assert_array_equal(
            _trajectory(reference.out_dir, a)["q"], _trajectory(tmp_path, b)["q"]
        )


# ---------------------------------------------------------------------------------- kill midway
def _cli(*args: str) -> list[str]:
    """The CLI as a command (run it outside the checkout: ``python -m`` puts the working
    directory first on sys.path, and the checkout's source tree has no compiled extensions:
    its runs would take the Python paths, equal to the native ones only to rounding)."""
    return [sys.executable, "-m", "packbot.cli", *args]


def _default_sigint() -> None:
    """In a child before it starts: SIGINT's default disposition (Python's KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL])
def test_kill_midway_then_rerun_completes_identically(reference, tmp_path: Path, sig) -> None:
    out = tmp_path / "out"
    total = len(reference.runs)
    cmd = _cli("batch", SMALL, "--out", str(out), "--workers", "1")
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        cwd=tmp_path,
        # Ctrl-C's default action in the batch even when this test runs with SIGINT ignored
        # (a shell's background job, as CI may be): an ignored SIGINT is inherited, and Python
        # then raises no KeyboardInterrupt
        preexec_fn=_default_sigint,
    )
    try:
        deadline = time.monotonic() + 60
        while not list((out / "runs").glob("*.json")) and time.monotonic() < deadline:
            time.sleep(0.02)
        # Frozen where it is first (SIGSTOP acts at once, in the kernel): a batch whose runs
        # take a few milliseconds cannot finish between the first record and the signal.
        # Then Ctrl-C reaches the whole process group; kill -9 of the group kills the workers
        # too.
        os.killpg(proc.pid, signal.SIGSTOP)
        os.killpg(proc.pid, sig)
        os.killpg(proc.pid, signal.SIGCONT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    if sig == signal.SIGINT:
        assert proc.returncode == 130, err.decode()
        assert b"interrupted" in err
        assert (out / "summary.csv").is_file()
    else:
        assert proc.returncode == -signal.SIGKILL
    done = read_records(out, reference.runs)
    assert 0 < len(done) < total, "the batch was not killed midway"
    # No half-written file survives as a record; temporary files are cleared by the rerun.
    res = subprocess.run([*cmd, "--no-progress"], capture_output=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr.decode()
    assert f"({total - len(done)} run now, {len(done)} finished before)" in res.stdout.decode()
    assert not list(out.rglob(".*.tmp"))
    again = read_records(out, reference.runs)
    assert set(again) == {r.id for r in reference.runs}
    for run in reference.runs:
        assert again[run.id].quantities() == reference.records[run.id].quantities(), run.id


# ---------------------------------------------------------------------------------- regression
def test_regression_detects_drift_and_update_rewrites(tmp_path: Path) -> None:
    m, runs = toy_runs(tmp_path)
    m.tolerances = {"q": 1e-3}
    golden = tmp_path / "golden"
    r = run_regression(m, golden, update=True, runs=runs, workers=0, runner=toy_runner)
    assert not r.had_golden and [p.name for p in r.written] == ["results.json", "summary.csv"]
    # Again: no drift.
    r = run_regression(m, golden, runs=runs, workers=0, runner=toy_runner)
    assert r.had_golden and r.drifts == [] and "no drift" in r.text()
    # Edit the golden file: q within its tolerance, an event time and a count beyond theirs.
    path = golden / "toy" / "results.json"
    data = json.loads(path.read_text())
    g = data["runs"][runs[1].id]
    g["final_q"][0] += 5e-4
    g["final_q"][1] += 2e-3
    g["event_times"][0] += 1e-5
    data["runs"][runs[2].id]["n_impacts"] = 2
    data["runs"][runs[2].id]["event_kinds"] = ["impact", "limit"]
    data["runs"][runs[2].id]["event_times"] = [0.1, 0.2]
    del data["runs"][runs[0].id]
    path.write_text(json.dumps(data))
    r = run_regression(m, golden, runs=runs, workers=0, runner=toy_runner)
    got = {(d.run, d.quantity) for d in r.drifts}
    assert got == {
        (runs[0].id, "run"),
        (runs[1].id, "q.b"),
        (runs[1].id, "event[0].t (impact)"),
        (runs[2].id, "events.limit"),
    }
    table = r.text()
    assert "q.b" in table and "0.001" in table and "4 quantities moved in 3 runs" in table
    r = run_regression(m, golden, update=True, runs=runs, workers=0, runner=toy_runner)
    assert len(r.drifts) == 4 and r.written
    assert run_regression(m, golden, runs=runs, workers=0, runner=toy_runner).drifts == []


def test_regress_cli_exit_codes(tmp_path: Path) -> None:
    golden = tmp_path / "golden"
    shutil.copytree(default_golden_dir() / SMALL, golden / SMALL)
    out = tmp_path / "out"  # kept: the second call resumes it (nothing to run again)
    cmd = _cli("regress", SMALL, "--golden", str(golden), "--workers", "0", "--out", str(out))
    # (cwd: not the checkout, whose source tree `python -m` would import without the extensions:
    # its runs would take the Python paths, which the golden bands do not cover)
    res = subprocess.run(cmd, capture_output=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stdout.decode() + res.stderr.decode()
    assert b"no drift" in res.stdout
    path = golden / SMALL / "results.json"
    data = json.loads(path.read_text())
    rid = next(iter(data["runs"]))
    data["runs"][rid]["rest_time"] = 0.25
    path.write_text(json.dumps(data))
    res = subprocess.run(cmd, capture_output=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 1
    out = res.stdout.decode()
    assert "rest_time" in out and rid in out and "1 quantities moved in 1 runs" in out
    res = subprocess.run(
        _cli("regress", "--golden", str(tmp_path / "none")), capture_output=True, cwd=tmp_path
    )
    assert res.returncode == 2 and b"no golden results" in res.stderr


# ---------------------------------------------------------------------------------- integrity
def _record_path(out: Path, run: Run) -> Path:
    return out / "runs" / f"{run.id}.json"


def _ok_batch(tmp_path: Path):
    """A finished toy batch: (matrix, runs, out, report)."""
    m, runs = toy_runs(tmp_path)
    out = tmp_path / "out"
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert [rep.records[r.id].status for r in runs] == ["ok", "ok", "ok"]
    return m, runs, out, rep


def test_records_carry_checksums_of_their_files_and_of_themselves(tmp_path: Path) -> None:
    _, runs, out, rep = _ok_batch(tmp_path)
    text = _record_path(out, runs[0]).read_text()
    assert text.startswith("{\n")  # readable, indented JSON
    data = json.loads(text)
    assert data["format"] == "packbot-batch-run/2"
    path = out / data["files"]["trajectory"]
    assert data["file_sha256"]["trajectory"] == file_sha256(path)
    assert len(data["record_sha256"]) == 64
    # The checksums are not part of the deterministic quantities (the golden results).
    rec = rep.records[runs[0].id]
    assert "file_sha256" not in rec.quantities() and "record_sha256" not in rec.quantities()
    assert rec.file_sha256 == data["file_sha256"]


def test_resume_reruns_a_corrupted_or_missing_trajectory(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    m, runs, out, rep = _ok_batch(tmp_path)
    bad = out / rep.records[runs[1].id].files["trajectory"]
    good_bytes = bad.read_bytes()
    bad.write_bytes(good_bytes[:-1] + b"7")  # same size, one byte changed
    gone = out / rep.records[runs[2].id].files["trajectory"]
    gone.unlink()
    untouched = _record_path(out, runs[0]).read_bytes()
    with caplog.at_level("WARNING", logger="packbot.batch"):
        rep2 = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep2.rerun == {runs[1].id: RERUN_CORRUPT_FILE, runs[2].id: RERUN_MISSING_FILE}
    assert rep2.executed == [runs[1].id, runs[2].id] and rep2.skipped == [runs[0].id]
    assert bad.read_bytes() == good_bytes and gone.is_file()
    assert _record_path(out, runs[0]).read_bytes() == untouched
    text = rep2.describe()
    assert f"rerun 2: 1 {RERUN_CORRUPT_FILE}, 1 {RERUN_MISSING_FILE}" in text
    logged = caplog.text
    assert runs[1].id in logged and "SHA-256" in logged and bad.name in logged
    assert runs[2].id in logged and RERUN_MISSING_FILE in logged
    # Now everything verifies: nothing to do.
    rep3 = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep3.executed == [] and rep3.rerun == {}


def test_resume_reruns_a_corrupted_npz_of_a_real_run(tmp_path: Path) -> None:
    m = load_matrix(SMALL)
    runs = m.runs()[:2]
    rep = run_batch(m, tmp_path, runs=runs, workers=0)
    npz = tmp_path / rep.records[runs[0].id].files["trajectory"]
    data = bytearray(npz.read_bytes())
    data[len(data) // 2] ^= 0x01  # one bit in the middle of the compressed trajectory
    npz.write_bytes(bytes(data))
    rep2 = run_batch(m, tmp_path, runs=runs, workers=0)
    assert rep2.rerun == {runs[0].id: RERUN_CORRUPT_FILE}
    assert rep2.executed == [runs[0].id]
    assert rep2.records[runs[0].id].quantities() == rep.records[runs[0].id].quantities()
    assert file_sha256(npz) == rep.records[runs[0].id].file_sha256["trajectory"]
    with np.load(npz) as z:
        assert z["q"].shape[0] > 1


def _set_final_q(data: dict[str, Any]) -> None:
    data["final_q"][0] = 123.0


def _set_failed(data: dict[str, Any]) -> None:
    data["status"] = "failed"


def _add_field(data: dict[str, Any]) -> None:
    data["note"] = "checked by hand"


def _drop_checksum(data: dict[str, Any]) -> None:
    del data["record_sha256"]


def _point_elsewhere(data: dict[str, Any]) -> None:
    data["files"]["trajectory"] = "../../elsewhere.txt"


def _wall_time(data: dict[str, Any]) -> None:
    data["wall_time"] = data["wall_time"] + 1.0


@pytest.mark.parametrize(
    "edit", [_set_final_q, _set_failed, _add_field, _drop_checksum, _point_elsewhere, _wall_time]
)
def test_resume_reruns_an_edited_record(tmp_path: Path, edit: Any) -> None:
    m, runs, out, _ = _ok_batch(tmp_path)
    path = _record_path(out, runs[1])
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=1))
    rep2 = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep2.rerun == {runs[1].id: RERUN_EDITED}
    assert rep2.executed == [runs[1].id]
    again = json.loads(path.read_text())
    assert again["final_q"] == [2.0, 4.0] and again["status"] == "ok" and "note" not in again
    assert again["files"]["trajectory"] == f"trajectories/{runs[1].id}.txt"
    assert not (tmp_path / "elsewhere.txt").exists()


def test_a_record_moved_to_another_run_is_rerun(tmp_path: Path) -> None:
    m, runs, out, _ = _ok_batch(tmp_path)
    shutil.copyfile(_record_path(out, runs[0]), _record_path(out, runs[1]))  # intact, wrong run
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep.rerun == {runs[1].id: RERUN_EDITED}
    assert rep.records[runs[1].id].final_q == (2.0, 4.0)


@pytest.mark.parametrize(
    "text", ["", '{"format": "packbot-batch-run/2", "id": ', "[1, 2]", "\udcff", "null"]
)
def test_resume_reruns_a_malformed_record(tmp_path: Path, text: str) -> None:
    m, runs, out, _ = _ok_batch(tmp_path)
    path = _record_path(out, runs[1])
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep.rerun == {runs[1].id: RERUN_MALFORMED}
    assert rep.executed == [runs[1].id]
    assert json.loads(path.read_text())["status"] == "ok"


def test_resume_reruns_old_records_without_checksums(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    m, runs, out, _ = _ok_batch(tmp_path)
    for run in runs:  # as packbot wrote them before the checksums
        path = _record_path(out, run)
        data = json.loads(path.read_text())
        data["format"] = "packbot-batch-run/1"
        del data["record_sha256"], data["file_sha256"]
        path.write_text(json.dumps(data, indent=1))
    assert set(read_records(out, runs)) == {r.id for r in runs}  # still readable
    with caplog.at_level("WARNING", logger="packbot.batch"):
        rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep.rerun == {r.id: RERUN_OLD_FORMAT for r in runs}
    assert rep.executed == [r.id for r in runs]
    assert f"3 runs made again: {RERUN_OLD_FORMAT}" in caplog.text
    assert f"rerun 3: 3 {RERUN_OLD_FORMAT}" in rep.describe()


def test_failed_and_stale_reruns_are_reported_and_leave_no_old_files(tmp_path: Path) -> None:
    m = Matrix(name="toy", base="toy", axes={"x": [1.0, 2.0, 3.0]})
    base = {"x": 0.0, "mode": "raise", "marker": str(tmp_path)}
    runs = expand(m, base)
    out = tmp_path / "out"
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    old = out / rep.records[runs[1].id].files["trajectory"]
    assert old.is_file()
    # The base scenario changes (every run stale) and x = 2 now fails: its earlier trajectory,
    # which belongs to no record any more, is removed.
    (tmp_path / "fail").touch()
    runs2 = expand(m, {**base, "y": 1})
    rep2 = run_batch(m, out, runs=runs2, workers=0, runner=toy_runner)
    assert rep2.rerun == {r.id: RERUN_STALE for r in runs2}
    assert rep2.records[runs2[1].id].status == "failed"
    assert not old.exists()
    assert sorted(p.name for p in (out / "trajectories").iterdir()) == sorted(
        f"{r.id}.txt" for r in (runs2[0], runs2[2])
    )
    (tmp_path / "fail").unlink()
    rep3 = run_batch(m, out, runs=runs2, workers=0, runner=toy_runner)
    assert rep3.rerun == {runs2[1].id: RERUN_FAILED} and rep3.failed == []
    assert "rerun 1: 1 failed before" in rep3.describe()


# ---------------------------------------------------------------------------------- lock
_HOLDER = """
import sys
from packbot import batch
batch.LOCK_WITH_FLOCK = sys.argv[2] == "flock"
lock = batch.BatchLock(sys.argv[1])
lock.acquire()
print("locked", flush=True)
sys.stdin.read()
lock.release()
"""


def _hold_lock(folder: Path, mode: str) -> subprocess.Popen[str]:
    """Another process that holds the folder's lock until its standard input is closed."""
    folder.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen(
        [sys.executable, "-c", _HOLDER, str(folder), mode],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        cwd=folder,  # outside the checkout, whose packbot/ has no compiled extension
    )
    assert proc.stdout is not None and proc.stdout.readline() == "locked\n"
    return proc


@pytest.fixture(params=["flock", "exclusive"])
def lock_mode(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both lock mechanisms: fcntl.flock (POSIX) and the exclusively created file."""
    monkeypatch.setattr(batch_module, "LOCK_WITH_FLOCK", request.param == "flock")
    return str(request.param)


def test_a_second_batch_on_a_locked_folder_fails_at_once(tmp_path: Path, lock_mode: str) -> None:
    m, runs = toy_runs(tmp_path)
    out = tmp_path / "out"
    holder = _hold_lock(out, lock_mode)
    try:
        with pytest.raises(BatchLockedError) as info:
            run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
        msg = str(info.value)
        assert str(out) in msg and f"pid {holder.pid}" in msg and socket.gethostname() in msg
        assert "another --out" in msg and "\n" not in msg
        assert info.value.holder["pid"] == holder.pid
        assert not (out / "runs").exists() and not (out / "matrix.json").exists()  # untouched
        # Another open of the lock in this very process is refused too (it names us).
        with pytest.raises(BatchLockedError, match=f"pid {holder.pid}"):
            BatchLock(out).acquire()
    finally:
        holder.communicate("")  # the holder releases the lock and exits
    assert holder.returncode == 0 and not (out / LOCK_NAME).exists()
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert len(rep.executed) == 3 and not (out / LOCK_NAME).exists()


def test_a_batch_in_this_process_holds_the_lock(tmp_path: Path, lock_mode: str) -> None:
    m, runs = toy_runs(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    with BatchLock(out) as lock:
        assert lock.held and (out / LOCK_NAME).is_file()
        with pytest.raises(BatchLockedError, match=f"pid {os.getpid()} on host"):
            run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert not lock.held and not (out / LOCK_NAME).exists()
    # Released however the batch ends, e.g. interrupted (Ctrl-C) in the middle.
    m, runs = toy_runs(tmp_path, "interrupt")
    with pytest.raises(KeyboardInterrupt):
        run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert not (out / LOCK_NAME).exists()
    assert len(read_records(out, runs)) == 1  # x = 1 was finished and kept


def test_a_stale_lock_is_taken_over_with_a_warning(
    tmp_path: Path, lock_mode: str, caplog: pytest.LogCaptureFixture
) -> None:
    m, runs = toy_runs(tmp_path)
    out = tmp_path / "out"
    holder = _hold_lock(out, lock_mode)
    holder.kill()  # kill -9: no clean-up, the lock file stays
    holder.communicate()
    assert (out / LOCK_NAME).is_file()
    assert json.loads((out / LOCK_NAME).read_text())["pid"] == holder.pid
    with caplog.at_level("WARNING", logger="packbot.batch"):
        rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert len(rep.executed) == 3
    assert "stale lock" in caplog.text and f"pid {holder.pid}" in caplog.text
    assert not (out / LOCK_NAME).exists()


def test_a_lock_left_by_another_host_is_refused(tmp_path: Path, lock_mode: str) -> None:
    m, runs = toy_runs(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    info = {"pid": 4242, "host": "not-" + socket.gethostname(), "started": "2026-01-01"}
    (out / LOCK_NAME).write_text(json.dumps(info))
    with pytest.raises(BatchLockedError, match="pid 4242 on host not-") as exc:
        run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    if lock_mode == "flock":
        assert "another machine" in str(exc.value) and f"remove {out / LOCK_NAME}" in str(exc.value)
    assert json.loads((out / LOCK_NAME).read_text()) == info  # left alone


def test_batch_cli_on_a_locked_folder_exits_2_with_one_line(tmp_path: Path) -> None:
    out = tmp_path / "out"
    holder = _hold_lock(out, "flock")
    try:
        res = subprocess.run(
            _cli("batch", SMALL, "--out", str(out), "--workers", "0", "--no-progress"),
            capture_output=True,
            text=True,
            timeout=120,
            cwd=tmp_path,
        )
    finally:
        holder.communicate("")
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr
    assert str(out) in lines[0] and f"pid {holder.pid}" in lines[0]
    assert socket.gethostname() in lines[0]
    assert not (out / "runs").exists()


# ---------------------------------------------------------------------------------- matrix
_TOY_MATRIX = """
name = "toy"
base = "toy"
[axes]
x = [1.0, 2.0, 3.0]
"""


def _toy_matrix(text: str) -> tuple[Matrix, list[Run]]:
    m = parse_matrix(text)
    return m, expand(m, {"x": 0.0, "mode": "ok", "marker": "/nonexistent"})


def test_a_different_matrix_in_a_batch_folder_is_refused(tmp_path: Path) -> None:
    m, runs = _toy_matrix(_TOY_MATRIX)
    out = tmp_path / "out"
    run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    stored = json.loads((out / "matrix.json").read_text())
    assert stored["sha256"] == m.content_digest() and stored["matrix"]["name"] == "toy"
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    others = [
        _TOY_MATRIX.replace("[1.0, 2.0, 3.0]", "[1.0, 2.0]"),  # fewer runs
        _TOY_MATRIX.replace("[1.0, 2.0, 3.0]", "[1.0, 2.0, 3.0, 4.0]"),  # more runs
        _TOY_MATRIX.replace('base = "toy"', 'base = "other"'),
        _TOY_MATRIX.replace('name = "toy"', 'name = "toy2"'),
        _TOY_MATRIX + "[set]\nduration = 2.0\n",
        _TOY_MATRIX + "y = [0, 1]\n",
    ]
    for text in others:
        m2, runs2 = _toy_matrix(text)
        with pytest.raises(ConfigurationError) as info:
            run_batch(m2, out, runs=runs2, workers=0, runner=toy_runner)
        msg = str(info.value)
        assert str(out) in msg and "another --out" in msg and "remove the folder" in msg, msg
        named = "matrix 'toy', not 'toy2'" if "toy2" in text else "another version of matrix 'toy'"
        assert named in msg, msg
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before  # untouched
    # The axes' order is the runs' order: another matrix too.
    m3 = Matrix(name="toy", base="toy", axes={"x": [1.0, 2.0, 3.0], "y": [0, 1]})
    m4 = Matrix(name="toy", base="toy", axes={"y": [0, 1], "x": [1.0, 2.0, 3.0]})
    assert m3.content_digest() != m4.content_digest()
    # A folder of an older packbot (matrix.toml, no matrix.json) is checked against its text.
    (out / "matrix.json").unlink()
    with pytest.raises(ConfigurationError, match=r"differ in: axes; stored in matrix\.toml"):
        run_batch(_toy_matrix(others[0])[0], out, runs=runs, workers=0, runner=toy_runner)
    rep = run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    assert rep.skipped == [r.id for r in runs] and (out / "matrix.json").is_file()


def test_the_same_matrix_written_differently_is_accepted(tmp_path: Path) -> None:
    m, runs = _toy_matrix(_TOY_MATRIX)
    out = tmp_path / "out"
    run_batch(m, out, runs=runs, workers=0, runner=toy_runner)
    same = """
    # The same runs: comments, layout, quoting, a description and tolerances do not count.
    base   =   'toy'       # the base
    name = "toy"
    description = "a toy matrix"

    [axes]
    "x" = [ 1.0,
            2.0,
            3.0 ]   # three values

    [tolerances]
    q = 1e-3
    """
    m2, runs2 = _toy_matrix(same)
    assert m2.content_digest() == m.content_digest()
    rep = run_batch(m2, out, runs=runs2, workers=0, runner=toy_runner)
    assert rep.skipped == [r.id for r in runs] and rep.executed == []
    assert (out / "matrix.toml").read_text() == same  # the newest text of the same matrix
    # A matrix built in Python (no file) is checked the same way.
    m3 = Matrix(name="toy", base="toy", axes={"x": [1.0, 2.0, 3.0]})
    assert run_batch(m3, out, runs=runs, workers=0, runner=toy_runner).executed == []
    m4 = Matrix(name="toy", base="toy", axes={"x": [1.0, 2.5]})
    with pytest.raises(ConfigurationError, match="another version of matrix 'toy'.*in: axes;"):
        run_batch(m4, out, runs=runs, workers=0, runner=toy_runner)


def test_a_submit_to_a_pool_a_worker_just_broke_puts_the_run_back(tmp_path: Path) -> None:
    # A worker that died between two waits breaks the pool before any future says so: the next
    # submit raises BrokenProcessPool. The run goes back to the front of its queue, not started
    # (it cannot have killed the worker), and the pool is replaced (CI saw the raise escape).
    from collections import deque
    from concurrent.futures.process import BrokenProcessPool

    class Broken:
        def submit(self, *args: Any, **kwargs: Any) -> Any:
            raise BrokenProcessPool("a child process terminated abruptly")

    _, runs = toy_runs(tmp_path)
    queue = deque(runs[1:])
    inflight: dict[Any, Any] = {}
    ok = batch_module._submit(Broken(), inflight, runs[0], queue, toy_runner, None)  # type: ignore[arg-type]
    assert not ok and not inflight
    assert list(queue) == runs
