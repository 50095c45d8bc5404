"""Independent checks of a zero-torque run, computed from its samples without the engine.

What the engine reports about itself (``Diagnostics.min_distance``, each event's energies) is
read at its step ends and events; these checks read every sample of the result (``t``, ``q``,
``v``) and recompute what they need with Pinocchio and Coal directly:

- **energy rise** (:func:`energy_rise`): with zero torque, no actuator input and dissipative
  contacts the total energy never rises; the largest rise of a sample's energy above the
  smallest energy of the samples before it [J]. The energy is recomputed from q and v
  (:func:`energies`: kinetic ``1/2 v^T M v`` of the rigid bodies plus ``1/2 sum armature v^2``,
  and Pinocchio's gravitational potential), and compared with ``result.energy``; inside a
  time-stepping window a sample is an interpolation between two step ends whose velocity blend
  can dip below both ends' energies across an impulse, and such a dip does not lower the
  running minimum (:func:`energy_rise`);
- **penetration** (:class:`PenetrationQuery`): the signed distance of every tested collision
  pair at every sample, by its own ``pin.computeDistances`` call on the collision world's
  geometry model (the pieces, obstacles and tested pairs ``CollisionWorld`` builds, so the
  disabled pairs -- one body, adjacent links, the SRDF's, two static bodies -- are skipped as
  the world skips them) with its own geometry data and request settings: no pruning, no sweep,
  no witness cache of the engine;
- **limit overrun** (:func:`limit_overrun`): how far each joint is beyond its position limit at
  each sample [rad].

The samples of a run are its regular ones every ``sample_dt`` (from the integrator's dense
output, or inside a time-stepping window the scheme's own interpolation), and the states just
before and just after each event: a fault between two samples is seen only at its next sample,
so a fine ``sample_dt`` (1 ms in ``benchmarks/robustness.py``) is what makes the checks see the
motion between events.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

#: The issue's bounds (issue 38): energy rise [J], penetration [m], limit overrun [rad].
RISE_BOUND = 1e-2
DEPTH_BOUND = -1.1e-5
OVERRUN_BOUND = 1e-5
#: Absolute GJK/EPA tolerance of the query [m] (Coal's default is relative, 1e-6).
GJK_TOLERANCE = 1e-10

FloatArray = NDArray[np.float64]


# ---------------------------------------------------------------------- energy
def energies(model: pin.Model, q: FloatArray, v: FloatArray) -> FloatArray:
    """Total mechanical energy [J] of every sample (rows of q [rad] and v [rad/s]).

    Kinetic: Pinocchio's rigid-body kinetic energy of a copy of the model without armature,
    plus ``1/2 sum armature_i v_i^2`` (the reflected rotor inertias, written out so that the
    sum does not depend on whether a Pinocchio version adds the armature itself); potential:
    ``pin.computePotentialEnergy`` (the model's gravity). Full model coordinates (a locked
    joint at its angle with zero speed: the same energy as the reduced model's).
    """
    rigid = model.copy()
    armature = np.array(model.armature, dtype=float)
    rigid.armature = np.zeros(model.nv)
    data = rigid.createData()
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    out = np.empty(len(q))
    for i, (qi, vi) in enumerate(zip(q, v, strict=True)):
        kinetic = pin.computeKineticEnergy(rigid, data, qi, vi) + 0.5 * float(armature @ vi**2)
        out[i] = kinetic + pin.computePotentialEnergy(rigid, data, qi)
    return out


@dataclass(frozen=True)
class Rise:
    """The largest rise of a sampled quantity above its running minimum.

    Attributes:
        rise: Largest ``e[i] - min(e[:i + 1])`` (0 if it never rises).
        t_from: Time of the running minimum it rose from [s].
        t_to: Time of the sample where the rise is largest [s].
        step: Largest rise from one sample to the next.
        t_step: Time of the later sample of that interval [s].
    """

    rise: float
    t_from: float
    t_to: float
    step: float
    t_step: float


def energy_rise(
    t: FloatArray, e: FloatArray, interpolated: NDArray[np.bool_] | None = None
) -> Rise:
    """The largest rise of the energy ``e`` [J] above its running minimum over samples t [s].

    Non-finite energies count as an infinite rise (a run that blew up).

    Args:
        t: Sample times [s].
        e: Energies [J].
        interpolated: Samples whose state is an interpolation inside a time-stepping window's
            step (:func:`window_samples`). Such a step's velocity is a linear blend of its two
            ends: across a step with an impulse (a rebound, e > 0) the blend passes near zero
            normal speed and the sample's kinetic energy dips below both ends', a dip of the
            sampling, not of the motion, which would make the next sample look like a rise. An
            interpolated sample that is a strict local minimum (below both neighbours) enters
            the running minimum at its lower neighbour's energy; its own energy still counts
            as a possible peak (a blend never exceeds its ends' energies but by the second-order
            change of the potential along the step).
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if len(e) == 0:
        return Rise(0.0, np.nan, np.nan, 0.0, np.nan)
    if not np.all(np.isfinite(e)):
        k = int(np.argmax(~np.isfinite(e)))
        return Rise(np.inf, float(t[0]), float(t[k]), np.inf, float(t[k]))
    floor = e.copy()  # what each sample contributes to the running minimum
    if interpolated is not None and len(e) > 2:
        inner = np.zeros(len(e), dtype=bool)
        inner[1:-1] = np.asarray(interpolated, dtype=bool)[1:-1]
        dip = inner.copy()
        dip[1:-1] &= (e[1:-1] < e[:-2]) & (e[1:-1] < e[2:])
        k = np.flatnonzero(dip)
        floor[k] = np.minimum(e[k - 1], e[k + 1])
    low = np.minimum.accumulate(floor)
    above = e - low
    k = int(np.argmax(above))
    j = int(np.flatnonzero(floor[: k + 1] == low[k])[0])
    steps = e[1:] - floor[:-1]
    s = int(np.argmax(steps)) if len(steps) else -1
    step = max(0.0, float(steps[s])) if s >= 0 else 0.0
    rise = max(0.0, float(above[k]))
    return Rise(rise, float(t[j]), float(t[k]), step, float(t[s + 1]) if s >= 0 else 0.0)


def window_samples(t: FloatArray, events: list[Any]) -> NDArray[np.bool_]:
    """Which samples are interpolated inside a time-stepping window's step.

    A window runs from its ``timestep`` event to its ``resume`` event (or the run's end);
    its regular samples (strictly inside, not sharing their time with another sample as an
    event's before/after pair does) interpolate between the window's step ends.

    Args:
        t: Sample times [s].
        events: The result's events (their ``t`` and ``kind``).
    """
    t = np.asarray(t, dtype=float)
    out = np.zeros(len(t), dtype=bool)
    start: float | None = None
    spans = []
    for ev in events:
        if ev.kind == "timestep" and start is None:
            start = float(ev.t)
        elif ev.kind == "resume" and start is not None:
            spans.append((start, float(ev.t)))
            start = None
    if start is not None:
        spans.append((start, np.inf))
    for a, b in spans:
        out |= (t > a) & (t < b)
    if len(t) > 1:
        shared = np.zeros(len(t), dtype=bool)
        same = t[1:] == t[:-1]
        shared[1:] |= same
        shared[:-1] |= same
        out &= ~shared
    return out


# ---------------------------------------------------------------------- penetration
class PenetrationQuery:
    """Signed distances of every tested pair of a collision world, by its own Coal calls.

    Args:
        model: The robot's Pinocchio model (full coordinates).
        geom_model: The world's geometry model with its tested pairs
            (``CollisionWorld(robot, environment).geom_model``). Read only: the query makes
            its own ``GeometryData`` with absolute GJK/EPA tolerances (:data:`GJK_TOLERANCE`)
            and computes every pair at every call (no pruning).
    """

    def __init__(self, model: pin.Model, geom_model: pin.GeometryModel) -> None:
        self.model = model
        self.geom_model = geom_model
        self._data = model.createData()
        self._gd = geom_model.createData()
        for req in self._gd.distanceRequests:
            req.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
            req.gjk_tolerance = GJK_TOLERANCE
            req.epa_tolerance = GJK_TOLERANCE
        self._results = list(self._gd.distanceResults)  # live proxies of the C++ results
        gos = geom_model.geometryObjects
        names = []
        for cp in geom_model.collisionPairs:
            g1, g2 = gos[int(cp.first)], gos[int(cp.second)]
            names.append(f"{g1.name} - {g2.name}")
        #: each pair's pieces, "piece1 - piece2"
        self.pair_names: tuple[str, ...] = tuple(names)

    def distances(self, q: FloatArray) -> FloatArray:
        """Signed distance of every tested pair at q [m] (negative: penetration depth)."""
        pin.updateGeometryPlacements(self.model, self._data, self.geom_model, self._gd, q)
        pin.computeDistances(self.geom_model, self._gd)
        return np.array([r.min_distance for r in self._results])

    def deepest(self, t: FloatArray, q: FloatArray) -> Depth:
        """The smallest signed distance over every pair and sample, and runs of samples below.

        Args:
            t: Sample times [s], shape (N,).
            q: Configurations [rad], shape (N, nq).
        """
        best = np.inf
        where = (np.nan, -1)
        below = 0
        for i, qi in enumerate(np.asarray(q, dtype=float)):
            d = self.distances(qi)
            if not len(d):
                continue
            k = int(np.argmin(d))
            below += bool(d[k] < DEPTH_BOUND)
            if d[k] < best:
                best, where = float(d[k]), (float(t[i]), k)
        pair = self.pair_names[where[1]] if where[1] >= 0 else ""
        return Depth(best, where[0], pair, below)


@dataclass(frozen=True)
class Depth:
    """The deepest penetration over a run's samples.

    Attributes:
        distance: Smallest signed distance of any pair at any sample [m] (inf: no pairs).
        t: Its sample time [s].
        pair: Its pair, ``"piece1 - piece2"``.
        samples_below: Samples where some pair is below :data:`DEPTH_BOUND`.
    """

    distance: float
    t: float
    pair: str
    samples_below: int


# ---------------------------------------------------------------------- limits
@dataclass(frozen=True)
class Overrun:
    """The largest excursion of a joint beyond its position limit over a run's samples.

    Attributes:
        overrun: Largest ``q - upper`` or ``lower - q`` of any joint at any sample [rad]
            (0: every joint always within its limits).
        t: Its sample time [s].
        joint: Its joint.
        side: ``"upper"`` or ``"lower"``.
    """

    overrun: float
    t: float
    joint: str
    side: str


def limit_overrun(
    t: FloatArray,
    q: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    names: tuple[str, ...],
) -> Overrun:
    """How far any joint goes beyond its position limits over the samples.

    Args:
        t: Sample times [s], shape (N,).
        q: Joint positions [rad], shape (N, nq) (one revolute coordinate per joint).
        lower: Lower limits [rad], shape (nq,).
        upper: Upper limits [rad], shape (nq,).
        names: Joint names, one per column.
    """
    q = np.asarray(q, dtype=float)
    if not len(q):
        return Overrun(0.0, np.nan, "", "")
    over_hi = q - np.asarray(upper, dtype=float)
    over_lo = np.asarray(lower, dtype=float) - q
    worst_hi, worst_lo = float(np.max(over_hi)), float(np.max(over_lo))
    side, arr = ("upper", over_hi) if worst_hi >= worst_lo else ("lower", over_lo)
    i, j = np.unravel_index(int(np.argmax(arr)), arr.shape)
    value = float(arr[i, j])
    if value <= 0.0:
        return Overrun(0.0, np.nan, "", "")
    return Overrun(value, float(t[i]), names[j], side)


# ---------------------------------------------------------------------- one result
@dataclass(frozen=True)
class Checks:
    """The independent checks of one result.

    Attributes:
        energy: The rise of the recomputed energy above its running minimum (the windows'
            interpolation dips lifted: :func:`energy_rise`).
        energy_raw: The same over the raw samples (every sample's energy in the minimum).
        energy_reported: The same as ``energy`` of ``result.energy``.
        energy_mismatch: Largest ``|recomputed - result.energy|`` over the samples [J].
        depth: The deepest penetration by the separate query.
        overrun: The largest limit overrun.
        samples: Number of samples checked.
    """

    energy: Rise
    energy_raw: Rise
    energy_reported: Rise
    energy_mismatch: float
    depth: Depth
    overrun: Overrun
    samples: int


def check_result(res: Any, model: pin.Model, query: PenetrationQuery) -> Checks:
    """Every independent check of one result (``packbot.SimResult``: t, q, v, energy, events).

    Args:
        res: The result.
        model: The robot's Pinocchio model (its limits, armature, gravity).
        query: The penetration query of the run's world.
    """
    t = np.asarray(res.t, dtype=float)
    q = np.asarray(res.q, dtype=float)
    e = energies(model, q, np.asarray(res.v, dtype=float))
    reported = np.asarray(res.energy, dtype=float)
    mismatch = float(np.max(np.abs(e - reported))) if len(e) else 0.0
    interpolated = window_samples(t, list(res.events))
    return Checks(
        energy=energy_rise(t, e, interpolated),
        energy_raw=energy_rise(t, e),
        energy_reported=energy_rise(t, reported, interpolated),
        energy_mismatch=mismatch,
        depth=query.deepest(t, q),
        overrun=limit_overrun(
            t,
            q,
            model.lowerPositionLimit,
            model.upperPositionLimit,
            tuple(str(n) for n in res.joint_names),
        ),
        samples=len(t),
    )
