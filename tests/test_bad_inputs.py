"""A catalogue of bad inputs (tests/bad_input_cases.py): each gives a clean error.

Every case of the catalogue is one test: a Python API call, a scenario file, a command line, a
matrix file or a broken URDF. An API case must raise the expected ``PackbotError`` subclass,
whose message names the field (or element); a command line must exit with code 2 and print
exactly one line on stderr, without a traceback. No case may be silently accepted. The cases
that used to hang run in a worker process with a timeout per case (a guard, not a timed
assertion; tests/bad_input_worker.py), a signals case in a process of its own.
"""

import json
import subprocess
import sys

import pytest
from bad_input_cases import (
    BASE_MATRIX,
    BASE_SCENARIO,
    BY_KEY,
    CASES,
    HERE,
    Case,
    counts,
    run_case,
)
from bad_input_worker import Worker

from packbot import SimConfig
from packbot.cli import main

GUARD_TIMEOUT = 300  # [s]: a guard against a hang, far above the time a refused case takes


def _params(guard: bool) -> list:
    # a signals case checks a process's exit code and files, not numbers (marked nonnumeric)
    return [
        pytest.param(
            c.key, id=c.key, marks=[pytest.mark.nonnumeric] if c.category == "signals" else []
        )
        for c in CASES
        if c.guard == guard
    ]


@pytest.mark.parametrize("key", _params(guard=False))
def test_bad_input_gets_a_clean_error(key, tmp_path):
    case = BY_KEY[key]
    outcome = run_case(case, tmp_path)
    assert outcome.status == "clean", f"{outcome.status}: {outcome.detail}"


@pytest.fixture(scope="module")
def guard_worker():
    """One worker process for the guard cases of this module: a hang kills it, not the run."""
    workers: list[Worker] = []

    def ask(key: str) -> dict[str, str]:
        if not workers or not workers[-1].usable:
            workers.append(Worker())  # the first case also imports packbot (~2 s)
        answer = workers[-1].ask(key, GUARD_TIMEOUT)
        if answer["status"] == "hang":
            workers[-1].close()  # stuck in the case: the next one gets a new worker
        return answer

    yield ask
    for w in workers:
        w.close()


@pytest.mark.parametrize("key", _params(guard=True))
def test_bad_input_that_used_to_hang_gets_a_clean_error(key, guard_worker):
    # In a worker process with a timeout, so that a regression shows as a failed case instead
    # of a stuck test run. A signals case sends signals to commands it starts and waits for
    # them: it gets a process of its own.
    if BY_KEY[key].category != "signals":
        answer = guard_worker(key)
    else:
        try:
            proc = subprocess.run(
                [sys.executable, str(HERE / "bad_input_cases.py"), "--case", key],
                capture_output=True,
                text=True,
                timeout=GUARD_TIMEOUT,
                check=False,
            )
        except subprocess.TimeoutExpired:
            pytest.fail(f"{key} did not finish within {GUARD_TIMEOUT} s (a hang)")
        assert proc.returncode == 0, proc.stderr[-2000:]
        answer = json.loads(proc.stdout.strip().splitlines()[-1])
    assert answer["status"] != "hang", f"{key} did not finish within {GUARD_TIMEOUT} s (a hang)"
    assert answer["key"] == key
    assert answer["status"] == "clean", f"{answer['status']}: {answer['detail']}"


def test_catalogue_size_and_spread():
    n = counts()
    assert sum(n.values()) >= 300
    assert n["api"] >= 120 and n["scenario"] >= 80 and n["cli"] >= 60
    assert n["matrix"] >= 30 and n["urdf"] >= 30
    assert len({c.key for c in CASES}) == len(CASES)


def test_the_harness_reports_what_is_not_clean(tmp_path):
    # A valid input is "accepted", another exception a "traceback", an error that does not name
    # the field "unclear".
    accepted = run_case(Case("api", "valid", lambda c: SimConfig()), tmp_path)
    assert accepted.status == "accepted"
    crash = run_case(Case("api", "crash", lambda c: [][1]), tmp_path)
    assert crash.status == "traceback" and "IndexError" in crash.detail
    vague = run_case(Case("api", "vague", lambda c: SimConfig(mu=-1), ("restitution",)), tmp_path)
    assert vague.status == "unclear"
    ok_cli = run_case(Case("cli", "list", lambda c: ["list"], cli=True), tmp_path)
    assert ok_cli.status == "accepted"
    other_code = Case("cli", "code", lambda c: ["run", "colapse"], cli=True, code=1)
    assert run_case(other_code, tmp_path).status == "unclear"  # exit 2, not the 1 asked for
    # hostile but legal input: its check says whether the outcome is right
    right = Case("content", "ok", lambda c: "&lt;b&gt;", check=lambda v: None)
    assert run_case(right, tmp_path).status == "clean"
    wrong = Case("content", "raw", lambda c: "<b>", check=lambda v: f"raw {v}")
    assert (run_case(wrong, tmp_path).status, run_case(wrong, tmp_path).detail) == (
        "accepted",
        "raw <b>",
    )
    refused = Case("content", "err", lambda c: SimConfig(mu=-1), ("mu",), check=lambda v: None)
    assert run_case(refused, tmp_path).status == "clean"  # an error: classified as before


INSIDE_A_BOX = (
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [4, 4, 4]\nxyz = [0, 0, 0.5]\n"
)


def test_a_rerun_with_bad_input_keeps_the_earlier_run(tmp_path, capsys):
    # The bad input (an initial state in collision, found only when the run starts) is refused
    # before the earlier run's files are deleted.
    scenario, out = tmp_path / "box.toml", tmp_path / "out"
    scenario.write_text(BASE_SCENARIO)
    assert main(["run", str(scenario), "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert "box.npz" in before
    capsys.readouterr()
    scenario.write_text(BASE_SCENARIO + INSIDE_A_BOX)
    assert main(["run", str(scenario), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "collision" in err and len(err.strip().splitlines()) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_matrix_with_a_bad_axis_value_runs_nothing(tmp_path, capsys):
    matrix, out = tmp_path / "m.toml", tmp_path / "batch"
    matrix.write_text(BASE_MATRIX + "[axes]\n'config.restitution' = [0.0, 0.5, 1.5]\n")
    assert main(["batch", str(matrix), "--out", str(out), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "config.restitution=1.5" in err and "restitution-1.5" in err  # the run and the field
    assert not out.exists()  # nothing written, not even the folder
