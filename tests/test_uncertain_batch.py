"""Uncertain studies through the batch machinery: resumable, on a real Dask cluster.

A short study (reconfig_elbow1 cut to 1.3 s, three arms) in this process is the reference; the
same arms through :func:`packbot.uncertain_batch.run_uncertain_study` (this process, killed and
resumed; a Dask scheduler and two workers started as processes on 127.0.0.1) must give its
numbers. The tolerance (1e-9 relative, 1e-12 m) covers only the rounding of another BLAS thread
count in the worker processes; the code that studies an arm is the same everywhere.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from packbot.errors import ConfigurationError, PackbotError
from packbot.study import RUN_NAMES
from packbot.uncertain_batch import ARM_FILE, run_uncertain_study
from packbot.uncertain_study import UncertainStudy, uncertain_study

SCENARIO = "reconfig_elbow1"
ARMS = 3
SEED = 7
FAST = {"duration": 1.3, "workspace_samples": 300}
#: Relative and absolute [m] tolerance between two places running the same arm's code: the
#: rounding of a different BLAS thread count, nothing else.
RTOL, ATOL = 1e-9, 1e-12


@pytest.fixture(scope="module")
def local() -> UncertainStudy:
    return uncertain_study(SCENARIO, samples=ARMS, seed=SEED, **FAST)


def _same_numbers(a: UncertainStudy, b: UncertainStudy) -> None:
    assert a.counts == b.counts
    np.testing.assert_array_equal(a.sample.values, b.sample.values)
    for run in RUN_NAMES:
        for metric in ("final_task_error_m", "rms_task_error_m", "peak_torque_ratio"):
            np.testing.assert_allclose(
                a.values(run, metric), b.values(run, metric), rtol=RTOL, atol=ATOL
            )
        for p, band in a.task_error_band(run).items():
            np.testing.assert_allclose(band, b.task_error_band(run)[p], rtol=RTOL, atol=ATOL)
    assert a.recovery_successes == b.recovery_successes
    assert a.recovery_interval == pytest.approx(b.recovery_interval, rel=RTOL)


class _Stop(KeyboardInterrupt):
    """Ctrl-C after the first arm (a killed study)."""


def test_a_stopped_study_resumes_without_redoing_finished_arms(local, tmp_path: Path) -> None:
    out = tmp_path / "u"

    def stop_after_one(done: int, failed: int, total: int) -> None:
        if done >= 1:
            raise _Stop

    with pytest.raises(KeyboardInterrupt):
        run_uncertain_study(
            SCENARIO, out, samples=ARMS, seed=SEED, workers=0, progress=stop_after_one, **FAST
        )
    assert (out / "arm_0000" / ARM_FILE).is_file()
    assert not (out / "arm_0001").exists()
    first = run_uncertain_study(SCENARIO, out, samples=ARMS, seed=SEED, workers=0, **FAST)
    assert first.batch.skipped == ["arm_0000"]
    assert first.batch.executed == ["arm_0001", "arm_0002"]
    _same_numbers(local, first.result)
    # one arm's file lost: only that arm is studied again
    (out / "arm_0001" / ARM_FILE).unlink()
    again = run_uncertain_study(SCENARIO, out, samples=ARMS, seed=SEED, workers=0, **FAST)
    assert again.batch.executed == ["arm_0001"]
    assert sorted(again.batch.skipped) == ["arm_0000", "arm_0002"]
    assert "missing" in again.batch.rerun["arm_0001"]
    _same_numbers(local, again.result)
    data = json.loads((out / "uncertain.json").read_text())
    assert data["batch"]["executed"] == 1 and data["batch"]["skipped"] == 2
    for name in ("report.html", "uncertain_task_error.png", "uncertain_sensitivity.svg"):
        assert (out / name).is_file(), name
    # another draw into the same folder is refused, nothing run
    with pytest.raises(ConfigurationError, match="out_dir"):
        run_uncertain_study(SCENARIO, out, samples=ARMS, seed=SEED + 1, workers=0, **FAST)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _dask_command(kind: str) -> list[str]:
    """``dask scheduler`` / ``dask worker`` of this interpreter's environment."""
    exe = Path(sys.executable).with_name("dask")
    if exe.is_file():
        return [str(exe), kind]
    found = shutil.which("dask")
    if found is None:
        pytest.skip("the `dask` command is not installed")
    return [found, kind]


def test_on_a_dask_cluster_the_numbers_are_the_local_ones(local, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = os.environ | {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    procs = []
    logs = []
    try:
        log = open(tmp_path / "scheduler.log", "wb")  # noqa: SIM115 (closed below)
        logs.append(log)
        procs.append(
            subprocess.Popen(
                [
                    *_dask_command("scheduler"),
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--no-dashboard",
                ],
                cwd=tmp_path,
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        )
        for k in range(2):
            log = open(tmp_path / f"worker{k}.log", "wb")  # noqa: SIM115 (closed below)
            logs.append(log)
            procs.append(
                subprocess.Popen(
                    [
                        *_dask_command("worker"),
                        address,
                        "--host",
                        "127.0.0.1",
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                        "--name",
                        f"w{k}",
                    ],
                    cwd=tmp_path,
                    env=env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                )
            )
        deadline = time.monotonic() + 120.0
        while True:
            try:
                with distributed.Client(address, timeout=10) as client:
                    client.wait_for_workers(2, timeout=max(1.0, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
                    logs_text = "".join(
                        (tmp_path / n).read_text(errors="replace")[-2000:]
                        for n in ("scheduler.log", "worker0.log", "worker1.log")
                    )
                    pytest.fail(f"the Dask cluster did not start:\n{logs_text}")
                time.sleep(1.0)
        rep = run_uncertain_study(
            SCENARIO, tmp_path / "d", samples=ARMS, seed=SEED, scheduler=address, **FAST
        )
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for log in logs:
            log.close()
    workers = {r.worker for r in rep.batch.records.values()}
    assert all(w.startswith("dask:tcp://127.0.0.1:") for w in workers), workers
    # (in the order the workers finish them)
    assert sorted(rep.batch.executed) == [f"arm_{k:04d}" for k in range(ARMS)]
    assert rep.result.workers == f"dask {address}"
    _same_numbers(local, rep.result)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"workers": -1}, "workers"),
        ({"timeout": 0.0}, "timeout"),
        ({"scheduler": 3}, "scheduler"),
        ({"html": "yes"}, "html"),
        ({"samples": 1}, "samples"),
        ({"seed": -3}, "seed"),
        ({"method": "grid"}, "method"),
        ({"controller": lambda robot: None}, "controller"),
    ],
)
def test_bad_arguments_are_refused_before_anything_runs(
    tmp_path: Path, kwargs: dict, field: str
) -> None:
    with pytest.raises(PackbotError, match=field) as exc:
        run_uncertain_study(SCENARIO, tmp_path / "b", **({"samples": 2, "workers": 0} | kwargs))
    assert field in str(exc.value)
    assert not (tmp_path / "b" / "runs").exists() or not any((tmp_path / "b" / "runs").iterdir())


def test_a_scenario_object_is_refused_naming_the_way_that_takes_it(tmp_path: Path) -> None:
    from packbot.scenario import load_scenario

    with pytest.raises(ConfigurationError, match="scenario") as exc:
        run_uncertain_study(load_scenario(SCENARIO), tmp_path / "s", samples=2)  # type: ignore[arg-type]
    assert "packbot.uncertain_study" in str(exc.value)
