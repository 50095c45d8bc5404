"""The summary of a study matrix: ``study-matrix.json``, the heat maps and ``report.html``.

:func:`write_matrix_report` writes, from the summary of :func:`packbot.study_matrix.
study_matrix_summary` (a JSON-ready dict, so a summary read back from ``study-matrix.json``
renders the same):

- ``study-matrix.json``: the summary, plus the figures' file names;
- ``study_heat_map.png`` and ``.svg``: three heat maps over failed joint (rows) x failure time
  (columns): the recovery rate (the share of the bin's studies whose reconfigured run ends
  within the tolerance), and the median final task error of the reconfigured and of the failed
  runs [mm] (one logarithmic colour scale, the tolerance marked on it). In the SVG each square
  links to its cell's report (a bin of several cells: to its row in ``report.html``);
- ``report.html``: one file that opens offline (the heat map inline as PNG, no script): the
  matrix, the counts, the heat map, a grid of the bins with a link to each cell's report, and a
  table of every cell (its failure, verdict, final errors, detection and recovery times, its
  status or error).
"""

from __future__ import annotations

import base64
import html as html_lib
import io
import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from packbot.errors import ConfigurationError
from packbot.study_matrix_format import SUMMARY_FORMAT
from packbot.viz.study_report import _write_atomic

if TYPE_CHECKING:
    from matplotlib.colors import Colormap, Normalize
    from matplotlib.figure import Figure

__all__ = [
    "HEAT_MAP",
    "PANELS",
    "heat_map_figure",
    "matrix_page",
    "write_matrix_report",
]

#: The heat map figure's file stem.
HEAT_MAP = "study_heat_map"
#: The heat map's panels: (key of ``summary["heat_map"]``, title).
PANELS: tuple[tuple[str, str], ...] = (
    ("recovery_rate", "recovery rate"),
    ("reconfigured_final_task_error_m", "final task error, reconfigured [mm]"),
    ("failed_final_task_error_m", "final task error, failed (unaware) [mm]"),
)
_RATE_CMAP = "RdYlGn"
_ERROR_CMAP = "viridis_r"
_EMPTY = "#d9d9d9"
_DPI = 110


def _cell_link(summary: Mapping[str, Any], ids: Sequence[str], r: int, k: int) -> str | None:
    """Where a bin's square links: its cell's report (or study.json), or its row in the page."""
    if not ids:
        return None
    if len(ids) > 1:
        return f"report.html#bin-{r}-{k}"
    cell = next(c for c in summary["cells"] if c["id"] == ids[0])
    return _relative_link(cell["report"] or cell["study_json"])


def _relative_link(target: Any) -> str | None:
    """A cell's file as a link: a relative path inside the folder, else None (no link).

    A summary read back from ``study-matrix.json`` is data: a ``javascript:`` or absolute
    target (an edited file) is not linked.
    """
    if not isinstance(target, str) or not target:
        return None
    if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", target) or target.startswith(("/", "\\")):
        return None
    if ".." in target.replace("\\", "/").split("/"):
        return None
    return target


def _norms(summary: Mapping[str, Any]) -> tuple[Normalize, Normalize]:
    from matplotlib.colors import LogNorm, Normalize

    hm = summary["heat_map"]
    values = [
        1000.0 * v
        for key in ("reconfigured_final_task_error_m", "failed_final_task_error_m")
        for row in hm[key]
        for v in row
        if v is not None and math.isfinite(v)
    ]
    tol_mm = 1000.0 * summary["tolerance_m"]
    lo = max(min([*values, tol_mm]), 0.01)
    hi = max([*values, tol_mm])
    if hi <= 1.5 * lo:
        hi = 10.0 * lo
    return Normalize(0.0, 1.0), LogNorm(lo, hi)


def _text_color(rgba: Sequence[float]) -> str:
    r, g, b = rgba[:3]
    return "black" if 0.299 * r + 0.587 * g + 0.114 * b > 0.5 else "white"


def heat_map_figure(summary: Mapping[str, Any]) -> Figure:
    """The heat maps (one figure, three panels: :data:`PANELS`) of a study matrix's summary.

    Rows: the failed joint; columns: the failure time [s]. Each square is annotated with its
    value (the rate as ``recovered/studied``); a bin without a study is grey and hatched
    (``not studied``, or ``missing`` where the matrix has no cell), a 0 mm bin takes the error
    scale's lowest colour.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    hm = summary["heat_map"]
    joints, times = list(hm["joints"]), list(hm["failure_times_s"])
    rate_norm, err_norm = _norms(summary)
    tol_mm = 1000.0 * summary["tolerance_m"]
    width = max(3.2, 1.0 + 1.15 * len(times))
    fig = Figure(figsize=(3 * width, 1.9 + 0.62 * len(joints)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3, sharey=True)
    for ax, (key, title) in zip(axes, PANELS, strict=True):
        is_rate = key == "recovery_rate"
        cmap: Colormap = colormaps[_RATE_CMAP if is_rate else _ERROR_CMAP]
        norm = rate_norm if is_rate else err_norm
        for r in range(len(joints)):
            for k in range(len(times)):
                ids = hm["cells"][r][k] or []
                value = hm[key][r][k]
                hatch = None
                if value is None:
                    face: Any = _EMPTY
                    hatch = "//"  # a missing bin is marked, never left blank
                    text = ("not studied" if hm["studied"][r][k] == 0 else "") if ids else "missing"
                elif is_rate:
                    face = cmap(norm(value))
                    text = f"{hm['recovered'][r][k]}/{hm['studied'][r][k]}"
                    if len(ids) > hm["studied"][r][k]:
                        text += f"\n({len(ids) - hm['studied'][r][k]} not studied)"
                else:
                    # a 0 mm bin (or below the scale) takes the scale's lowest colour: a
                    # logarithmic norm masks it, and it would not be drawn
                    face = cmap(norm(max(1000.0 * value, float(norm.vmin or 0.0))))
                    text = f"{1000.0 * value:.3g} mm"
                rect = Rectangle(
                    (k - 0.5, r - 0.5),
                    1.0,
                    1.0,
                    facecolor=face,
                    edgecolor="white",
                    lw=2.0,
                )
                link = _cell_link(summary, ids, r, k)
                if link is not None:
                    rect.set_url(link)
                ax.add_patch(rect)
                if hatch is not None:
                    ax.add_patch(
                        Rectangle(
                            (k - 0.45, r - 0.45),
                            0.9,
                            0.9,
                            fill=False,
                            hatch=hatch,
                            edgecolor="#a0a0a0",
                            lw=0.0,
                        )
                    )
                if text:
                    color = "black" if value is None else _text_color(face)
                    ax.text(k, r, text, ha="center", va="center", fontsize="small", color=color)
        ax.set_xlim(-0.5, len(times) - 0.5)
        ax.set_ylim(len(joints) - 0.5, -0.5)
        ax.set_xticks(range(len(times)), [f"{t:g}" for t in times])
        ax.set_yticks(range(len(joints)), joints)
        ax.set_xlabel("failure time [s]")
        ax.set_title(title, fontsize="medium")
        ax.tick_params(length=0)
        for spine in ax.spines.values():
            spine.set_visible(False)
        bar = fig.colorbar(
            ScalarMappable(norm=norm, cmap=cmap), ax=ax, location="bottom", shrink=0.85, aspect=25
        )
        if is_rate:
            bar.set_label(f"share ending within {tol_mm:g} mm", fontsize="small")
        else:
            bar.ax.axvline(tol_mm, color="black", lw=1.5)
            bar.set_label(f"[mm], bin median; black: tolerance {tol_mm:g} mm", fontsize="small")
    axes[0].set_ylabel("failed joint")
    c = summary["counts"]
    fig.suptitle(
        f"{summary['matrix']['name']}: {c['studied']} failure studies, the reconfigured run "
        f"recovers in {c['recovered']}, recovery possible in {c['recovery_possible']}",
        fontsize="medium",
    )
    return fig


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return buf.getvalue()


def _svg(fig: Figure) -> bytes:
    from matplotlib import rc_context

    buf = io.BytesIO()
    with rc_context({"svg.hashsalt": "packbot"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def write_matrix_report(
    summary: Mapping[str, Any], out_dir: str | os.PathLike[str]
) -> dict[str, Path]:
    """Write ``study-matrix.json``, the heat map (PNG, SVG) and ``report.html`` into ``out_dir``.

    Returns:
        Name -> path of each file written.

    Raises:
        ConfigurationError: ``summary`` is not a study matrix's summary, or ``out_dir`` a file.
    """
    if not isinstance(summary, Mapping) or summary.get("format") != SUMMARY_FORMAT:
        raise ConfigurationError(
            "summary", type(summary).__name__, f"a study matrix's summary ({SUMMARY_FORMAT})"
        )
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigurationError("out_dir", str(out), "a directory (this is a file)")
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    fig = heat_map_figure(summary)
    png = _png(fig)
    for ext, image in (("png", png), ("svg", _svg(fig))):
        path = out / f"{HEAT_MAP}.{ext}"
        _write_atomic(path, image)
        written[path.name] = path
    data = dict(summary)
    data["figures"] = sorted(written)
    path = out / "study-matrix.json"
    _write_atomic(path, (json.dumps(data, indent=1, allow_nan=False) + "\n").encode())
    written[path.name] = path
    path = out / "report.html"
    _write_atomic(path, matrix_page(summary, png).encode("utf-8"))
    written[path.name] = path
    return written


# ---------------------------------------------------------------------------------- page
def _mm(x: float | None) -> str:
    return "&mdash;" if x is None else f"{1000.0 * x:.3g} mm"


def _s(x: float | None) -> str:
    return "&mdash;" if x is None else f"{x:.3g} s"


def _hex(rgba: Sequence[float]) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgba[:3])


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _verdict(possible: bool | None) -> str:
    return {True: "possible", False: "not possible", None: "not assessed"}[possible]


def _other_params(cell: Mapping[str, Any], failure: str) -> dict[str, Any]:
    """A cell's parameters besides the failed joint and the failure time (the heat map's)."""
    skip = (f"{failure}.joint", f"{failure}.t")
    return {k: v for k, v in cell["params"].items() if k not in skip}


def _cell_label(cell: Mapping[str, Any], failure: str) -> str:
    """A cell's link text: its other parameters, or "report"."""
    extra = [f"{k.split('.')[-1]} {v}" for k, v in _other_params(cell, failure).items()]
    return ", ".join(extra) if extra else "report"


_CSS = """
body { font: 14px sans-serif; margin: 12px 18px; color: #222; max-width: 1400px; }
h1 { font-size: 20px; margin: 4px 0; } h2 { font-size: 16px; margin: 18px 0 6px; }
table.grid { border-collapse: collapse; margin: 4px 0; }
table.grid td, table.grid th { border: 1px solid #bbb; padding: 3px 7px; text-align: left;
  font-size: 13px; vertical-align: top; }
table.bins td { min-width: 150px; }
table.bins td.bin { border: 2px solid #fff; }
.small { font-size: 12px; color: #444; }
.ok { color: #1a7f1a; } .no { color: #b02020; }
img.fig { max-width: 100%; display: block; margin: 6px 0; }
tr:target { outline: 2px solid #1f77b4; }
"""


def matrix_page(summary: Mapping[str, Any], heat_map_png: bytes | None = None) -> str:
    """The summary page (HTML text): self-contained, no script; links to each cell's report.

    Args:
        summary: The study matrix's summary (:func:`packbot.study_matrix.study_matrix_summary`).
        heat_map_png: The heat map as PNG (default: drawn here).
    """
    from matplotlib import colormaps

    esc = html_lib.escape
    if heat_map_png is None:
        heat_map_png = _png(heat_map_figure(summary))
    hm = summary["heat_map"]
    joints, times = hm["joints"], hm["failure_times_s"]
    m, c = summary["matrix"], summary["counts"]
    tol_mm = 1000.0 * summary["tolerance_m"]
    cells = {cell["id"]: cell for cell in summary["cells"]}
    failure = summary["failure"]
    show_other = any(_other_params(cell, failure) for cell in summary["cells"])
    rate_cmap = colormaps[_RATE_CMAP]

    # the bins: one square per failed joint x failure time, its cells linked
    head = "".join(f"<th>t = {t:g} s</th>" for t in times)
    rows = [f"<tr><th>failed joint</th>{head}</tr>"]
    for r, joint in enumerate(joints):
        tds = []
        for k in range(len(times)):
            ids = hm["cells"][r][k] or []
            rate = hm["recovery_rate"][r][k]
            if not ids:
                tds.append('<td class="bin" style="background:#eee">no cell</td>')
                continue
            bg = (
                "#e6e6e6"
                if rate is None
                else _hex(tuple(0.55 + 0.45 * x for x in rate_cmap(rate)[:3]))
            )
            lines = []
            if rate is not None:
                lines.append(
                    f"<b>recovered {hm['recovered'][r][k]}/{hm['studied'][r][k]}</b> "
                    f"(possible {hm['recovery_possible'][r][k]})"
                )
                lines.append(
                    f"final error: reconfigured "
                    f"{_mm(hm['reconfigured_final_task_error_m'][r][k])}, failed "
                    f"{_mm(hm['failed_final_task_error_m'][r][k])}"
                )
            links = []
            for cid in ids:
                cell = cells[cid]
                target = _relative_link(cell["report"] or cell["study_json"])
                label = esc(_cell_label(cell, failure))
                if target:
                    links.append(f'<a href="{esc(target)}">{label}</a>')
                else:
                    links.append(f'<span class="no">{label}: {esc(cell["status"])}</span>')
            lines.append(" &middot; ".join(links))
            tds.append(
                f'<td class="bin" id="bin-{r}-{k}" style="background:{bg}">'
                + "<br>".join(lines)
                + "</td>"
            )
        rows.append(f"<tr><th>{esc(str(joint))}</th>{''.join(tds)}</tr>")
    bins = '<table class="grid bins">' + "".join(rows) + "</table>"

    # every cell
    crow = [
        "<tr><th>#</th><th>cell</th><th>failed joint</th><th>kind</th><th>failure time</th>"
        + ("<th>other parameters</th>" if show_other else "")
        + "<th>status</th><th>recovery</th><th>recovered</th>"
        "<th>final error failed</th><th>final error reconfigured</th><th>detected at</th>"
        "<th>within tolerance from</th><th>why / error</th></tr>"
    ]
    for cell in summary["cells"]:
        target = _relative_link(cell["report"] or cell["study_json"])
        name = esc(str(cell["id"]))
        link = f'<a href="{esc(target)}">{name}</a>' if target else name
        runs = cell["runs"]
        failed = runs.get("failed", {}).get("final_task_error_m")
        reconf = runs.get("reconfigured", {}).get("final_task_error_m")
        why = "; ".join(cell["recovery_reasons"]) if cell["status"] == "ok" else cell["error"]
        bad = [f"{n} {v['status']}: {v['reason']}" for n, v in runs.items() if v["status"] != "ok"]
        why = "; ".join([*bad, why] if why else bad)
        recovered = cell["recovered"]
        rec_text = (
            "&mdash;"
            if recovered is None
            else ('<span class="ok">yes</span>' if recovered else '<span class="no">no</span>')
        )
        r = joints.index(cell["joint"])
        k = times.index(cell["failure_time_s"])
        other = ", ".join(
            f"{key} = {json.dumps(v)}" for key, v in _other_params(cell, failure).items()
        )
        other_td = f"<td>{esc(other)}</td>" if show_other else ""
        crow.append(
            f'<tr id="cell-{name}"><td><a href="#bin-{r}-{k}">{esc(str(cell["index"]))}</a></td>'
            f"<td>{link}</td><td>{esc(str(cell['joint']))}</td><td>{esc(str(cell['kind']))}</td>"
            f"<td>{cell['failure_time_s']:g} s</td>{other_td}"
            f"<td>{esc(cell['status'])}</td>"
            f"<td>{_verdict(cell['recovery_possible']) if cell['status'] == 'ok' else '&mdash;'}"
            f"</td><td>{rec_text}</td><td>{_mm(failed)}</td><td>{_mm(reconf)}</td>"
            f"<td>{_s(cell.get('detect_time_s'))}</td><td>{_s(cell.get('recover_time_s'))}</td>"
            f'<td class="small">{esc(str(why))}</td></tr>'
        )
    table = '<table class="grid">' + "".join(crow) + "</table>"
    img = base64.b64encode(heat_map_png).decode("ascii")
    durations = ", ".join(f"{d:g}" for d in summary["durations_s"]) or "&mdash;"
    axes = "; ".join(
        f"<code>{esc(k)}</code> = {esc(', '.join(json.dumps(v) for v in vs))}"
        for k, vs in summary["axes"].items()
    )
    missing = (
        f" <b>{_count(c['missing'], 'cell')} not studied yet</b> (rerun the same command to "
        "finish)."
        if c["missing"]
        else ""
    )
    failed_text = (
        f" <b>{_count(c['failed'], 'cell')} failed</b> (table below)." if c["failed"] else ""
    )
    body = f"""<h1>Failure study over a matrix: {esc(m["name"])}</h1>
<p>{esc(m["description"])}<br>base scenario <b>{esc(m["base"])}</b>; axes: {axes}.<br>
Each cell is a failure study (a healthy, a failed and a reconfigured run of {durations} s; the task
is the healthy run's <code>gripper_tool</code> path; recovered: the reconfigured run ends within
{tol_mm:g} mm of it).<br>
{c["cells"]} cells: {c["studied"]} studied, recovery possible in {c["recovery_possible"]}, the
reconfigured run recovers in {c["recovered"]}.{failed_text}{missing}</p>
<h2>Recovery and final task error by failed joint and failure time</h2>
<img class="fig" alt="heat map" src="data:image/png;base64,{img}">
<p class="small">Recovery rate: the share of the bin's studies whose reconfigured run ends within
the tolerance; errors: the median over the bin's studies. Files: <code>{HEAT_MAP}.png</code>,
<code>{HEAT_MAP}.svg</code> (its squares link to the cells' reports),
<code>study-matrix.json</code>.</p>
<h2>Bins and their cells (links to each cell's report)</h2>{bins}
<h2>Every cell</h2>{table}
"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>packbot study matrix: {esc(m["name"])}</title>
<style>{_CSS}</style>
</head>
<body>
{body}</body>
</html>
"""
