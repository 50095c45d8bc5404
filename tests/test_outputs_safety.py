"""What packbot writes is safe to open: pages, CSV cells, file names, deletions, signals, workers.

- every page (a run's HTML animation, a study's report, ok or refused, a study matrix's report)
  shows hostile names as text, never as markup: checked in a real headless Chromium (skipped only
  where chromium is not installed), after the page's scripts ran;
- CSV cells a spreadsheet would run as formulas get a leading ``'`` (numbers stay numbers);
- no stem, scenario name or run id writes outside its folder;
- ``packbot run`` deletes only files its manifest lists with the SHA-256 they still have;
- SIGTERM and SIGHUP stop ``packbot run`` / ``batch`` as Ctrl-C does (the partial run saved),
  exiting 128 + the signal;
- a batch's pool workers die with its main process (``kill -9``);
- a resume moves aside what cannot be read in place of a run's file, and reruns that run.

The subprocess tests wait with generous timeouts (guards, never timed assertions).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import packbot
from packbot import Environment, Obstacle
from packbot.batch import csv_text, run_batch
from packbot.cli import MANIFEST_NAME, main
from packbot.environment import FLOOR
from packbot.errors import ConfigurationError
from packbot.matrix import load_matrix
from packbot.result import Event
from packbot.scenario import Scenario, load_scenario, save_run
from packbot.study import study
from packbot.viz import write_html
from packbot.viz.html import screenshot_command
from packbot.viz.study_report import write_study

#: What it checks is what pages, files and processes show and do, not numbers.
pytestmark = pytest.mark.nonnumeric

# --------------------------------------------------------------------------- hostile names
#: Each one marks the page (``data-pwned`` on <body>, an element id ``pwned...``) if it runs.
HOSTILE = (
    "<img src=x onerror=\"document.body.setAttribute('data-pwned','img')\">",
    "</script><script>document.body.setAttribute('data-pwned','script')</script>",
    "\"' onmouseover=\"document.body.setAttribute('data-pwned','attr')\" x='",
    '<b id="pwned-b">bold</b> & <!-- <i>',
    "caf\u00e9 \u2192 \U0001f916 \u2028 &amp; <svg onload=alert(1)>",
)
GUARD = 180  # [s]: a browser, a subprocess: a guard against a hang, not a timing


def _hostile_env(far: bool = True) -> Environment:
    """The floor and one small box per hostile name, out of the arm's way."""
    boxes = tuple(
        Obstacle(name=n, kind="box", size=(0.05, 0.05, 0.05), xyz=(3.0 + k, 3.0, 0.1))
        for k, n in enumerate(HOSTILE)
    )
    return Environment(obstacles=(FLOOR, *boxes))


class _Dom(HTMLParser):
    """The elements and the visible text of a dumped DOM."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.elements: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []
        self._skip = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.elements.append((tag, dict(attrs)))
        if tag in ("script", "style"):
            self._skip += 1

    def handle_endtag(self, tag: str) -> None:
        if tag in ("script", "style") and self._skip:
            self._skip -= 1

    def handle_data(self, data: str) -> None:
        if not self._skip:
            self.text.append(data)


@pytest.fixture(scope="module")
def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("chromium is not installed (apt-get install chromium): the page tests are skipped")


def _dom(chromium: str, page: Path, tmp_path: Path) -> _Dom:
    """The page's DOM after its scripts ran (3 s of virtual time) in a headless Chromium."""
    cmd = [
        c
        for c in screenshot_command(chromium, page.as_uri(), tmp_path / "x.png", tmp_path / "p")
        if not c.startswith("--screenshot")
    ]
    cmd[-1:-1] = ["--dump-dom"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=GUARD, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    dom = _Dom()
    dom.feed(proc.stdout)
    return dom


def _assert_inert(dom: _Dom, scripts: int, shown: tuple[str, ...]) -> None:
    """Nothing hostile ran or became markup; the names are there as text."""
    body = [a for tag, a in dom.elements if tag == "body"]
    assert body and "data-pwned" not in body[0], body
    for tag, attrs in dom.elements:
        assert not str(attrs.get("id") or "").startswith("pwned"), (tag, attrs)
        assert not any(k.startswith("on") for k in attrs), (tag, attrs)  # no handler injected
        assert tag not in ("svg", "i") or not attrs, (tag, attrs)
    assert sum(tag == "script" for tag, _ in dom.elements) == scripts
    text = "".join(dom.text)
    for name in shown:
        assert name.replace("\u2028", " ") in text.replace("\u2028", " "), name


def test_html_animation_shows_hostile_names_as_text(
    chromium: str, robot: packbot.Robot, tmp_path: Path
) -> None:
    env = _hostile_env()
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.05, environment=env)
    events = [
        Event(t=0.01 * (k + 1), kind="impact", link1="link3", link2=n, piece1="tube", piece2=n)
        for k, n in enumerate(HOSTILE)
    ]
    res = dataclasses.replace(res, events=events)
    page = write_html(robot, res, tmp_path / "anim.html", environment=env)
    dom = _dom(chromium, page, tmp_path)
    _assert_inert(dom, scripts=2, shown=HOSTILE)


@pytest.fixture(scope="module")
def hostile_studies(
    robot: packbot.Robot, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[Any, Path]]:
    """A study that runs (hostile scenario name, description, obstacles) and one refused."""
    base = load_scenario("reconfig_elbow1")
    ok = dataclasses.replace(
        base, name=HOSTILE[0], description=" ".join(HOSTILE), environment=_hostile_env()
    )
    # a box around the arm: every run is refused, the reason quoting the obstacle's name
    box = Obstacle(name=HOSTILE[0], kind="box", size=(4.0, 4.0, 4.0), xyz=(0.0, 0.0, 0.5))
    refused = dataclasses.replace(
        base, name=HOSTILE[1], environment=Environment(obstacles=(FLOOR, box))
    )
    out = {}
    for key, sc in (("ok", ok), ("refused", refused)):
        folder = tmp_path_factory.mktemp(f"study-{key}")
        res = study(sc, robot=robot, duration=1.2)
        write_study(res, folder)
        out[key] = (res, folder / "report.html")
    return out


def test_study_report_shows_hostile_names_as_text(
    chromium: str, hostile_studies: dict[str, tuple[Any, Path]], tmp_path: Path
) -> None:
    res, page = hostile_studies["ok"]
    assert all(r.status == "ok" for r in res.runs.values())
    _assert_inert(_dom(chromium, page, tmp_path), scripts=2, shown=(HOSTILE[0], *HOSTILE))


def test_refused_study_report_shows_the_reason_as_text(
    chromium: str, hostile_studies: dict[str, tuple[Any, Path]], tmp_path: Path
) -> None:
    """The reason of a refused run quotes the obstacle: it is text in the pane, not markup."""
    res, page = hostile_studies["refused"]
    assert all(r.status == "refused" for r in res.runs.values())
    assert HOSTILE[0] in res.healthy.reason
    dom = _dom(chromium, page, tmp_path)
    _assert_inert(dom, scripts=2, shown=(HOSTILE[1], "no animation: " + res.healthy.reason))
    # and it still reads as a report (the screenshot: the three panes with their reasons)
    png = tmp_path / "refused.png"
    cmd = screenshot_command(chromium, page.as_uri(), png, tmp_path / "p2")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=GUARD, check=False)
    assert proc.returncode == 0 and png.exists(), proc.stderr[-2000:]
    keep = os.environ.get("PACKBOT_KEEP_SCREENSHOT")
    if keep:  # for a look by eye
        shutil.copy(png, keep)


def test_matrix_report_shows_hostile_text_as_text(chromium: str, tmp_path: Path) -> None:
    from packbot.batch import BatchReport, RunRecord
    from packbot.matrix import parse_matrix
    from packbot.study_matrix import StudyMatrix, study_matrix_summary
    from packbot.viz.study_matrix_report import write_matrix_report

    toml_list = json.dumps(list(HOSTILE[:2]), ensure_ascii=False)
    text = (
        f'name = "agg"\ndescription = {json.dumps(" ".join(HOSTILE), ensure_ascii=False)}\n'
        'base = "frozen_elbow_reach"\n[axes]\n"failures.0.joint" = ["elbow1", "shoulder"]\n'
        f'"failures.0.t" = [0.5]\n"description" = {toml_list}\n[study]\n'
    )
    sm = StudyMatrix.from_matrix(parse_matrix(text))
    runs = sm.runs()
    records = {}
    for k, run in enumerate(runs):
        f = sm.failure_of(run)
        if k == 0:  # a failed cell: its error quotes a name
            records[run.id] = RunRecord(
                id=run.id, index=run.index, params=run.params, digest=run.digest,
                status="failed", error="CellTimeout: " + HOSTILE[2],
            )  # fmt: skip
            continue
        (tmp_path / run.id).mkdir()
        data = {
            "duration_s": 1.0,
            "failures": [{"joint": f["joint"], "kind": "frozen", "t_s": f["t"]}],
            "recovery": {"possible": False, "reasons": [HOSTILE[3], HOSTILE[4]]},
            "runs": {
                name: {"status": "refused", "reason": HOSTILE[0], "final_task_error_m": 0.1}
                for name in ("healthy", "failed", "reconfigured")
            },
        }
        (tmp_path / run.id / "study.json").write_text(json.dumps(data))
        records[run.id] = RunRecord(
            id=run.id, index=run.index, params=run.params, digest=run.digest, status="ok",
            files={"study.json": f"{run.id}/study.json"},
        )  # fmt: skip
    batch = BatchReport(out_dir=tmp_path, runs=runs, records=records)
    summary = study_matrix_summary(sm, tmp_path, runs, batch)
    summary["cells"][1]["report"] = "javascript:document.body.setAttribute('data-pwned','href')"
    page = write_matrix_report(summary, tmp_path)["report.html"]
    dom = _dom(chromium, page, tmp_path)
    _assert_inert(dom, scripts=0, shown=(" ".join(HOSTILE), HOSTILE[2], HOSTILE[3]))
    hrefs = [a.get("href") or "" for tag, a in dom.elements if tag == "a"]
    assert hrefs and not any(h.lower().startswith("javascript:") for h in hrefs), hrefs


def test_uncertain_report_shows_hostile_text_as_text(chromium: str, tmp_path: Path) -> None:
    """An uncertain study's page: the scenario's name, the controller and each arm's reasons."""
    from packbot.uncertain_study import ArmStudy, UncertainStudy
    from packbot.uncertainty import sample_values
    from packbot.viz.uncertain_report import write_uncertain_report

    runs = ("healthy", "failed", "reconfigured")
    arms = tuple(
        ArmStudy(
            index=k,
            status=dict.fromkeys(runs, "error"),
            reasons=dict.fromkeys(runs, HOSTILE[k]),
            metrics=dict.fromkeys(runs),
            possible=None,
            error=HOSTILE[k],
        )
        for k in range(2)
    )
    unc = UncertainStudy(
        scenario=HOSTILE[3],
        sample=sample_values(2, 0),
        arms=arms,
        tolerance_m=0.01,
        controller=HOSTILE[4],
        duration_s=1.0,
        failure_time_s=0.5,
    )
    page = write_uncertain_report(unc.summary(), tmp_path)["report.html"]
    dom = _dom(chromium, page, tmp_path)
    _assert_inert(dom, scripts=0, shown=(HOSTILE[0], HOSTILE[1], HOSTILE[3], HOSTILE[4]))


# --------------------------------------------------------------------------- CSV cells
FORMULAS = ('=HYPERLINK("http://x","y")', "+1+cmd|' /C calc'!A0", "-2+3", "@SUM(A1)", "\tx", "\rx")


def test_event_csv_neutralises_formulas_and_keeps_numbers(
    robot: packbot.Robot, tmp_path: Path
) -> None:
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.02)
    events = [
        Event(t=0.001 * (k + 1), kind="impact", link1="link3", link2=f, piece1="tube", piece2=f,
              distance=-0.5, energy_before=-1.25, energy_after=-1.5)
        for k, f in enumerate(FORMULAS)
    ]  # fmt: skip
    res = dataclasses.replace(res, events=events)
    sc = Scenario(name="hostile", duration=0.02, pose="drive")
    paths = save_run(res, sc, tmp_path)
    with paths["events"].open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["link2"] for r in rows] == ["'" + f for f in FORMULAS]
    assert [r["piece2"] for r in rows] == ["'" + f for f in FORMULAS]
    assert {r["distance_m_or_rad"] for r in rows} == {"-0.5"}  # a number: as it is
    assert {r["energy_change_J"] for r in rows} == {"-0.250000"}


def test_summary_csv_neutralises_formulas_and_keeps_numbers() -> None:
    from packbot.csv_cells import spreadsheet_safe

    text = csv_text(
        [{"id": "=cmd()", "x": -0.5, "s": "-0.5", "e": "-1e-3", "n": "-inf", "w": "@me", "k": 3}],
        ["id", "x", "s", "e", "n", "w", "k", "=col"],
    )
    head, row = list(csv.reader(text.splitlines()))
    assert head[-1] == "'=col"
    assert row == ["'=cmd()", "-0.5", "-0.5", "-1e-3", "-inf", "'@me", "3", ""]
    assert spreadsheet_safe("- 1") == "'- 1" and spreadsheet_safe("-1_0") == "'-1_0"
    assert spreadsheet_safe(-0.5) == -0.5 and spreadsheet_safe("plain") == "plain"


# --------------------------------------------------------------------------- paths
@pytest.mark.parametrize(
    ("stem", "name", "field"),
    [
        ("../x", "s", "stem"),
        ("{abs}", "s", "stem"),
        ("a/b", "s", "stem"),
        ("..", "s", "stem"),
        ("a\x00b", "s", "stem"),
        (None, "../../x", "scenario.name"),
        (None, "{abs}", "scenario.name"),
        (None, "x" * 300, "scenario.name"),
    ],
)
def test_save_run_never_writes_outside_its_folder(
    robot: packbot.Robot, tmp_path: Path, stem: str | None, name: str, field: str
) -> None:
    out = tmp_path / "a" / "b" / "out"
    absolute = str(tmp_path / "elsewhere")
    stem = None if stem is None else stem.replace("{abs}", absolute)
    sc = Scenario(name=name.replace("{abs}", absolute), duration=0.02, pose="drive")
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.02)
    with pytest.raises(ConfigurationError) as exc:
        save_run(res, sc, out, stem=stem)
    assert exc.value.field == field and "single file name" in str(exc.value)
    assert not any(p.is_file() for p in tmp_path.rglob("*"))  # nothing written anywhere


def test_batch_refuses_a_run_id_that_is_not_a_file_name(tmp_path: Path) -> None:
    m = tmp_path / "m.toml"
    m.write_text(
        'base = "collapse"\n[set]\nduration = 0.02\n[axes]\n"config.restitution" = [0.0]\n'
    )
    matrix = load_matrix(m)
    run = dataclasses.replace(matrix.runs()[0], id="../../escaped")
    with pytest.raises(ConfigurationError) as exc:
        run_batch(matrix, tmp_path / "out", runs=[run], workers=0)
    assert exc.value.field == "runs[0].id" and "../../escaped" in str(exc.value)
    assert not (tmp_path / "escaped.json").exists() and not (tmp_path / "out").exists()


def test_cli_refuses_a_scenario_named_dot_dot(tmp_path: Path, capsys: Any) -> None:
    (tmp_path / "...toml").write_text('duration = 0.02\n[initial]\npose = "drive"\n')
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert main(["run", "...toml"]) == 2  # default --out: out/<name>, i.e. out/..
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert "scenario.name" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["...toml"]


# --------------------------------------------------------------------------- the manifest
def _manifest(out: Path, files: list[str], sums: dict[str, Any] | None = None) -> None:
    data: dict[str, Any] = {"tool": "packbot", "format": 2, "files": files}
    if sums is not None:
        data["checksums"] = sums
    (out / MANIFEST_NAME).write_text(json.dumps(data))


RUN = ["run", "collapse", "--duration", "0.05"]


def test_a_manifest_listing_a_foreign_file_does_not_delete_it(tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "o"
    out.mkdir()
    (out / "precious.txt").write_text("mine")
    _manifest(out, ["precious.txt"])  # listed, without a checksum (hand-made, or format 1)
    assert main([*RUN, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "precious.txt" in err and "--overwrite" in err and "SHA-256" in err
    assert (out / "precious.txt").read_text() == "mine"
    # with a checksum that does not match, or as a symbolic link: still kept
    _manifest(out, ["precious.txt"], {"precious.txt": {"sha256": "0" * 64, "size": 4}})
    assert main([*RUN, "--out", str(out)]) == 2
    assert (out / "precious.txt").read_text() == "mine"
    assert main([*RUN, "--out", str(out), "--overwrite"]) == 0
    assert (out / "precious.txt").read_text() == "mine"
    m = json.loads((out / MANIFEST_NAME).read_text())
    assert m["format"] == 2 and m["files"] == ["collapse.npz", "collapse_events.csv"]
    npz = out / "collapse.npz"
    assert m["checksums"]["collapse.npz"]["size"] == npz.stat().st_size
    # a rerun deletes its own files (checksums match), not a symlink put in their place
    (out / "precious.txt").unlink()
    npz.unlink()
    (tmp_path / "target.npz").write_text("elsewhere")
    npz.symlink_to(tmp_path / "target.npz")
    assert main([*RUN, "--out", str(out)]) == 2
    assert "collapse.npz (a symbolic link)" in capsys.readouterr().err
    npz.unlink()
    assert main([*RUN, "--out", str(out)]) == 0  # the events CSV: its own, deleted and rewritten
    assert (tmp_path / "target.npz").read_text() == "elsewhere"


# --------------------------------------------------------------------------- signals
def _packbot(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    # (cwd: not the checkout, whose source tree `python -m` would import, without the extensions)
    return subprocess.Popen(
        [sys.executable, "-m", "packbot.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
    )


def _wait_for(what: Any, proc: subprocess.Popen[str], timeout: float = GUARD) -> None:
    deadline = time.monotonic() + timeout
    while not what() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert what(), proc.stderr.read() if proc.poll() is not None else "not started in time"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_save_the_partial_run(tmp_path: Path, sig: int) -> None:
    out = tmp_path / "o"
    proc = _packbot(["run", "loose_shoulder", "--duration", "300", "--out", str(out)], tmp_path)
    try:
        _wait_for((out / MANIFEST_NAME).exists, proc)  # the handlers are in place
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=GUARD)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 128 + sig, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and signal.Signals(sig).name in lines[0], err
    assert "loose_shoulder_partial.npz" in lines[0]
    data = np.load(out / "loose_shoulder_partial.npz")
    assert 0.0 <= data["t"][-1] < 300.0
    m = json.loads((out / MANIFEST_NAME).read_text())
    assert m["status"] == "interrupted" and "loose_shoulder_partial.npz" in m["checksums"]


SLOW_MATRIX = (
    'base = "loose_shoulder"\n[set]\nduration = 300.0\n'
    '[axes]\n"config.restitution" = [0.0, 0.1, 0.2, 0.3]\n'
)


def _workers(pid: int) -> list[Any]:
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _alive(procs: list[Any]) -> list[Any]:
    import psutil

    out = []
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


def _batch_with_workers(tmp_path: Path) -> tuple[subprocess.Popen[str], list[Any]]:
    pytest.importorskip("psutil")
    (tmp_path / "m.toml").write_text(SLOW_MATRIX)
    args = ["batch", str(tmp_path / "m.toml"), "--out", str(tmp_path / "b"), "--workers", "2"]
    proc = _packbot([*args, "--no-progress"], tmp_path)
    # the 2 workers (and the resource tracker) started, and busy: each has a run's temp state
    _wait_for(lambda: len(_workers(proc.pid)) >= 3, proc)
    time.sleep(1.0)  # the workers past their start (a guard: any later moment does as well)
    return proc, _workers(proc.pid)


def _assert_gone(procs: list[Any]) -> None:
    deadline = time.monotonic() + 30  # a guard: they go within a second
    while _alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = _alive(procs)
    for p in left:  # do not leave them to the next test
        p.kill()
    assert not left, [(p.pid, p.cmdline()) for p in left]


def test_batch_workers_die_with_a_killed_main_process(tmp_path: Path) -> None:
    proc, workers = _batch_with_workers(tmp_path)
    try:
        proc.kill()  # kill -9: no clean-up in the main process
        proc.wait(timeout=GUARD)
        _assert_gone(workers)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def test_sigterm_stops_a_batch_as_ctrl_c_does(tmp_path: Path) -> None:
    proc, workers = _batch_with_workers(tmp_path)
    try:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=GUARD)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, err
    assert "SIGTERM" in err and "rerun the same command" in err
    assert (tmp_path / "b" / "summary.csv").is_file()
    _assert_gone(workers)


# --------------------------------------------------------------------------- resume
def test_resume_moves_aside_a_directory_in_place_of_a_trajectory(tmp_path: Path) -> None:
    from packbot.batch import RERUN_UNREADABLE_FILE

    m = tmp_path / "m.toml"
    m.write_text(
        'base = "collapse"\n[set]\nduration = 0.02\n[axes]\n"config.restitution" = [0.0, 0.5]\n'
    )
    matrix = load_matrix(m)
    out = tmp_path / "b"
    first = run_batch(matrix, out, workers=0)
    rid = first.runs[0].id
    traj = out / "trajectories" / f"{rid}.npz"
    traj.unlink()
    traj.mkdir()
    (traj / "inside.txt").write_text("keep")
    record = out / "runs" / f"{first.runs[1].id}.json"
    record.unlink()
    record.mkdir()  # the record itself a directory
    again = run_batch(matrix, out, workers=0)
    assert sorted(again.executed) == sorted(r.id for r in first.runs)
    assert again.rerun == {r.id: RERUN_UNREADABLE_FILE for r in first.runs}
    assert traj.is_file() and record.is_file() and not again.failed
    assert (out / "trajectories" / f"{rid}.npz.bad-1" / "inside.txt").read_text() == "keep"
    assert again.moved_aside == {
        f"trajectories/{rid}.npz": f"trajectories/{rid}.npz.bad-1",
        f"runs/{first.runs[1].id}.json": f"runs/{first.runs[1].id}.json.bad-1",
    }
    assert "moved aside 2" in again.describe()
    assert run_batch(matrix, out, workers=0).executed == []  # and finished now
