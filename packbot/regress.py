"""Regression: compare a batch's results with committed golden results, quantity by quantity.

The golden results of a matrix live in ``<golden>/<matrix name>/``: ``results.json`` (the
deterministic part of each run's record, :meth:`packbot.batch.RunRecord.quantities`, by run id,
with the run's trajectory at checkpoints and its measured sensitivity) and ``summary.csv`` (the
same as a table, for reading). :func:`compare` checks, for every run:

- its status (``"ok"``/``"failed"``), exactly;
- the trajectory at the checkpoints (every :data:`CHECKPOINT_DT` s), joint by joint, and the
  final pose: ``|q_new - q_golden| <= tol_q`` [rad];
- the rest time: both None, or ``|dt| <= tol_time`` [s];
- the event count of each kind, exactly, and the event times: same kinds in the same order,
  ``|t_new - t_golden| <= tol_time`` [s] for each;
- the minimum signed distance: ``|d_new - d_golden| <= tol_distance`` [m] (inf == inf);
- the energy change: ``|dE| <= tol_energy`` [J];

and lists the runs that are in one set and not the other.

**What is reproducible.** Another CPU, BLAS kernel or library build rounds differently, and the
integrator's step-size control and event location carry such differences along. ``--update``
therefore measures each run's sensitivity: it makes the run again with its tolerances moved by
one part in 10^9 (:data:`PERTURBATIONS`, a change of the rounding, not of the physics) and
stores, per quantity, how far those runs land from the nominal one (:class:`Sensitivity`). Each
tolerance is then ``max(tolerances.X, NOISE_FACTOR * noise_X)``: the absolute tolerance, or ten
times the run's own measured noise where that is larger. A run whose perturbed copies part from
it (another event sequence, or a trajectory that leaves ``tolerances.q``) is chaotic from that
time, its **horizon**: up to the horizon it is compared as above (checkpoints and events); its
final quantities are compared on the band that more perturbed copies span
(:data:`CHAOTIC_PERTURBATIONS`), widened by its own width and by ``tolerances.chaotic_q`` (the
pose) or :data:`CHAOTIC_SHARE` of its size (the others): what is reproducible of them, loosely.
docs/batch.md gives the measurements behind these numbers.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tempfile
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

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
from packbot.config import SimConfig
from packbot.errors import ConfigurationError, ResourceNotFound
from packbot.keywords import checked_arguments
from packbot.matrix import Matrix, Run, apply_overrides, digest
from packbot.result_file import read_trajectory
from packbot.tolerances import Tolerances

__all__ = [
    "CHAOTIC_DISTANCE",
    "CHAOTIC_PERTURBATIONS",
    "CHAOTIC_SHARE",
    "CHECKPOINT_DT",
    "GOLDEN_FORMAT",
    "NOISE_FACTOR",
    "PERTURBATIONS",
    "Drift",
    "RegressionResult",
    "Sensitivity",
    "Tolerances",
    "compare",
    "default_golden_dir",
    "format_drifts",
    "golden_matrices",
    "measure_sensitivity",
    "read_golden",
    "read_trajectories",
    "run_regression",
    "write_golden",
]

#: Format tag of a golden results file (2: with checkpoints and each run's sensitivity).
GOLDEN_FORMAT = "packbot-golden/2"
#: Older format tags that are still read (no checkpoints, no sensitivity: absolute tolerances).
LEGACY_GOLDEN_FORMATS: tuple[str, ...] = ("packbot-golden/1",)
#: The runs that measure a run's sensitivity: (dotted scenario key, factor on its value). A
#: relative change of 1e-9 of the integrator's tolerances moves its step sizes in their last
#: digits: the kind of difference another machine's rounding makes, at every step.
PERTURBATIONS: tuple[tuple[str, float], ...] = (
    ("config.rtol", 1.0 + 1e-9),
    ("config.rtol", 1.0 - 1e-9),
    ("config.atol", 1.0 + 1e-9),
)
#: More copies of a run found chaotic (a horizon): its final quantities' band is a sample of
#: where rounding sends the run, and three copies sample it poorly (measured: a chaotic
#: contact-normal run's shoulder angle spread over 1.8e-4 rad in 21 copies, over 7.3e-5 rad in
#: three; a fresh install with other library builds landed outside the widened three-copy band).
CHAOTIC_PERTURBATIONS: tuple[tuple[str, float], ...] = tuple(
    ("config.rtol", 1.0 + k * 1e-9) for k in (-6, -5, -4, -3, -2, 2, 3, 4, 5, 6)
)
#: A quantity's tolerance is at least this multiple of its measured noise (docs/batch.md gives
#: the largest ratio measured with other BLAS kernels).
NOISE_FACTOR = 10.0
#: A chaotic run's event count, rest time and energy change are compared on their band widened
#: by its width, their absolute tolerance and this share of the band's centre: after the
#: horizon they are reproducible only to about that (docs/batch.md: the event count of a 1 s
#: run spread over 26 to 40 events in 40 copies).
CHAOTIC_SHARE = 0.25
#: A chaotic run's smallest signed distance is compared on its band widened by its width and
#: this [m] (docs/batch.md: a loose run's spread over 4e-12 to 4.9e-6 m in 40 copies).
CHAOTIC_DISTANCE = 1e-5
#: Interval of the trajectory checkpoints kept in the golden results [s].
CHECKPOINT_DT = 0.25

FloatArray = NDArray[np.float64]
#: A run's trajectory: sample times [s] and joint positions [rad], shape (n,) and (n, nq).
Trajectory = tuple[FloatArray, FloatArray]


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Sensitivity:
    """How far a run's perturbed copies (:data:`PERTURBATIONS`) land from it.

    Attributes:
        q: Largest joint position difference, over the checkpoints before the horizon and the
            final pose [rad].
        time: Largest difference of an event time or of the rest time [s].
        distance: Difference of the minimum signed distance [m].
        energy: Difference of the energy change [J].
        horizon: Time from which the copies part from the run [s]: the first event where their
            event sequences differ, or the first sample where a trajectory leaves
            ``tolerances.q``; None if they never do.
        band: With a horizon: quantity -> (lowest, highest) over the run and its copies, of the
            final pose (``"q.<joint>"``), ``"rest_time"``, ``"n_events"``, ``"min_distance"``
            and ``"energy_change"``.
    """

    q: float = 0.0
    time: float = 0.0
    distance: float = 0.0
    energy: float = 0.0
    horizon: float | None = None
    band: dict[str, tuple[float, float]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (finite floats; a band's None rest time as NaN -> "nan")."""
        return {
            "q": self.q,
            "time": self.time,
            "distance": _json_float(self.distance),
            "energy": self.energy,
            "horizon": self.horizon,
            "band": {k: [_json_float(lo), _json_float(hi)] for k, (lo, hi) in self.band.items()},
        }

    @classmethod
    @checked_arguments
    def from_json(cls, data: Mapping[str, Any]) -> Sensitivity:
        """Inverse of :meth:`to_json`."""
        return cls(
            q=float(data.get("q", 0.0)),
            time=float(data.get("time", 0.0)),
            distance=float(data.get("distance", 0.0)),
            energy=float(data.get("energy", 0.0)),
            horizon=None if data.get("horizon") is None else float(data["horizon"]),
            band={k: (float(lo), float(hi)) for k, (lo, hi) in data.get("band", {}).items()},
        )


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else str(x)


def perturbed_runs(
    run: Run, perturbations: Sequence[tuple[str, float]] = PERTURBATIONS, *, first: int = 0
) -> list[Run]:
    """The copies of a run that measure its sensitivity, one per entry of ``perturbations``.

    Args:
        run: The run.
        perturbations: (dotted scenario key, factor on its value) of each copy.
        first: The number of the first copy (its id's suffix ``-perturbed<k>``).
    """
    defaults = SimConfig()
    out = []
    for k, (key, factor) in enumerate(perturbations, start=first):
        section, name = key.split(".")
        value = run.scenario.get(section, {}).get(name, getattr(defaults, name))
        scenario = apply_overrides(run.scenario, {key: float(value) * factor}, field_prefix="set")
        out.append(
            dataclasses.replace(
                run, id=f"{run.id}-perturbed{k}", scenario=scenario, digest=digest(scenario)
            )
        )
    return out


def checkpoints(traj: Trajectory, duration: float) -> tuple[list[float], list[list[float]]]:
    """The samples of a trajectory at the multiples of :data:`CHECKPOINT_DT` up to ``duration``.

    Returns:
        The checkpoint times [s] and the joint positions there [rad].
    """
    t, q = traj
    times, rows = [], []
    for k in range(int(duration / CHECKPOINT_DT + 1e-9) + 1):
        tk = k * CHECKPOINT_DT
        i = int(np.searchsorted(t, tk - 1e-9))
        if i < len(t) and abs(t[i] - tk) <= 1e-9:
            times.append(float(t[i]))
            rows.append([float(x) for x in q[i]])
    return times, rows


@checked_arguments
def measure_sensitivity(
    nominal: RunRecord,
    traj: Trajectory,
    members: Sequence[tuple[RunRecord, Trajectory]],
    tolerances: Tolerances,
) -> Sensitivity:
    """Compare a run with its perturbed copies (see :class:`Sensitivity`)."""
    horizon = math.inf
    q_noise = time_noise = dist_noise = energy_noise = 0.0
    records = [nominal]
    for rec, (tm, qm) in members:
        records.append(rec)
        if rec.status != nominal.status or rec.status != "ok":
            horizon = 0.0
            continue
        # Events: the first one where the sequences differ is a branch.
        ka, kb = nominal.event_kinds, rec.event_kinds
        n_same = next(
            (i for i, (a, b) in enumerate(zip(ka, kb, strict=False)) if a != b),
            min(len(ka), len(kb)),
        )
        if n_same < max(len(ka), len(kb)):
            later = [
                *nominal.event_times[n_same : n_same + 1],
                *rec.event_times[n_same : n_same + 1],
            ]
            horizon = min(horizon, min(later))
        for i in range(n_same):
            time_noise = max(time_noise, abs(nominal.event_times[i] - rec.event_times[i]))
        # Trajectories on their common samples.
        t, q = traj
        n = min(len(t), len(tm))
        dev = np.abs(qm[:n] - q[:n]).max(axis=1) if n else np.zeros(0)
        out = np.flatnonzero(dev > tolerances.q)
        if len(out):
            horizon = min(horizon, float(t[out[0]]))
        before = t[:n] < horizon
        if np.any(before):
            q_noise = max(q_noise, float(dev[before].max()))
        if (nominal.rest_time is None) != (rec.rest_time is None):
            known = [x for x in (nominal.rest_time, rec.rest_time) if x is not None]
            horizon = min(horizon, *known)
        elif nominal.rest_time is not None and rec.rest_time is not None:
            time_noise = max(time_noise, abs(nominal.rest_time - rec.rest_time))
        if math.isinf(nominal.min_distance) != math.isinf(rec.min_distance):
            horizon = min(horizon, float(t[-1]))
        elif not math.isinf(nominal.min_distance):
            dist_noise = max(dist_noise, abs(nominal.min_distance - rec.min_distance))
        energy_noise = max(energy_noise, abs(nominal.energy_change - rec.energy_change))
    if math.isinf(horizon):
        return Sensitivity(q=q_noise, time=time_noise, distance=dist_noise, energy=energy_noise)
    ok = [r for r in records if r.status == "ok"]
    band: dict[str, tuple[float, float]] = {}

    def span(name: str, values: Sequence[float]) -> None:
        nan = any(math.isnan(x) for x in values)  # e.g. a rest time in some runs only
        band[name] = (math.nan, math.nan) if nan else (min(values), max(values))

    for j, joint in enumerate(nominal.joint_names):
        span(f"q.{joint}", [r.final_q[j] for r in ok])
    span("rest_time", [math.nan if r.rest_time is None else r.rest_time for r in ok])
    span("n_events", [float(r.n_events) for r in ok])
    span("min_distance", [r.min_distance for r in ok])
    span("energy_change", [r.energy_change for r in ok])
    return Sensitivity(
        q=q_noise,
        time=time_noise,
        distance=dist_noise,
        energy=energy_noise,
        horizon=horizon,
        band=band,
    )


@checked_arguments
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


@checked_arguments
def compare(
    golden: Mapping[str, Mapping[str, Any]],
    new: Mapping[str, RunRecord],
    tolerances: Tolerances | None = None,
    trajectories: Mapping[str, Trajectory] | None = None,
) -> list[Drift]:
    """The quantities that moved between golden and new results.

    Args:
        golden: Run id -> golden quantities (:func:`read_golden`), with their checkpoints and
            sensitivity where the golden file has them.
        new: Run id -> new record.
        tolerances: Absolute tolerances (default: :class:`Tolerances`); each is widened to
            :data:`NOISE_FACTOR` times the run's measured noise where that is larger.
        trajectories: Run id -> the new run's trajectory (:func:`read_trajectories`), to check
            the golden checkpoints; None: the checkpoints are not checked.

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
        quantities = {k: v for k, v in gdata.items() if k not in _GOLDEN_EXTRAS}
        g = RunRecord.from_json({"format": RECORD_FORMAT, "index": 0, **quantities, "id": rid})
        sens = Sensitivity.from_json(gdata.get("sensitivity", {}))
        drifts += _compare_run(g, new[rid], _widened(tol, sens), sens)
        if trajectories is not None and rid in trajectories and g.status == new[rid].status:
            drifts += _compare_checkpoints(
                rid, gdata.get("checkpoints"), trajectories[rid], g.joint_names, tol, sens
            )
    drifts += [Drift(rid, "run", "missing", "present") for rid in new if rid not in golden]
    return drifts


#: Keys of a golden run that are not record quantities.
_GOLDEN_EXTRAS = ("checkpoints", "sensitivity")


def _widened(tol: Tolerances, sens: Sensitivity) -> Tolerances:
    """Each tolerance at least NOISE_FACTOR times the run's measured noise."""
    return Tolerances(
        q=max(tol.q, NOISE_FACTOR * sens.q),
        time=max(tol.time, NOISE_FACTOR * sens.time),
        distance=max(tol.distance, NOISE_FACTOR * sens.distance),
        energy=max(tol.energy, NOISE_FACTOR * sens.energy),
    )


def _compare_checkpoints(
    rid: str,
    stored: Mapping[str, Any] | None,
    traj: Trajectory,
    joints: Sequence[str],
    tol: Tolerances,
    sens: Sensitivity,
) -> list[Drift]:
    """The new trajectory at the golden checkpoints before the horizon: the worst joint."""
    if not stored:
        return []
    limit = max(tol.q, NOISE_FACTOR * sens.q)
    horizon = math.inf if sens.horizon is None else sens.horizon
    t_new, q_new = traj
    worst: tuple[float, int, int, float, float] | None = None
    for tk, qk in zip(stored["t"], stored["q"], strict=True):
        if tk >= horizon:
            break
        i = int(np.searchsorted(t_new, tk - 1e-9))
        if i >= len(t_new) or abs(t_new[i] - tk) > 1e-9:
            return [Drift(rid, f"q(t={tk:g})", "a sample", "no sample")]
        diff = np.abs(q_new[i] - np.asarray(qk))
        j = int(np.argmax(diff))
        if worst is None or diff[j] > worst[0]:
            worst = (float(diff[j]), j, i, float(qk[j]), float(q_new[i][j]))
    if worst is None or worst[0] <= limit:
        return []
    diff, j, i, a, b = worst
    return [Drift(rid, f"q(t={t_new[i]:g}).{joints[j]}", _fmt(a), _fmt(b), diff, limit)]


def _compare_run(g: RunRecord, n: RunRecord, tol: Tolerances, sens: Sensitivity) -> list[Drift]:
    rid = g.id
    out: list[Drift] = []
    if g.status != n.status:
        return [Drift(rid, "status", g.status, f"{n.status} {n.error}".strip())]
    if g.status != "ok":
        return out
    if list(g.joint_names) != list(n.joint_names):
        return [Drift(rid, "joint_names", " ".join(g.joint_names), " ".join(n.joint_names))]
    if sens.horizon is not None:
        return _compare_chaotic(g, n, tol, sens)
    for joint, a, b in zip(g.joint_names, g.final_q, n.final_q, strict=True):
        out += _number(rid, f"q.{joint}", a, b, tol.q)
    if (g.rest_time is None) != (n.rest_time is None):
        out.append(Drift(rid, "rest_time", _fmt(g.rest_time), _fmt(n.rest_time)))
    elif g.rest_time is not None and n.rest_time is not None:
        out += _number(rid, "rest_time", g.rest_time, n.rest_time, tol.time)
    gk, nk = Counter(g.event_kinds), Counter(n.event_kinds)
    for kind in sorted(gk.keys() | nk.keys()):
        if gk[kind] != nk[kind]:
            out.append(Drift(rid, f"events.{kind}", str(gk[kind]), str(nk[kind])))
    if gk == nk:
        out += _compare_events(rid, g, n, math.inf, tol.time)
    out += _number(rid, "min_distance", g.min_distance, n.min_distance, tol.distance)
    out += _number(rid, "energy_change", g.energy_change, n.energy_change, tol.energy)
    return out


def _compare_events(
    rid: str, g: RunRecord, n: RunRecord, before: float, tol_time: float
) -> list[Drift]:
    """The golden run's events before ``before`` [s], and as many of the new run's.

    The same kinds in order, each time within tol_time. By count, not by time: the event at
    the horizon is the one the copies disagree on, and rounding moves it to either side of the
    horizon (measured: a stick event at 0.33286 to 0.33341 s against a horizon of 0.33341 s);
    the new run may have the events of that one instant more before the horizon, not more.
    """
    gi = [i for i, t in enumerate(g.event_times) if t < before]
    extra = [t for t in n.event_times[len(gi) :] if t < before]
    if extra and max(extra) - min(extra) > tol_time:
        # (the horizon's restart came earlier: its events share one instant; more is a change)
        n_new = len(gi) + len(extra)
        return [Drift(rid, "events before the horizon", str(len(gi)), str(n_new))]
    ni = list(range(min(len(gi), len(n.event_times))))
    kinds_g = [g.event_kinds[i] for i in gi]
    kinds_n = [n.event_kinds[i] for i in ni]
    if kinds_g != kinds_n:
        k = next(
            (i for i, (a, b) in enumerate(zip(kinds_g, kinds_n, strict=False)) if a != b),
            min(len(kinds_g), len(kinds_n)),
        )
        a = kinds_g[k] if k < len(kinds_g) else "none"
        b = kinds_n[k] if k < len(kinds_n) else "none"
        return [Drift(rid, f"event[{k}].kind", a, b)]
    if not gi:
        return []
    diffs = [abs(g.event_times[i] - n.event_times[j]) for i, j in zip(gi, ni, strict=True)]
    k = max(range(len(diffs)), key=diffs.__getitem__)
    if diffs[k] <= tol_time:
        return []
    return [
        Drift(
            rid,
            f"event[{k}].t ({kinds_g[k]})",
            _fmt(g.event_times[gi[k]]),
            _fmt(n.event_times[ni[k]]),
            diffs[k],
            tol_time,
        )
    ]


def _compare_chaotic(g: RunRecord, n: RunRecord, tol: Tolerances, sens: Sensitivity) -> list[Drift]:
    """A run with a horizon: its events before it; its final quantities on their band."""
    assert sens.horizon is not None
    rid = g.id
    out = _compare_events(rid, g, n, sens.horizon, tol.time)
    new_values: dict[str, float] = {
        **{f"q.{j}": x for j, x in zip(n.joint_names, n.final_q, strict=True)},
        "rest_time": math.nan if n.rest_time is None else n.rest_time,
        "n_events": float(n.n_events),
        "min_distance": n.min_distance,
        "energy_change": n.energy_change,
    }
    absolute = {"rest_time": tol.time, "n_events": 0.0, "min_distance": tol.distance}
    for name, (lo, hi) in sens.band.items():
        x = new_values.get(name, math.nan)
        if math.isnan(lo) or math.isnan(hi):  # a rest time in some copies, none in others
            continue
        if name.startswith("q."):
            pad = (hi - lo) + max(tol.q, tol.chaotic_q)
        elif name == "min_distance":  # (its size says nothing of its spread: an absolute floor)
            pad = (hi - lo) + max(tol.distance, CHAOTIC_DISTANCE)
        else:
            pad = (hi - lo) + absolute.get(name, tol.energy) + CHAOTIC_SHARE * abs(lo + hi) / 2
        if lo == hi == x or lo - pad <= x <= hi + pad:
            continue
        out.append(
            Drift(rid, f"{name} (band)", f"[{_fmt(lo)}, {_fmt(hi)}]", _fmt(x), math.nan, pad)
        )
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


@checked_arguments
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


@checked_arguments
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
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigurationError(str(path), "unreadable", f"a golden results file ({exc})") from exc
    valid = (GOLDEN_FORMAT, *LEGACY_GOLDEN_FORMATS)
    if not isinstance(data, dict) or data.get("format") not in valid:
        fmt = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ConfigurationError(f"{path}: format", fmt, valid)
    return str(data["matrix"]), dict(data["runs"])


@checked_arguments
def write_golden(
    folder: str | Path,
    matrix_name: str,
    runs: Sequence[Run],
    records: Mapping[str, RunRecord],
    tolerances: Tolerances | None = None,
    extras: Mapping[str, Mapping[str, Any]] | None = None,
) -> list[Path]:
    """Write ``results.json`` and ``summary.csv`` for the runs that have a record.

    Args:
        folder: The matrix's golden folder.
        matrix_name: The matrix's name.
        runs: The runs, in matrix order.
        records: Run id -> record.
        tolerances: The tolerances (stored for the reader).
        extras: Run id -> ``{"checkpoints": ..., "sensitivity": ...}`` (see
            :func:`run_regression`), stored with the run's quantities.

    Returns:
        The files written.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    kept = [r for r in runs if r.id in records]
    more = extras or {}
    data = {
        "format": GOLDEN_FORMAT,
        "matrix": matrix_name,
        "tolerances": asdict(tolerances or Tolerances()),
        "noise": {
            "perturbations": [[k, f] for k, f in PERTURBATIONS],
            "factor": NOISE_FACTOR,
            "checkpoint_dt": CHECKPOINT_DT,
        },
        "runs": {r.id: {**records[r.id].quantities(), **more.get(r.id, {})} for r in kept},
    }
    results = out / "results.json"
    atomic_write(results, _golden_json(data).encode())
    rows = summary_rows(kept, records)
    columns = [c for c in rows[0] if c not in ("wall_time", "worker")] if rows else ["id"]
    summary = out / "summary.csv"
    atomic_write(summary, csv_text(rows, columns).encode())
    return [results, summary]


@checked_arguments
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


@checked_arguments
def default_golden_dir() -> Path:
    """The shipped golden results folder, ``sims/golden/``."""
    from packbot.resources import data_dir

    return data_dir("sims") / "golden"


@checked_arguments
def golden_matrices(golden_root: str | Path) -> list[str]:
    """Names of the matrices that have golden results in ``golden_root``."""
    root = Path(golden_root)
    return sorted(p.parent.name for p in root.glob("*/results.json"))


@checked_arguments
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
    batch_args: dict[str, Any] = {
        "workers": workers,
        "scheduler": scheduler,
        "runner": runner,
        "progress": progress,
    }
    with tempfile.TemporaryDirectory(prefix=f"packbot-regress-{matrix.name}-") as tmp:
        out = Path(tmp) / "nominal" if out_dir is None else Path(out_dir)
        batch = run_batch(matrix, out, runs=runs, **batch_args)
        records = {r.id: batch.records[r.id] for r in batch.runs if r.id in batch.records}
        trajectories = read_trajectories(out, records)
        extras: dict[str, dict[str, Any]] = {}
        if update:
            extras = _measure(matrix, batch.runs, records, trajectories, tol, Path(tmp), batch_args)
    drifts = [] if golden is None else compare(golden, records, tol, trajectories)
    result = RegressionResult(
        matrix=matrix.name,
        drifts=drifts,
        batch=batch,
        golden_dir=folder,
        had_golden=golden is not None,
    )
    if update:
        result.written = write_golden(folder, matrix.name, batch.runs, records, tol, extras)
    return result


def _measure(
    matrix: Matrix,
    runs: Sequence[Run],
    records: Mapping[str, RunRecord],
    trajectories: Mapping[str, Trajectory],
    tol: Tolerances,
    tmp: Path,
    batch_args: Mapping[str, Any],
) -> dict[str, dict[str, Any]]:
    """Each run's checkpoints and sensitivity (its perturbed copies made in ``tmp``).

    Every run gets the copies of :data:`PERTURBATIONS`; a run they find chaotic (a horizon)
    also those of :data:`CHAOTIC_PERTURBATIONS`, and its sensitivity is measured on them all.
    """
    made = [r for r in runs if r.id in records and r.id in trajectories]
    copies = {r.id: perturbed_runs(r) for r in made}
    members = _made(
        matrix, [c for cs in copies.values() for c in cs], tmp / "perturbed", batch_args
    )
    sens = {r.id: _sensitivity(r, records, trajectories, copies, members, tol) for r in made}
    chaotic = [r for r in made if sens[r.id].horizon is not None]
    if chaotic:
        extra = {
            r.id: perturbed_runs(r, CHAOTIC_PERTURBATIONS, first=len(PERTURBATIONS))
            for r in chaotic
        }
        members.update(
            _made(matrix, [c for cs in extra.values() for c in cs], tmp / "chaotic", batch_args)
        )
        for r in chaotic:
            copies[r.id] += extra[r.id]
            sens[r.id] = _sensitivity(r, records, trajectories, copies, members, tol)
    extras: dict[str, dict[str, Any]] = {}
    for run in runs:
        if run.id not in records:
            continue
        entry: dict[str, Any] = {}
        if run.id in trajectories:
            t, q = checkpoints(trajectories[run.id], records[run.id].t_end)
            entry["checkpoints"] = {"t": t, "q": q}
            entry["sensitivity"] = sens[run.id].to_json()
        extras[run.id] = entry
    return extras


def _made(
    matrix: Matrix, runs: Sequence[Run], folder: Path, batch_args: Mapping[str, Any]
) -> dict[str, tuple[RunRecord, Trajectory]]:
    """The runs made as one batch in ``folder``: run id -> (record, trajectory)."""
    batch = run_batch(matrix, folder, runs=runs, **batch_args)
    traj = read_trajectories(folder, batch.records)
    return {rid: (rec, traj.get(rid, _EMPTY)) for rid, rec in batch.records.items()}


def _sensitivity(
    run: Run,
    records: Mapping[str, RunRecord],
    trajectories: Mapping[str, Trajectory],
    copies: Mapping[str, Sequence[Run]],
    members: Mapping[str, tuple[RunRecord, Trajectory]],
    tol: Tolerances,
) -> Sensitivity:
    """A run's sensitivity from those of its copies that were made."""
    pairs = [members[c.id] for c in copies[run.id] if c.id in members]
    return measure_sensitivity(records[run.id], trajectories[run.id], pairs, tol)


_EMPTY: Trajectory = (np.zeros(0), np.zeros((0, 0)))


@checked_arguments
def read_trajectories(
    out_dir: str | Path, records: Mapping[str, RunRecord]
) -> dict[str, Trajectory]:
    """The sample times and joint positions of each record's trajectory file, where it has one.

    Args:
        out_dir: The batch folder.
        records: Run id -> record (its ``files["trajectory"]`` is relative to ``out_dir``).

    Raises:
        ResultFileError: A trajectory file that is damaged, or whose ``t`` or ``q`` is of
            another dtype or shape or not finite (read with the bounds of
            :func:`packbot.result_file.read_trajectory`).
    """
    out: dict[str, Trajectory] = {}
    for rid, rec in records.items():
        name = rec.files.get("trajectory")
        if rec.status != "ok" or not name or not name.endswith(".npz"):
            continue  # a runner of another kind (tests' toy runner) writes no npz
        path = Path(out_dir) / name
        if not path.is_file():
            continue
        traj = read_trajectory(path)  # bounded and checked, as SimResult.load reads
        if traj is not None:
            out[rid] = traj
    return out
