"""Batch runs of a scenario matrix: in this process, on a local process pool or on Dask.

:func:`run_batch` runs a matrix's runs (:mod:`packbot.matrix`) and writes, under its output
directory::

    batch.lock                  held while a batch runs here (:class:`BatchLock`)
    matrix.json                 the matrix's canonical form and its SHA-256
    matrix.toml                 the matrix file's text
    runs/<id>.json              one record per finished run (:class:`RunRecord`)
    trajectories/<id>.npz       each run's trajectory and event log (packbot.scenario.save_run)
    trajectories/<id>_events.csv
    summary.csv                 one row per run (and summary.parquet with pyarrow)

A run function other than the default (:data:`Runner`, e.g. the failure study's cells of
:mod:`packbot.study_matrix`) may name its files ``"<run id>/<name>"``: they go into the run's own
folder ``<out>/<run id>/`` instead of ``trajectories/``; it may return named scalar results
(``metrics``, written in the record and as columns of the summary) and no final state.

Nothing finished is lost: each run's files, then its record, are written atomically (temporary
file, then rename) by this process as soon as the run finishes; the record comes last, so a run
counts as finished only when all its files are there. Each record holds the SHA-256 of each of
its files and of its own content. Rerunning verifies every record and skips the runs whose
record is intact, says ``"ok"`` for the same resolved scenario (same :attr:`Run.digest`) and
whose files are there with their checksums; it redoes the missing, failed and stale ones, and
those whose record is malformed, edited or of an older format without checksums, or whose files
are missing or changed (:attr:`BatchReport.rerun` says which and why). A run that raises,
diverges (non-finite state) or exceeds its wall-time limit is recorded as ``"failed"`` with its
message and the batch goes on. Ctrl-C stops the workers and loses only the runs in flight; a
worker process that dies (killed, crashed) breaks the pool: its runs in flight are run again,
one at a time, and a run that kills its worker again is recorded as failed.

One batch at a time per folder: :class:`BatchLock` (``batch.lock``) makes a second one fail at
once, and a folder holds the runs of one matrix (:meth:`packbot.matrix.Matrix.canonical`):
another matrix is refused.

Determinism: every run builds its own robot, solver and collision objects (nothing is shared
between runs), and the worker processes run with one BLAS/OpenMP thread (the variables are set
before the workers start, so before they import numpy); the same run gives bit-identical records
in this process, a local worker or a Dask worker.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import logging
import math
import multiprocessing
import os
import signal
import socket
import sys
import tempfile
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, TextIO

from packbot.csv_cells import spreadsheet_row
from packbot.errors import ConfigurationError, PackbotError, SimulationError
from packbot.keywords import checked_arguments
from packbot.matrix import Matrix, Run, canonical_json, parse_matrix
from packbot.paths import check_stem
from packbot.validation import MAX_WORKERS, integer, is_number

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    LOCK_WITH_FLOCK = False
else:
    #: Lock with ``fcntl.flock`` (POSIX); else with an exclusively created file.
    LOCK_WITH_FLOCK = True

if TYPE_CHECKING:
    from packbot.model import Robot
    from packbot.result import SimResult

__all__ = [
    "LEGACY_RECORD_FORMATS",
    "LOCK_NAME",
    "RECORD_FORMAT",
    "RERUN_CORRUPT_FILE",
    "RERUN_EDITED",
    "RERUN_FAILED",
    "RERUN_MALFORMED",
    "RERUN_MISSING_FILE",
    "RERUN_OLD_FORMAT",
    "RERUN_STALE",
    "RERUN_UNREADABLE_FILE",
    "RUN_STATUSES",
    "SINGLE_THREAD_ENV",
    "BatchLock",
    "BatchLockedError",
    "BatchReport",
    "ProgressBar",
    "RunFiles",
    "RunRecord",
    "Runner",
    "atomic_write",
    "check_matrix",
    "check_runs",
    "csv_text",
    "execute",
    "file_sha256",
    "read_records",
    "run_batch",
    "scenario_runner",
    "summarize",
    "summary_rows",
    "write_matrix",
    "write_summary",
]

log = logging.getLogger(__name__)

#: Format tag of a run record (2: with the checksums of its files and of itself).
RECORD_FORMAT = "packbot-batch-run/2"
#: Older format tags of run records: readable, but without checksums (a resume reruns them).
LEGACY_RECORD_FORMATS: tuple[str, ...] = ("packbot-batch-run/1",)
#: Name of the lock file in a batch folder.
LOCK_NAME = "batch.lock"
# Why a run that had a record is run again (the values of :attr:`BatchReport.rerun`):
#: Rerun reason: the run's record says it failed.
RERUN_FAILED = "failed before"
#: Rerun reason: the run's resolved scenario changed (another :attr:`Run.digest`).
RERUN_STALE = "stale (its scenario changed)"
#: Rerun reason: a file the record lists is missing.
RERUN_MISSING_FILE = "file missing"
#: Rerun reason: a file the record lists (or the record itself) is there but cannot be read: a
#: directory, a special file or an unreadable one (moved aside to ``<name>.bad-<n>``, then made
#: again).
RERUN_UNREADABLE_FILE = "file unreadable (a directory or not a readable file: moved aside)"
#: Rerun reason: a file's SHA-256 differs from the record's.
RERUN_CORRUPT_FILE = "file corrupted (SHA-256 differs)"
#: Rerun reason: the record's own SHA-256 does not match its content.
RERUN_EDITED = "record edited (SHA-256 differs)"
#: Rerun reason: the record is not valid JSON or lacks fields.
RERUN_MALFORMED = "record unreadable (malformed JSON or fields)"
#: Rerun reason: the record is of a legacy format, without checksums.
RERUN_OLD_FORMAT = "record of an older format, without checksums (unverifiable)"
#: The statuses of a run record.
RUN_STATUSES: tuple[str, ...] = ("ok", "failed")
#: Environment of the worker processes: one thread for BLAS and OpenMP (determinism, and no
#: oversubscription of the cores the pool already fills).
SINGLE_THREAD_ENV: Mapping[str, str] = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "VECLIB_MAXIMUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
}

#: A run's output files: role -> (file name, contents).
RunFiles = dict[str, tuple[str, bytes]]
#: A run function: ``runner(run, progress) -> (quantities, files)``. ``progress`` must be called
#: with the simulated time [s] now and then (it raises when the wall-time limit is exceeded);
#: ``quantities`` are :class:`RunRecord` fields (see :func:`summarize`; without ``final_q`` the
#: run is not checked for divergence). Files are named ``"<name>"`` (written to
#: ``trajectories/``) or ``"<run id>/<name>"`` (the run's own folder). Must be picklable (a
#: module-level function, or a ``functools.partial`` of one) to run on workers.
Runner = Callable[[Run, Callable[[float], None]], tuple[dict[str, Any], RunFiles]]

_FLOAT_FIELDS = ("rest_time", "min_distance", "energy_change", "t_end", "wall_time")
_NON_FINITE = ("inf", "-inf", "nan")


@checked_arguments
@dataclass(kw_only=True)
class RunRecord:
    """What a run produced: one JSON file per run, ``runs/<id>.json``.

    Attributes:
        id: The run's id (:attr:`packbot.matrix.Run.id`).
        index: Its position in the matrix.
        params: Its parameters, dotted name -> value.
        digest: Digest of its resolved scenario (:attr:`packbot.matrix.Run.digest`).
        status: ``"ok"`` or ``"failed"``.
        error: The failure's message (``"ExceptionType: message"``), "" if ok.
        traceback: The traceback of an unexpected (non-packbot) exception, else "".
        joint_names: Names of the columns of ``final_q``.
        final_q: Joint positions at the end [rad], full coordinates.
        rest_time: Rest time [s] (:attr:`packbot.SimResult.rest_time`), None if not at rest.
        n_impacts: Number of ``"impact"`` events.
        n_limits: Number of ``"limit"`` events.
        n_events: Number of events of every kind.
        event_times: Time of each event [s].
        event_kinds: Kind of each event.
        min_distance: Smallest signed distance seen [m] (inf: no pair within the margin).
        energy_change: Final minus initial mechanical energy [J].
        t_end: Last simulated time [s].
        wall_time: Wall-clock time of the run, scenario building and saving included [s].
        worker: Where it ran: ``"main"``, ``"local:<pid>"`` or ``"dask:<address>"``.
        files: Role -> path of the run's files, relative to the output directory
            (``trajectories/<name>``, or ``<id>/<name>`` in the run's own folder).
        file_sha256: Role -> SHA-256 (hex) of that file's bytes.
        metrics: Named scalar results of a run function other than the default (name ->
            number, string, bool or None; e.g. a failure study's final task errors); written
            only when there are some, so a simulation's record is unchanged.

    The record file also holds ``record_sha256``, the SHA-256 of the canonical JSON of the rest
    of the record (:func:`_record_bytes`): a resume reruns a run whose record does not match it.
    """

    id: str
    index: int
    params: dict[str, Any]
    digest: str
    status: str
    error: str = ""
    traceback: str = ""
    joint_names: tuple[str, ...] = ()
    final_q: tuple[float, ...] = ()
    rest_time: float | None = None
    n_impacts: int = 0
    n_limits: int = 0
    n_events: int = 0
    event_times: tuple[float, ...] = ()
    event_kinds: tuple[str, ...] = ()
    min_distance: float = math.nan
    energy_change: float = math.nan
    t_end: float = math.nan
    wall_time: float = 0.0
    worker: str = ""
    files: dict[str, str] = field(default_factory=dict)
    file_sha256: dict[str, str] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first inconsistent field."""
        if self.status not in RUN_STATUSES:
            raise ConfigurationError("status", self.status, RUN_STATUSES)
        if len(self.final_q) != len(self.joint_names):
            raise ConfigurationError(
                "final_q", self.final_q, f"{len(self.joint_names)} values (one per joint name)"
            )
        if len(self.event_times) != len(self.event_kinds):
            raise ConfigurationError(
                "event_times", self.event_times, "one time per entry of event_kinds"
            )
        for key, value in self.metrics.items():
            if not isinstance(key, str) or not (
                value is None or isinstance(value, (str, bool, int, float))
            ):
                raise ConfigurationError(
                    f"metrics.{key}", value, "a number, a string, a bool or None"
                )

    def quantities(self) -> dict[str, Any]:
        """The deterministic part: what must be identical whenever and wherever the run is made.

        Everything but the wall time, the worker, the file paths and checksums and the traceback.
        """
        out = self.to_json()
        for key in ("format", "wall_time", "worker", "files", "file_sha256", "traceback", "index"):
            out.pop(key, None)
        return out

    def to_json(self) -> dict[str, Any]:
        """The record as a JSON-ready dict (non-finite floats as ``"inf"``, ``"nan"``)."""
        out = {
            "format": RECORD_FORMAT,
            "id": self.id,
            "index": self.index,
            "params": self.params,
            "digest": self.digest,
            "status": self.status,
            "error": self.error,
            "traceback": self.traceback,
            "joint_names": list(self.joint_names),
            "final_q": [_enc(x) for x in self.final_q],
            "rest_time": None if self.rest_time is None else _enc(self.rest_time),
            "n_impacts": self.n_impacts,
            "n_limits": self.n_limits,
            "n_events": self.n_events,
            "event_times": [_enc(x) for x in self.event_times],
            "event_kinds": list(self.event_kinds),
            "min_distance": _enc(self.min_distance),
            "energy_change": _enc(self.energy_change),
            "t_end": _enc(self.t_end),
            "wall_time": _enc(self.wall_time),
            "worker": self.worker,
            "files": dict(self.files),
            "file_sha256": dict(self.file_sha256),
        }
        if self.metrics:
            out["metrics"] = {
                k: _enc(v) if isinstance(v, float) else v for k, v in self.metrics.items()
            }
        return out

    @classmethod
    @checked_arguments
    def from_json(cls, data: Mapping[str, Any]) -> RunRecord:
        """Read a record written by :meth:`to_json` (or of a :data:`LEGACY_RECORD_FORMATS`).

        The checksums are read, not verified (:func:`run_batch` verifies them).

        Raises:
            ConfigurationError: Not a run record, or a missing or bad field.
        """
        if not isinstance(data, Mapping):
            raise ConfigurationError("record", type(data).__name__, "a JSON object")
        if data.get("format") not in (RECORD_FORMAT, *LEGACY_RECORD_FORMATS):
            raise ConfigurationError(
                "format", data.get("format"), (RECORD_FORMAT, *LEGACY_RECORD_FORMATS)
            )
        try:
            record = cls(
                id=str(data["id"]),
                index=int(data["index"]),
                params=dict(data["params"]),
                digest=str(data["digest"]),
                status=str(data["status"]),
                error=str(data.get("error", "")),
                traceback=str(data.get("traceback", "")),
                joint_names=tuple(data.get("joint_names", ())),
                final_q=tuple(_dec(x) for x in data.get("final_q", ())),
                rest_time=None if data.get("rest_time") is None else _dec(data["rest_time"]),
                n_impacts=int(data.get("n_impacts", 0)),
                n_limits=int(data.get("n_limits", 0)),
                n_events=int(data.get("n_events", 0)),
                event_times=tuple(_dec(x) for x in data.get("event_times", ())),
                event_kinds=tuple(data.get("event_kinds", ())),
                min_distance=_dec(data.get("min_distance", "nan")),
                energy_change=_dec(data.get("energy_change", "nan")),
                t_end=_dec(data.get("t_end", "nan")),
                wall_time=_dec(data.get("wall_time", 0.0)),
                worker=str(data.get("worker", "")),
                files={str(k): str(v) for k, v in dict(data.get("files", {})).items()},
                file_sha256={str(k): str(v) for k, v in dict(data.get("file_sha256", {})).items()},
                metrics={
                    str(k): _dec(v) if isinstance(v, str) and v in _NON_FINITE else v
                    for k, v in dict(data.get("metrics", {})).items()
                },
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigurationError(
                "record", dict(data).get("id"), f"a run record ({exc})"
            ) from exc
        record.validate()
        return record


@checked_arguments
@dataclass(kw_only=True)
class BatchReport:
    """What :func:`run_batch` did.

    Attributes:
        out_dir: The output directory.
        runs: The matrix's runs.
        records: The records of the runs that have one, by id (this batch's and earlier ones').
        executed: Ids of the runs made by this call.
        skipped: Ids of the runs already finished by an earlier call (record and files verified).
        rerun: Id -> why, for each run that had a record but was run again (one of the
            ``RERUN_*`` reasons: failed before, stale, a file missing or corrupted, the record
            edited, malformed or of an older format).
        summary: The summary files written.
        moved_aside: Path -> new path (relative to the output directory) of each file that was
            in the way of a run's file or record and could not be read (a directory, a special
            or unreadable file): renamed ``<name>.bad-<n>`` beside it, kept for a look.
    """

    out_dir: Path
    runs: list[Run]
    records: dict[str, RunRecord]
    executed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    rerun: dict[str, str] = field(default_factory=dict)
    summary: list[Path] = field(default_factory=list)
    moved_aside: dict[str, str] = field(default_factory=dict)

    @property
    def failed(self) -> list[str]:
        """Ids of the runs recorded as failed."""
        return [r.id for r in self.runs if r.id in self.records and not self._ok(r.id)]

    @property
    def missing(self) -> list[str]:
        """Ids of the runs without a record (not run yet)."""
        return [r.id for r in self.runs if r.id not in self.records]

    def _ok(self, rid: str) -> bool:
        return self.records[rid].status == "ok"

    def describe(self) -> str:
        """A few lines for the command line: counts, failures and where the summary is."""
        ok = sum(self.records[r.id].status == "ok" for r in self.runs if r.id in self.records)
        lines = [
            f"{len(self.runs)} runs: {ok} ok, {len(self.failed)} failed, "
            f"{len(self.missing)} missing ({len(self.executed)} run now, "
            f"{len(self.skipped)} finished before)"
        ]
        if self.rerun:
            counts = _count_reasons(self.rerun)
            lines.append(
                f"rerun {len(self.rerun)}: " + ", ".join(f"{n} {why}" for why, n in counts.items())
            )
        if self.moved_aside:
            lines.append(
                f"moved aside {len(self.moved_aside)} unreadable files: "
                + ", ".join(f"{a} -> {b}" for a, b in self.moved_aside.items())
            )
        for rid in self.failed:
            lines.append(f"  failed {rid}: {self.records[rid].error}")
        if self.summary:
            lines.append("summary: " + ", ".join(str(p) for p in self.summary))
        return "\n".join(lines)


def _duration_text(seconds: float) -> str:
    """A time left or taken, to the second: ``"42 s"``, ``"12 min 05 s"``, ``"3 h 07 min"``."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


@checked_arguments
class ProgressBar:
    """A text progress bar counting finished runs: ``progress(done, failed, total)``.

    On a terminal it redraws one line, cut to the terminal's width and blanked past its end
    (a shorter line leaves nothing of the longer one before it); otherwise (a file, a pipe, a
    CI log) it writes a whole line, ended by a newline, every 5 % of the runs and at the end:
    at most 21 lines, whatever the number of runs or their pace. The rate and the time left
    count the runs finished since the bar's first call (a resumed batch's earlier runs do not
    inflate them); a slow pace is given as minutes per run. While the bar is drawn on a terminal,
    a log record sent by a handler of the root logger to the same stream (a failed run's warning)
    first blanks the bar's line, so the message stands on a line of its own and the bar is
    redrawn under it. docs/batch.md says why this and not tqdm or rich.

    Args:
        stream: Where to write (default: standard error).
        width: Bar width [characters].
    """

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._t0 = time.perf_counter()
        self._first: int | None = None
        self._last_line = -1
        self._drawn = 0  # characters of the line on the terminal
        self._handlers: list[logging.Handler] = []

    def filter(self, record: logging.LogRecord) -> bool:
        """A logging filter: blank the bar's line before a record is written; keep the record."""
        if self._drawn:
            self.stream.write("\r" + " " * self._drawn + "\r")
            self._drawn = 0
        return True

    def _attach(self) -> None:
        for handler in logging.getLogger().handlers:
            if getattr(handler, "stream", None) is self.stream and handler not in self._handlers:
                handler.addFilter(self)
                self._handlers.append(handler)

    def close(self) -> None:
        """Stop blanking the line for log records (done by the call that shows the last run)."""
        for handler in self._handlers:
            handler.removeFilter(self)
        self._handlers.clear()

    def _columns(self) -> int:
        """The terminal's width [characters] (80 if it cannot be asked)."""
        try:
            return os.get_terminal_size(self.stream.fileno()).columns or 80
        except (AttributeError, OSError, ValueError):  # no descriptor, not a terminal
            return 80

    def text(self, done: int, failed: int, total: int) -> str:
        """The bar's line for ``done`` of ``total`` runs finished, ``failed`` of them failed."""
        if self._first is None:
            self._first, self._t0 = done, time.perf_counter()
        elapsed = time.perf_counter() - self._t0
        new = done - self._first
        per_min = new / elapsed * 60.0 if elapsed > 0 and new > 0 else 0.0
        pace = ""
        if per_min >= 1.0:
            pace = f", {per_min:.0f} runs/min"
        elif per_min > 0:
            pace = f", {_duration_text(60.0 / per_min)}/run"
        eta = ""
        if per_min > 0 and done < total:
            eta = f", {_duration_text((total - done) / per_min * 60.0)} left"
        frac = min(done / total, 1.0) if total else 1.0
        fill = round(frac * self.width)
        return (
            f"[{'#' * fill}{'.' * (self.width - fill)}] {done}/{total} runs"
            f"{f' ({failed} failed)' if failed else ''}{pace}{eta}"
        )

    def __call__(self, done: int, failed: int, total: int) -> None:
        """Show ``done`` of ``total`` runs finished, ``failed`` of them failed."""
        text = self.text(done, failed, total)
        if self.tty:
            text = text[: max(self._columns() - 1, 1)]  # a wrapped line cannot be redrawn
            pad = " " * max(self._drawn - len(text), 0)
            self._drawn = len(text)
            self.stream.write("\r" + text + pad)
            if done >= total:
                self.stream.write("\n")
                self._drawn = 0
                self.close()
            elif not self._handlers:
                self._attach()
        else:
            step = max(1, total // 20)
            if done >= total or done // step != self._last_line:
                self._last_line = done // step
                self.stream.write(text + "\n")
        self.stream.flush()


# ---------------------------------------------------------------------------------- running
@checked_arguments
def summarize(result: SimResult) -> dict[str, Any]:
    """The summary quantities of a result, as :class:`RunRecord` fields."""
    events = result.events
    return {
        "joint_names": tuple(result.joint_names),
        "final_q": tuple(float(x) for x in result.q[-1]),
        "rest_time": None if result.rest_time is None else float(result.rest_time),
        "n_impacts": sum(e.kind == "impact" for e in events),
        "n_limits": sum(e.kind == "limit" for e in events),
        "n_events": len(events),
        "event_times": tuple(float(e.t) for e in events),
        "event_kinds": tuple(e.kind for e in events),
        "min_distance": float(result.diagnostics.min_distance),
        "energy_change": float(result.energy[-1] - result.energy[0]),
        "t_end": float(result.t[-1]),
    }


@checked_arguments
def scenario_runner(run: Run, progress: Callable[[float], None]) -> tuple[dict[str, Any], RunFiles]:
    """The default :data:`Runner`: build the run's scenario, simulate it, save its trajectory.

    Everything is built fresh (robot, controller, collision world): no state is shared between
    runs. The trajectory is written by :func:`packbot.scenario.save_run` (the format of
    ``packbot run``) into a temporary directory and returned as bytes, so that the process
    collecting the results (maybe on another machine) writes it.
    """
    from packbot.scenario import run_scenario, save_run

    scenario = run.build_scenario()
    result = run_scenario(scenario, progress=progress)
    quantities = summarize(result)
    with tempfile.TemporaryDirectory(prefix="packbot-run-") as tmp:
        paths = save_run(result, scenario, tmp, stem=run.id)
        files = {role: (p.name, p.read_bytes()) for role, p in paths.items()}
    return quantities, files


@checked_arguments
def check_runs(runs: Sequence[Run]) -> None:
    """Check every run's scenario before any is made: a bad value in a matrix is bad input.

    Each run's resolved scenario is built (:meth:`packbot.matrix.Run.build_scenario`: keys,
    types, ranges) and checked against its arm (:meth:`packbot.scenario.Scenario.validate`:
    the names of poses, joints, frames and links, and the controller's parameters), as
    :func:`scenario_runner` would at the start of the run. What only the simulation finds (an
    initial state in collision, a run that cannot continue) still fails that run alone.

    Raises:
        ConfigurationError: A run's scenario is bad; the message names the run, its parameters
            and the field.
    """
    from packbot.scenario import scenario_robot

    robots: dict[tuple[Any, Any], Robot] = {}  # each arm loaded once: (its spec, its folder)
    for run in runs:
        try:
            scenario = run.build_scenario()
            where = None if scenario.source_path is None else scenario.source_path.parent
            key = (scenario.robot, where)
            if key not in robots:
                robots[key] = scenario_robot(scenario)
            scenario.validate(robots[key])
        except ConfigurationError as exc:
            raise ConfigurationError(
                f"run {run.id} ({_params_text(run)}): {exc.field}", exc.value, exc.expected
            ) from None
        except PackbotError as exc:  # an unknown name, a degenerate obstacle...
            raise ConfigurationError(
                f"run {run.id}", _params_text(run), f"parameters its scenario accepts: {exc}"
            ) from None


def _params_text(run: Run) -> str:
    return ", ".join(f"{k} = {canonical_json(v)}" for k, v in run.params.items())


@checked_arguments
def execute(
    run: Run,
    runner: Runner = scenario_runner,
    timeout: float | None = None,
    worker: str = "main",
) -> tuple[RunRecord, RunFiles]:
    """Make one run and catch its failure: never raises for a failed run.

    Args:
        run: The run.
        runner: The run function.
        timeout: Wall-time limit of the run [s] (checked at each integration step), or None.
        worker: Label of where it runs (stored in the record; ``"local"``/``"dask"`` get the
            process id / worker address appended).

    Returns:
        The record (status ``"ok"``, or ``"failed"`` with the message) and the files to write.
    """
    if worker == "local":
        worker = f"local:{os.getpid()}"
    t0 = time.perf_counter()

    def progress(t: float) -> None:
        if timeout is not None and time.perf_counter() - t0 > timeout:
            raise SimulationError(f"wall-time limit of {timeout:g} s exceeded", t)

    base: dict[str, Any] = {
        "id": run.id,
        "index": run.index,
        "params": run.params,
        "digest": run.digest,
    }
    try:
        quantities, files = runner(run, progress)
        record = RunRecord(**base, status="ok", **quantities)
        record.joint_names = tuple(str(j) for j in record.joint_names)
        record.final_q = tuple(float(x) for x in record.final_q)
        record.event_times = tuple(float(x) for x in record.event_times)
        record.event_kinds = tuple(str(k) for k in record.event_kinds)
        record.validate()
        finite = [*record.final_q, record.energy_change]
        if record.final_q and not all(math.isfinite(x) for x in finite):
            raise SimulationError("diverged: non-finite final state or energy", record.t_end)
    except Exception as exc:  # a failed run is recorded, and the batch goes on
        log.debug("run %s failed", run.id, exc_info=True)
        tb = "" if isinstance(exc, PackbotError) else traceback.format_exc()
        record = RunRecord(**base, status="failed", error=f"{type(exc).__name__}: {exc}")
        record.traceback = tb
        files = {}
    record.wall_time = time.perf_counter() - t0
    record.worker = worker
    return record, files


@checked_arguments
def run_batch(
    matrix: Matrix,
    out_dir: str | Path,
    *,
    runs: Sequence[Run] | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    runner: Runner = scenario_runner,
    timeout: float | None = None,
    progress: Callable[[int, int, int], None] | None = None,
) -> BatchReport:
    """Run a matrix's missing, failed or stale runs; write their records and the summary.

    Args:
        matrix: The matrix.
        out_dir: Output directory (created; an existing one is resumed).
        runs: Its runs (default: ``matrix.runs()``).
        workers: Local worker processes (default: the number of CPUs); 0 runs them one after
            the other in this process. With a Dask scheduler: the workers of ``"local"``.
        scheduler: None (local processes), the address of a Dask scheduler
            (``"tcp://host:port"``), ``"local"`` (a Dask ``LocalCluster`` on 127.0.0.1, for the
            dashboard) or a ``distributed.Client``.
        runner: The run function (default: :func:`scenario_runner`).
        timeout: Wall-time limit per run [s], or None.
        progress: Called as ``progress(done, failed, total)`` at the start and after each run.

    Returns:
        The report; failed runs are in the records, not raised; the runs made again, and why,
        in :attr:`BatchReport.rerun`.

    Raises:
        KeyboardInterrupt: On Ctrl-C, after the workers are stopped and the summary written;
            the finished runs are kept.
        BatchLockedError: Another batch runs in ``out_dir`` (at once, nothing written).
        ConfigurationError: A bad argument (names it), dask.distributed missing, an
            ``out_dir`` that cannot be created, or one that holds another matrix's runs
            (:func:`check_matrix`; nothing written); with the default runner, a run whose
            scenario is bad (:func:`check_runs`; nothing run or written), or a study matrix
            (its ``[study]`` table: :mod:`packbot.study_matrix` runs those).
    """
    if workers is not None:
        integer("workers", workers, low=0, high=MAX_WORKERS, what="an integer >= 0")
    if timeout is not None and not (is_number(timeout) and math.isfinite(timeout) and timeout > 0):
        raise ConfigurationError("timeout", timeout, "a finite positive time [s], or None")
    if not isinstance(out_dir, (str, os.PathLike)) or not str(out_dir):
        raise ConfigurationError("out_dir", out_dir, "a folder path")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigurationError("out_dir", str(out), "a directory (this is a file)")
    if matrix.study is not None and runner is scenario_runner:
        raise ConfigurationError(
            "matrix",
            matrix.name,
            "a matrix of simulations (this one has a [study] table: its cells are failure "
            "studies, run by packbot.study_matrix.run_study_matrix or `packbot study`)",
        )
    runs = list(matrix.runs() if runs is None else runs)
    for k, run in enumerate(runs):  # a run's id names its files: one file name each
        if not isinstance(run, Run):
            raise ConfigurationError(f"runs[{k}]", type(run).__name__, "a packbot.matrix.Run")
        check_stem(f"runs[{k}].id", run.id)
        if run.id.startswith("."):
            raise ConfigurationError(f"runs[{k}].id", run.id, "a file name not beginning with '.'")
    if runner is scenario_runner:  # a bad value in the matrix is refused before anything runs
        check_runs(runs)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigurationError(
            "out_dir", str(out), f"a folder that can be created ({exc.strerror or exc})"
        ) from exc
    with BatchLock(out):
        return _run_locked(matrix, out, runs, workers, scheduler, runner, timeout, progress)


def _run_locked(
    matrix: Matrix,
    out: Path,
    runs: Sequence[Run] | None,
    workers: int | None,
    scheduler: Any,
    runner: Runner,
    timeout: float | None,
    progress: Callable[[int, int, int], None] | None,
) -> BatchReport:
    """:func:`run_batch` once the folder is locked."""
    check_matrix(out, matrix)
    runs = list(matrix.runs() if runs is None else runs)  # (given by run_batch)
    if runner is scenario_runner:
        (out / "trajectories").mkdir(exist_ok=True)
    (out / "runs").mkdir(exist_ok=True)
    for sub in ("runs", "trajectories", *(r.id for r in runs)):
        for stale in (out / sub).glob(".*.tmp"):  # left by a killed batch (none runs: locked)
            stale.unlink(missing_ok=True)
    write_matrix(out, matrix)
    report = BatchReport(out_dir=out, runs=runs, records={})
    todo: list[Run] = []
    old_files: dict[str, tuple[Path, ...]] = {}  # verified files of the runs to redo
    details: dict[str, str] = {}
    for run in runs:
        check = _check_record(out, run)
        if check.record is not None and check.reason is None:
            report.records[run.id] = check.record
            report.skipped.append(run.id)
            continue
        if check.reason is not None:
            report.rerun[run.id] = check.reason
            details[run.id] = check.detail
            old_files[run.id] = check.files
        if check.record is not None:
            report.records[run.id] = check.record  # a failed or stale record, replaced when redone
        todo.append(run)
    _log_reruns(out, report.rerun, details)
    total = len(runs)
    state = {"done": len(report.skipped), "failed": 0}
    if progress is not None:
        progress(state["done"], 0, total)

    def store(record: RunRecord, files: RunFiles) -> None:
        _store(out, record, files, report.moved_aside)
        keep = {out / p for p in record.files.values()}
        for path in old_files.pop(record.id, ()):  # an earlier run's files it did not rewrite
            if path not in keep:
                if path.is_symlink() or path.is_file():
                    path.unlink(missing_ok=True)
                elif path.exists():  # a directory in its place: not ours to delete
                    _move_aside(out, path, report.moved_aside)
        report.records[record.id] = record
        report.executed.append(record.id)
        state["done"] += 1
        state["failed"] += record.status != "ok"
        if record.status != "ok":
            log.warning("run %s failed: %s", record.id, record.error)
        if progress is not None:
            progress(state["done"], state["failed"], total)

    log.info(
        "%d runs: %d finished before, %d to run (%d of them again)",
        total,
        len(report.skipped),
        len(todo),
        len(report.rerun),
    )
    try:
        if not todo:
            pass
        elif scheduler is not None:
            _run_dask(todo, scheduler, workers, runner, timeout, store)
        elif workers == 0:
            for run in todo:
                store(*execute(run, runner, timeout, "main"))
        else:
            n = (os.cpu_count() or 1) if workers is None else workers
            _run_pool(todo, min(n, len(todo)), runner, timeout, store)
    finally:
        report.summary = write_summary(out, runs, report.records)
    return report


# ---------------------------------------------------------------------------------- lock
class BatchLockedError(PackbotError):
    """Another batch holds the batch folder's lock.

    Attributes:
        folder: The batch folder.
        holder: What the lock file says of its holder (``pid``, ``host``, ``started``), maybe
            empty (a holder still writing it).
    """

    def __init__(self, folder: Path, holder: Mapping[str, Any], why: str) -> None:
        self.folder = folder
        self.holder = dict(holder)
        super().__init__(f"batch folder {folder} {why}")


@checked_arguments
class BatchLock:
    """The lock of a batch folder: one batch at a time (``<folder>/batch.lock``).

    With ``fcntl.flock`` (POSIX): the lock is the kernel's lock on the open file, released when
    the holding process exits however it exits (even ``kill -9``), so it never outlives its
    holder; the file's content (pid, host, start time) names the holder in the error message.
    A second holder (another process, or another open in the same process) fails at once. A
    file left with the content of a process that is gone is taken over with a warning; one
    left by another host is refused (the process there cannot be checked), with the command to
    remove it. Without ``fcntl``: the file is created exclusively (``O_CREAT | O_EXCL``) and a
    file whose process is gone (its pid not alive on this host) is taken over with a warning.

    The lock is held by the process that calls :func:`run_batch`, which alone writes in the
    folder: local workers and Dask workers return their results to it and never open the
    folder (the descriptor is not inherited by the workers).

    Args:
        folder: The batch folder (it must exist).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self._fd: int | None = None

    def __enter__(self) -> BatchLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    @property
    def held(self) -> bool:
        """Whether this object holds the lock."""
        return self._fd is not None

    def acquire(self) -> None:
        """Take the lock, or raise at once.

        Raises:
            BatchLockedError: Another batch holds it (names its pid and host).
            ConfigurationError: The lock file cannot be created (names the folder).
        """
        if self._fd is not None:
            raise BatchLockedError(self.folder, _lock_info(), "is already locked by this object")
        try:
            if LOCK_WITH_FLOCK:
                self._acquire_flock()
            else:
                self._acquire_exclusive()
        except OSError as exc:
            raise ConfigurationError(
                "out_dir", str(self.folder), f"a folder where {LOCK_NAME} can be written ({exc})"
            ) from exc

    def _acquire_flock(self) -> None:
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise
                holder = _read_lock(self.path)
                raise BatchLockedError(self.folder, holder, _held_by(holder, self.path)) from None
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if not same:  # released and removed by its holder meanwhile: lock the new one
                os.close(fd)
                continue
            break
        try:
            previous = _parse_lock(os.read(fd, 65536))
            if previous and previous.get("host") != socket.gethostname():
                raise BatchLockedError(
                    self.folder,
                    previous,
                    f"is locked by {_holder_text(previous)}, another machine: its process "
                    f"cannot be checked from here; if no batch runs there, remove {self.path}",
                )
            if previous:
                log.warning(
                    "taking over the stale lock %s of %s: that process no longer holds it",
                    self.path,
                    _holder_text(previous),
                )
            os.lseek(fd, 0, os.SEEK_SET)
            os.ftruncate(fd, 0)
            os.write(fd, _lock_bytes())
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd

    def _acquire_exclusive(self) -> None:
        for attempt in range(2):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                holder = _read_lock(self.path)
                alive = _holder_alive(holder)
                if alive is not False or attempt:
                    raise BatchLockedError(
                        self.folder, holder, _held_by(holder, self.path)
                    ) from None
                log.warning(
                    "taking over the stale lock %s of %s: that process is gone",
                    self.path,
                    _holder_text(holder),
                )
                self.path.unlink(missing_ok=True)
                continue
            try:
                os.write(fd, _lock_bytes())
            except BaseException:
                os.close(fd)
                self.path.unlink(missing_ok=True)
                raise
            self._fd = fd
            return

    def release(self) -> None:
        """Remove the lock file and release the lock (nothing if not held)."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            with contextlib.suppress(OSError):
                if os.path.samestat(os.fstat(fd), os.stat(self.path)):
                    self.path.unlink()  # before unlocking: a waiter re-checks the inode
        finally:
            os.close(fd)


def _lock_info() -> dict[str, Any]:
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def _lock_bytes() -> bytes:
    return (json.dumps(_lock_info()) + "\n").encode()


def _parse_lock(data: bytes) -> dict[str, Any]:
    try:
        info = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}


def _read_lock(path: Path) -> dict[str, Any]:
    try:
        return _parse_lock(path.read_bytes())
    except OSError:
        return {}


def _holder_text(holder: Mapping[str, Any]) -> str:
    if not holder:
        return "another process (not named yet)"
    text = f"pid {holder.get('pid')} on host {holder.get('host')}"
    if holder.get("started"):
        text += f" (since {holder['started']})"
    return text


def _held_by(holder: Mapping[str, Any], path: Path) -> str:
    return (
        f"is in use by another batch: {path.name} is held by {_holder_text(holder)}; "
        "wait for it to finish, or use another --out"
    )


def _holder_alive(holder: Mapping[str, Any]) -> bool | None:
    """Whether the lock's holder runs: None if unknown (another host, no pid, not POSIX)."""
    pid = holder.get("pid")
    if holder.get("host") != socket.gethostname() or not isinstance(pid, int) or pid <= 0:
        return None
    if os.name != "posix":  # pragma: no cover - os.kill(pid, 0) would terminate it on Windows
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


# ---------------------------------------------------------------------------------- matrix
@checked_arguments
def check_matrix(out_dir: str | Path, matrix: Matrix) -> None:
    """Refuse a batch folder that holds another matrix's runs.

    Compares the matrix's canonical form (:meth:`packbot.matrix.Matrix.canonical`: comments,
    layout, the description and the tolerances do not count) with the one stored in
    ``matrix.json`` (or, for a folder of an older packbot, with the stored ``matrix.toml``).

    Raises:
        ConfigurationError: Another matrix, or an unreadable stored one (names the folder).
    """
    out = Path(out_dir)
    stored: dict[str, Any] | None = None
    source = out / "matrix.json"
    try:
        if source.is_file():
            data = json.loads(source.read_text(encoding="utf-8"))
            stored = data["matrix"]
            if not isinstance(stored, dict):
                raise TypeError("'matrix' is not a table")
        elif (out / "matrix.toml").is_file():
            source = out / "matrix.toml"
            text = source.read_text(encoding="utf-8")
            stored = parse_matrix(text, path=source, default_name=matrix.name).canonical()
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, PackbotError) as exc:
        raise ConfigurationError(
            "out_dir",
            str(out),
            f"a batch folder whose {source.name} can be read ({exc}); "
            "use another --out, or remove the folder",
        ) from exc
    if stored is None:
        return
    mine = matrix.canonical()
    if canonical_json(stored) == canonical_json(mine):
        return
    differ = sorted(k for k in set(stored) | set(mine) if stored.get(k) != mine.get(k))
    if stored.get("name") == matrix.name:
        other = f"another version of matrix {matrix.name!r}"
    else:
        other = f"matrix {stored.get('name')!r}, not {matrix.name!r}"
    raise ConfigurationError(
        "out_dir",
        str(out),
        f"a folder of this matrix: it holds the runs of {other} (they differ in: "
        f"{', '.join(differ)}; stored in {source.name}); use another --out, or remove the folder",
    )


@checked_arguments
def write_matrix(out_dir: str | Path, matrix: Matrix) -> None:
    """Write ``matrix.json`` (canonical form and SHA-256) and ``matrix.toml`` (its text)."""
    out = Path(out_dir)
    data = {"sha256": matrix.content_digest(), "matrix": matrix.canonical()}
    atomic_write(out / "matrix.json", (json.dumps(data, indent=1) + "\n").encode())
    if matrix.source_text:
        atomic_write(out / "matrix.toml", matrix.source_text.encode())


@contextlib.contextmanager
def _single_thread_env() -> Iterator[None]:
    """Set :data:`SINGLE_THREAD_ENV` in os.environ (inherited by the workers started inside)."""
    saved = {k: os.environ.get(k) for k in SINGLE_THREAD_ENV}
    os.environ.update(SINGLE_THREAD_ENV)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _pin_threads() -> None:
    """In a worker: one BLAS/OpenMP thread.

    Sets the variables (for later imports and subprocesses) and, if threadpoolctl is installed,
    limits the libraries already loaded.
    """
    os.environ.update(SINGLE_THREAD_ENV)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(1)


#: How often a local worker without ``prctl`` checks that its parent still runs [s].
_PARENT_POLL_S = 0.5
_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _die_with_parent(parent: int) -> None:
    """Make this process (a local worker) end when its parent, the batch's process, ends.

    A batch's process killed outright (``kill -9``) cannot stop its workers: they would run on,
    holding the caller's pipes open. On Linux the kernel sends the worker SIGKILL when its
    parent dies (``prctl(PR_SET_PDEATHSIG)``; the pool's workers are started by the batch's
    main thread, which lives as long as the process); elsewhere, or if that call fails, a
    daemon thread polls ``os.getppid()`` every :data:`_PARENT_POLL_S` seconds and ends the
    process once the parent changed.
    """
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
                if os.getppid() != parent:  # died before the call: nobody would signal
                    os._exit(1)
                return
        except (OSError, AttributeError):  # pragma: no cover - no libc, no prctl
            pass

    def watch() -> None:  # pragma: no cover - not Linux
        while os.getppid() == parent:
            time.sleep(_PARENT_POLL_S)
        os._exit(1)

    import threading

    threading.Thread(target=watch, name="packbot-parent-watch", daemon=True).start()


def _init_worker(parent: int | None = None) -> None:
    """Initializer of the local pool's workers.

    Args:
        parent: The batch's process id: the worker ends when it does (:func:`_die_with_parent`).
    """
    if parent is not None:
        _die_with_parent(parent)
    _pin_threads()
    # Ctrl-C goes to the whole process group: the parent stops the workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_pool(
    todo: Sequence[Run],
    n: int,
    runner: Runner,
    timeout: float | None,
    store: Callable[[RunRecord, RunFiles], None],
) -> None:
    """Run on ``n`` local worker processes ('spawn').

    At most n + 1 runs are submitted at a time, so that a broken pool's runs in flight are known.
    When a worker process dies, the pool breaks: its runs in flight are run again on a fresh
    pool, one at a time, so that a run that kills its worker again is known for sure (and is
    recorded as failed) while the others complete.
    """
    queue = deque(todo)
    isolate: deque[Run] = deque()
    ctx = multiprocessing.get_context("spawn")
    with _single_thread_env():
        while queue or isolate:
            pool = ProcessPoolExecutor(
                max_workers=n,
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(os.getpid(),),
            )
            inflight: dict[Future[tuple[RunRecord, RunFiles]], Run] = {}
            alone: Run | None = None  # the run submitted alone, if any
            lost: list[Run] = []
            broken = False  # (a submit found the pool broken: a worker died since the last wait)

            try:
                while (queue or isolate or inflight) and not lost and not broken:
                    if isolate:
                        if not inflight:
                            alone = isolate.popleft()
                            broken = not _submit(pool, inflight, alone, isolate, runner, timeout)
                            alone = None if broken else alone
                    else:
                        while queue and len(inflight) <= n and not broken:
                            run = queue.popleft()
                            broken = not _submit(pool, inflight, run, queue, runner, timeout)
                    if broken and not inflight:
                        break
                    done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                    for fut in done:
                        run = inflight.pop(fut)
                        try:
                            record, files = fut.result()
                        except BrokenProcessPool:
                            lost.append(run)
                            continue
                        store(record, files)
            except BaseException:
                _terminate(pool)
                raise
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            lost.extend(inflight.values())
            if lost == [alone] and alone is not None:
                log.warning("run %s killed its worker process again: recorded failed", alone.id)
                msg = (
                    "WorkerDied: the worker process died (killed or crashed) while running "
                    "this run, twice (the second time alone)"
                )
                store(_failed(alone, msg, "local"), {})
            elif lost:
                ids = ", ".join(r.id for r in lost)
                log.warning("a worker process died; running again one at a time: %s", ids)
                isolate.extend(lost)


def _submit(
    pool: ProcessPoolExecutor,
    inflight: dict[Future[tuple[RunRecord, RunFiles]], Run],
    run: Run,
    back: deque[Run],
    runner: Runner,
    timeout: float | None,
) -> bool:
    """Submit ``run`` to ``pool`` (into ``inflight``); False if the pool is broken already.

    A worker that died since the last wait breaks the pool before its future says so: the run
    goes back to the front of ``back`` (not started, it cannot have killed the worker).
    """
    try:
        inflight[pool.submit(execute, run, runner, timeout, "local")] = run
    except BrokenProcessPool:
        back.appendleft(run)
        return False
    return True


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop a pool's worker processes now (their runs in flight are lost)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python >= 3.14
    if terminate is not None:
        terminate()
        return
    processes = getattr(pool, "_processes", None) or {}
    for proc in list(processes.values()):
        with contextlib.suppress(Exception):
            proc.terminate()


def _dask_execute(run: Run, runner: Runner, timeout: float | None) -> tuple[RunRecord, RunFiles]:
    """The task run on a Dask worker."""
    _pin_threads()
    try:
        from distributed import get_worker

        where = f"dask:{get_worker().address}"
    except (ImportError, ValueError):
        where = "dask"
    return execute(run, runner, timeout, where)


def _run_dask(
    todo: Sequence[Run],
    scheduler: Any,
    workers: int | None,
    runner: Runner,
    timeout: float | None,
    store: Callable[[RunRecord, RunFiles], None],
) -> None:
    """Run on a Dask cluster.

    A task that fails there (e.g. its worker was killed too often) is recorded as failed.
    """
    try:
        import distributed
    except ImportError as exc:
        raise ConfigurationError(
            "scheduler",
            scheduler,
            "dask.distributed installed (pip install 'packbot[distributed]')",
        ) from exc
    with contextlib.ExitStack() as stack:
        if not log.isEnabledFor(logging.INFO):  # Dask logs every start and stop at INFO
            dlog = logging.getLogger("distributed")
            stack.callback(dlog.setLevel, dlog.level)
            dlog.setLevel(logging.WARNING)
        if isinstance(scheduler, distributed.Client):
            client = scheduler
        elif scheduler == "local":
            cluster = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=workers or os.cpu_count() or 1,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address="127.0.0.1:0",
                    env=dict(SINGLE_THREAD_ENV),
                )
            )
            client = stack.enter_context(distributed.Client(cluster))
            log.warning("Dask LocalCluster: dashboard at %s", client.dashboard_link)
        elif isinstance(scheduler, str):
            client = stack.enter_context(distributed.Client(scheduler))
        else:
            raise ConfigurationError(
                "scheduler", scheduler, "'tcp://host:port', 'local' or a distributed.Client"
            )
        futures = {
            client.submit(
                _dask_execute, run, runner, timeout, key=f"packbot-{run.id}-{os.urandom(4).hex()}"
            ): run
            for run in todo
        }
        try:
            for fut in distributed.as_completed(list(futures)):
                run = futures[fut]
                try:
                    record, files = fut.result()
                except Exception as exc:  # KilledWorker, a failed deserialization, ...
                    record, files = _failed(run, f"{type(exc).__name__}: {exc}", "dask"), {}
                store(record, files)
        except BaseException:
            client.cancel(list(futures))
            raise


def _failed(run: Run, message: str, worker: str) -> RunRecord:
    return RunRecord(
        id=run.id,
        index=run.index,
        params=run.params,
        digest=run.digest,
        status="failed",
        error=message,
        worker=worker,
    )


# ---------------------------------------------------------------------------------- files
@checked_arguments
def read_records(out_dir: str | Path, runs: Sequence[Run] | None = None) -> dict[str, RunRecord]:
    """The run records in ``out_dir/runs/`` (of ``runs`` only, if given), by id.

    An unreadable record (corrupt, another format) is skipped with a warning: its run counts as
    not finished. The checksums are not verified here (:func:`run_batch` verifies them).
    """
    folder = Path(out_dir) / "runs"
    if runs is None:
        paths = sorted(folder.glob("*.json"))
    else:
        paths = [folder / f"{r.id}.json" for r in runs]
    out: dict[str, RunRecord] = {}
    for path in paths:
        if not path.is_file():
            continue
        try:
            rec = RunRecord.from_json(json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError, ConfigurationError) as exc:
            log.warning("ignoring unreadable run record %s: %s", path, exc)
            continue
        out[rec.id] = rec
    return out


def _store(
    out: Path, record: RunRecord, files: RunFiles, moved: dict[str, str] | None = None
) -> None:
    """Write a run's files, then its record (last: it marks the run finished).

    Whatever is in the way and cannot be read (a directory where a file goes, a file where the
    run's folder goes) is moved aside first (:func:`_move_aside`; noted in ``moved``).
    """
    moved = {} if moved is None else moved
    record.files = {}
    record.file_sha256 = {}
    for role, (name, data) in files.items():
        rel = _file_path(record.id, name)
        if rel is None:
            raise ConfigurationError(
                f"files.{role}", name, f"a plain file name, or {record.id}/<plain file name>"
            )
        _clear_way(out, rel, moved)
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out / rel, data)
        record.files[role] = rel
        record.file_sha256[role] = hashlib.sha256(data).hexdigest()
    _clear_way(out, f"runs/{record.id}.json", moved)
    atomic_write(out / "runs" / f"{record.id}.json", _record_bytes(record))


def _unreadable(path: Path) -> bool:
    """Whether something is at ``path`` that is not a regular file this process can read."""
    if path.is_symlink() and not path.exists():
        return False  # a dangling link: replaced by the rename as it is
    return path.exists() and not (path.is_file() and os.access(path, os.R_OK))


def _clear_way(out: Path, rel: str, moved: dict[str, str]) -> None:
    """Move aside what is in the way of writing ``out/rel``.

    That is a non-folder where a folder goes, or an unreadable thing (a directory, a special
    file) where the file goes.
    """
    parts = Path(rel).parts
    for k in range(1, len(parts)):
        folder = out.joinpath(*parts[:k])
        if (folder.exists() or folder.is_symlink()) and not folder.is_dir():
            _move_aside(out, folder, moved)
    target = out / rel
    if _unreadable(target):
        _move_aside(out, target, moved)


def _move_aside(out: Path, path: Path, moved: dict[str, str]) -> Path:
    """Rename ``path`` to ``<name>.bad-<n>`` beside it (the first free n), with a warning."""
    n = 1
    while True:
        new = path.with_name(f"{path.name}.bad-{n}")
        if not (new.exists() or new.is_symlink()):
            break
        n += 1
    os.rename(path, new)
    what = "a directory" if new.is_dir() else "not a readable file"
    rel_old, rel_new = path.relative_to(out).as_posix(), new.relative_to(out).as_posix()
    log.warning(
        "%s: %s is %s: moved aside to %s (its run is made again)", out, rel_old, what, rel_new
    )
    moved[rel_old] = rel_new
    return new


def _plain_name(name: str) -> bool:
    return bool(name) and Path(name).name == name and not name.startswith(".")


def _file_path(rid: str, name: str) -> str | None:
    """Where a run's file goes, relative to the output folder (None: a name not allowed).

    A plain name goes to ``trajectories/<name>``; ``"<run id>/<name>"`` to the run's folder.
    """
    if _plain_name(name):
        return f"trajectories/{name}"
    folder, _, rest = name.partition("/")
    if folder == rid and _plain_name(rest):
        return name
    return None


def _record_bytes(record: RunRecord) -> bytes:
    """The record file: readable JSON of :meth:`RunRecord.to_json` plus ``record_sha256``.

    ``record_sha256`` is the SHA-256 of the canonical JSON (sorted keys, no spaces) of the rest;
    floats are written as their shortest repr, so the JSON read back gives the same canonical
    text and the same checksum.
    """
    data = record.to_json()
    data["record_sha256"] = _sha256_json(data)
    return (json.dumps(data, indent=1, allow_nan=False) + "\n").encode()


def _sha256_json(data: Mapping[str, Any]) -> str:
    return hashlib.sha256(canonical_json(data).encode()).hexdigest()


@checked_arguments
def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes, read in blocks of 1 MiB."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class _Check(NamedTuple):
    """What :func:`_check_record` found."""

    record: RunRecord | None  # the record, if it can be trusted (else None)
    reason: str | None  # why the run must be made again (None: finished, or no record)
    detail: str = ""  # the evidence, for the log
    files: tuple[Path, ...] = ()  # the run's files, per its verified record


def _check_record(out: Path, run: Run) -> _Check:
    """Verify a run's record and files.

    Returns ``(None, None)`` for no record; ``(record, None)`` for a finished run; otherwise the
    reason to make it again, with the record if it can be trusted (failed or stale: its
    checksum matches) and its files (removed if the run, made again, does not rewrite them).
    """
    path = out / "runs" / f"{run.id}.json"
    if _unreadable(path):
        return _Check(None, RERUN_UNREADABLE_FILE, f"runs/{run.id}.json is not a readable file")
    if not path.is_file():
        return _Check(None, None)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        return _Check(None, RERUN_MALFORMED, f"{type(exc).__name__}: {exc}")
    if not isinstance(data, dict):
        return _Check(None, RERUN_MALFORMED, f"a JSON {type(data).__name__}, not an object")
    fmt = data.get("format")
    if fmt in LEGACY_RECORD_FORMATS:
        return _Check(None, RERUN_OLD_FORMAT, f"format {fmt!r}, not {RECORD_FORMAT!r}")
    if fmt != RECORD_FORMAT:
        return _Check(None, RERUN_MALFORMED, f"format {fmt!r}, not {RECORD_FORMAT!r}")
    stored = data.pop("record_sha256", None)
    actual = _sha256_json(data)
    if stored != actual:
        return _Check(None, RERUN_EDITED, f"record_sha256 {stored!r}, content {actual}")
    try:
        rec = RunRecord.from_json(data)
    except ConfigurationError as exc:
        return _Check(None, RERUN_MALFORMED, str(exc))
    if rec.id != run.id:
        return _Check(None, RERUN_EDITED, f"the record of run {rec.id!r}, not {run.id!r}")
    paths: list[Path] = []
    for role, rel in rec.files.items():
        parts = Path(rel).parts
        if (
            len(parts) != 2
            or parts[0] not in ("trajectories", run.id)
            or not _plain_name(parts[1])
            or rel != "/".join(parts)
        ):
            return _Check(
                None,
                RERUN_EDITED,
                f"files.{role} = {rel!r} is not trajectories/<name> or {run.id}/<name>",
            )
        if role not in rec.file_sha256:
            return _Check(None, RERUN_EDITED, f"no checksum of files.{role}")
        paths.append(out / rel)
    files = tuple(paths)
    if rec.status != "ok":
        return _Check(rec, RERUN_FAILED, rec.error, files)
    if rec.digest != run.digest:
        return _Check(rec, RERUN_STALE, f"digest {rec.digest}, scenario now {run.digest}", files)
    for role, file in zip(rec.files, files, strict=True):
        if _unreadable(file):
            detail = f"{rec.files[role]} ({role}) is not a readable file"
            return _Check(None, RERUN_UNREADABLE_FILE, detail, files)
        if not file.is_file():
            return _Check(None, RERUN_MISSING_FILE, f"{rec.files[role]} ({role})", files)
        try:
            got = file_sha256(file)
        except OSError as exc:
            return _Check(None, RERUN_MISSING_FILE, f"{rec.files[role]}: {exc}", files)
        if got != rec.file_sha256[role]:
            detail = f"{rec.files[role]}: SHA-256 {got}, recorded {rec.file_sha256[role]}"
            return _Check(None, RERUN_CORRUPT_FILE, detail, files)
    return _Check(rec, None, "", files)


def _count_reasons(rerun: Mapping[str, str]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for why in rerun.values():
        counts[why] = counts.get(why, 0) + 1
    return counts


def _log_reruns(out: Path, rerun: Mapping[str, str], details: Mapping[str, str]) -> None:
    """Log the runs made again: one line per run whose record or files did not verify."""
    routine = (RERUN_FAILED, RERUN_STALE)
    for rid, why in rerun.items():
        if why not in routine and why != RERUN_OLD_FORMAT:
            log.warning("%s: run %s made again: %s: %s", out, rid, why, details.get(rid, ""))
    for why, n in _count_reasons(rerun).items():
        if why == RERUN_OLD_FORMAT:
            log.warning("%s: %d runs made again: %s", out, n, why)
        elif why in routine:
            log.info("%s: %d runs made again: %s", out, n, why)


@checked_arguments
def csv_text(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> str:
    """Rows as CSV text: a header, floats exact (shortest repr), None as an empty cell.

    A text cell a spreadsheet would run as a formula (beginning with ``=``, ``+``, ``-``, ``@``,
    a tab or a carriage return, and not a number) gets a leading ``'``
    (:func:`packbot.csv_cells.spreadsheet_safe`); numbers, ``-0.5`` among them, stay numbers.
    """
    import csv
    import io

    # Rows end in "\n"; written with "\r\n" so that a cell holding a carriage return is quoted
    # (the writer quotes the characters of its line terminator), then the row's end replaced.
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\r\n")
    lines = []
    for cells in (
        columns,
        *(
            ["" if v is None else repr(v) if isinstance(v, float) else v for v in cells]
            for cells in ([row.get(c) for c in columns] for row in rows)
        ),
    ):
        buf.seek(0)
        buf.truncate()
        w.writerow(spreadsheet_row(cells))
        lines.append(buf.getvalue()[:-2] + "\n")
    return "".join(lines)


@checked_arguments
def atomic_write(path: Path, data: bytes) -> None:
    """Write a file atomically: a temporary file in the same folder, then renamed over ``path``.

    A process killed at any point leaves the old file or the new one, never a part of it. The
    data are not fsync'ed (that would cost about 4 ms per file here): a crash of the machine
    itself may lose the last files written.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@checked_arguments
def summary_rows(runs: Sequence[Run], records: Mapping[str, RunRecord]) -> list[dict[str, Any]]:
    """One row per run of the matrix (status ``"missing"`` for a run without a record).

    Columns: ``id``, ``index``, the parameters (lists and tables as JSON), ``status``,
    ``q.<joint>`` [rad], ``rest_time`` [s], ``n_impacts``, ``n_limits``, ``n_events``,
    ``min_distance`` [m], ``energy_change`` [J], ``t_end`` [s], ``wall_time`` [s], ``worker``,
    ``error``; then ``metrics.<name>`` for each name of the records' :attr:`RunRecord.metrics`.
    Records with metrics and none with a final state (a failure study's cells) have no
    simulation columns (``q.<joint>`` to ``t_end``). Missing values are None.
    """
    param_names: list[str] = []
    joints: list[str] = []
    metric_names: list[str] = []
    for run in runs:
        param_names += [k for k in run.params if k not in param_names]
        rec = records.get(run.id)
        if rec is not None:
            joints += [j for j in rec.joint_names if j not in joints]
            metric_names += [k for k in rec.metrics if k not in metric_names]
    simulation = bool(joints) or not metric_names
    rows = []
    for run in runs:
        rec = records.get(run.id)
        row: dict[str, Any] = {"id": run.id, "index": run.index}
        for name in param_names:
            value = run.params.get(name)
            row[name] = json.dumps(value) if isinstance(value, (list, dict)) else value
        row["status"] = "missing" if rec is None else rec.status
        q = dict(zip(rec.joint_names, rec.final_q, strict=True)) if rec is not None else {}
        for j in joints:
            row[f"q.{j}"] = q.get(j)
        keys = ("rest_time", "n_impacts", "n_limits", "n_events", "min_distance")
        for key in (*keys, "energy_change", "t_end") if simulation else ():
            row[key] = None if rec is None or rec.status != "ok" else getattr(rec, key)
        row["wall_time"] = None if rec is None else rec.wall_time
        row["worker"] = None if rec is None else rec.worker
        row["error"] = None if rec is None else rec.error
        for key in metric_names:
            row[f"metrics.{key}"] = None if rec is None else rec.metrics.get(key)
        rows.append(row)
    return rows


@checked_arguments
def write_summary(
    out_dir: str | Path, runs: Sequence[Run], records: Mapping[str, RunRecord]
) -> list[Path]:
    """Write ``summary.csv`` and, if pyarrow is installed, ``summary.parquet`` (atomically).

    Floats are written exactly (shortest repr that reads back the same number).

    Returns:
        The files written.
    """
    import io

    rows = summary_rows(runs, records)
    columns = list(rows[0]) if rows else ["id", "status"]
    out = Path(out_dir)
    paths = [out / "summary.csv"]
    atomic_write(paths[0], csv_text(rows, columns).encode())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        log.info("pyarrow not installed: no summary.parquet")
        return paths
    arrays = {}
    for c in columns:
        values = [row[c] for row in rows]
        try:
            arrays[c] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed types: as text
            arrays[c] = pa.array([None if v is None else json.dumps(v) for v in values])
    sink = io.BytesIO()
    pq.write_table(pa.table(arrays), sink)
    paths.append(out / "summary.parquet")
    atomic_write(paths[1], sink.getvalue())
    return paths


def _enc(x: float) -> float | str:
    """A float for JSON: finite as is (exact repr), else ``"inf"``, ``"-inf"``, ``"nan"``."""
    x = float(x)
    return x if math.isfinite(x) else str(x)


def _dec(x: Any) -> float:
    return float(x)
