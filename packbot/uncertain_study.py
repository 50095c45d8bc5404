"""The failure study over the model's uncertainty: one study per arm drawn within the tolerances.

:func:`uncertain_study` draws ``samples`` arms within the parameter table's tolerances (the
draw of :func:`packbot.sample_robots`: :func:`packbot.sample_values`, quasi-random, a scrambled
Sobol sequence by default, each arm built by :func:`packbot.uncertainty.robot_from_values`
where it runs), runs :func:`packbot.study` on each (the same options, the user's controller and
recovery strategy included) and returns an :class:`UncertainStudy`:

- :meth:`UncertainStudy.quantiles`: per run (``"healthy"``, ``"failed"``, ``"reconfigured"``)
  and numeric metric of :class:`~packbot.study.RunMetrics` the 5th, 50th and 95th percentiles
  over the arms;
- :attr:`UncertainStudy.recovery_probability`: the share of arms whose reconfigured run ends
  within the study's tolerance (``RunMetrics.recovered``, what ``study`` reports as recovered),
  with its 95 % Wilson score interval (:attr:`UncertainStudy.recovery_interval`);
- :meth:`UncertainStudy.sensitivity`: the sampled parameters ranked by the absolute Spearman
  rank correlation between their drawn values and a metric.

Each arm's study keeps its metrics, its runs' statuses and its verdict (not its trajectories:
:class:`ArmStudy`). An arm whose study raises a :class:`~packbot.errors.PackbotError` or one of
whose runs is not ``"ok"`` is counted and reported (:attr:`UncertainStudy.counts`), never
dropped silently: its metrics are left out of the quantiles of that run only.

The controller on each arm is built on that arm's model (it knows the arm exactly): the spread
is that of the arm's physics, not of a controller tuned on the nominal model running a different
arm.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.study import DEFAULT_TOLERANCE, RUN_NAMES, RunMetrics
from packbot.validation import MAX_WORKERS, finite_number, integer

if TYPE_CHECKING:
    from packbot.control.user_code import ControllerSpec, StrategySpec
    from packbot.model import Robot
    from packbot.scenario import Scenario
    from packbot.uncertainty import ParameterSample

__all__ = [
    "METRICS",
    "PERCENTILES",
    "ArmStudy",
    "UncertainStudy",
    "uncertain_study",
    "wilson_interval",
]

log = logging.getLogger(__name__)

#: The percentiles :meth:`UncertainStudy.quantiles` returns.
PERCENTILES: tuple[int, ...] = (5, 50, 95)
#: The numeric metrics of :class:`~packbot.study.RunMetrics` (all but names, flags and the
#: wall time, which is not a property of the arm): what quantiles and sensitivity take.
METRICS: tuple[str, ...] = tuple(
    f.name
    for f in dataclasses.fields(RunMetrics)
    if str(f.type) in ("float", "int", "float | None") and f.name != "wall_time_s"
)
#: The metrics :meth:`UncertainStudy.summary` gives per run.
SUMMARY_METRICS: tuple[str, ...] = (
    "final_task_error_m",
    "rms_task_error_m",
    "max_task_error_m",
    "peak_torque_ratio",
    "peak_torque_nm",
    "detect_delay_s",
    "recover_time_s",
)
#: How many parameters :meth:`UncertainStudy.summary` lists per sensitivity ranking.
SUMMARY_TOP = 5
#: Two-sided 95 % standard normal quantile (the Wilson interval's z).
Z95 = 1.959963984540054
#: Most arms one call studies (:data:`packbot.uncertainty.MAX_SAMPLED_ROBOTS`).
MAX_SAMPLES = 1_000


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (95 % by default).

    Unlike the normal approximation it stays within [0, 1] and is not empty at 0 or ``trials``
    successes, which matters for the few arms a study affords.

    Example::

        wilson_interval(4, 4)  # (0.51, 1.0): four recoveries out of four arms

    Args:
        successes: Number of successes (0 to ``trials``).
        trials: Number of trials (>= 1).
        z: The standard normal quantile of the confidence (1.96: 95 %).

    Returns:
        (low, high), within [0, 1].

    Raises:
        ConfigurationError: ``trials`` < 1, ``successes`` outside [0, trials], ``z`` <= 0.
    """
    n = integer("trials", trials, low=1, what="a number of trials")
    k = integer("successes", successes, low=0, high=n, what="a number of successes")
    z = finite_number("z", z, low=0.0, low_open=True, what="a normal quantile")
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True, kw_only=True)
class ArmStudy:
    """One sampled arm's failure study, without its trajectories.

    Attributes:
        index: The arm's index in the sample.
        status: Per run name, the run's status (``"ok"``, ``"refused"``, ``"error"``), or
            ``"error"`` for every run when the study itself raised.
        reasons: Per run name, why it is not ok ("" when ok).
        metrics: Per run name, its metrics (None without: a run that is not ok).
        possible: The study's verdict on recovery (:attr:`packbot.study.Recovery.possible`).
        error: The error the study raised ("" if none).
        wall_time_s: Wall time of building the arm and studying it [s].
    """

    index: int
    status: dict[str, str]
    reasons: dict[str, str]
    metrics: dict[str, RunMetrics | None]
    possible: bool | None
    error: str = ""
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether every run of the arm's study is ``"ok"``."""
        return all(s == "ok" for s in self.status.values())

    @property
    def recovered(self) -> bool | None:
        """Whether the reconfigured run ends within the tolerance (None: no such run)."""
        m = self.metrics.get("reconfigured")
        return None if m is None else bool(m.recovered)


@dataclass(frozen=True, kw_only=True)
class UncertainStudy:
    """What :func:`uncertain_study` returns: the studies of the sampled arms and their spread.

    Attributes:
        scenario: The scenario's name.
        sample: The drawn parameter values (arm ``k`` is row ``k``).
        arms: Each arm's study (:class:`ArmStudy`), in sample order.
        tolerance_m: The studies' recovery tolerance [m].
        controller: The controller's description ("" : the scenario's).
        wall_time_s: Wall time of the whole call [s].
        workers: Processes used (1: this one).
    """

    scenario: str
    sample: ParameterSample
    arms: tuple[ArmStudy, ...]
    tolerance_m: float
    controller: str = ""
    wall_time_s: float = 0.0
    workers: int = 1

    def __len__(self) -> int:
        return len(self.arms)

    # ------------------------------------------------------------------------- values
    def values(self, run: str, metric: str) -> np.ndarray:
        """A metric of one run on every arm, NaN where the arm has none (shape (n,)).

        Raises:
            UnknownNameError: ``run`` or ``metric`` is not a valid name.
        """
        _check_run_metric(run, metric)
        out = np.full(len(self.arms), np.nan)
        for k, arm in enumerate(self.arms):
            m = arm.metrics.get(run)
            v = None if m is None else getattr(m, metric)
            if v is not None and math.isfinite(float(v)):
                out[k] = float(v)
        return out

    def quantiles(self, run: str, metric: str) -> dict[int, float]:
        """The 5th, 50th and 95th percentiles of a metric of a run over the arms.

        Linear interpolation between order statistics (NumPy's default); arms without the
        value (a run not ok, a metric that is None such as ``detect_delay_s`` without a
        detection) are left out (:meth:`count` says how many are in).

        Args:
            run: ``"healthy"``, ``"failed"`` or ``"reconfigured"``.
            metric: A name of :data:`METRICS` (e.g. ``"final_task_error_m"``).

        Returns:
            {5: ..., 50: ..., 95: ...} in the metric's unit; NaN values if no arm has it.

        Raises:
            UnknownNameError: ``run`` or ``metric`` is not a valid name.
        """
        x = self.values(run, metric)
        x = x[np.isfinite(x)]
        if len(x) == 0:
            return {p: math.nan for p in PERCENTILES}
        q = np.percentile(x, PERCENTILES)
        return {p: float(v) for p, v in zip(PERCENTILES, q, strict=True)}

    def count(self, run: str, metric: str) -> int:
        """How many arms have a value of ``metric`` for ``run``."""
        return int(np.isfinite(self.values(run, metric)).sum())

    # ----------------------------------------------------------------------- recovery
    @property
    def recovery_trials(self) -> int:
        """Arms whose reconfigured run has metrics (the probability's denominator)."""
        return sum(a.recovered is not None for a in self.arms)

    @property
    def recovery_successes(self) -> int:
        """Arms whose reconfigured run ends within the tolerance."""
        return sum(a.recovered is True for a in self.arms)

    @property
    def recovery_probability(self) -> float:
        """Share of the arms whose reconfigured run ends within the tolerance (NaN: none ran).

        The arms whose reconfigured run is not ``"ok"`` are not in the denominator; they are
        counted in :attr:`counts` (``"reconfigured_not_ok"``).
        """
        n = self.recovery_trials
        return self.recovery_successes / n if n else math.nan

    @property
    def recovery_interval(self) -> tuple[float, float]:
        """The 95 % Wilson score interval of :attr:`recovery_probability` ((NaN, NaN): none)."""
        n = self.recovery_trials
        if n == 0:
            return math.nan, math.nan
        return wilson_interval(self.recovery_successes, n)

    @property
    def possible_share(self) -> float:
        """Share of the arms whose study says recovery is possible (``Recovery.possible``).

        The arms where it was not assessed (None) are out of the denominator (NaN: none).
        """
        decided = [a.possible for a in self.arms if a.possible is not None]
        return sum(decided) / len(decided) if decided else math.nan

    @property
    def counts(self) -> dict[str, int]:
        """Arms in all, arms whose every run is ok, and per run the arms whose run is not ok."""
        out = {
            "arms": len(self.arms),
            "ok": sum(a.ok for a in self.arms),
            "errors": sum(bool(a.error) for a in self.arms),
        }
        for run in RUN_NAMES:
            out[f"{run}_not_ok"] = sum(a.status.get(run) != "ok" for a in self.arms)
        return out

    # -------------------------------------------------------------------- sensitivity
    def sensitivity(self, run: str, metric: str) -> list[tuple[str, float]]:
        """The sampled parameters ranked by how strongly a metric follows them.

        Spearman's rank correlation rho (:func:`scipy.stats.spearmanr`) between each sampled
        parameter's drawn values and the metric over the arms that have it, sorted by
        ``|rho|``, largest first. Rank correlation, not Sobol indices: Sobol indices need
        thousands of model runs per parameter (Saltelli's estimator: N * (d + 2) runs for d of
        them), and a study afford tens of arms; a rank correlation is defined for any N >= 3,
        catches monotone effects that are not linear, and is what the sample supports. With
        few arms it is noisy: read the top of the ranking, not its order further down.

        Args:
            run: ``"healthy"``, ``"failed"`` or ``"reconfigured"``.
            metric: A name of :data:`METRICS`.

        Returns:
            (parameter name, rho) for every sampled parameter, by ``|rho|`` descending; rho is
            NaN (listed last) where it is undefined: fewer than 3 arms with the metric, or the
            metric (or the parameter) the same on all of them.

        Raises:
            UnknownNameError: ``run`` or ``metric`` is not a valid name.
        """
        y = self.values(run, metric)
        keep = np.isfinite(y)
        names = self.sample.names
        rhos = [math.nan] * len(names)
        ys = y[keep]
        if keep.sum() >= 3 and np.ptp(ys) > 0:
            from scipy.stats import spearmanr  # lazy: scipy.stats costs ~0.3 s of import

            x = np.asarray(self.sample.values)[keep]
            for j in range(len(names)):
                if np.ptp(x[:, j]) > 0:
                    rhos[j] = float(spearmanr(x[:, j], ys).statistic)
        ranked = sorted(
            zip(names, rhos, strict=True),
            key=lambda nr: (math.isnan(nr[1]), -abs(nr[1]) if not math.isnan(nr[1]) else 0.0),
        )
        return ranked

    # ------------------------------------------------------------------------ summary
    def summary(self, top: int = SUMMARY_TOP) -> dict[str, Any]:
        """The spread, JSON-ready (what ``uncertain.json`` holds).

        Keys: the scenario, the sample (size, seed, method, the sampled parameters), the counts,
        per run and metric of :data:`SUMMARY_METRICS` the quantiles (``"5"``, ``"50"``,
        ``"95"``) and the number of arms with a value, the recovery probability and its Wilson
        interval, the share the studies judged possible, the ``top`` parameters of the
        sensitivity of each run's final task error and peak torque ratio, and per arm its
        statuses, its verdict and its reasons for a run not ok.
        """
        top = integer("top", top, low=1, what="a number of parameters")
        quant: dict[str, Any] = {}
        for run in RUN_NAMES:
            quant[run] = {
                metric: {str(p): _num(v) for p, v in self.quantiles(run, metric).items()}
                | {"arms": self.count(run, metric)}
                for metric in SUMMARY_METRICS
            }
        sens: dict[str, Any] = {}
        for run in ("failed", "reconfigured"):
            sens[run] = {
                metric: [
                    {"parameter": name, "rho": _num(rho)}
                    for name, rho in self.sensitivity(run, metric)[:top]
                ]
                for metric in ("final_task_error_m", "peak_torque_ratio")
            }
        lo, hi = self.recovery_interval
        return {
            "scenario": self.scenario,
            "controller": self.controller,
            "tolerance_m": self.tolerance_m,
            "sample": {
                "arms": len(self.arms),
                "seed": self.sample.seed,
                "method": self.sample.method,
                "parameters": list(self.sample.names),
            },
            "counts": self.counts,
            "quantiles": quant,
            "recovery": {
                "probability": _num(self.recovery_probability),
                "interval_95": [_num(lo), _num(hi)],
                "interval_method": "Wilson score",
                "recovered": self.recovery_successes,
                "arms": self.recovery_trials,
                "possible_share": _num(self.possible_share),
            },
            "sensitivity": {"method": "Spearman rank correlation", "top": sens},
            "arms": [
                {
                    "index": a.index,
                    "status": dict(a.status),
                    "possible": a.possible,
                    "recovered": a.recovered,
                    "error": a.error,
                }
                | ({"reasons": {r: t for r, t in a.reasons.items() if t}} if not a.ok else {})
                for a in self.arms
            ],
            "wall_time_s": self.wall_time_s,
            "workers": self.workers,
        }

    def text(self) -> str:
        """The summary as lines of text (what ``packbot study --uncertain`` prints)."""
        c = self.counts
        lines = [
            f"uncertain study {self.scenario}: {c['arms']} arms ({self.sample.method}, seed "
            f"{self.sample.seed}, {len(self.sample.names)} parameters), {c['ok']} with every "
            "run ok"
        ]
        for run in RUN_NAMES:
            if c[f"{run}_not_ok"]:
                lines.append(f"  {run}: {c[f'{run}_not_ok']} arms not ok (uncertain.json: why)")
        p, (lo, hi) = self.recovery_probability, self.recovery_interval
        if math.isnan(p):
            lines.append("  recovery: no arm's reconfigured run finished")
        else:
            lines.append(
                f"  recovery within {self.tolerance_m * 1000:g} mm: {self.recovery_successes} of "
                f"{self.recovery_trials} arms, p = {p:.2f} (95 % Wilson interval {lo:.2f} .. "
                f"{hi:.2f})"
            )
        lines.append("  final task error [mm] (5 / 50 / 95 %):")
        for run in RUN_NAMES:
            q = self.quantiles(run, "final_task_error_m")
            lines.append(
                f"    {run:<13} {q[5] * 1000:8.2f} {q[50] * 1000:8.2f} {q[95] * 1000:8.2f}"
            )
        q = self.quantiles("reconfigured", "peak_torque_ratio")
        lines.append(
            f"  reconfigured peak torque ratio (5 / 50 / 95 %): {q[5]:.3f} {q[50]:.3f} {q[95]:.3f}"
        )
        ranked = [
            (name, rho)
            for name, rho in self.sensitivity("reconfigured", "final_task_error_m")
            if not math.isnan(rho)
        ]
        if not ranked:
            lines.append(
                "  sensitivity undefined: fewer than 3 arms, or the same error on all of them"
            )
        else:
            lines.append("  reconfigured final task error follows (Spearman rho):")
            for name, rho in ranked[:SUMMARY_TOP]:
                lines.append(f"    {name:<28} {rho:+.2f}")
        return "\n".join(lines)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _check_run_metric(run: str, metric: str) -> None:
    if not isinstance(run, str) or run not in RUN_NAMES:
        raise UnknownNameError("run", run, RUN_NAMES)
    if not isinstance(metric, str) or metric not in METRICS:
        raise UnknownNameError("metric", metric, METRICS)


# --------------------------------------------------------------------------------- the runs
@dataclass(frozen=True)
class _Job:
    """What one arm's study needs (picklable: sent to a worker process)."""

    index: int
    values: dict[str, float]
    scenario: Any
    options: dict[str, Any]
    directory: str


def _study_arm(job: _Job) -> ArmStudy:
    """Build arm ``job.index`` and study it; a PackbotError becomes the arm's error."""
    from packbot.study import study
    from packbot.uncertainty import robot_from_values

    start = time.perf_counter()
    try:
        folder = Path(job.directory) / f"arm_{job.index:04d}"
        robot = robot_from_values(job.values, directory=folder)
        res = study(job.scenario, robot=robot, **job.options)
    except PackbotError as exc:
        log.warning("arm %d: study failed: %s", job.index, exc)
        text = f"{type(exc).__name__}: {exc}"
        return ArmStudy(
            index=job.index,
            status=dict.fromkeys(RUN_NAMES, "error"),
            reasons=dict.fromkeys(RUN_NAMES, text),
            metrics=dict.fromkeys(RUN_NAMES),
            possible=None,
            error=text,
            wall_time_s=time.perf_counter() - start,
        )
    runs = res.runs
    return ArmStudy(
        index=job.index,
        status={n: r.status for n, r in runs.items()},
        reasons={n: r.reason if r.status != "ok" else "" for n, r in runs.items()},
        metrics={n: r.metrics if r.status == "ok" else None for n, r in runs.items()},
        possible=res.recovery.possible,
        wall_time_s=time.perf_counter() - start,
    )


def _drawn(sample: ParameterSample, k: int) -> dict[str, float]:
    """Arm ``k``'s drawn values (the sampled entries only: the others stay nominal)."""
    return {n: float(x) for n, x in zip(sample.names, sample.values[k], strict=True)}


def _init_worker() -> None:
    from packbot.batch import _init_worker as batch_init  # the batch pool's worker set-up

    batch_init(None)


def _run_jobs(
    jobs: Sequence[_Job], workers: int, say: Callable[[str], None]
) -> tuple[ArmStudy, ...]:
    if workers == 1:
        out = []
        for job in jobs:
            say(f"arm {job.index + 1} of {len(jobs)}")
            out.append(_study_arm(job))
        return tuple(out)
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from packbot.batch import _single_thread_env  # one BLAS thread per worker, as the batch's

    ctx = multiprocessing.get_context("spawn")
    with (
        _single_thread_env(),
        ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker) as pool,
    ):
        results = []
        for k, arm in enumerate(pool.map(_study_arm, jobs)):
            say(f"arm {k + 1} of {len(jobs)} done")
            results.append(arm)
    return tuple(results)


def _picklable(name: str, value: Any) -> None:
    import pickle

    try:
        pickle.dumps(value)
    except Exception as exc:
        raise ConfigurationError(
            name,
            value,
            "with workers > 1, an import path 'module:Name' or a module-level class or "
            f"function (worker processes receive it by pickling: {type(exc).__name__})",
        ) from None


@checked_arguments
def uncertain_study(
    scenario: Scenario | str | Path,
    *,
    samples: int = 8,
    seed: int = 0,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    robot: Robot | None = None,
    duration: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    contact_mode: str | None = None,
    workspace_samples: int = 2000,
    controller: ControllerSpec | None = None,
    recovery: StrategySpec = "builtin",
    workers: int = 1,
    directory: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> UncertainStudy:
    """Run the failure study of a scenario on arms drawn within the model's tolerances.

    Example::

        unc = packbot.uncertain_study("reconfig_elbow1", samples=8, seed=1, duration=1.5)
        unc.quantiles("reconfigured", "final_task_error_m")  # {5: ..., 50: ..., 95: ...} [m]
        unc.recovery_probability, unc.recovery_interval  # share recovered, Wilson 95 %
        unc.sensitivity("failed", "final_task_error_m")[:3]  # [(parameter, rho), ...]

    Args:
        scenario: A scenario name (``sims/``), a TOML path or a :class:`Scenario` with
            ``[[failures]]``.
        samples: Number of arms (2 to :data:`MAX_SAMPLES`; a power of 2 keeps a Sobol
            sample balanced).
        seed: Seed of the draw (and of each study's workspace sampler): the same seed gives
            the same arms and the same numbers.
        vary: The table entries to draw (:func:`packbot.sample_values`); None: all toleranced.
        method: ``"sobol"`` (scrambled Sobol, the default) or ``"lhs"`` (Latin hypercube).
        robot: The arm the scenario and the controller are checked on before any run (default
            :func:`packbot.load_robot`); the arms themselves are drawn around the parameter
            table (:mod:`packbot.uncertainty`), not around this robot.
        duration: As :func:`packbot.study` (simulated time of each run [s]).
        tolerance: As :func:`packbot.study` (recovery tolerance [m]).
        contact_mode: As :func:`packbot.study`.
        workspace_samples: As :func:`packbot.study`.
        controller: As :func:`packbot.study`: your controller on every arm (built on that
            arm's model). With ``workers`` > 1 it must pickle (an import path or a
            module-level class or function).
        recovery: As :func:`packbot.study`, likewise.
        workers: Processes (1: this one; more: a local pool of that many, 'spawn', one BLAS
            thread each, as :mod:`packbot.batch`'s).
        directory: Folder for the arms' description packages (``arm_0000/`` ...); None: a
            temporary folder, removed on return.
        progress: Called with a line of text as each arm starts (or ends, on a pool).

    Returns:
        The arms' studies and their spread (:class:`UncertainStudy`).

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid), a
            scenario without failures, a controller that does not pickle with workers > 1.
        UnknownNameError: An unknown scenario or parameter name.
    """
    import tempfile

    from packbot.control.user_code import controller_factory, describe_spec, strategy_factory
    from packbot.study import _check_inputs
    from packbot.uncertainty import sample_values

    samples = integer("samples", samples, low=2, high=MAX_SAMPLES, what="a number of arms")
    seed = integer("seed", seed, low=0, high=2**63 - 1, what="a non-negative integer seed")
    workers = integer("workers", workers, low=1, high=MAX_WORKERS, what="a number of processes")
    scenario, robot = _check_inputs(
        scenario, robot, duration, tolerance, contact_mode, workspace_samples
    )
    if controller is not None:
        controller_factory(controller)(robot)  # a factory that fails does so before any arm
    strategy_factory(recovery)
    if workers > 1:
        for name, value in (("controller", controller), ("recovery", recovery)):
            _picklable(name, value)
    if directory is not None and not isinstance(directory, (str, Path)):
        raise ConfigurationError("directory", directory, "a folder path, or None")
    sample = sample_values(samples, seed, vary=vary, method=method)
    options: dict[str, Any] = {
        "duration": duration,
        "tolerance": float(tolerance),
        "contact_mode": contact_mode,
        "workspace_samples": workspace_samples,
        "seed": seed,
        "controller": controller,
        "recovery": recovery,
    }
    say = progress if progress is not None else (lambda text: log.info("%s", text))
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="packbot-unc-") as tmp:
        folder = str(directory) if directory is not None else tmp
        os.makedirs(folder, exist_ok=True)
        jobs = [_Job(k, _drawn(sample, k), scenario, options, folder) for k in range(samples)]
        arms = _run_jobs(jobs, workers, say)
    wall = time.perf_counter() - start
    log.info("uncertain study %s: %d arms in %.1f s", scenario.name, samples, wall)
    return UncertainStudy(
        scenario=scenario.name,
        sample=sample,
        arms=arms,
        tolerance_m=float(tolerance),
        controller="" if controller is None else describe_spec(controller),
        wall_time_s=wall,
        workers=workers,
    )
