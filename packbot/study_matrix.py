"""Failure studies over a matrix: one study per cell, run by the batch machinery, one summary.

A *study matrix* is a matrix file (:mod:`packbot.matrix`) with a ``[study]`` table. Its base
scenario has ``[[failures]]`` (or ``[set]`` creates one) and its axes vary the failure: the
failed joint, the failure time, the kind, ... Each cell (a run of the matrix) is one failure
study (:func:`packbot.study`: healthy, failed and reconfigured runs)::

    name = "study-frozen-elbows"
    description = "elbow1 or elbow2 frozen early or late in a computed-torque reach"
    base = "frozen_elbow_reach"        # a scenario with [[failures]]

    [set]
    duration = 2.5                     # [s], each of the three runs of each cell

    [axes]                             # they vary one failure: failures.<i>.<field>
    "failures.0.joint" = ["elbow1", "elbow2"]
    "failures.0.t" = [0.5, 1.5]        # [s]

    [study]                            # what makes it a study matrix (all keys optional)
    tolerance = 0.01                   # [m] recovery tolerance on the task error (0.01)
    workspace_samples = 800            # reach test's workspace samples (2000)
    seed = 0                           # the workspace sampler's seed (0)
    html = true                        # each cell's report.html (true)

Other axes (a contact mode, an initial pose, ...) are allowed: the summary's heat maps put the
cells in bins by failed joint and failure time and aggregate over the rest (a recovery *rate*).

:func:`run_study_matrix` runs the cells with :func:`packbot.batch.run_batch` (this process, a
local pool or Dask; resumable: records, checksums, the folder's lock) and writes::

    DIR/<cell id>/study.json, report.html, study_*.png/svg   each cell's study
    DIR/study-matrix.json        the matrix's summary (cells, bins, counts)
    DIR/study_heat_map.png/svg   recovery rate and final task errors by joint and failure time
    DIR/report.html              the summary page (offline), linking each cell's report
    DIR/runs/, matrix.json, summary.csv, ...   the batch's records (packbot.batch)
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
import os
import statistics
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from packbot.batch import BatchReport, RunFiles, check_runs, run_batch
from packbot.errors import ConfigurationError, PackbotError, SimulationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.matrix import Matrix, Run, load_matrix
from packbot.study_matrix_format import SUMMARY_FORMAT
from packbot.validation import MAX_CONFIG_SAMPLES, MAX_STUDY_CELLS, at_most, integer, is_number

__all__ = [
    "FAILURE_FIELDS",
    "STUDY_KEYS",
    "SUMMARY_FORMAT",
    "CellTimeout",
    "StudyMatrix",
    "StudyMatrixReport",
    "StudyOptions",
    "load_study_matrix",
    "run_study_matrix",
    "study_cell",
    "study_matrix_summary",
]

log = logging.getLogger(__name__)

#: The keys of a study matrix's ``[study]`` table.
STUDY_KEYS: tuple[str, ...] = ("tolerance", "workspace_samples", "seed", "html")
#: The fields of a failure an axis may vary (``failures.<i>.<field>``).
FAILURE_FIELDS: tuple[str, ...] = ("joint", "kind", "t", "scale", "torque", "threshold")
#: The run names whose metrics a cell's record and the summary keep.
_RUNS = ("healthy", "failed", "reconfigured")


class CellTimeout(PackbotError):
    """A study cell exceeded its wall-time limit (``timeout``); the cell is recorded failed."""


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class StudyOptions:
    """The ``[study]`` table: how each cell is studied (:func:`packbot.study`'s arguments).

    Attributes:
        tolerance: Recovery tolerance on the task error [m].
        workspace_samples: Samples of the frozen arm's workspace seeding the reach test.
        seed: Seed of the workspace sampler.
        html: Whether each cell writes its ``report.html`` (about 3 MB each).
    """

    tolerance: float = 0.01
    workspace_samples: int = 2000
    seed: int = 0
    html: bool = True

    def __post_init__(self) -> None:
        tol = self.tolerance
        if not (is_number(tol) and math.isfinite(tol) and tol > 0):
            raise ConfigurationError("study.tolerance", tol, "a finite distance > 0 [m]")
        integer("study.workspace_samples", self.workspace_samples, low=100, high=MAX_CONFIG_SAMPLES)
        integer("study.seed", self.seed, low=0, what="an integer seed >= 0")
        if not isinstance(self.html, bool):
            raise ConfigurationError("study.html", self.html, "true or false")
        object.__setattr__(self, "tolerance", float(tol))

    @classmethod
    @checked_arguments
    def from_mapping(cls, table: Mapping[str, Any]) -> StudyOptions:
        """Read a ``[study]`` table.

        Raises:
            UnknownNameError: An unknown key (the valid ones: :data:`STUDY_KEYS`).
            ConfigurationError: A bad value (names ``study.<key>``).
        """
        for key in table:
            if key not in STUDY_KEYS:
                raise UnknownNameError("study key", key, STUDY_KEYS)
        return cls(**dict(table))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, with the unit in the tolerance's name."""
        return {
            "tolerance_m": self.tolerance,
            "workspace_samples": self.workspace_samples,
            "seed": self.seed,
            "html": self.html,
        }


@checked_arguments
@dataclass(kw_only=True)
class StudyMatrix:
    """A study matrix: the matrix, its study options and the failure its axes vary.

    Attributes:
        matrix: The matrix (its ``study`` table is not None).
        options: The ``[study]`` table, read.
        failure_index: The index ``i`` of the failure the axes vary (``failures.<i>``).
    """

    matrix: Matrix
    options: StudyOptions
    failure_index: int = 0

    @property
    def name(self) -> str:
        """The matrix's name."""
        return self.matrix.name

    def runs(self) -> list[Run]:
        """The cells, in matrix order (:meth:`packbot.matrix.Matrix.runs`)."""
        return self.matrix.runs()

    @classmethod
    @checked_arguments
    def from_matrix(cls, matrix: Matrix) -> StudyMatrix:
        """Check a matrix as a study matrix.

        Raises:
            ConfigurationError: No ``[study]`` table, a bad value in it, or axes that do not
                vary a failure, or vary more than one (names the field).
            UnknownNameError: An unknown ``[study]`` key or failure field.
        """
        if not isinstance(matrix, Matrix):
            raise ConfigurationError("matrix", matrix, "a packbot.matrix.Matrix")
        if matrix.study is None:
            raise ConfigurationError(
                "study",
                None,
                f"a [study] table (matrix {matrix.name!r} has none: it is a matrix of "
                "simulations, for `packbot batch`; add [study] to study its failures)",
            )
        options = StudyOptions.from_mapping(matrix.study)
        at_most("axes", matrix.axes, matrix.run_count(), MAX_STUDY_CELLS, "cells")
        keys = [*matrix.axes, *(k for t in matrix.include for k in t)]
        indices: dict[int, list[str]] = {}
        for key in keys:
            parts = key.split(".")
            if parts[0] != "failures":
                continue
            if len(parts) != 3 or not parts[1].isdigit():
                raise ConfigurationError(
                    f"axes.{key}", key, "failures.<index>.<field>, e.g. failures.0.joint"
                )
            if parts[2] not in FAILURE_FIELDS:
                raise UnknownNameError(f"failure field (in axes.{key})", parts[2], FAILURE_FIELDS)
            indices.setdefault(int(parts[1]), []).append(key)
        if not indices:
            raise ConfigurationError(
                "axes",
                list(matrix.axes),
                "axes (or [[include]] tables) that vary the failure: failures.<i>.joint, "
                "failures.<i>.t, failures.<i>.kind, ...",
            )
        if len(indices) > 1:
            raise ConfigurationError(
                "axes",
                sorted(k for ks in indices.values() for k in ks),
                "axes that vary one failure (one index i in failures.<i>.<field>): the heat "
                "map's rows are that failure's joint, its columns its time",
            )
        return cls(matrix=matrix, options=options, failure_index=next(iter(indices)))

    def failure_of(self, run: Run) -> dict[str, Any]:
        """The varied failure of a cell, as resolved: ``joint``, ``kind``, ``t`` [s]."""
        failures = run.scenario.get("failures")
        i = self.failure_index
        if (
            not isinstance(failures, list)
            or len(failures) <= i
            or not isinstance(failures[i], dict)
        ):
            raise ConfigurationError(
                f"run {run.id}: failures.{i}",
                failures,
                f"a scenario whose [[failures]] has an item {i} (the failure the axes vary)",
            )
        f = failures[i]
        t = f.get("t", 0.0)
        return {"joint": f.get("joint"), "kind": f.get("kind"), "t": float(t)}

    def check(self, runs: Sequence[Run]) -> None:
        """Check every cell before any runs (:func:`packbot.batch.check_runs`, the failure).

        Raises:
            ConfigurationError: A cell's scenario is bad, lacks the varied failure or ends
                before its first failure (names the cell and the field).
        """
        from packbot.study import check_failure_within

        check_runs(runs)
        for run in runs:
            self.failure_of(run)
            check_failure_within(run.build_scenario(), None, f"run {run.id}: duration")


@checked_arguments
def load_study_matrix(name_or_path: str | os.PathLike[str]) -> StudyMatrix:
    """Read and check a study matrix (a name in ``sims/matrices/`` or a path).

    Raises:
        UnknownNameError: No such matrix, an unknown key.
        ConfigurationError: A bad value, no ``[study]`` table, axes not varying one failure.
    """
    return StudyMatrix.from_matrix(load_matrix(Path(name_or_path)))


# ---------------------------------------------------------------------------------- a cell
#: The healthy runs of the cells this process studied last, by :func:`_healthy_key`: a cell
#: whose scenario differs from an earlier one's only in its failures (the healthy run has
#: none) takes that healthy run (``study(healthy=...)``) instead of simulating it again: a
#: matrix over the failed joint, its time and its kind simulates one healthy run per process,
#: not one per cell. The same run either way (a simulation is deterministic, and each run
#: builds its own robot and collision world).
_HEALTHY_RUNS: dict[str, Any] = {}
#: How many of them a process keeps (each holds one run's samples).
_HEALTHY_KEPT = 4


def _healthy_key(run: Run, controller: Any) -> str:
    """The key of a cell's healthy run in :data:`_HEALTHY_RUNS`.

    What the healthy run depends on: the cell's scenario but its failures, its folder (the
    arm's relative paths), the controller given in place of the scenario's.
    """
    from packbot.control.user_code import describe_spec
    from packbot.matrix import digest

    scenario = {k: v for k, v in run.scenario.items() if k != "failures"}
    spec = None if controller is None else describe_spec(controller)
    return digest({"scenario": scenario, "folder": run.source_path, "controller": spec})


@checked_arguments
def study_cell(
    run: Run,
    progress: Callable[[float], None],
    *,
    options: StudyOptions,
    controller: Any = None,
    recovery: Any = "builtin",
) -> tuple[dict[str, Any], RunFiles]:
    """The batch's run function of a study cell (bound with ``functools.partial``).

    ``functools.partial(study_cell, options=..., controller=..., recovery=...)`` is a
    :data:`packbot.batch.Runner`; ``controller`` and ``recovery`` are :func:`packbot.study`'s
    (import paths or picklable classes: they travel to the worker processes).

    Studies the cell's scenario (:func:`packbot.study`, a fresh robot: the scenario's arm),
    writes its study (:func:`packbot.viz.study_report.write_study`) into a temporary folder
    and returns its
    files as ``"<cell id>/<name>"`` (the batch writes them into the cell's folder) and the
    cell's headline metrics (the record's ``metrics``: the failure, the verdict, each run's
    status and final task error [m], the reconfigured run's detection and recovery times [s]).

    Raises:
        CellTimeout: The wall-time limit was exceeded (``progress`` raised).
    """
    from packbot.scenario import scenario_robot
    from packbot.study import study
    from packbot.viz.study_report import write_study

    where = {"step": "setting up"}

    def step(t: float) -> None:
        try:
            progress(t)
        except SimulationError as exc:  # the batch's wall-time limit
            why = str(exc).split(": ", 1)[-1]
            at = f" at t = {t:.4g} s" if t > 0 else ""
            raise CellTimeout(f"{why} ({where['step']}{at})") from None

    def say(text: str) -> None:
        where["step"] = text.split(": ", 1)[-1]
        step(0.0)

    scenario = run.build_scenario()
    key = _healthy_key(run, controller)
    result = study(
        scenario,
        robot=scenario_robot(scenario),
        tolerance=options.tolerance,
        workspace_samples=options.workspace_samples,
        seed=options.seed,
        controller=controller,
        recovery=recovery,
        progress=say,
        step=step,
        healthy=_HEALTHY_RUNS.get(key),
    )
    _HEALTHY_RUNS[key] = result.healthy
    while len(_HEALTHY_RUNS) > _HEALTHY_KEPT:
        del _HEALTHY_RUNS[next(iter(_HEALTHY_RUNS))]
    with tempfile.TemporaryDirectory(prefix="packbot-study-") as tmp:
        written = write_study(result, tmp, html=options.html)
        files = {
            name: (f"{run.id}/{path.name}", path.read_bytes())
            for name, path in sorted(written.items())
        }
    summary = result.summary()
    metrics: dict[str, Any] = {"recovery_possible": summary["recovery"]["possible"]}
    decision = summary.get("reconfiguration") or {}
    metrics["reconfiguration_applied"] = decision.get("applied")
    for name in _RUNS:
        entry = summary["runs"][name]
        metrics[f"{name}_status"] = entry["status"]
        if name != "healthy":
            metrics[f"{name}_final_task_error_m"] = entry.get("final_task_error_m")
            metrics[f"{name}_recovered"] = entry.get("recovered")
    reconf = summary["runs"]["reconfigured"]
    for key in ("detect_time_s", "recover_time_s"):
        metrics[f"reconfigured_{key}"] = reconf.get(key)
    return {"metrics": metrics, "t_end": float(result.duration_s)}, files


# ---------------------------------------------------------------------------------- the matrix
@checked_arguments
@dataclass(kw_only=True)
class StudyMatrixReport:
    """What :func:`run_study_matrix` did.

    Attributes:
        study_matrix: The study matrix.
        batch: The batch's report (:class:`packbot.batch.BatchReport`: records, executed,
            skipped, rerun, failed, missing).
        summary: The content of ``study-matrix.json`` (:func:`study_matrix_summary`).
        files: Name -> path of the summary's files (``study-matrix.json``, the heat maps,
            ``report.html``).
    """

    study_matrix: StudyMatrix
    batch: BatchReport
    summary: dict[str, Any]
    files: dict[str, Path] = field(default_factory=dict)

    def describe(self) -> str:
        """A few lines for the command line: the batch's counts, the recoveries, the files."""
        c = self.summary["counts"]
        lines = [self.batch.describe()]
        lines.append(
            f"{c['studied']} studies: recovery possible in {c['recovery_possible']}, "
            f"the reconfigured run ends within {self.summary['study']['tolerance_m'] * 1000:g} mm "
            f"of the task in {c['recovered']}"
        )
        if "report.html" in self.files:
            lines.append(f"report: {self.files['report.html']}")
        return "\n".join(lines)


@checked_arguments
def run_study_matrix(
    matrix: StudyMatrix | Matrix | str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    scheduler: Any = None,
    timeout: float | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    controller: Any = None,
    recovery: Any = "builtin",
) -> StudyMatrixReport:
    """Study every cell of a study matrix through the batch machinery; write the summary.

    Args:
        matrix: A :class:`StudyMatrix`, a :class:`packbot.matrix.Matrix` with a ``[study]``
            table, or the name or path of its file.
        out_dir: Output folder (created; an existing one is resumed: the cells whose record
            and files verify are not studied again).
        workers: Local worker processes (default: the CPUs; 0: one after the other in this
            process); with ``scheduler="local"``, Dask's workers.
        scheduler: None (local processes), a Dask scheduler's address, ``"local"`` or a
            ``distributed.Client`` (as :func:`packbot.batch.run_batch`).
        timeout: Wall-time limit of each cell [s] (its three runs), or None.
        progress: Called as ``progress(done, failed, total)`` (cells).
        controller: Every cell's controller instead of the scenario's (:func:`packbot.study`):
            an import path ``"module:Name"`` or a class or factory defined at a module's top
            level. It must reach the worker processes: a lambda or a function defined inside
            another does not pickle and is refused.
        recovery: Every cell's recovery strategy (:func:`packbot.study`), likewise.

    Returns:
        The report; a cell that raised is recorded failed (the summary lists it), not raised.

    Raises:
        ConfigurationError: A bad argument or matrix, a cell whose scenario is bad (before
            anything runs), an ``out_dir`` holding another matrix's runs.
        BatchLockedError: Another batch runs in ``out_dir``.
        KeyboardInterrupt: Ctrl-C; the finished cells are kept (rerun to finish).
    """
    if isinstance(matrix, StudyMatrix):
        sm = matrix
    elif isinstance(matrix, Matrix):
        sm = StudyMatrix.from_matrix(matrix)
    elif isinstance(matrix, (str, os.PathLike)):
        sm = load_study_matrix(matrix)
    else:
        raise ConfigurationError(
            "matrix", matrix, "a StudyMatrix, a Matrix with [study], or a matrix name or path"
        )
    from packbot.control.user_code import (
        check_picklable,
        controller_factory,
        describe_spec,
        strategy_factory,
    )

    batch_matrix = sm.matrix
    if controller is not None or recovery != "builtin":
        if controller is not None:
            controller_factory(controller)
            check_picklable(controller, "controller")
        strategy_factory(recovery)
        check_picklable(recovery, "recovery")
        # part of the batch's identity: a folder studied with another controller is refused
        assert batch_matrix.study is not None
        batch_matrix = dataclasses.replace(
            batch_matrix,
            study={
                **batch_matrix.study,
                "controller": None if controller is None else describe_spec(controller),
                "recovery": describe_spec(recovery),
            },
        )
    runs = sm.runs()
    sm.check(runs)
    batch = run_batch(
        batch_matrix,
        Path(out_dir) if isinstance(out_dir, os.PathLike) else out_dir,
        runs=runs,
        workers=workers,
        scheduler=scheduler,
        runner=functools.partial(
            study_cell, options=sm.options, controller=controller, recovery=recovery
        ),
        timeout=timeout,
        progress=progress,
    )
    summary = study_matrix_summary(sm, batch.out_dir, runs, batch)
    summary["study"]["controller"] = None if controller is None else describe_spec(controller)
    summary["study"]["recovery"] = describe_spec(recovery)
    from packbot.viz.study_matrix_report import write_matrix_report

    files = write_matrix_report(summary, batch.out_dir)
    return StudyMatrixReport(study_matrix=sm, batch=batch, summary=summary, files=files)


def _median(values: Sequence[float | None]) -> float | None:
    got = [float(v) for v in values if v is not None]
    return statistics.median(got) if got else None


@checked_arguments
def study_matrix_summary(
    sm: StudyMatrix,
    out_dir: str | os.PathLike[str],
    runs: Sequence[Run],
    batch: BatchReport,
) -> dict[str, Any]:
    """The matrix's summary (``study-matrix.json``), from each finished cell's ``study.json``.

    Keys: ``format``; ``matrix`` (name, description, base, SHA-256); ``study`` (the options);
    ``failure`` (``"failures.<i>"``, the failure the axes vary); ``axes``; ``durations_s``
    (the cells' simulated times [s]); ``tolerance_m``;
    ``counts`` (cells, ``ok``, ``failed``, ``missing``, ``studied``, ``recovery_possible``,
    ``recovered``); ``cells`` (one per cell in matrix order: id, params, the failure's
    ``joint``, ``kind`` and ``failure_time_s``, status, error, its files, ``recovery_possible``
    and ``recovery_reasons``, ``recovered`` (the reconfigured run ends within the tolerance),
    ``runs`` -> name -> status, ``final_task_error_m``, ``rms_task_error_m``, and the
    reconfigured run's ``detect_time_s`` and ``recover_time_s``); ``heat_map``: ``joints``
    (rows, in order of appearance) and ``failure_times_s`` (columns, ascending), and per bin
    (rows x columns, None where no cell studied): ``cells`` (ids), ``studied``, ``recovered``,
    ``recovery_rate`` (recovered / studied), ``recovery_possible``, and the medians of the
    reconfigured and failed runs' final task errors [m] over the bin's studies.
    """
    out = Path(out_dir)
    tol = sm.options.tolerance
    cells: list[dict[str, Any]] = []
    for run in runs:
        f = sm.failure_of(run)
        rec = batch.records.get(run.id)
        status = "missing" if rec is None else rec.status
        cell: dict[str, Any] = {
            "id": run.id,
            "index": run.index,
            "params": run.params,
            "joint": f["joint"],
            "kind": f["kind"],
            "failure_time_s": f["t"],
            "status": status,
            "error": "" if rec is None else rec.error,
            "wall_time_s": None if rec is None else rec.wall_time,
            "study_json": None,
            "report": None,
            "recovery_possible": None,
            "recovery_reasons": [],
            "duration_s": None,
            "recovered": None,
            "runs": {},
        }
        if rec is not None and rec.status == "ok":
            files = set(rec.files.values())
            path = f"{run.id}/study.json"
            data = json.loads((out / path).read_text(encoding="utf-8"))
            cell["study_json"] = path
            cell["duration_s"] = data["duration_s"]
            if f"{run.id}/report.html" in files:
                cell["report"] = f"{run.id}/report.html"
            cell["recovery_possible"] = data["recovery"]["possible"]
            cell["recovery_reasons"] = list(data["recovery"]["reasons"])
            for name in _RUNS:
                entry = data["runs"][name]
                cell["runs"][name] = {
                    "status": entry["status"],
                    "reason": entry["reason"],
                    "final_task_error_m": entry.get("final_task_error_m"),
                    "rms_task_error_m": entry.get("rms_task_error_m"),
                    "recovered": entry.get("recovered"),
                }
            cell["reconfiguration"] = data.get("reconfiguration")
            reconf = data["runs"]["reconfigured"]
            cell["recovered"] = bool(reconf.get("recovered", False))
            cell["detect_time_s"] = reconf.get("detect_time_s")
            cell["recover_time_s"] = reconf.get("recover_time_s")
        cells.append(cell)
    joints: list[str] = []
    for c in cells:
        if c["joint"] not in joints:
            joints.append(c["joint"])
    times = sorted({c["failure_time_s"] for c in cells})
    grids: dict[str, list[list[Any]]] = {
        k: [[None] * len(times) for _ in joints]
        for k in (
            "cells",
            "studied",
            "recovered",
            "recovery_rate",
            "recovery_possible",
            "reconfigured_final_task_error_m",
            "failed_final_task_error_m",
        )
    }
    for r, joint in enumerate(joints):
        for k, t in enumerate(times):
            members = [c for c in cells if c["joint"] == joint and c["failure_time_s"] == t]
            if not members:
                continue
            studied = [c for c in members if c["status"] == "ok"]
            grids["cells"][r][k] = [c["id"] for c in members]
            grids["studied"][r][k] = len(studied)
            if not studied:
                continue
            grids["recovered"][r][k] = sum(bool(c["recovered"]) for c in studied)
            grids["recovery_rate"][r][k] = grids["recovered"][r][k] / len(studied)
            grids["recovery_possible"][r][k] = sum(c["recovery_possible"] is True for c in studied)
            for name in ("reconfigured", "failed"):
                grids[f"{name}_final_task_error_m"][r][k] = _median(
                    [c["runs"][name]["final_task_error_m"] for c in studied]
                )
    studied_all = [c for c in cells if c["status"] == "ok"]
    return {
        "format": SUMMARY_FORMAT,
        "matrix": {
            "name": sm.name,
            "description": sm.matrix.description,
            "base": sm.matrix.base,
            "sha256": sm.matrix.content_digest(),
        },
        "study": sm.options.to_dict(),
        "failure": f"failures.{sm.failure_index}",
        "axes": {k: list(v) for k, v in sm.matrix.axes.items()},
        "durations_s": sorted({c["duration_s"] for c in studied_all}),
        "tolerance_m": tol,
        "counts": {
            "cells": len(cells),
            "ok": len(studied_all),
            "failed": sum(c["status"] == "failed" for c in cells),
            "missing": sum(c["status"] == "missing" for c in cells),
            "studied": len(studied_all),
            "recovery_possible": sum(c["recovery_possible"] is True for c in studied_all),
            "recovered": sum(bool(c["recovered"]) for c in studied_all),
        },
        "cells": cells,
        "heat_map": {"joints": joints, "failure_times_s": times, **grids},
    }
