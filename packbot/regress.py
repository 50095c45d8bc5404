"""Regression: compare a batch's results with committed golden results, quantity by quantity.

The golden results of a matrix live in ``<golden>/<matrix name>/``: ``results.json`` (the
deterministic part of each run's record, :meth:`packbot.batch.RunRecord.quantities`, by run id)
and ``summary.csv`` (the same as a table, for reading). :func:`compare` checks, for every run:

- its status (``"ok"``/``"failed"``), exactly;
- the final pose, joint by joint: ``|q_new - q_golden| <= tolerances.q`` [rad];
- the rest time: both None, or ``|dt| <= tolerances.time`` [s];
- the event count of each kind, exactly, and the event times: same kinds in the same order,
  ``|t_new - t_golden| <= tolerances.time`` [s] for each;
- the minimum signed distance: ``|d_new - d_golden| <= tolerances.distance`` [m] (inf == inf);
- the energy change: ``|dE| <= tolerances.energy`` [J];

and lists the runs that are in one set and not the other. Each tolerance is absolute; the
defaults sit far above the last-bit noise between machines (the same machine gives bit-identical
results) and far below any change of behaviour worth knowing about.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from packbot.batch import (
    RECORD_FORMAT,
    BatchReport,
    Runner,
    RunRecord,
    atomic_write,
    csv_text,
    run_batch,
    scenario_runner,
    summary_rows,
)
from packbot.errors import ConfigurationError, ResourceNotFound, UnknownNameError
from packbot.matrix import Matrix, Run

__all__ = [
    "GOLDEN_FORMAT",
    "Drift",
    "RegressionResult",
    "Tolerances",
    "compare",
    "default_golden_dir",
    "format_drifts",
    "golden_matrices",
    "read_golden",
    "run_regression",
    "write_golden",
]

#: Format tag of a golden results file.
GOLDEN_FORMAT = "packbot-golden/1"


@dataclass(frozen=True, kw_only=True)
class Tolerances:
    """Absolute tolerances of :func:`compare`.

    Attributes:
        q: Final joint positions [rad].
        time: Rest time and event times [s].
        distance: Minimum signed distance [m].
        energy: Energy change [J].
    """

    q: float = 1e-6
    time: float = 1e-6
    distance: float = 1e-7
    energy: float = 1e-6

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad tolerance."""
        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigurationError(f"tolerances.{f.name}", v, "a finite number >= 0")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> Tolerances:
        """From a matrix file's ``[tolerances]`` table (missing names keep their default).

        Raises:
            UnknownNameError: An unknown tolerance name.
            ConfigurationError: A bad value.
        """
        names = [f.name for f in fields(cls)]
        for key in data:
            if key not in names:
                raise UnknownNameError("tolerance", key, names)
        tol = cls(**{k: float(v) for k, v in data.items()})
        tol.validate()
        return tol


@dataclass(frozen=True)
class Drift:
    """One quantity of one run that moved beyond its tolerance.

    Attributes:
        run: The run's id.
        quantity: What moved (``"q.shoulder"``, ``"rest_time"``, ``"events.impact"``, ...).
        golden: Its golden value (as text).
        new: Its new value (as text).
        diff: ``|new - golden|`` for a number, else NaN.
        tolerance: The tolerance it exceeded (NaN: must be equal).
    """

    run: str
    quantity: str
    golden: str
    new: str
    diff: float = math.nan
    tolerance: float = math.nan


def compare(
    golden: Mapping[str, Mapping[str, Any]],
    new: Mapping[str, RunRecord],
    tolerances: Tolerances | None = None,
) -> list[Drift]:
    """The quantities that moved between golden and new results.

    Args:
        golden: Run id -> golden quantities (:func:`read_golden`).
        new: Run id -> new record.
        tolerances: Absolute tolerances (default: :class:`Tolerances`).

    Returns:
        The drifts, by run (golden order, then the new runs), empty when everything matches.
    """
    tol = Tolerances() if tolerances is None else tolerances
    tol.validate()
    drifts: list[Drift] = []
    for rid, gdata in golden.items():
        if rid not in new:
            drifts.append(Drift(rid, "run", "present", "missing"))
            continue
        g = RunRecord.from_json({"format": RECORD_FORMAT, "index": 0, **gdata, "id": rid})
        drifts += _compare_run(g, new[rid], tol)
    drifts += [Drift(rid, "run", "missing", "present") for rid in new if rid not in golden]
    return drifts


def _compare_run(g: RunRecord, n: RunRecord, tol: Tolerances) -> list[Drift]:
    rid = g.id
    out: list[Drift] = []
    if g.status != n.status:
        return [Drift(rid, "status", g.status, f"{n.status} {n.error}".strip())]
    if g.status != "ok":
        return out
    gq = dict(zip(g.joint_names, g.final_q, strict=True))
    nq = dict(zip(n.joint_names, n.final_q, strict=True))
    if list(gq) != list(nq):
        out.append(Drift(rid, "joint_names", " ".join(gq), " ".join(nq)))
    for joint in (j for j in gq if j in nq):
        out += _number(rid, f"q.{joint}", gq[joint], nq[joint], tol.q)
    if (g.rest_time is None) != (n.rest_time is None):
        out.append(Drift(rid, "rest_time", _fmt(g.rest_time), _fmt(n.rest_time)))
    elif g.rest_time is not None and n.rest_time is not None:
        out += _number(rid, "rest_time", g.rest_time, n.rest_time, tol.time)
    gk, nk = Counter(g.event_kinds), Counter(n.event_kinds)
    for kind in sorted(gk.keys() | nk.keys()):
        if gk[kind] != nk[kind]:
            out.append(Drift(rid, f"events.{kind}", str(gk[kind]), str(nk[kind])))
    if gk == nk and g.event_kinds != n.event_kinds:
        k = next(
            i for i, (a, b) in enumerate(zip(g.event_kinds, n.event_kinds, strict=True)) if a != b
        )
        out.append(Drift(rid, f"event[{k}].kind", g.event_kinds[k], n.event_kinds[k]))
    elif g.event_kinds == n.event_kinds and g.event_times:
        diffs = [abs(a - b) for a, b in zip(g.event_times, n.event_times, strict=True)]
        k = max(range(len(diffs)), key=diffs.__getitem__)
        if not diffs[k] <= tol.time:
            out.append(
                Drift(
                    rid,
                    f"event[{k}].t ({g.event_kinds[k]})",
                    _fmt(g.event_times[k]),
                    _fmt(n.event_times[k]),
                    diffs[k],
                    tol.time,
                )
            )
    out += _number(rid, "min_distance", g.min_distance, n.min_distance, tol.distance)
    out += _number(rid, "energy_change", g.energy_change, n.energy_change, tol.energy)
    return out


def _number(rid: str, name: str, a: float, b: float, tol: float) -> list[Drift]:
    if a == b or (math.isnan(a) and math.isnan(b)):
        return []
    diff = abs(a - b)
    if diff <= tol:  # NaN (inf - inf, nan) compares False: a drift
        return []
    return [Drift(rid, name, _fmt(a), _fmt(b), diff, tol)]


def _fmt(x: float | None) -> str:
    return "None" if x is None else f"{x:.10g}"


def format_drifts(drifts: Sequence[Drift], n_runs: int) -> str:
    """A table of the drifts (one line each) and a last line counting them."""
    if not drifts:
        return f"{n_runs} runs compared: no drift"
    head = ("run", "quantity", "golden", "new", "|diff|", "tolerance")
    rows = [
        (
            d.run,
            d.quantity,
            d.golden,
            d.new,
            "" if math.isnan(d.diff) else f"{d.diff:.3g}",
            "exact" if math.isnan(d.tolerance) else f"{d.tolerance:.3g}",
        )
        for d in drifts
    ]
    widths = [max(len(r[i]) for r in (head, *rows)) for i in range(len(head))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
        for r in (head, *rows)
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    moved = len({d.run for d in drifts})
    lines.append(f"{n_runs} runs compared: {len(drifts)} quantities moved in {moved} runs")
    return "\n".join(lines)


def _golden_json(data: Mapping[str, Any]) -> str:
    """JSON with one line per quantity of each run (readable diffs, a third of indent=1's size)."""

    def dump(x: Any) -> str:
        return json.dumps(x, allow_nan=False)

    lines = ["{"]
    for key, value in data.items():
        if key != "runs":
            lines.append(f" {dump(key)}: {dump(value)},")
    lines.append(' "runs": {')
    for k, (rid, run) in enumerate(data["runs"].items()):
        lines.append(f"  {dump(rid)}: {{")
        items = [f"   {dump(q)}: {dump(v)}" for q, v in run.items()]
        lines.append(",\n".join(items))
        lines.append("  }" + ("," if k < len(data["runs"]) - 1 else ""))
    lines.append(" }")
    lines.append("}")
    return "\n".join(lines) + "\n"


def read_golden(folder: str | Path) -> tuple[str, dict[str, dict[str, Any]]]:
    """Read ``folder/results.json``.

    Returns:
        The matrix name and run id -> golden quantities.

    Raises:
        ResourceNotFound: No golden results there.
        ConfigurationError: Not a golden results file.
    """
    path = Path(folder) / "results.json"
    if not path.is_file():
        raise ResourceNotFound(path, "create the golden results with `packbot regress --update`")
    data = json.loads(path.read_text())
    if data.get("format") != GOLDEN_FORMAT:
        raise ConfigurationError(f"{path}: format", data.get("format"), repr(GOLDEN_FORMAT))
    return str(data["matrix"]), dict(data["runs"])


def write_golden(
    folder: str | Path,
    matrix_name: str,
    runs: Sequence[Run],
    records: Mapping[str, RunRecord],
    tolerances: Tolerances | None = None,
) -> list[Path]:
    """Write ``results.json`` and ``summary.csv`` for the runs that have a record.

    Returns:
        The files written.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    kept = [r for r in runs if r.id in records]
    data = {
        "format": GOLDEN_FORMAT,
        "matrix": matrix_name,
        "tolerances": asdict(tolerances or Tolerances()),
        "runs": {r.id: records[r.id].quantities() for r in kept},
    }
    results = out / "results.json"
    atomic_write(results, _golden_json(data).encode())
    rows = summary_rows(kept, records)
    columns = [c for c in rows[0] if c not in ("wall_time", "worker")] if rows else ["id"]
    summary = out / "summary.csv"
    atomic_write(summary, csv_text(rows, columns).encode())
    return [results, summary]


@dataclass(kw_only=True)
class RegressionResult:
    """What :func:`run_regression` found.

    Attributes:
        matrix: The matrix's name.
        drifts: What moved (against the golden results as they were before any update).
        batch: The batch that made the new results.
        golden_dir: The matrix's golden folder.
        had_golden: Whether golden results existed.
        written: The golden files written (``update=True``), else empty.
    """

    matrix: str
    drifts: list[Drift]
    batch: BatchReport
    golden_dir: Path
    had_golden: bool
    written: list[Path] = field(default_factory=list)

    def text(self) -> str:
        """The report printed by ``packbot regress``."""
        head = f"{self.matrix}: {len(self.batch.runs)} runs, golden {self.golden_dir}"
        if not self.had_golden:
            body = "no golden results before"
        else:
            body = format_drifts(self.drifts, len(self.batch.runs))
        lines = [head, body]
        if self.written:
            lines.append("updated: " + ", ".join(str(p) for p in self.written))
        return "\n".join(lines)


def default_golden_dir() -> Path:
    """The shipped golden results folder, ``sims/golden/``."""
    from packbot.resources import data_dir

    return data_dir("sims") / "golden"


def golden_matrices(golden_root: str | Path) -> list[str]:
    """Names of the matrices that have golden results in ``golden_root``."""
    root = Path(golden_root)
    return sorted(p.parent.name for p in root.glob("*/results.json"))


def run_regression(
    matrix: Matrix,
    golden_root: str | Path,
    *,
    runs: Sequence[Run] | None = None,
    out_dir: str | Path | None = None,
    update: bool = False,
    workers: int | None = None,
    scheduler: Any = None,
    runner: Runner = scenario_runner,
    progress: Callable[[int, int, int], None] | None = None,
) -> RegressionResult:
    """Run a matrix and compare its results with its golden results.

    Args:
        matrix: The matrix.
        golden_root: The golden folder; the matrix's results are in ``<golden_root>/<name>/``.
        runs: The matrix's runs (default: ``matrix.runs()``).
        out_dir: Where the batch writes (resumed if it exists); None: a temporary folder,
            removed afterwards (so no stale result is ever compared).
        update: Rewrite the golden files with the new results (on purpose).
        workers: Local worker processes (see :func:`packbot.batch.run_batch`).
        scheduler: A Dask scheduler (see :func:`packbot.batch.run_batch`).
        runner: The run function.
        progress: Progress callback (see :func:`packbot.batch.run_batch`).

    Raises:
        ResourceNotFound: No golden results, and not ``update``.
    """
    tol = Tolerances.from_mapping(matrix.tolerances)
    folder = Path(golden_root) / matrix.name
    golden: dict[str, dict[str, Any]] | None = None
    if (folder / "results.json").is_file():
        golden = read_golden(folder)[1]
    elif not update:
        read_golden(folder)  # raises ResourceNotFound with the hint
    with tempfile.TemporaryDirectory(prefix=f"packbot-regress-{matrix.name}-") as tmp:
        out = Path(tmp) if out_dir is None else Path(out_dir)
        batch = run_batch(
            matrix,
            out,
            runs=runs,
            workers=workers,
            scheduler=scheduler,
            runner=runner,
            progress=progress,
        )
    records = {r.id: batch.records[r.id] for r in batch.runs if r.id in batch.records}
    drifts = [] if golden is None else compare(golden, records, tol)
    result = RegressionResult(
        matrix=matrix.name,
        drifts=drifts,
        batch=batch,
        golden_dir=folder,
        had_golden=golden is not None,
    )
    if update:
        result.written = write_golden(folder, matrix.name, batch.runs, records, tol)
    return result
