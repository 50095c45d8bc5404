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

Each arm's study keeps its metrics, its runs' statuses, its verdict and each run's task error on
a common time grid of :data:`TRACE_POINTS` samples (not its trajectories: :class:`ArmStudy`);
:meth:`UncertainStudy.task_error_band` gives its 5-95 % band over the arms. An arm whose study
raises a :class:`~packbot.errors.PackbotError` or one of whose runs is not ``"ok"`` is counted
and reported (:attr:`UncertainStudy.counts`), never dropped silently: its metrics are left out
of the quantiles of that run only.

The controller on each arm is built on that arm's model (it knows the arm exactly): the spread
is that of the arm's physics, not of a controller tuned on the nominal model running a different
arm.

:func:`uncertain_study` studies the arms one after the other in this process. The same arms on
a local pool or a Dask cluster, resumable from a folder with one file per arm, are
:func:`packbot.uncertain_batch.run_uncertain_study` (the batch machinery; ``packbot study
SCENARIO --uncertain N``): both run each arm with :meth:`UncertainPlan.study_arm`.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, TypeVar

import numpy as np

from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.study import DEFAULT_TOLERANCE, RUN_NAMES, RunMetrics
from packbot.validation import finite_number, integer

if TYPE_CHECKING:
    from packbot.control.user_code import ControllerSpec, StrategySpec
    from packbot.model import Robot
    from packbot.scenario import Scenario
    from packbot.uncertainty import ParameterSample

__all__ = [
    "METRICS",
    "PERCENTILES",
    "TRACE_POINTS",
    "ArmStudy",
    "UncertainPlan",
    "UncertainStudy",
    "percentiles",
    "plan_uncertain_study",
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
#: Samples of each arm's task error kept per run (a grid over the runs' duration, both ends in).
TRACE_POINTS = 201
#: How many parameters the sensitivity bars (``uncertain.json``, the report) show.
BAR_TOP = 10


def percentiles(values: Any) -> dict[int, Any]:
    """The 5th, 50th and 95th percentiles of ``values`` over its first axis, non-finite left out.

    Linear interpolation between order statistics (NumPy's default). ``values`` of shape (n,)
    give floats; of shape (n, m) (arms x times) arrays of m values, each over the arms that have
    a finite value there. No finite value: NaN.

    Example::

        percentiles([1.0, 2.0, float("nan"), 3.0])  # {5: 1.1, 50: 2.0, 95: 2.9}

    Raises:
        ConfigurationError: ``values`` is not numeric or has more than two axes.
    """
    try:
        x = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigurationError("values", type(values).__name__, "numbers") from None
    if x.ndim not in (1, 2):
        raise ConfigurationError("values", f"shape {x.shape}", "shape (n,) or (n, m)")
    x[~np.isfinite(x)] = np.nan
    with warnings.catch_warnings():  # an all-NaN column is NaN, as documented
        warnings.simplefilter("ignore", RuntimeWarning)
        q = np.nanpercentile(x, PERCENTILES, axis=0) if x.shape[0] else None
    if q is None:
        return dict.fromkeys(PERCENTILES, math.nan if x.ndim == 1 else np.full(x.shape[1], np.nan))
    return {
        p: (float(v) if x.ndim == 1 else np.asarray(v)) for p, v in zip(PERCENTILES, q, strict=True)
    }


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
        task_error: Per run name, its task error [m] at the :data:`TRACE_POINTS` times of
            :attr:`UncertainStudy.trace_time` (linear between the run's samples; NaN after a
            run that stopped early); empty for a run without samples.
    """

    index: int
    status: dict[str, str]
    reasons: dict[str, str]
    metrics: dict[str, RunMetrics | None]
    possible: bool | None
    error: str = ""
    wall_time_s: float = 0.0
    task_error: dict[str, tuple[float, ...]] = field(default_factory=dict)

    @classmethod
    def failed(cls, index: int, error: str, wall_time_s: float = 0.0) -> ArmStudy:
        """An arm whose study did not finish: every run ``"error"``, for ``error``.

        Args:
            index: The arm's index in the sample.
            error: Why (the error the study raised, or the batch's record of it).
            wall_time_s: Wall time spent on the arm [s].
        """
        return cls(
            index=index,
            status=dict.fromkeys(RUN_NAMES, "error"),
            reasons=dict.fromkeys(RUN_NAMES, error),
            metrics=dict.fromkeys(RUN_NAMES),
            possible=None,
            error=error,
            wall_time_s=wall_time_s,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, exactly: :meth:`from_dict` gives back the same arm, bit for bit.

        Floats are written as JSON numbers (shortest repr), a non-finite metric as ``"inf"``,
        ``"-inf"`` or ``"nan"``, a NaN of a task error as null.
        """
        return {
            "index": self.index,
            "status": dict(self.status),
            "reasons": dict(self.reasons),
            "metrics": {
                run: None if m is None else {k: _enc(v) for k, v in dataclasses.asdict(m).items()}
                for run, m in self.metrics.items()
            },
            "possible": self.possible,
            "error": self.error,
            "wall_time_s": self.wall_time_s,
            "task_error": {
                run: [x if math.isfinite(x) else None for x in e]
                for run, e in self.task_error.items()
            },
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ArmStudy:
        """Read what :meth:`to_dict` wrote.

        Raises:
            ConfigurationError: ``data`` is not such a dict (names the key that is wrong).
        """
        try:
            metrics = {
                run: None if m is None else RunMetrics(**{k: _dec(v) for k, v in m.items()})
                for run, m in data["metrics"].items()
            }
            return cls(
                index=int(data["index"]),
                status={str(k): str(v) for k, v in data["status"].items()},
                reasons={str(k): str(v) for k, v in data["reasons"].items()},
                metrics=metrics,
                possible=data["possible"],
                error=str(data["error"]),
                wall_time_s=float(data["wall_time_s"]),
                task_error={
                    str(run): tuple(math.nan if x is None else float(x) for x in e)
                    for run, e in data["task_error"].items()
                },
            )
        except KeyError as exc:
            raise ConfigurationError(
                "arm", f"no key {exc.args[0]!r}", "an arm written by ArmStudy.to_dict"
            ) from None
        except (TypeError, ValueError, AttributeError, PackbotError) as exc:
            raise ConfigurationError(
                "arm", str(exc), "an arm written by ArmStudy.to_dict"
            ) from None

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
        workers: Where the arms ran: ``"this process"``, ``"2 local processes"``,
            ``"dask tcp://..."``.
        duration_s: Simulated time of each run [s] (the task error grid's span).
        failure_time_s: The first failure's time [s].
    """

    scenario: str
    sample: ParameterSample
    arms: tuple[ArmStudy, ...]
    tolerance_m: float
    controller: str = ""
    wall_time_s: float = 0.0
    workers: str = "this process"
    duration_s: float = math.nan
    failure_time_s: float = math.nan

    def __len__(self) -> int:
        return len(self.arms)

    @property
    def trace_time(self) -> np.ndarray:
        """The times of :attr:`ArmStudy.task_error` [s]: :data:`TRACE_POINTS`, 0 to the end."""
        return trace_grid(self.duration_s)

    def task_error_band(self, run: str) -> dict[int, np.ndarray]:
        """The 5th, 50th and 95th percentiles over the arms of a run's task error at each time.

        Args:
            run: ``"healthy"``, ``"failed"`` or ``"reconfigured"``.

        Returns:
            {5: ..., 50: ..., 95: ...}, each of shape (:data:`TRACE_POINTS`,) [m] at
            :attr:`trace_time`; NaN where no arm's run has a sample.

        Raises:
            UnknownNameError: ``run`` is not a run name.
        """
        _check_run_metric(run, "final_task_error_m")
        rows = [a.task_error[run] for a in self.arms if len(a.task_error.get(run, ())) > 0]
        grid = np.array(rows) if rows else np.empty((0, TRACE_POINTS))
        return percentiles(grid)

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
        return percentiles(self.values(run, metric))

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
    def summary(self, top: int = BAR_TOP) -> dict[str, Any]:
        """The spread, JSON-ready (what ``uncertain.json`` holds; the report is drawn from it).

        Keys: the scenario, the sample (size, seed, method, the sampled parameters), the counts,
        per run and metric of :data:`SUMMARY_METRICS` the quantiles (``"5"``, ``"50"``,
        ``"95"``) and the number of arms with a value, the recovery probability and its Wilson
        interval, the share the studies judged possible, the ``top`` parameters of the
        sensitivity of each run's final task error and peak torque ratio, the distributions
        (``task_error_band``: the times [s] and per run the 5, 50 and 95 % of the task error
        [m] at each; ``final_task_error_m``: per run each arm's value, null without), and per
        arm its statuses, its verdict and its reasons for a run not ok.
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
            "duration_s": _num(self.duration_s),
            "failure_time_s": _num(self.failure_time_s),
            "task_error_band": {"t_s": [float(x) for x in self.trace_time]}
            | {
                run: {str(p): [_num(x) for x in v] for p, v in self.task_error_band(run).items()}
                for run in RUN_NAMES
            },
            "final_task_error_m": {
                run: [_num(x) for x in self.values(run, "final_task_error_m")] for run in RUN_NAMES
            },
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


_NON_FINITE = ("inf", "-inf", "nan")


def _enc(v: Any) -> Any:
    """A metric for JSON, exactly: a non-finite float as its name."""
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    return v


def _dec(v: Any) -> Any:
    return float(v) if isinstance(v, str) and v in _NON_FINITE else v


def trace_grid(duration: float) -> np.ndarray:
    """The :data:`TRACE_POINTS` times of the kept task errors: 0 to ``duration`` [s]."""
    return np.linspace(0.0, float(duration), TRACE_POINTS)


def _check_run_metric(run: str, metric: str) -> None:
    if not isinstance(run, str) or run not in RUN_NAMES:
        raise UnknownNameError("run", run, RUN_NAMES)
    if not isinstance(metric, str) or metric not in METRICS:
        raise UnknownNameError("metric", metric, METRICS)


# --------------------------------------------------------------------------------- the runs
class _Arm(Protocol):
    @property
    def index(self) -> int: ...


_A = TypeVar("_A", bound=_Arm)
_T = TypeVar("_T")


def _check_draw(samples: int, seed: int) -> tuple[int, int]:
    """The number of arms and the seed of a draw, checked.

    Raises:
        ConfigurationError: Either is not an integer in its range.
    """
    samples = integer("samples", samples, low=2, high=MAX_SAMPLES, what="a number of arms")
    seed = integer("seed", seed, low=0, high=2**63 - 1, what="a non-negative integer seed")
    return samples, seed


def _in_sample_order(arms: Iterable[_A], n: int) -> tuple[_A, ...]:
    """The arms in sample order, checked to be the ``n`` arms of the sample, each once.

    Raises:
        ConfigurationError: The arms are not the sample's, each once.
    """
    ordered = tuple(sorted(arms, key=lambda a: a.index))
    if [a.index for a in ordered] != list(range(n)):
        raise ConfigurationError(
            "arms", [a.index for a in ordered], f"the {n} arms of the sample, each once"
        )
    return ordered


def _arms_here(
    n: int,
    arm: Callable[[int, str], _T],
    directory: str | Path | None,
    progress: Callable[[str], None] | None,
    prefix: str,
) -> tuple[list[_T], float]:
    """Arms ``0 .. n - 1`` one after the other in this process, and the wall time [s].

    Args:
        n: Number of arms.
        arm: Called as ``arm(k, folder)`` for arm ``k``'s result.
        directory: Folder for the arms' description packages; None: a temporary one (its
            name starting with ``prefix``), removed on return.
        progress: Called with a line of text as each arm starts; None: logged.
        prefix: See ``directory``.

    Raises:
        ConfigurationError: ``directory`` is neither a folder path nor None.
    """
    import tempfile

    if directory is not None and not isinstance(directory, (str, Path)):
        raise ConfigurationError("directory", directory, "a folder path, or None")
    say = progress if progress is not None else (lambda text: log.info("%s", text))
    start = time.perf_counter()
    arms = []
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        folder = str(directory) if directory is not None else tmp
        os.makedirs(folder, exist_ok=True)
        for k in range(n):
            say(f"arm {k + 1} of {n}")
            arms.append(arm(k, folder))
    return arms, time.perf_counter() - start


@dataclass(frozen=True)
class UncertainPlan:
    """An uncertain study, checked and drawn, before any arm runs (picklable: sent to workers).

    Made by :func:`plan_uncertain_study`; :meth:`study_arm` studies one arm (the one piece of
    code every way of running the arms calls), :meth:`result` gathers the arms' studies.

    Attributes:
        scenario: The scenario, checked against the nominal arm.
        sample: The drawn values (arm ``k`` is row ``k``).
        options: :func:`packbot.study`'s options for every arm (duration, tolerance, contact
            mode, workspace samples, seed, controller, recovery).
        controller: The controller's description ("": the scenario's).
        recovery: The recovery strategy's description.
        duration_s: Simulated time of each run [s].
        tolerance_m: The recovery tolerance [m].
    """

    scenario: Scenario
    sample: ParameterSample
    options: dict[str, Any]
    controller: str
    recovery: str
    duration_s: float
    tolerance_m: float

    def __len__(self) -> int:
        return len(self.sample)

    def arm_values(self, k: int) -> dict[str, float]:
        """Arm ``k``'s drawn values (the sampled entries only: the others stay nominal)."""
        return self.sample.drawn(k)

    def identity(self) -> dict[str, Any]:
        """What defines the arms' studies, JSON-ready (a resumed folder must hold the same)."""
        return {
            "scenario": self.scenario.name,
            **self.sample.identity(),
            "duration_s": self.duration_s,
            "tolerance_m": self.tolerance_m,
            "contact_mode": self.options["contact_mode"],
            "workspace_samples": self.options["workspace_samples"],
            "controller": self.controller,
            "recovery": self.recovery,
        }

    def study_arm(
        self,
        k: int,
        directory: str | Path,
        step: Callable[[float], None] | None = None,
    ) -> ArmStudy:
        """Build arm ``k`` and study it; a :class:`PackbotError` becomes the arm's error.

        Args:
            k: The arm's index in the sample.
            directory: Folder for its description package (``arm_<k>/`` in it).
            step: Called with the simulated time now and then (:func:`packbot.study`'s
                ``step``; a wall-time limit raises from it).
        """
        from packbot.study import study
        from packbot.uncertainty import robot_from_values

        start = time.perf_counter()
        try:
            folder = Path(directory) / f"arm_{k:04d}"
            robot = robot_from_values(self.arm_values(k), directory=folder)
            res = study(self.scenario, robot=robot, step=step, **self.options)
        except PackbotError as exc:
            log.warning("arm %d: study failed: %s", k, exc)
            return ArmStudy.failed(
                k, f"{type(exc).__name__}: {exc}", wall_time_s=time.perf_counter() - start
            )
        grid = trace_grid(self.duration_s)
        traces: dict[str, tuple[float, ...]] = {}
        for name, run in res.runs.items():
            if run.result is not None and run.task_error is not None and len(run.task_error):
                e = np.interp(grid, run.result.t, run.task_error, right=np.nan)
                traces[name] = tuple(float(x) for x in e)
        return ArmStudy(
            index=k,
            status={n: r.status for n, r in res.runs.items()},
            reasons={n: r.reason if r.status != "ok" else "" for n, r in res.runs.items()},
            metrics={n: r.metrics if r.status == "ok" else None for n, r in res.runs.items()},
            possible=res.recovery.possible,
            wall_time_s=time.perf_counter() - start,
            task_error=traces,
        )

    def result(self, arms: Iterable[ArmStudy], wall_time_s: float, workers: str) -> UncertainStudy:
        """The :class:`UncertainStudy` of the arms' studies (put in sample order).

        Raises:
            ConfigurationError: The arms are not the sample's, each once.
        """
        return UncertainStudy(
            scenario=self.scenario.name,
            sample=self.sample,
            arms=_in_sample_order(arms, len(self.sample)),
            tolerance_m=self.tolerance_m,
            controller=self.controller,
            wall_time_s=wall_time_s,
            workers=workers,
            duration_s=self.duration_s,
            failure_time_s=min(float(f.t) for f in self.scenario.failures),
        )


@checked_arguments
def plan_uncertain_study(
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
) -> UncertainPlan:
    """Check an uncertain study's arguments and draw its arms (:func:`uncertain_study`'s).

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid), a
            scenario without failures.
        UnknownNameError: An unknown scenario or parameter name.
    """
    from packbot.control.user_code import controller_factory, describe_spec, strategy_factory
    from packbot.study import _check_inputs
    from packbot.uncertainty import sample_values

    samples, seed = _check_draw(samples, seed)
    scenario, robot = _check_inputs(
        scenario, robot, duration, tolerance, contact_mode, workspace_samples
    )
    if controller is not None:
        controller_factory(controller)(robot)  # a factory that fails does so before any arm
    strategy_factory(recovery)
    sample = sample_values(samples, seed, vary=vary, method=method)
    options: dict[str, Any] = {
        "duration": None if duration is None else float(duration),
        "tolerance": float(tolerance),
        "contact_mode": contact_mode,
        "workspace_samples": int(workspace_samples),
        "seed": seed,
        "controller": controller,
        "recovery": recovery,
    }
    return UncertainPlan(
        scenario=scenario,
        sample=sample,
        options=options,
        controller="" if controller is None else describe_spec(controller),
        recovery=describe_spec(recovery),
        duration_s=float(scenario.duration if duration is None else duration),
        tolerance_m=float(tolerance),
    )


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
    directory: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> UncertainStudy:
    """Run the failure study of a scenario on arms drawn within the model's tolerances.

    The arms are studied one after the other in this process; on a local pool or a Dask
    cluster, resumable, with the same numbers: :func:`packbot.uncertain_batch.
    run_uncertain_study` (``packbot study SCENARIO --uncertain N``).

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
            arm's model).
        recovery: As :func:`packbot.study`, likewise.
        directory: Folder for the arms' description packages (``arm_0000/`` ...); None: a
            temporary folder, removed on return.
        progress: Called with a line of text as each arm starts.

    Returns:
        The arms' studies and their spread (:class:`UncertainStudy`).

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid), a
            scenario without failures.
        UnknownNameError: An unknown scenario or parameter name.
    """
    plan = plan_uncertain_study(
        scenario,
        samples=samples,
        seed=seed,
        vary=vary,
        method=method,
        robot=robot,
        duration=duration,
        tolerance=tolerance,
        contact_mode=contact_mode,
        workspace_samples=workspace_samples,
        controller=controller,
        recovery=recovery,
    )
    arms, wall = _arms_here(len(plan), plan.study_arm, directory, progress, "packbot-unc-")
    log.info("uncertain study %s: %d arms in %.1f s", plan.scenario.name, len(plan), wall)
    return plan.result(arms, wall, "this process")
