"""A scenario run over the model's uncertainty: the rest pose and the events as distributions.

:func:`uncertain_run` simulates a scenario on ``samples`` arms drawn within the parameter
table's tolerances (the draw of :func:`packbot.sample_values`, each arm built by
:func:`packbot.uncertainty.robot_from_values`) and returns an :class:`UncertainRun`: per arm
(:class:`ArmRun`) the final joint angles, where link 3 ends (the origin of frame
:data:`LINK3_END`, the wrist's axis at link 3's far end, in the world frame), the rest time,
the events by kind and the first of each kind; over the arms their 5th, 50th and 95th
percentiles (:func:`packbot.uncertain_study.percentiles`) and the counts. For the collapse it
answers "where does link 3 end, over the model's uncertainty".

An arm whose run raises a :class:`~packbot.errors.PackbotError` is kept with its error and
counted (:attr:`UncertainRun.counts`), never dropped silently; it is left out of the
percentiles. :func:`uncertain_run` runs the arms one after the other in this process; on a
local pool or a Dask cluster, resumable: :func:`packbot.uncertain_batch.run_uncertain_runs`
(``packbot run SCENARIO --uncertain N``), both through :meth:`UncertainRunPlan.run_arm`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.uncertain_study import (
    PERCENTILES,
    _arms_here,
    _check_draw,
    _in_sample_order,
    percentiles,
)
from packbot.validation import finite_number

if TYPE_CHECKING:
    from packbot.control.user_code import ControllerSpec
    from packbot.scenario import Scenario
    from packbot.uncertainty import ParameterSample

__all__ = [
    "AXES",
    "EVENT_KINDS",
    "LINK3_END",
    "ArmRun",
    "UncertainRun",
    "UncertainRunPlan",
    "plan_uncertain_run",
    "uncertain_run",
]

log = logging.getLogger(__name__)

#: The frame whose origin is link 3's end: the gripper's roll axis at the link's far end.
LINK3_END = "gripper_link"
#: The coordinates of a position, in the world frame (x forward, y left, z up) [m].
AXES: tuple[str, ...] = ("x", "y", "z")
#: The event kinds counted per arm (the others are counted in ``"other"``).
EVENT_KINDS: tuple[str, ...] = ("impact", "limit", "release", "rest", "failure")


@dataclass(frozen=True, kw_only=True)
class ArmRun:
    """One sampled arm's run of the scenario, reduced to its end and its events.

    Attributes:
        index: The arm's index in the sample.
        error: Why the run did not finish ("" if it did).
        final_q: Joint name -> its final angle [rad] (empty after an error).
        link3_end: Where link 3 ends at the end, (x, y, z) in the world frame [m].
        rest_time: When every joint came to rest [s] (None: not at rest at the end).
        events: Event kind -> how many (every kind of the run's log).
        first: Event kind -> the time of its first event [s].
        min_distance: Smallest signed distance seen [m] (inf: no pair within the margin).
        energy_change: Final minus initial mechanical energy [J].
        wall_time_s: Wall time of building the arm and running it [s].
    """

    index: int
    error: str = ""
    final_q: dict[str, float] = field(default_factory=dict)
    link3_end: tuple[float, ...] = ()
    rest_time: float | None = None
    events: dict[str, int] = field(default_factory=dict)
    first: dict[str, float] = field(default_factory=dict)
    min_distance: float = math.nan
    energy_change: float = math.nan
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether the run finished."""
        return not self.error

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, exactly (:meth:`from_dict` gives the same arm back; inf as ``"inf"``)."""
        return {
            "index": self.index,
            "error": self.error,
            "final_q_rad": dict(self.final_q),
            "link3_end_m": list(self.link3_end),
            "rest_time_s": self.rest_time,
            "events": dict(self.events),
            "first_event_s": dict(self.first),
            "min_distance_m": self.min_distance
            if math.isfinite(self.min_distance)
            else str(self.min_distance),
            "energy_change_j": _enc(self.energy_change),
            "wall_time_s": self.wall_time_s,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ArmRun:
        """Read what :meth:`to_dict` wrote.

        Raises:
            ConfigurationError: ``data`` is not such a dict.
        """
        try:
            return cls(
                index=int(data["index"]),
                error=str(data["error"]),
                final_q={str(k): float(v) for k, v in data["final_q_rad"].items()},
                link3_end=tuple(float(x) for x in data["link3_end_m"]),
                rest_time=None if data["rest_time_s"] is None else float(data["rest_time_s"]),
                events={str(k): int(v) for k, v in data["events"].items()},
                first={str(k): float(v) for k, v in data["first_event_s"].items()},
                min_distance=float(data["min_distance_m"]),
                energy_change=float(data["energy_change_j"]),
                wall_time_s=float(data["wall_time_s"]),
            )
        except KeyError as exc:
            raise ConfigurationError(
                "arm", f"no key {exc.args[0]!r}", "an arm written by ArmRun.to_dict"
            ) from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise ConfigurationError("arm", str(exc), "an arm written by ArmRun.to_dict") from None


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class UncertainRun:
    """What :func:`uncertain_run` returns: the arms' runs and their spread.

    Attributes:
        scenario: The scenario's name.
        sample: The drawn parameter values (arm ``k`` is row ``k``).
        arms: Each arm's run (:class:`ArmRun`), in sample order.
        duration_s: Simulated time of each run [s].
        joints: The joints whose final angles are reported (the scenario's robot's, q order).
        wall_time_s: Wall time of the whole call [s].
        workers: Where the arms ran (``"this process"``, ``"2 local processes"``, ...).
    """

    scenario: str
    sample: ParameterSample
    arms: tuple[ArmRun, ...]
    duration_s: float
    joints: tuple[str, ...]
    wall_time_s: float = 0.0
    workers: str = "this process"

    def __len__(self) -> int:
        return len(self.arms)

    def _ok(self) -> list[ArmRun]:
        return [a for a in self.arms if a.ok]

    def final_angles(self, joint: str) -> np.ndarray:
        """A joint's final angle on every arm [rad], NaN where the run did not finish.

        Raises:
            UnknownNameError: ``joint`` is not one of :attr:`joints`.
        """
        if joint not in self.joints:
            raise UnknownNameError("joint", joint, self.joints)
        return np.array([a.final_q.get(joint, math.nan) for a in self.arms], dtype=float)

    def link3_end(self) -> np.ndarray:
        """Where link 3 ends on every arm, shape (n, 3) [m] (NaN rows: not finished)."""
        rows = [a.link3_end if len(a.link3_end) == 3 else (math.nan,) * 3 for a in self.arms]
        return np.array(rows, dtype=float).reshape(len(self.arms), 3)

    def event_counts(self, kind: str) -> np.ndarray:
        """How many events of a kind each arm's run logged (NaN: not finished)."""
        return np.array(
            [a.events.get(kind, 0) if a.ok else math.nan for a in self.arms], dtype=float
        )

    def first_times(self, kind: str) -> np.ndarray:
        """The time of each arm's first event of a kind [s] (NaN: none, or not finished)."""
        return np.array([a.first.get(kind, math.nan) for a in self.arms], dtype=float)

    def rest_times(self) -> np.ndarray:
        """Each arm's rest time [s] (NaN: not at rest at the end, or not finished)."""
        return np.array(
            [math.nan if a.rest_time is None else a.rest_time for a in self.arms], dtype=float
        )

    @property
    def kinds(self) -> tuple[str, ...]:
        """Every event kind some arm logged, the :data:`EVENT_KINDS` first."""
        seen = {k for a in self.arms for k in a.events}
        return tuple(k for k in EVENT_KINDS if k in seen) + tuple(sorted(seen - set(EVENT_KINDS)))

    @property
    def counts(self) -> dict[str, int]:
        """Arms in all, arms whose run finished, arms at rest at the end."""
        return {
            "arms": len(self.arms),
            "ok": len(self._ok()),
            "errors": sum(not a.ok for a in self.arms),
            "at_rest": sum(a.rest_time is not None for a in self._ok()),
        }

    def summary(self) -> dict[str, Any]:
        """The spread, JSON-ready (what ``uncertain-run.json`` holds; its figure reads it).

        Keys: the scenario, the sample, the counts; ``final_q_rad``: per joint the 5, 50 and
        95 % of its final angle; ``link3_end_m``: per coordinate likewise, and ``frame``;
        ``rest_time_s``; ``events``: per kind the percentiles of its count and of its first
        time, and how many arms logged one; ``arms``: each arm's values (what the figure
        draws).
        """

        def q(x: np.ndarray) -> dict[str, Any]:
            return {str(p): _num(v) for p, v in percentiles(x).items()} | {
                "arms": int(np.isfinite(x).sum())
            }

        ends = self.link3_end()
        return {
            "scenario": self.scenario,
            "duration_s": self.duration_s,
            "sample": {
                "arms": len(self.arms),
                "seed": self.sample.seed,
                "method": self.sample.method,
                "parameters": list(self.sample.names),
            },
            "counts": self.counts,
            "final_q_rad": {j: q(self.final_angles(j)) for j in self.joints},
            "link3_end_m": {"frame": LINK3_END}
            | {axis: q(ends[:, i]) for i, axis in enumerate(AXES)},
            "rest_time_s": q(self.rest_times()),
            "events": {
                kind: {
                    "count": q(self.event_counts(kind)),
                    "first_s": q(self.first_times(kind)),
                    "arms_with": int(np.nansum(self.event_counts(kind) > 0)),
                }
                for kind in self.kinds
            },
            "arms": [a.to_dict() for a in self.arms],
            "wall_time_s": self.wall_time_s,
            "workers": self.workers,
        }

    def text(self) -> str:
        """The summary as lines of text (what ``packbot run --uncertain`` prints)."""
        c = self.counts
        lines = [
            f"uncertain run {self.scenario}: {c['arms']} arms ({self.sample.method}, seed "
            f"{self.sample.seed}, {len(self.sample.names)} parameters), {self.duration_s:g} s "
            f"each; {c['ok']} finished, {c['at_rest']} at rest at the end"
        ]
        for a in self.arms:
            if not a.ok:
                lines.append(f"  arm {a.index}: {a.error}")
        lines.append(f"  {'':<24} {'5 %':>9} {'50 %':>9} {'95 %':>9}")

        def row(label: str, x: np.ndarray, scale: float = 1.0, fmt: str = "9.4f") -> None:
            p = percentiles(x)
            lines.append(f"  {label:<24} " + " ".join(f"{p[k] * scale:{fmt}}" for k in PERCENTILES))

        for j in self.joints:
            row(f"final {j} [rad]", self.final_angles(j))
        ends = self.link3_end()
        for i, axis in enumerate(AXES):
            row(f"link 3 end {axis} [mm]", ends[:, i], 1000.0, "9.1f")
        row("rest time [s]", self.rest_times())
        for kind in self.kinds:
            row(f"{kind} events", self.event_counts(kind), 1.0, "9.1f")
            row(f"first {kind} [s]", self.first_times(kind))
        return "\n".join(lines)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _enc(x: float) -> float | str:
    return x if math.isfinite(x) else str(x)


@dataclass(frozen=True)
class UncertainRunPlan:
    """An uncertain run, checked and drawn, before any arm runs (picklable: sent to workers).

    Attributes:
        scenario: The scenario, checked against the nominal arm.
        sample: The drawn values.
        duration_s: Simulated time of each run [s].
        controller: Your controller (instead of the scenario's), or None.
        joints: The robot's joints (the final angles reported).
    """

    scenario: Scenario
    sample: ParameterSample
    duration_s: float
    controller: ControllerSpec | None
    joints: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.sample)

    def arm_values(self, k: int) -> dict[str, float]:
        """Arm ``k``'s drawn values (the sampled entries only)."""
        return self.sample.drawn(k)

    def identity(self) -> dict[str, Any]:
        """What defines the arms' runs, JSON-ready (a resumed folder must hold the same)."""
        from packbot.control.user_code import describe_spec

        return {
            "scenario": self.scenario.name,
            **self.sample.identity(),
            "duration_s": self.duration_s,
            "controller": None if self.controller is None else describe_spec(self.controller),
        }

    def run_arm(
        self,
        k: int,
        directory: str | Path,
        progress: Callable[[float], None] | None = None,
    ) -> ArmRun:
        """Build arm ``k`` and run the scenario on it; a :class:`PackbotError` is its error.

        Args:
            k: The arm's index in the sample.
            directory: Folder for its description package (``arm_<k>/`` in it).
            progress: Called with the simulated time after each step (a wall-time limit
                raises from it: that exception is not caught).
        """
        from packbot.control.user_code import controller_factory
        from packbot.scenario import run_scenario
        from packbot.uncertainty import robot_from_values

        start = time.perf_counter()
        raised: list[BaseException] = []

        def step(t: float) -> None:
            if progress is not None:
                try:
                    progress(t)
                except BaseException as exc:
                    raised.append(exc)
                    raise

        try:
            robot = robot_from_values(self.arm_values(k), directory=Path(directory) / f"a{k}")
            mine = None
            if self.controller is not None:
                mine = controller_factory(self.controller)(robot)  # built on this arm's model
            res = run_scenario(
                self.scenario, robot, duration=self.duration_s, progress=step, controller=mine
            )
            end = res.frame_positions(LINK3_END, robot)[-1]
        except PackbotError as exc:
            if raised:
                raise
            log.warning("arm %d: run failed: %s", k, exc)
            return ArmRun(
                index=k,
                error=f"{type(exc).__name__}: {exc}",
                wall_time_s=time.perf_counter() - start,
            )
        events: dict[str, int] = {}
        first: dict[str, float] = {}
        for e in res.events:
            events[e.kind] = events.get(e.kind, 0) + 1
            first.setdefault(e.kind, float(e.t))
        return ArmRun(
            index=k,
            final_q={n: float(res.q[-1, res.joint(n)]) for n in self.joints},
            link3_end=tuple(float(x) for x in end),
            rest_time=None if res.rest_time is None else float(res.rest_time),
            events=events,
            first=first,
            min_distance=float(res.diagnostics.min_distance),
            energy_change=float(res.energy[-1] - res.energy[0]),
            wall_time_s=time.perf_counter() - start,
        )

    def result(self, arms: Iterable[ArmRun], wall_time_s: float, workers: str) -> UncertainRun:
        """The :class:`UncertainRun` of the arms' runs (put in sample order).

        Raises:
            ConfigurationError: The arms are not the sample's, each once.
        """
        return UncertainRun(
            scenario=self.scenario.name,
            sample=self.sample,
            arms=_in_sample_order(arms, len(self.sample)),
            duration_s=self.duration_s,
            joints=self.joints,
            wall_time_s=wall_time_s,
            workers=workers,
        )


@checked_arguments
def plan_uncertain_run(
    scenario: Scenario | str | Path,
    *,
    samples: int = 8,
    seed: int = 0,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    duration: float | None = None,
    controller: ControllerSpec | None = None,
) -> UncertainRunPlan:
    """Check an uncertain run's arguments and draw its arms (:func:`uncertain_run`'s).

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid).
        UnknownNameError: An unknown scenario or parameter name.
    """
    from packbot.control.user_code import controller_factory
    from packbot.scenario import Scenario, load_scenario, scenario_robot
    from packbot.uncertainty import sample_values

    samples, seed = _check_draw(samples, seed)
    if isinstance(scenario, (str, Path)):
        scenario = load_scenario(scenario)
    elif not isinstance(scenario, Scenario):
        raise ConfigurationError(
            "scenario", scenario, "a scenario name, a TOML path or a packbot.scenario.Scenario"
        )
    if duration is not None:
        finite_number("duration", duration, low=0.0, low_open=True, unit="s", what="a time")
    robot = scenario_robot(scenario)
    if not robot.is_packbot:
        raise ConfigurationError(
            "scenario.robot", scenario.robot, "PackBot (the uncertain model is its parameter table)"
        )
    scenario.validate(robot)
    if controller is not None:
        controller_factory(controller)(robot)  # a factory that fails does so before any arm
    sample = sample_values(samples, seed, vary=vary, method=method)
    return UncertainRunPlan(
        scenario=scenario,
        sample=sample,
        duration_s=float(scenario.duration if duration is None else duration),
        controller=controller,
        joints=tuple(robot.joint_names),
    )


@checked_arguments
def uncertain_run(
    scenario: Scenario | str | Path,
    *,
    samples: int = 8,
    seed: int = 0,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    duration: float | None = None,
    controller: ControllerSpec | None = None,
    directory: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> UncertainRun:
    """Run a scenario on arms drawn within the model's tolerances: its end as a distribution.

    The arms run one after the other in this process; on a local pool or a Dask cluster,
    resumable, with the same numbers: :func:`packbot.uncertain_batch.run_uncertain_runs`
    (``packbot run SCENARIO --uncertain N``).

    Example::

        unc = packbot.uncertain_run("collapse", samples=8, seed=1, duration=2.0)
        unc.summary()["link3_end_m"]["z"]  # {"5": ..., "50": ..., "95": ..., "arms": 8} [m]
        unc.final_angles("elbow2")  # each arm's final elbow2 angle [rad]

    Args:
        scenario: A scenario name (``sims/``), a TOML path or a :class:`Scenario`.
        samples: Number of arms (2 to :data:`~packbot.uncertain_study.MAX_SAMPLES`).
        seed: Seed of the draw: the same seed gives the same arms and the same numbers.
        vary: The table entries to draw (:func:`packbot.sample_values`); None: all toleranced.
        method: ``"sobol"`` (scrambled Sobol, the default) or ``"lhs"`` (Latin hypercube).
        duration: Simulated time of each run [s] instead of the scenario's.
        controller: Your controller instead of the scenario's (a ``Controller`` subclass, a
            factory ``robot -> Controller`` or an import path ``"module:Name"``), built on
            each arm's model.
        directory: Folder for the arms' description packages; None: a temporary one.
        progress: Called with a line of text as each arm starts.

    Returns:
        The arms' runs and their spread (:class:`UncertainRun`).

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid).
        UnknownNameError: An unknown scenario or parameter name.
    """
    plan = plan_uncertain_run(
        scenario,
        samples=samples,
        seed=seed,
        vary=vary,
        method=method,
        duration=duration,
        controller=controller,
    )
    arms, wall = _arms_here(len(plan), plan.run_arm, directory, progress, "packbot-unc-run-")
    return plan.result(arms, wall, "this process")
