"""The batch progress bar: whole lines in a log, one redrawn line on a terminal.

The clock is replaced by a counter (``packbot.batch.time``), so the rate and the time left are
exact; nothing is timed.
"""

from __future__ import annotations

import io
import logging
import types
from pathlib import Path
from typing import Any

import pytest

import packbot.batch as batch_module
from packbot.batch import ProgressBar, _duration_text, run_batch
from packbot.matrix import Matrix, Run, expand


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def perf_counter(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> _Clock:
    c = _Clock()
    monkeypatch.setattr(batch_module, "time", types.SimpleNamespace(perf_counter=c.perf_counter))
    return c


class _Terminal(io.StringIO):
    """A stream that says it is a terminal of ``columns`` characters (no descriptor)."""

    def isatty(self) -> bool:
        return True

    def screen(self) -> list[str]:
        """The lines as a terminal shows them: ``\\r`` returns to the line's start."""
        shown = []
        for line in self.getvalue().split("\n"):
            cells: list[str] = []
            for part in line.split("\r"):
                cells[: len(part)] = part
            shown.append("".join(cells))
        return shown


def test_a_log_gets_a_whole_line_every_5_percent(clock: _Clock) -> None:
    out = io.StringIO()
    bar = ProgressBar(out)
    for done in range(101):
        bar(done, done // 10, 100)
        clock.now += 3.0  # 20 runs/min
    text = out.getvalue()
    assert "\r" not in text and text.endswith("\n")
    lines = text.splitlines()
    assert len(lines) == 21
    assert lines[0] == "[" + "." * 30 + "] 0/100 runs"
    assert lines[1] == "[" + "#" * 2 + "." * 28 + "] 5/100 runs, 20 runs/min, 4 min 45 s left"
    assert lines[10].startswith("[" + "#" * 15 + "." * 15 + "] 50/100 runs (5 failed), 20 runs/")
    assert lines[-1] == "[" + "#" * 30 + "] 100/100 runs (10 failed), 20 runs/min"


def test_a_log_of_a_few_slow_runs_gets_each_and_the_pace_per_run(clock: _Clock) -> None:
    out = io.StringIO()
    bar = ProgressBar(out)
    for done in range(4):
        bar(done, 0, 3)
        clock.now += 150.0  # 2.5 min a run
    lines = out.getvalue().splitlines()
    assert len(lines) == 4
    assert lines[1].endswith("1/3 runs, 2 min 30 s/run, 5 min 00 s left")
    assert lines[3].endswith("3/3 runs, 2 min 30 s/run")


def test_a_resumed_batch_counts_only_the_runs_made_now(clock: _Clock) -> None:
    bar = ProgressBar(io.StringIO())
    bar.text(90, 0, 100)  # 90 finished before
    clock.now += 60.0
    assert bar.text(92, 0, 100).endswith("92/100 runs, 2 runs/min, 4 min 00 s left")


def test_a_terminal_shows_one_line_with_nothing_left_of_longer_ones(clock: _Clock) -> None:
    term = _Terminal()
    bar = ProgressBar(term)
    texts = []
    for done in range(11):
        bar(done, 5 if done == 3 else 0, 10)  # a longer line (failed), then shorter ones
        texts.append(bar.text(done, 5 if done == 3 else 0, 10))
        clock.now += 6.0 if done < 5 else 0.5  # the time left shrinks to a few seconds
    assert term.getvalue().count("\n") == 1 and term.getvalue().endswith("\n")
    screen = term.screen()
    assert screen[1] == ""
    assert screen[0].rstrip() == texts[-1]
    # each redraw blanked what the previous one left past its end
    lengths = [len(t) for t in texts]
    assert max(lengths) > lengths[-1]


def test_a_terminal_line_is_cut_to_its_width(clock: _Clock, monkeypatch) -> None:
    term = _Terminal()
    bar = ProgressBar(term)
    monkeypatch.setattr(bar, "_columns", lambda: 40)
    bar(1, 1, 1000)
    clock.now += 1.0
    bar(2, 1, 1000)
    assert all(len(part) <= 39 for part in term.getvalue().split("\r"))


@pytest.mark.parametrize(
    ("seconds", "text"),
    [
        (0.2, "0 s"),
        (42.4, "42 s"),
        (65, "1 min 05 s"),
        (3599, "59 min 59 s"),
        (11220, "3 h 07 min"),
    ],
)
def test_duration_text(seconds: float, text: str) -> None:
    assert _duration_text(seconds) == text


def _toy(run: Run, progress: Any) -> tuple[dict[str, Any], dict[str, tuple[str, bytes]]]:
    """A run without simulation (in this process: ``workers=0``)."""
    progress(0.0)
    x = float(run.scenario["x"])
    quantities = {
        "joint_names": ("a",),
        "final_q": (x,),
        "rest_time": None,
        "n_impacts": 0,
        "n_events": 0,
        "event_times": (),
        "event_kinds": (),
        "min_distance": 1.0,
        "energy_change": 0.0,
        "t_end": 1.0,
    }
    return quantities, {"trajectory": (f"{run.id}.txt", repr(x).encode())}


def test_run_batch_drives_the_bar_in_a_log(tmp_path: Path) -> None:
    m = Matrix(name="toy", base="toy", axes={"x": [float(i) for i in range(40)]})
    m.validate()
    runs = expand(m, {"x": 0.0})
    out = io.StringIO()
    run_batch(m, tmp_path / "b", runs=runs, workers=0, runner=_toy, progress=ProgressBar(out))
    lines = out.getvalue().splitlines()
    assert len(lines) == 21 and "\r" not in out.getvalue()
    assert lines[0] == "[" + "." * 30 + "] 0/40 runs"
    assert lines[-1].startswith("[" + "#" * 30 + "] 40/40 runs, ")
    # resumed: nothing to do, the bar says so in one line
    out2 = io.StringIO()
    run_batch(m, tmp_path / "b", runs=runs, workers=0, runner=_toy, progress=ProgressBar(out2))
    assert out2.getvalue() == "[" + "#" * 30 + "] 40/40 runs\n"


def test_a_log_record_gets_its_own_line_above_the_bar(clock: _Clock) -> None:
    term = _Terminal()
    handler = logging.StreamHandler(term)
    handler.setFormatter(logging.Formatter("%(levelname)s %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        bar = ProgressBar(term)
        bar(0, 0, 3)
        clock.now += 30.0
        logging.getLogger("packbot.batch").warning("run r1 failed: ValueError: no")
        bar(1, 1, 3)
        clock.now += 30.0
        bar(2, 1, 3)
        assert handler.filters == [bar]
        bar(3, 1, 3)
        assert handler.filters == []  # the bar is finished: records go through untouched
        logging.getLogger("packbot.batch").warning("after")
    finally:
        root.removeHandler(handler)
    screen = [line.rstrip() for line in term.screen()]
    assert screen == [
        "WARNING run r1 failed: ValueError: no",
        bar.text(3, 1, 3),
        "WARNING after",
        "",
    ]
