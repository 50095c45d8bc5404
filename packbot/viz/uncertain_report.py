"""The uncertain study's report and the uncertain run's figure, drawn from their JSON summaries.

:func:`write_uncertain_report` writes, from :meth:`packbot.uncertain_study.UncertainStudy.
summary` (a JSON-ready dict: a summary read back from ``uncertain.json`` renders the same):

- ``uncertain.json``: the summary, plus the figures' file names;
- figures, each as PNG and SVG: ``uncertain_task_error`` (each run's task error against time:
  the median over the arms and the 5-95 % band around it, the tolerance and the failure
  marked), ``uncertain_final_error`` (a histogram of the final task error of the failed and the
  reconfigured runs over the arms, the tolerance marked), ``uncertain_sensitivity`` (the
  parameters with the largest Spearman rank correlation with each run's final task error);
- ``report.html``: one file that opens offline (the figures inline as PNG, no script): the
  sample, the recovery probability and its interval, the quantiles' table, the figures and
  every arm's statuses.

:func:`write_uncertain_run` writes ``uncertain-run.json`` and ``uncertain_run`` (PNG, SVG):
each joint's final angle over the arms, where link 3 ends (side and top views) and the events
per arm, from :meth:`packbot.uncertain_run.UncertainRun.summary`.
"""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from packbot.errors import ConfigurationError
from packbot.viz.study_matrix_report import _png, _svg
from packbot.viz.study_report import RUN_COLORS, _write_atomic

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "RUN_FIGURE",
    "STUDY_FIGURES",
    "uncertain_figures",
    "uncertain_page",
    "uncertain_run_figure",
    "write_uncertain_report",
    "write_uncertain_run",
]

#: The uncertain study's figures' file stems, in the page's order.
STUDY_FIGURES: tuple[str, ...] = (
    "uncertain_task_error",
    "uncertain_final_error",
    "uncertain_sensitivity",
)
#: The uncertain run's figure's file stem.
RUN_FIGURE = "uncertain_run"
_RUNS = ("healthy", "failed", "reconfigured")
_BAR_RUNS = ("failed", "reconfigured")


def _arr(values: Sequence[float | None]) -> Any:
    import numpy as np

    return np.array([math.nan if v is None else v for v in values], dtype=float)


def _check(summary: Any, key: str, what: str) -> None:
    if not isinstance(summary, Mapping) or key not in summary:
        raise ConfigurationError("summary", type(summary).__name__, what)


def uncertain_figures(summary: Mapping[str, Any]) -> dict[str, Figure]:
    """The uncertain study's figures (:data:`STUDY_FIGURES`), from its summary.

    Raises:
        ConfigurationError: ``summary`` is not an uncertain study's summary.
    """
    from matplotlib.figure import Figure

    _check(summary, "task_error_band", "an uncertain study's summary (UncertainStudy.summary)")
    tol_mm = 1000.0 * summary["tolerance_m"]
    n = summary["sample"]["arms"]
    out: dict[str, Figure] = {}

    band = summary["task_error_band"]
    t = _arr(band["t_s"])
    ft = summary.get("failure_time_s")
    fig = Figure(figsize=(9.0, 6.4), layout="constrained")
    lin, log = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    for ax, runs in ((lin, _RUNS), (log, _BAR_RUNS)):
        for run in runs:
            q = {p: 1000.0 * _arr(band[run][p]) for p in ("5", "50", "95")}
            color = RUN_COLORS[run]
            ax.fill_between(t, q["5"], q["95"], color=color, alpha=0.25, lw=0)
            ax.plot(t, q["50"], color=color, lw=1.6, label=f"{run}: median, 5-95 % band")
        ax.axhline(tol_mm, color="0.3", ls="--", lw=1.0, label=f"tolerance {tol_mm:g} mm")
        if ft is not None:
            ax.axvline(ft, color="0.5", ls=":", lw=1.0, label=f"failure at {ft:g} s")
        ax.grid(alpha=0.3)
        ax.set_ylabel("task error [mm]")
    lin.legend(loc="upper left", fontsize="small")
    lin.set_title(
        f"{summary['scenario']}: gripper task error over {n} arms drawn within the tolerances"
    )
    log.set_yscale("log")
    log.set_ylim(bottom=1e-3)
    log.set_title("the same after the failure, logarithmic (healthy: 0)", fontsize="medium")
    log.set_xlabel("time [s]")
    if ft is not None:
        log.set_xlim(left=0.0)
    out["uncertain_task_error"] = fig

    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    for ax, run in zip(fig.subplots(1, len(_BAR_RUNS)), _BAR_RUNS, strict=True):
        x = 1000.0 * _arr(summary["final_task_error_m"][run])
        x = x[~_isnan(x)]
        if len(x):
            ax.hist(x, bins=min(20, max(5, len(x) // 2)), color=RUN_COLORS[run], alpha=0.8)
            lo, hi = ax.get_xlim()
            if lo <= tol_mm <= hi:
                ax.axvline(tol_mm, color="0.3", ls="--", lw=1.0, label=f"tolerance {tol_mm:g} mm")
                ax.legend(fontsize="small")
            else:
                side = "above" if tol_mm > hi else "below"
                where = "within" if side == "above" else "beyond"
                ax.text(
                    0.02 if side == "below" else 0.98,
                    0.95,
                    f"tolerance {tol_mm:g} mm: every arm {where}",
                    ha="left" if side == "below" else "right",
                    va="top",
                    transform=ax.transAxes,
                    fontsize="small",
                    bbox={"facecolor": "white", "alpha": 0.85, "lw": 0},
                )
        else:
            ax.text(0.5, 0.5, "no arm finished", ha="center", va="center", transform=ax.transAxes)
        ax.set_xlabel("final task error [mm]")
        ax.set_ylabel("arms")
        ax.set_title(f"{run}: {len(x)} arms", fontsize="medium")
        ax.grid(alpha=0.3)
    fig.suptitle("final task error over the arms", fontsize="medium")
    out["uncertain_final_error"] = fig

    top = summary["sensitivity"]["top"]
    chance = 2.0 / math.sqrt(max(n - 1, 1))
    fig = Figure(figsize=(9.0, 4.6), layout="constrained")
    axes = fig.subplots(1, len(_BAR_RUNS), sharex=True)
    for ax, run in zip(axes, _BAR_RUNS, strict=True):
        rows = [r for r in top[run]["final_task_error_m"] if r["rho"] is not None][::-1]
        if rows:
            ax.barh([r["parameter"] for r in rows], [r["rho"] for r in rows], color=RUN_COLORS[run])
        else:
            ax.text(0.5, 0.5, "undefined", ha="center", va="center", transform=ax.transAxes)
        ax.axvline(0.0, color="0.3", lw=0.8)
        for sign in (-1, 1):
            ax.axvline(sign * min(chance, 1.0), color="0.4", ls=":", lw=1.0)
        ax.set_xlim(-1.0, 1.0)
        ax.set_xlabel("Spearman rho")
        ax.set_title(f"{run}: its final task error follows", fontsize="medium")
        ax.tick_params(axis="y", labelsize="small")
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(
        f"sensitivity over {n} arms: one parameter's |rho| passes the dotted lines "
        f"(2 / sqrt(n - 1) = {chance:.2f}) by chance about 1 time in 20",
        fontsize="medium",
    )
    out["uncertain_sensitivity"] = fig
    return out


def _isnan(x: Any) -> Any:
    import numpy as np

    return np.isnan(x)


def _save_figures(
    figures: Mapping[str, Figure], out: Path
) -> tuple[dict[str, Path], dict[str, bytes]]:
    written: dict[str, Path] = {}
    pngs: dict[str, bytes] = {}
    for stem, fig in figures.items():
        pngs[stem] = _png(fig)
        for ext, image in (("png", pngs[stem]), ("svg", _svg(fig))):
            path = out / f"{stem}.{ext}"
            _write_atomic(path, image)
            written[path.name] = path
    return written, pngs


def _folder(out_dir: Any) -> Path:
    if not isinstance(out_dir, (str, os.PathLike)) or not str(out_dir):
        raise ConfigurationError("out_dir", out_dir, "a folder path")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigurationError("out_dir", str(out), "a directory (this is a file)")
    out.mkdir(parents=True, exist_ok=True)
    return out


def _write_summary(summary: Mapping[str, Any], path: Path, written: dict[str, Path]) -> None:
    """Write ``summary`` as JSON at ``path``, listing the figures ``written``; add it to them."""
    data = dict(summary) | {"figures": sorted(written)}
    _write_atomic(path, (json.dumps(data, indent=1, allow_nan=False) + "\n").encode())
    written[path.name] = path


def write_uncertain_report(
    summary: Mapping[str, Any], out_dir: str | os.PathLike[str], *, html: bool = True
) -> dict[str, Path]:
    """Write ``uncertain.json``, the figures (PNG, SVG) and ``report.html`` into ``out_dir``.

    Returns:
        Name -> path of each file written.

    Raises:
        ConfigurationError: ``summary`` is not an uncertain study's summary, or ``out_dir`` a
            file.
    """
    figures = uncertain_figures(summary)
    out = _folder(out_dir)
    written, pngs = _save_figures(figures, out)
    _write_summary(summary, out / "uncertain.json", written)
    if html:
        path = out / "report.html"
        _write_atomic(path, uncertain_page(summary, pngs).encode("utf-8"))
        written[path.name] = path
    return written


def _mm(x: float | None) -> str:
    return "&mdash;" if x is None else f"{1000.0 * x:.2f}"


_CSS = """
body { font-family: system-ui, sans-serif; margin: 16px 24px; color: #222; max-width: 1100px; }
h1 { font-size: 1.35em; } h2 { font-size: 1.1em; margin-top: 1.4em; }
table.grid { border-collapse: collapse; font-size: 0.9em; }
table.grid td, table.grid th { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
table.grid th { background: #f3f3f3; }
table.grid td.l, table.grid th.l { text-align: left; }
.ok { color: #2ca02c; font-weight: bold; } .no { color: #d62728; font-weight: bold; }
.small { font-size: 0.85em; color: #555; }
img.fig { max-width: 100%; display: block; margin: 6px 0; }
"""


def uncertain_page(summary: Mapping[str, Any], pngs: Mapping[str, bytes] | None = None) -> str:
    """The uncertain study's page (HTML text): self-contained, no script; every text escaped.

    Args:
        summary: :meth:`packbot.uncertain_study.UncertainStudy.summary` (or ``uncertain.json``).
        pngs: The figures as PNG by stem (default: drawn here).
    """
    esc = html_lib.escape
    if pngs is None:
        pngs = {k: _png(f) for k, f in uncertain_figures(summary).items()}
    s, c, rec = summary["sample"], summary["counts"], summary["recovery"]
    tol_mm = 1000.0 * summary["tolerance_m"]
    p = rec["probability"]
    lo, hi = rec["interval_95"]
    if p is None:
        verdict = "no arm's reconfigured run finished"
    else:
        verdict = (
            f"the reconfigured run ends within {tol_mm:g} mm of the task on "
            f"<b>{rec['recovered']} of {rec['arms']}</b> arms: p = <b>{p:.2f}</b> (95 % Wilson "
            f"interval {lo:.2f} to {hi:.2f})"
        )
        if rec["possible_share"] is not None:
            verdict += f"; the studies judged recovery possible on {rec['possible_share']:.0%}"
    rows = [
        '<tr><th class="l">run</th><th>final task error 5 / 50 / 95 % [mm]</th>'
        "<th>RMS task error 50 % [mm]</th><th>peak torque ratio 5 / 50 / 95 %</th>"
        "<th>arms</th></tr>"
    ]
    for run in _RUNS:
        q = summary["quantiles"][run]
        e, r = q["final_task_error_m"], q["peak_torque_ratio"]
        ratio = " / ".join("&mdash;" if r[k] is None else f"{r[k]:.3f}" for k in ("5", "50", "95"))
        rows.append(
            f'<tr><td class="l">{esc(run)}</td>'
            f"<td>{_mm(e['5'])} / {_mm(e['50'])} / {_mm(e['95'])}</td>"
            f"<td>{_mm(q['rms_task_error_m']['50'])}</td><td>{ratio}</td>"
            f"<td>{e['arms']}</td></tr>"
        )
    quant = '<table class="grid">' + "".join(rows) + "</table>"
    arow = [
        '<tr><th>arm</th><th class="l">healthy</th><th class="l">failed</th>'
        '<th class="l">reconfigured</th><th class="l">recovery possible</th>'
        '<th class="l">recovered</th><th class="l">why not ok</th></tr>'
    ]
    for arm in summary["arms"]:
        rec_arm = arm["recovered"]
        rtext = (
            "&mdash;"
            if rec_arm is None
            else ('<span class="ok">yes</span>' if rec_arm else '<span class="no">no</span>')
        )
        why = "; ".join(f"{k}: {v}" for k, v in arm.get("reasons", {}).items())
        arow.append(
            f"<tr><td>{arm['index']}</td>"
            + "".join(f'<td class="l">{esc(str(arm["status"].get(r)))}</td>' for r in _RUNS)
            + f'<td class="l">{esc(str(arm["possible"]))}</td><td class="l">{rtext}</td>'
            f'<td class="l small">{esc(why)}</td></tr>'
        )
    arms = '<table class="grid">' + "".join(arow) + "</table>"
    figs = "".join(
        f'<img class="fig" alt="{esc(stem)}" '
        f'src="data:image/png;base64,{base64.b64encode(pngs[stem]).decode("ascii")}">'
        for stem in STUDY_FIGURES
        if stem in pngs
    )
    batch = summary.get("batch")
    batch_text = (
        ""
        if not batch
        else f" This call studied {batch['executed']} arms and read {batch['skipped']} back "
        "from the folder."
    )
    controller = summary.get("controller") or "the scenario's"
    body = f"""<h1>Failure study over the model's uncertainty: {esc(str(summary["scenario"]))}</h1>
<p>{s["arms"]} arms drawn within the parameter table's tolerances ({esc(str(s["method"]))}, seed
{s["seed"]}, {len(s["parameters"])} parameters); each arm's failure study (healthy, failed and
reconfigured runs of {summary["duration_s"]:g} s, controller {esc(str(controller))}); {c["ok"]}
arms with every run ok, {c["errors"]} errors.{batch_text}</p>
<p>Recovery: {verdict}.</p>
<h2>Quantiles over the arms</h2>{quant}
<h2>Distributions</h2>{figs}
<p class="small">Sensitivity: {esc(summary["sensitivity"]["method"])} between each sampled
parameter and the final task error, the largest |rho| first. Files: <code>uncertain.json</code>,
{", ".join(f"<code>{esc(s_)}.png</code>/<code>.svg</code>" for s_ in STUDY_FIGURES)}.</p>
<h2>Every arm</h2>{arms}
"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>packbot uncertain study: {esc(str(summary["scenario"]))}</title>
<style>{_CSS}</style>
</head>
<body>
{body}</body>
</html>
"""


# ---------------------------------------------------------------------------------- runs
def uncertain_run_figure(summary: Mapping[str, Any]) -> Figure:
    """The uncertain run's figure: final angles, where link 3 ends, the events, per arm.

    Raises:
        ConfigurationError: ``summary`` is not an uncertain run's summary.
    """
    import numpy as np
    from matplotlib.figure import Figure

    _check(summary, "link3_end_m", "an uncertain run's summary (UncertainRun.summary)")
    arms = [a for a in summary["arms"] if not a["error"]]
    joints = list(summary["final_q_rad"])
    fig = Figure(figsize=(11.0, 7.6), layout="constrained")
    grid = fig.add_gridspec(2, 3)
    ax = fig.add_subplot(grid[0, :])
    for i, j in enumerate(joints):
        x = [a["final_q_rad"][j] for a in arms]
        jitter = np.linspace(-0.18, 0.18, len(x)) if len(x) > 1 else np.zeros(len(x))
        ax.plot(i + jitter, x, "o", ms=4, color="#1f77b4", alpha=0.7)
        q = summary["final_q_rad"][j]
        if q["50"] is not None:
            ax.plot([i - 0.3, i + 0.3], [q["50"]] * 2, color="k", lw=1.5)
            ax.plot([i, i], [q["5"], q["95"]], color="k", lw=0.8)
    ax.set_xticks(range(len(joints)), joints, fontsize="small")
    ax.set_ylabel("final angle [rad]")
    ax.set_title("final joint angles per arm (dots), median (bar) and 5-95 % (line)")
    ax.grid(alpha=0.3)
    ends = np.array([a["link3_end_m"] for a in arms], dtype=float).reshape(-1, 3) * 1000.0
    for col, (i, k, title) in enumerate(((0, 2, "side view (x, z)"), (0, 1, "top view (x, y)"))):
        ax = fig.add_subplot(grid[1, col])
        ax.plot(ends[:, i], ends[:, k], "o", ms=5, color="#d62728", alpha=0.75)
        ax.set_xlabel(f"{'xyz'[i]} [mm]")
        ax.set_ylabel(f"{'xyz'[k]} [mm]")
        ax.set_title(f"where link 3 ends: {title}", fontsize="medium")
        ax.grid(alpha=0.3)
        ax.set_aspect("equal", adjustable="datalim")
    ax = fig.add_subplot(grid[1, 2])
    kinds = list(summary["events"])
    for i, kind in enumerate(kinds):
        x = [a["events"].get(kind, 0) for a in arms]
        jitter = np.linspace(-0.18, 0.18, len(x)) if len(x) > 1 else np.zeros(len(x))
        ax.plot(i + jitter, x, "o", ms=4, color="#2ca02c", alpha=0.7)
    ax.set_xticks(range(len(kinds)), kinds, fontsize="small", rotation=30, ha="right")
    ax.set_ylabel("events per arm")
    ax.set_title("events per arm", fontsize="medium")
    ax.grid(alpha=0.3)
    fig.suptitle(
        f"{summary['scenario']}: {summary['duration_s']:g} s on {len(arms)} of "
        f"{summary['sample']['arms']} arms drawn within the tolerances"
    )
    return fig


def write_uncertain_run(
    summary: Mapping[str, Any], out_dir: str | os.PathLike[str]
) -> dict[str, Path]:
    """Write ``uncertain-run.json`` and the figure (PNG, SVG) into ``out_dir``.

    Returns:
        Name -> path of each file written.

    Raises:
        ConfigurationError: ``summary`` is not an uncertain run's summary, or ``out_dir`` a
            file.
    """
    fig = uncertain_run_figure(summary)
    out = _folder(out_dir)
    written, _ = _save_figures({RUN_FIGURE: fig}, out)
    _write_summary(summary, out / "uncertain-run.json", written)
    return written
