"""Bad-input catalogue, category ``content``: hostile strings reaching pages, CSV cells and plots.

A hostile name is legal input (an obstacle may be called ``<img onerror=...>``): it must be
escaped where it is shown, not refused. Each case writes one output with one hostile string in
the name fields that reach it and its ``check`` reads the output back (see the ``check`` field
of ``Case`` in ``tests/bad_input_cases.py``): ``clean`` when the string is there as text (a
page: escaped, or ``\\uXXXX`` in the inline script; a CSV cell: as it is, or with a leading ``'``
when a spreadsheet would run it as a formula; a plot: drawn, ``$`` not read as TeX), ``accepted``
with the problem otherwise. The sinks:

- ``events-csv``: an event's link and piece names in ``<stem>_events.csv`` (:func:`save_run`);
- ``summary-csv``: a batch's ``summary.csv`` cell and column (:func:`packbot.batch.csv_text`);
- ``html``: a run's HTML animation (:func:`packbot.viz.write_html`): the obstacle's name in the
  scene, the event list's labels;
- ``study``: a refused study's ``report.html`` (the scenario's name, the obstacle quoted by the
  reasons, set as text by the page's script);
- ``matrix``: a study matrix's ``report.html`` (its description, a failed cell's error);
- ``plot``: a plot's event labels (the obstacle's name in an impact's label).
"""

from __future__ import annotations

import csv
import dataclasses
import html as html_lib
import io
import json
import re
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

#: The hostile strings, by id: markup, script ends, quotes, entities, unicode, formulas, TeX.
HOSTILE: dict[str, str] = {
    "img-onerror": "<img src=x onerror=alert(1)>",
    "script-end": "</script><script>alert(1)</script>",
    "attr-break": '"><svg onload=alert(1)>',
    "single-quote": "' onmouseover='alert(1)",
    "ampersand": "a & b &amp; c &lt;",
    "comment": "<!-- x",
    "unicode": "caf\u00e9 \u2192 \U0001f916",
    "line-separators": "a\u2028b\u2029c",
    "formula-eq": '=HYPERLINK("http://x","y")',
    "formula-plus": "+cmd|' /C calc'!A0",
    "formula-minus": "-2+3",
    "formula-at": "@SUM(A1:A2)",
    "formula-tab": "\t=1+1",
    "formula-cr": "\r=1+1",
    "tex": "$x^$",
    "javascript-url": "javascript:alert(1)",
}
#: Strings that would break a plot's text (TeX math between two ``$``).
TEX: dict[str, str] = {
    "tex-frac": "$\\frac$",
    "tex-sub": "x$_$y",
    "tex-pair": "a$b$c",
    "tex-dollars": "$$",
}


def _viewer_js() -> str:
    from meshcat.servers.zmqserver import VIEWER_ROOT

    return (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")


def _shown_as_text(name: str, page: str) -> str | None:
    """None if ``name`` is on ``page`` escaped (HTML or script JSON) and nowhere raw."""
    from packbot.viz.html import script_json

    body = page.replace(_viewer_js(), "")
    if any(c in name for c in "<>&") and name in body:
        return f"{name!r} is raw in the page (markup, not text)"
    for script in re.findall(r"<script>(.*?)</script>", body, flags=re.S):
        if any(c in script for c in "\u2028\u2029"):
            return "a raw line separator (U+2028, U+2029) in an inline script"
    if html_lib.escape(name) not in body and script_json(name)[1:-1] not in body:
        return f"{name!r} is not shown (neither escaped text nor script data)"
    return None


def _cell(name: str, cell: str) -> str | None:
    """None if a CSV cell holds ``name`` as it is, or quoted when a spreadsheet would run it."""
    from packbot.csv_cells import FORMULA_STARTS

    formula = name.startswith(FORMULA_STARTS)
    want = "'" + name if formula else name
    if cell != want:
        return f"cell {cell!r}, expected {want!r}"
    return None


def _hostile_result(c: Any, name: str) -> Any:
    """The catalogue's short run with an impact against an obstacle named ``name``."""
    from packbot import Environment, Obstacle
    from packbot.environment import FLOOR
    from packbot.result import Event

    box = Obstacle(name=name, kind="box", size=(0.05, 0.05, 0.05), xyz=(3.0, 3.0, 0.1))
    ev = Event(t=0.01, kind="impact", link1="link3", link2=name, piece1="tube", piece2=name)
    env = Environment(obstacles=(FLOOR, box))
    return dataclasses.replace(c.result, events=[ev], environment=env), env


def register(catalogue: ModuleType) -> None:
    """Add the ``content`` cases to the catalogue."""

    def add(id: str, action: Any, check: Any) -> None:
        catalogue.add("content", id, action, check=check)

    for key, name in HOSTILE.items():
        add(f"events-csv-{key}", _events_csv(name), _check_events(name))
        add(f"summary-csv-{key}", _summary_csv(name), _check_summary(name))
        add(f"html-{key}", _html(name), lambda page, n=name: _shown_as_text(n, page))
        add(f"study-{key}", _study(name), lambda page, n=name: _shown_as_text(n, page))
        add(f"matrix-{key}", _matrix(name), lambda page, n=name: _shown_as_text(n, page))
    for key, name in {**TEX, "tex": HOSTILE["tex"]}.items():
        add(f"plot-{key}", _plot(name), _check_png)


# ------------------------------------------------------------------------ the sinks
def _events_csv(name: str) -> Any:
    def action(c: Any) -> list[dict[str, str]]:
        from packbot.scenario import Scenario, save_run

        res, _ = _hostile_result(c, name)
        paths = save_run(res, Scenario(name="hostile", duration=0.02, pose="drive"), c.tmp)
        with paths["events"].open(newline="", encoding="utf-8") as fh:
            return list(csv.DictReader(fh))

    return action


def _check_events(name: str) -> Any:
    def check(rows: list[dict[str, str]]) -> str | None:
        if len(rows) != 1:
            return f"{len(rows)} rows, not 1"
        for column in ("link2", "piece2"):
            problem = _cell(name, rows[0][column])
            if problem:
                return f"{column}: {problem}"
        return None

    return check


def _summary_csv(name: str) -> Any:
    def action(c: Any) -> list[list[str]]:
        from packbot.batch import csv_text

        text = csv_text([{"id": "r1", name: name, "x": -0.5}], ["id", name, "x"])
        return list(csv.reader(io.StringIO(text, newline="")))

    return action


def _check_summary(name: str) -> Any:
    def check(rows: list[list[str]]) -> str | None:
        if len(rows) != 2 or len(rows[1]) != 3:
            return f"rows {rows!r}"
        if rows[1][2] != "-0.5":
            return f"the number -0.5 became {rows[1][2]!r}"
        return _cell(name, rows[0][1]) or _cell(name, rows[1][1])

    return check


def _html(name: str) -> Any:
    def action(c: Any) -> str:
        from packbot.viz import write_html

        res, env = _hostile_result(c, name)
        return write_html(c.robot, res, c.tmp / "a.html", environment=env).read_text("utf-8")

    return action


def _study(name: str) -> Any:
    def action(c: Any) -> str:
        from packbot import Environment, Obstacle
        from packbot.environment import FLOOR
        from packbot.scenario import load_scenario
        from packbot.study import study
        from packbot.viz.study_report import write_study

        # a box around the arm: every run refused, the reasons quoting the obstacle's name
        box = Obstacle(name=name, kind="box", size=(4.0, 4.0, 4.0), xyz=(0.0, 0.0, 0.5))
        sc = dataclasses.replace(
            load_scenario("reconfig_elbow1"),
            name=name,
            environment=Environment(obstacles=(FLOOR, box)),
        )
        res = study(sc, robot=c.robot, duration=0.3)
        return write_study(res, c.tmp / "s")["report.html"].read_text("utf-8")

    return action


@cache
def _matrix_summary() -> str:
    """A study matrix's summary (as JSON), one cell failed, one studied (no simulation)."""
    from packbot.batch import BatchReport, RunRecord
    from packbot.matrix import parse_matrix
    from packbot.study_matrix import StudyMatrix, study_matrix_summary

    text = (
        'name = "m"\nbase = "frozen_elbow_reach"\n[axes]\n'
        '"failures.0.joint" = ["elbow1", "shoulder"]\n"failures.0.t" = [0.5]\n[study]\n'
    )
    sm = StudyMatrix.from_matrix(parse_matrix(text))
    runs = sm.runs()
    records = {
        r.id: RunRecord(
            id=r.id,
            index=r.index,
            params=r.params,
            digest=r.digest,
            status="failed",
            error="CellTimeout: x",
        )
        for r in runs
    }
    summary = study_matrix_summary(
        sm, Path("."), runs, BatchReport(out_dir=Path("."), runs=runs, records=records)
    )
    return json.dumps(summary)


def _matrix(name: str) -> Any:
    def action(c: Any) -> str:
        from packbot.viz.study_matrix_report import matrix_page

        summary = json.loads(_matrix_summary())
        summary["matrix"]["description"] = name
        summary["cells"][0]["error"] = name
        return matrix_page(summary, b"")

    return action


def _plot(name: str) -> Any:
    def action(c: Any) -> Path:
        from packbot.plots import plot_joints

        res, _ = _hostile_result(c, name)
        plot_joints(res, path=c.tmp / "joints", formats=("png",))
        return c.tmp / "joints.png"

    return action


def _check_png(path: Path) -> str | None:
    if not path.is_file() or path.stat().st_size < 1000:
        return f"no plot at {path}"
    return None
