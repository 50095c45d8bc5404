"""Uncertain studies and runs through the batch machinery: local pool or Dask, resumable.

:func:`run_uncertain_study` studies the arms of :func:`packbot.uncertain_study.
plan_uncertain_study` and :func:`run_uncertain_runs` runs those of :func:`packbot.uncertain_run.
plan_uncertain_run`, each arm a run of :func:`packbot.batch.run_batch` (this process, a local
pool or a Dask cluster). Under the output folder::

    arm_0000/arm.json ...       each arm's study or run (ArmStudy / ArmRun .to_dict), one file
    runs/arm_0000.json ...      the batch's record of each arm (checksums: packbot.batch)
    matrix.json, summary.csv    what defines the arms (the scenario, the draw, the options)
    batch.lock                  held while it runs
    uncertain.json, report.html, uncertain_*.png/svg       a study's spread and its figures
    uncertain-run.json, uncertain_run.png/svg              a run's spread and its figure

A killed or interrupted call loses only the arms in flight: rerun it and the arms whose record
and file verify are read back, not run again (:attr:`UncertainReport.batch`: executed, skipped,
rerun). A folder holds one draw: another scenario, seed, size or option is refused (the batch's
matrix check). Each arm runs the same code wherever it runs (:meth:`packbot.uncertain_study.
UncertainPlan.study_arm`, :meth:`packbot.uncertain_run.UncertainRunPlan.run_arm`), so this
process, a local worker and a Dask worker give the same numbers.
"""

from __future__ import annotations

import functools
import json
import logging
import os
import re
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from packbot.batch import BatchReport, RunFiles, RunRecord, atomic_write, run_batch
from packbot.errors import ConfigurationError, SimulationError
from packbot.keywords import checked_arguments
from packbot.matrix import Matrix, Run, digest
from packbot.study import DEFAULT_TOLERANCE, RUN_NAMES
from packbot.uncertain_run import ArmRun, UncertainRunPlan, plan_uncertain_run
from packbot.uncertain_study import ArmStudy, UncertainPlan, plan_uncertain_study

if TYPE_CHECKING:
    from packbot.control.user_code import ControllerSpec, StrategySpec

__all__ = [
    "ARM_FILE",
    "ArmTimeout",
    "UncertainReport",
    "run_uncertain_runs",
    "run_uncertain_study",
    "uncertain_arm_run",
    "uncertain_arm_study",
]

log = logging.getLogger(__name__)

#: Name of each arm's file in its folder (``arm_0000/arm.json``).
ARM_FILE = "arm.json"


class ArmTimeout(SimulationError):
    """An arm exceeded its wall-time limit (``timeout``); its record says failed."""


@dataclass(kw_only=True)
class UncertainReport:
    """What :func:`run_uncertain_study` or :func:`run_uncertain_runs` did.

    Attributes:
        result: The spread (:class:`~packbot.uncertain_study.UncertainStudy` or
            :class:`~packbot.uncertain_run.UncertainRun`); an arm the batch recorded failed
            (a wall-time limit, a worker lost) is in it with that error.
        batch: The batch's report (executed, skipped, rerun, failed).
        files: Name -> path of the summary's files.
    """

    result: Any
    batch: BatchReport
    files: dict[str, Path] = field(default_factory=dict)

    def describe(self) -> str:
        """The batch's counts and the files, for the command line."""
        lines = [self.batch.describe()]
        lines += [f"wrote {p}" for p in self.files.values()]
        return "\n".join(lines)


def _arm_id(k: int) -> str:
    return f"arm_{k:04d}"


def _step(progress: Callable[[float], None]) -> Callable[[float], None]:
    def step(t: float) -> None:
        try:
            progress(t)
        except SimulationError as exc:  # the batch's wall-time limit
            raise ArmTimeout(str(exc).split(": ", 1)[-1], t) from None

    return step


@checked_arguments
def uncertain_arm_study(
    run: Run, progress: Callable[[float], None], *, plan: UncertainPlan
) -> tuple[dict[str, Any], RunFiles]:
    """The batch's run function of one arm's study (bound with ``functools.partial``).

    Studies arm ``run.index`` (:meth:`UncertainPlan.study_arm`, its description package in a
    temporary folder) and returns its :class:`ArmStudy` as ``arm_<k>/arm.json`` and the headline
    metrics of the record (the verdict, each run's status and final task error [m]).

    Raises:
        ArmTimeout: The wall-time limit was exceeded.
    """
    with tempfile.TemporaryDirectory(prefix="packbot-arm-") as tmp:
        arm = plan.study_arm(run.index, tmp, step=_step(progress))
    metrics: dict[str, Any] = {"possible": arm.possible, "recovered": arm.recovered}
    for name in RUN_NAMES:
        m = arm.metrics.get(name)
        metrics[f"{name}_status"] = arm.status.get(name)
        metrics[f"{name}_final_task_error_m"] = None if m is None else m.final_task_error_m
    data = json.dumps(arm.to_dict(), allow_nan=False).encode()
    return {"metrics": metrics, "t_end": plan.duration_s}, {"arm": (f"{run.id}/{ARM_FILE}", data)}


@checked_arguments
def uncertain_arm_run(
    run: Run, progress: Callable[[float], None], *, plan: UncertainRunPlan
) -> tuple[dict[str, Any], RunFiles]:
    """The batch's run function of one arm's run of the scenario (``functools.partial``).

    Runs arm ``run.index`` (:meth:`UncertainRunPlan.run_arm`) and returns its :class:`ArmRun`
    as ``arm_<k>/arm.json``, and its final angles and events as the record's quantities.

    Raises:
        ArmTimeout: The wall-time limit was exceeded.
    """
    with tempfile.TemporaryDirectory(prefix="packbot-arm-") as tmp:
        arm = plan.run_arm(run.index, tmp, progress=_step(progress))
    data = json.dumps(arm.to_dict(), allow_nan=False).encode()
    quantities: dict[str, Any] = {"t_end": plan.duration_s}
    if arm.ok:
        quantities |= {
            "joint_names": tuple(arm.final_q),
            "final_q": tuple(arm.final_q.values()),
            "rest_time": arm.rest_time,
            "n_impacts": arm.events.get("impact", 0),
            "n_limits": arm.events.get("limit", 0),
            "n_events": sum(arm.events.values()),
            "min_distance": arm.min_distance,
            "energy_change": arm.energy_change,
            "metrics": {f"link3_end_{a}_m": x for a, x in zip("xyz", arm.link3_end, strict=True)},
        }
    else:
        quantities["metrics"] = {"error": arm.error}
    return quantities, {"arm": (f"{run.id}/{ARM_FILE}", data)}


def _matrix(kind: str, scenario: str | Path, identity: dict[str, Any], n: int) -> Matrix:
    """The batch's matrix: one axis ``arm``, the draw and the options in its ``study`` table."""
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", str(identity["scenario"])) or "scenario"
    return Matrix(
        name=f"{kind}-{name}",
        base=str(scenario),
        description=f"{kind} of {identity['scenario']}: {n} arms drawn within the tolerances",
        axes={"arm": list(range(n))},
        study={kind: identity},
    )


def _runs(
    scenario: str | Path, identity: dict[str, Any], values: Sequence[dict[str, float]]
) -> list[Run]:
    """One batch run per arm, its digest over the scenario file, the arm's values, the options.

    A changed scenario file makes every arm stale.
    """
    from packbot.scenario import read_scenario_dict, scenario_path

    raw = read_scenario_dict(scenario)
    text = scenario_path(scenario).read_text(errors="replace")
    runs = []
    for k, arm in enumerate(values):
        resolved = {"scenario": raw, "arm": arm, "options": identity}
        runs.append(
            Run(
                id=_arm_id(k),
                index=k,
                params={"arm": k},
                scenario=resolved,
                scenario_name=str(identity["scenario"]),
                digest=digest(resolved),
                source_text=text,
            )
        )
    return runs


def _scenario_path(scenario: Any) -> str | Path:
    if isinstance(scenario, (str, os.PathLike)) and str(scenario):
        return scenario if isinstance(scenario, str) else Path(scenario)
    raise ConfigurationError(
        "scenario",
        type(scenario).__name__,
        "a scenario name or TOML path (the batch's records check its file; a Scenario built in "
        "code: packbot.uncertain_study or packbot.uncertain_run, in this process)",
    )


def _where(workers: int | None, scheduler: Any) -> str:
    if scheduler is not None:
        return f"dask {scheduler if isinstance(scheduler, str) else type(scheduler).__name__}"
    if workers == 0:
        return "this process"
    n = (os.cpu_count() or 1) if workers is None else workers
    return f"{n} local process{'es' if n != 1 else ''}"


def _read_arms(
    batch: BatchReport, read: Callable[[dict[str, Any]], Any], failed: Callable[[int, str], Any]
) -> list[Any]:
    """Each arm from its file; an arm the batch recorded failed, from its record's error."""
    arms = []
    for run in batch.runs:
        record: RunRecord | None = batch.records.get(run.id)
        if record is None or record.status != "ok":
            why = "not run" if record is None else record.error
            arms.append(failed(run.index, why))
            continue
        path = batch.out_dir / record.files["arm"]
        arms.append(read(json.loads(path.read_text(encoding="utf-8"))))
    return arms


def _write_json(path: Path, data: dict[str, Any]) -> Path:
    atomic_write(path, (json.dumps(data, indent=1, allow_nan=False) + "\n").encode())
    return path


def _check_specs(controller: Any, recovery: Any) -> None:
    from packbot.control.user_code import check_picklable

    if controller is not None:
        check_picklable(controller, "controller")
    if recovery != "builtin":
        check_picklable(recovery, "recovery")


@checked_arguments
def run_uncertain_study(
    scenario: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    samples: int = 8,
    seed: int = 0,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    duration: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    contact_mode: str | None = None,
    workspace_samples: int = 2000,
    controller: ControllerSpec | None = None,
    recovery: StrategySpec = "builtin",
    workers: int | None = None,
    scheduler: Any = None,
    timeout: float | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    html: bool = True,
) -> UncertainReport:
    """:func:`packbot.uncertain_study` through the batch machinery, resumable; its report.

    Args:
        scenario: A scenario name (``sims/``) or a TOML path with ``[[failures]]``.
        out_dir: Output folder (created; an existing one of the same draw is resumed).
        samples: As :func:`packbot.uncertain_study` (and ``seed``, ``vary``, ``method``,
            ``duration``, ``tolerance``, ``contact_mode``, ``workspace_samples``).
        seed: See ``samples``.
        vary: See ``samples``.
        method: See ``samples``.
        duration: See ``samples``.
        tolerance: See ``samples``.
        contact_mode: See ``samples``.
        workspace_samples: See ``samples``.
        controller: Your controller on every arm: an import path ``"module:Name"`` or a class
            or factory defined at a module's top level (it travels to the workers by pickling;
            a lambda is refused).
        recovery: Your recovery strategy, likewise.
        workers: Local worker processes (default: the CPUs; 0: this process); with
            ``scheduler="local"``, Dask's workers (:func:`packbot.batch.run_batch`).
        scheduler: None (local processes), a Dask scheduler's address ``"tcp://host:port"``,
            ``"local"`` or a ``distributed.Client``.
        timeout: Wall-time limit of each arm's study [s], or None.
        progress: Called as ``progress(done, failed, total)`` (arms).
        html: Write ``report.html`` beside ``uncertain.json`` and the figures.

    Returns:
        The report: the :class:`~packbot.uncertain_study.UncertainStudy` (``result``), the
        batch's report, the files written.

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid), a folder
            holding another draw's arms.
        BatchLockedError: Another batch runs in ``out_dir``.
        KeyboardInterrupt: Ctrl-C; the finished arms are kept (rerun to finish).
    """
    path = _scenario_path(scenario)
    if not isinstance(html, bool):
        raise ConfigurationError("html", html, "true or false")
    plan = plan_uncertain_study(
        path,
        samples=samples,
        seed=seed,
        vary=vary,
        method=method,
        duration=duration,
        tolerance=tolerance,
        contact_mode=contact_mode,
        workspace_samples=workspace_samples,
        controller=controller,
        recovery=recovery,
    )
    _check_specs(controller, recovery)
    unc, batch, summary = _run_arms(
        "uncertain",
        path,
        out_dir,
        plan,
        functools.partial(uncertain_arm_study, plan=plan),
        (ArmStudy.from_dict, ArmStudy.failed),
        workers=workers,
        scheduler=scheduler,
        timeout=timeout,
        progress=progress,
    )
    from packbot.viz.uncertain_report import write_uncertain_report

    files = write_uncertain_report(summary, batch.out_dir, html=html)
    return UncertainReport(result=unc, batch=batch, files=files)


@checked_arguments
def run_uncertain_runs(
    scenario: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    samples: int = 8,
    seed: int = 0,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    duration: float | None = None,
    controller: ControllerSpec | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    timeout: float | None = None,
    progress: Callable[[int, int, int], None] | None = None,
) -> UncertainReport:
    """:func:`packbot.uncertain_run` through the batch machinery, resumable; its figure.

    Writes ``uncertain-run.json`` (:meth:`~packbot.uncertain_run.UncertainRun.summary`) and
    ``uncertain_run.png`` / ``.svg`` (:func:`packbot.viz.uncertain_report.
    uncertain_run_figure`) into ``out_dir``.

    Args:
        scenario: A scenario name (``sims/``) or a TOML path.
        out_dir: Output folder (created; an existing one of the same draw is resumed).
        samples: As :func:`packbot.uncertain_run` (and ``seed``, ``vary``, ``method``,
            ``duration``).
        seed: See ``samples``.
        vary: See ``samples``.
        method: See ``samples``.
        duration: See ``samples``.
        controller: Your controller instead of the scenario's (an import path or a top-level
            class or factory: it must pickle).
        workers: As :func:`run_uncertain_study`.
        scheduler: As :func:`run_uncertain_study`.
        timeout: Wall-time limit of each arm's run [s], or None.
        progress: Called as ``progress(done, failed, total)`` (arms).

    Returns:
        The report (``result``: the :class:`~packbot.uncertain_run.UncertainRun`).

    Raises:
        ConfigurationError: A bad argument, a folder holding another draw's arms.
        BatchLockedError: Another batch runs in ``out_dir``.
        KeyboardInterrupt: Ctrl-C; the finished arms are kept.
    """
    path = _scenario_path(scenario)
    plan = plan_uncertain_run(
        path,
        samples=samples,
        seed=seed,
        vary=vary,
        method=method,
        duration=duration,
        controller=controller,
    )
    _check_specs(controller, "builtin")
    unc, batch, summary = _run_arms(
        "uncertain-run",
        path,
        out_dir,
        plan,
        functools.partial(uncertain_arm_run, plan=plan),
        (ArmRun.from_dict, lambda k, why: ArmRun(index=k, error=why)),
        workers=workers,
        scheduler=scheduler,
        timeout=timeout,
        progress=progress,
    )
    from packbot.viz.uncertain_report import write_uncertain_run

    files = write_uncertain_run(summary, batch.out_dir)
    return UncertainReport(result=unc, batch=batch, files=files)


def _run_arms(
    kind: str,
    path: str | Path,
    out_dir: str | os.PathLike[str],
    plan: UncertainPlan | UncertainRunPlan,
    runner: Callable[[Run, Callable[[float], None]], tuple[dict[str, Any], RunFiles]],
    arm: tuple[Callable[[dict[str, Any]], Any], Callable[[int, str], Any]],
    *,
    workers: int | None,
    scheduler: Any,
    timeout: float | None,
    progress: Callable[[int, int, int], None] | None,
) -> tuple[Any, BatchReport, dict[str, Any]]:
    """Run the plan's arms as a batch in ``out_dir`` and gather them.

    Args:
        kind: The batch's kind (its matrix's name and ``study`` table).
        path: The scenario's name or TOML path.
        out_dir: Output folder.
        plan: The checked, drawn arms.
        runner: The batch's run function of one arm, bound to ``plan``.
        arm: How an arm is read from its file, and made from the error of an arm the batch
            recorded failed (``failed(k, why)``).
        workers: As :func:`packbot.batch.run_batch`.
        scheduler: As :func:`packbot.batch.run_batch`.
        timeout: As :func:`packbot.batch.run_batch`.
        progress: As :func:`packbot.batch.run_batch`.

    Returns:
        The plan's result, the batch's report and the result's summary with the batch's counts.
    """
    identity = plan.identity()
    values = [plan.arm_values(k) for k in range(len(plan))]
    start = time.perf_counter()
    batch = run_batch(
        _matrix(kind, path, identity, len(plan)),
        out_dir if isinstance(out_dir, str) else Path(out_dir),
        runs=_runs(path, identity, values),
        workers=workers,
        scheduler=scheduler,
        runner=runner,
        timeout=timeout,
        progress=progress,
    )
    arms = _read_arms(batch, *arm)
    unc = plan.result(arms, time.perf_counter() - start, _where(workers, scheduler))
    return unc, batch, unc.summary() | {"batch": _batch_counts(batch)}


def _batch_counts(batch: BatchReport) -> dict[str, Any]:
    return {
        "executed": len(batch.executed),
        "skipped": len(batch.skipped),
        "rerun": dict(batch.rerun),
        "failed": list(batch.failed),
    }
