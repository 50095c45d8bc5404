"""The event-driven simulator: :func:`simulate`.

Between events the smooth dynamics (Pinocchio ABA with armature, the engaged joint locks
applied) are integrated by an adaptive Dormand-Prince 5(4) method (:mod:`packbot.ode`). After
every accepted step the step's end is checked for events; an event function that changed sign
is located on the step's dense output to ``EVENT_XTOL`` seconds by root finding, the step is cut
there, the event is handled, and the stepper restarts with a fresh step. Event functions:

- ``impact``: an inactive pair's signed distance d falls to +contact_tolerance;
- ``limit``: a joint reaches a position limit (a hard stop, handled like an impact);
- ``release``: an active pair separates beyond proximity_tolerance;
- ``secondary_intersection``: an active, clamped pair's distance falls below zero (the
  report's "secondary intersection", self-diagnosed: logged, and the impact law is applied again
  with the current geometry);
- ``engage`` / ``disengage``: a clamped joint's sign condition changes (it starts to accelerate
  toward its contact, or its lock torque would pull); see :mod:`packbot.contact.locks`.

Inside a step the set of engaged locks is fixed, so the right-hand side is smooth and the steps
stay long. A step never moves any point of the arm by more than half the query margin (a bound
from the joint speeds), so a pair cannot pass from outside the margin through contact within a
step unseen.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.config import SimConfig
from packbot.contact import JointLocks, clamp_directions, impact_reset, relevant_joints
from packbot.environment import Environment
from packbot.errors import (
    ConfigurationError,
    ControllerError,
    InitialCollisionError,
    SimulationError,
)
from packbot.model import Robot
from packbot.ode import DenseSegment, RK45Stepper, StepSizeUnderflow, locate_root
from packbot.result import Diagnostics, Event, SimResult, rest_time
from packbot.system import System

__all__ = ["EVENT_XTOL", "Controller", "simulate"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
#: A controller: joint torques [N*m] (shape (nv,), full coordinates) from t [s], q [rad], v [rad/s].
Controller = Callable[[float, FloatArray, FloatArray], Any]

#: Time resolution of event location [s].
EVENT_XTOL = 1e-10
#: Bound on the distance from any joint axis to any point of the arm [m] (reach is ~2 m).
REACH_BOUND = 2.2


@dataclass
class _Active:
    """An active contact: a pair (None for a limit stop) and the clamps it imposes.

    Its key in ``_Run.active`` is ``("pair", index)`` or ``("limit", joint, side)`` with side +1
    for the upper stop and -1 for the lower one.
    """

    pair: PairInfo | None
    clamps: list[tuple[int, int]]


@dataclass
class _Crossing:
    """An event function that changed sign within a step."""

    kind: str
    key: tuple[Any, ...]
    g: Callable[[float], float]
    g0: float
    g1: float


class _Run:
    """One simulation run: the state of the event loop."""

    def __init__(
        self,
        robot: Robot,
        q0: FloatArray,
        v0: FloatArray,
        duration: float,
        controller: Controller | None,
        environment: Environment | None,
        config: SimConfig,
    ) -> None:
        self.cfg = config
        self.duration = duration
        self.sys = System(robot, q0, config, environment)
        self.controller = controller
        self.n = self.sys.nv
        self.locks = JointLocks()
        self.active: dict[tuple[Any, ...], _Active] = {}
        self.events: list[Event] = []
        self.diag = Diagnostics()
        self.samples_t: list[float] = []
        self.samples_y: list[FloatArray] = []
        self.next_sample = 0
        self.q_full0 = np.asarray(q0, dtype=float)
        self.tau_zero = np.zeros(self.n)
        self.stepper = RK45Stepper(
            self.rhs, rtol=config.rtol, atol=config.atol, h_max=config.max_step
        )
        self.t = 0.0
        self.y = np.concatenate([self.sys.reduce(q0), self.sys.reduce(v0)])
        self.last_d: dict[int, float] = {}  # pair -> distance at the last kept state [m]
        self.pending_d: dict[int, float] = {}  # the same at the end of the step being checked
        self.pending_min: tuple[float, int] = (math.inf, -1)

    # ------------------------------------------------------------------ dynamics
    def torque(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Controller torque on the integrated joints [N*m]."""
        if self.controller is None:
            return self.tau_zero
        qf, vf = self.sys.q_full(q), self.sys.v_full(v)
        try:
            tau = np.asarray(self.controller(t, qf, vf), dtype=float)
        except Exception as exc:
            raise ControllerError(f"raised {type(exc).__name__}: {exc}", t) from exc
        nq = self.sys.full.nq
        if tau.shape != (nq,):
            raise ControllerError(f"returned shape {tau.shape}, expected ({nq},)", t)
        if not np.all(np.isfinite(tau)):
            bad = self.sys.full.joint_names[int(np.flatnonzero(~np.isfinite(tau))[0])]
            raise ControllerError(f"returned a non-finite torque for joint {bad!r}", t, bad)
        return tau[self.sys.free]

    def free_accel(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        return self.sys.aba(q, v, self.torque(t, q, v))

    def rhs(self, t: float, y: FloatArray) -> FloatArray:
        n = self.n
        q, v = y[:n], y[n:]
        a = self.free_accel(t, q, v)
        if self.locks.engaged:
            a = self.locks.accelerations(a, self.sys.minv(q))
        return np.concatenate([v, a])

    def lock_conditions(self, t: float, y: FloatArray) -> dict[int, float]:
        n = self.n
        q, v = y[:n], y[n:]
        a = self.free_accel(t, q, v)
        minv = self.sys.minv(q) if self.locks.engaged else None
        return self.locks.conditions(a, minv)

    # ------------------------------------------------------------------ recording
    def record(self, seg: DenseSegment, t_end: float) -> None:
        dt = self.cfg.sample_dt
        while True:
            ts = self.next_sample * dt
            if ts > t_end + 1e-12 or ts > self.duration + 1e-12:
                break
            self.samples_t.append(ts)
            self.samples_y.append(seg(min(max(ts, seg.t0), seg.t1)))
            self.next_sample += 1

    def record_point(self, t: float, y: FloatArray) -> None:
        self.samples_t.append(t)
        self.samples_y.append(y.copy())

    # ------------------------------------------------------------------ events
    def distance(self, pair: int, y: FloatArray) -> float:
        world = self.sys.world
        assert world is not None
        self.diag.distance_queries += 1
        return world.pair_contact(y[: self.n], pair).distance

    def crossings(self, seg: DenseSegment, y1: FloatArray) -> list[_Crossing]:
        """Event functions that changed sign over the step (evaluated at its end)."""
        cfg, n, out = self.cfg, self.n, []
        q1 = y1[:n]
        if cfg.joint_limits:  # numpy screen first: a limit crossing is rare
            upper, lower = self.sys.upper, self.sys.lower
            for j in np.flatnonzero((q1 >= upper) | (q1 <= lower)).tolist():
                side, lim = (1, upper[j]) if q1[j] >= upper[j] else (-1, lower[j])
                if ("limit", j, side) in self.active:
                    continue

                def g(t: float, j: int = j, side: int = side, lim: float = lim) -> float:
                    return float(side * (lim - seg(t)[j]))

                g0 = side * (lim - seg.y0[j])
                out.append(_Crossing("limit", ("limit", j, side), g, g0, side * (lim - q1[j])))
        world = self.sys.world
        if world is not None:
            sw = world.sweep(q1)
            self.diag.sweeps += 1
            self.pending_min = (sw.min_distance, sw.min_pair)
            d_now = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
            for p_idx, d1 in d_now.items():
                key = ("pair", p_idx)
                d0 = self.last_d.get(p_idx, math.inf)
                if key in self.active:
                    if d1 > cfg.proximity_tolerance:
                        out.append(
                            self._pair_crossing(
                                "release",
                                key,
                                p_idx,
                                seg,
                                d0,
                                d1,
                                lambda d: cfg.proximity_tolerance - d,
                            )
                        )
                    elif d1 < 0.0 <= d0:
                        out.append(
                            self._pair_crossing(
                                "secondary_intersection", key, p_idx, seg, d0, d1, lambda d: d
                            )
                        )
                elif d1 <= cfg.contact_tolerance:
                    out.append(
                        self._pair_crossing(
                            "impact", key, p_idx, seg, d0, d1, lambda d: d - cfg.contact_tolerance
                        )
                    )
            self.pending_d = d_now
        if any(len(s) == 1 for s in self.locks.signs.values()):
            cond1 = self.lock_conditions(seg.t1, y1)
            bad = [j for j, g in cond1.items() if g < 0.0]
            if bad:
                cond0 = self.lock_conditions(seg.t0, seg.y0)
                for j in bad:

                    def gl(t: float, j: int = j) -> float:
                        return self.lock_conditions(t, seg(t))[j]

                    kind = "disengage" if j in self.locks.engaged else "engage"
                    out.append(_Crossing(kind, ("lock", j), gl, cond0.get(j, 1.0), cond1[j]))
        return out

    def _pair_crossing(
        self,
        kind: str,
        key: tuple[Any, ...],
        p_idx: int,
        seg: DenseSegment,
        d0: float,
        d1: float,
        fn: Callable[[float], float],
    ) -> _Crossing:
        def g(t: float) -> float:
            return fn(self.distance(p_idx, seg(t)))

        g0 = fn(d0) if math.isfinite(d0) else 1.0
        if g0 <= 0.0:  # not a clean crossing (e.g. just restarted on it): take the step start
            g0 = g(seg.t0)
        return _Crossing(kind, key, g, g0, fn(d1))

    def locate(
        self, seg: DenseSegment, crossings: list[_Crossing]
    ) -> tuple[float, list[_Crossing]]:
        """Earliest crossing time and the crossings that happen at it."""
        times = []
        for c in crossings:
            if c.g0 <= 0.0:
                times.append(seg.t0)  # already on the event side at the step start
                continue
            times.append(locate_root(c.g, seg.t0, seg.t1, c.g0, c.g1, xtol=EVENT_XTOL))
        t_star = min(times)
        at = [c for c, tc in zip(crossings, times, strict=True) if tc <= t_star + 10 * EVENT_XTOL]
        return t_star, at

    def handle(self, t: float, y: FloatArray, crossings: list[_Crossing]) -> FloatArray:
        """Apply the events at time t to state y; returns the post-event state."""
        n = self.n
        q, v = y[:n], y[n:].copy()
        flip: int | None = None
        for c in sorted(crossings, key=lambda c: c.kind != "release"):
            if c.kind in ("impact", "secondary_intersection"):
                v = self.impact(t, q, v, c.key[1], c.kind)
            elif c.kind == "limit":
                v = self.limit(t, q, v, c.key[1], c.key[2])
            elif c.kind == "release":
                act = self.active.pop(c.key, None)
                if act is not None and act.pair is not None:
                    self.log_event(
                        t, "release", q, v, v, act.pair, d=self.distance(act.pair.index, y)
                    )
            else:  # engage / disengage
                flip = c.key[1]
                self.log_event(t, c.kind, q, v, v, None, joints=(self.sys.names[flip],))
        self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
        if self.locks.signs:
            a_free = self.free_accel(t, q, v)
            self.locks.solve_engaged(a_free, self.sys.minv(q), flip=flip)
        return np.concatenate([q, v])

    def impact(self, t: float, q: FloatArray, v: FloatArray, p_idx: int, kind: str) -> FloatArray:
        world = self.sys.world
        assert world is not None
        cfg = self.cfg
        c = world.pair_contact(q, p_idx)
        J1 = self.sys.point_jacobian(q, c.pair.joint1, c.p1)
        J2 = self.sys.point_jacobian(q, c.pair.joint2, c.p2)
        Jn = c.normal @ (J2 - J1)
        rel = relevant_joints(Jn, cfg.relevant_threshold)
        clamps = clamp_directions(v, Jn, rel, cfg.clamp_rule)
        key = ("pair", p_idx)
        if key in self.active:  # secondary intersection: add the new clamps
            old = self.active[key].clamps
            clamps = sorted(set(old) | set(clamps))
        self.active[key] = _Active(c.pair, clamps)
        v_new, acted = v, rel
        if float(Jn @ v) < 0.0 and len(rel):  # approaching: apply the reset
            v_new, acted = self.reset(q, v, rel)
        self.log_event(
            t,
            kind,
            q,
            v,
            v_new,
            c.pair,
            d=c.distance,
            joints=tuple(self.sys.names[i] for i in acted),
        )
        return v_new

    def reset(
        self, q: FloatArray, v: FloatArray, rel: NDArray[np.intp]
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        """Apply the reset rule on ``rel``, widened where it would push a clamped joint.

        The widening takes in every clamped joint that the impulse would set moving toward its
        own contact: one simultaneous impact, not a cascade of secondary ones.

        Returns:
            The new velocities and the joints acted on.
        """
        cfg = self.cfg
        minv = self.sys.minv(q) if cfg.reset_rule == "momentum" else None
        acted = np.array(sorted(set(rel.tolist())), dtype=np.intp)
        clamps = [cl for a in self.active.values() for cl in a.clamps]
        for _ in range(self.n + 1):
            v_new = impact_reset(v, acted, cfg.restitution, cfg.reset_rule, minv)
            tiny = 1e-12 * (1.0 + float(np.abs(v).max()))
            more = {j for j, s in clamps if s * v_new[j] > tiny and j not in set(acted.tolist())}
            if not more:
                return v_new, acted
            acted = np.array(sorted(set(acted.tolist()) | more), dtype=np.intp)
        return v_new, acted

    def limit(self, t: float, q: FloatArray, v: FloatArray, j: int, side: int) -> FloatArray:
        self.active[("limit", j, side)] = _Active(None, [(j, side)])
        v_new, acted = v, np.array([j])
        if side * v[j] > 0.0:
            v_new, acted = self.reset(q, v, np.array([j]))
        lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
        ev_before, ev_after = self.energy(q, v), self.energy(q, v_new)
        self.events.append(
            Event(
                t,
                "limit",
                self.sys.names[j],
                "upper" if side > 0 else "lower",
                "",
                "",
                float(side * (lim - q[j])),
                tuple(self.sys.names[i] for i in acted),
                self.sys.v_full(v),
                self.sys.v_full(v_new),
                ev_before,
                ev_after,
            )
        )
        return v_new

    def release_limits(self, y: FloatArray) -> None:
        """Limit stops let go when the joint has left the stop (moving away)."""
        n = self.n
        for key in [k for k in self.active if k[0] == "limit"]:
            _, j, side = key
            lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
            if side * (lim - y[j]) > 1e-6 and j not in self.locks.engaged:
                self.active.pop(key)
                energy = self.energy(y[:n], y[n:])
                self.events.append(
                    Event(
                        self.t,
                        "release",
                        self.sys.names[j],
                        "upper" if side > 0 else "lower",
                        distance=float(side * (lim - y[j])),
                        relevant_joints=(self.sys.names[j],),
                        v_before=self.sys.v_full(y[n:]),
                        v_after=self.sys.v_full(y[n:]),
                        energy_before=energy,
                        energy_after=energy,
                    )
                )
                self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)

    def note_min(self, d: float, pair: int) -> None:
        """Track the smallest signed distance of the states the run keeps."""
        if pair >= 0 and d < self.diag.min_distance:
            assert self.sys.world is not None
            p = self.sys.world.pairs[pair]
            self.diag.min_distance = d
            self.diag.min_distance_pair = f"{p.piece1} - {p.piece2}"

    def energy(self, q: FloatArray, v: FloatArray) -> float:
        return self.sys.energy(q, v)

    def log_event(
        self,
        t: float,
        kind: str,
        q: FloatArray,
        v0: FloatArray,
        v1: FloatArray,
        pair: PairInfo | None,
        d: float = math.nan,
        joints: tuple[str, ...] = (),
    ) -> None:
        e0 = self.energy(q, v0)
        e1 = e0 if v1 is v0 else self.energy(q, v1)
        self.events.append(
            Event(
                t,
                kind,
                pair.link1 if pair else "",
                pair.link2 if pair else "",
                pair.piece1 if pair else "",
                pair.piece2 if pair else "",
                d,
                joints,
                self.sys.v_full(v0),
                self.sys.v_full(v1),
                e0,
                e1,
            )
        )
        if len(self.events) > self.cfg.max_events:
            raise SimulationError(
                f"more than max_events={self.cfg.max_events} events (a Zeno sequence or "
                "chattering contact?)",
                t,
            )

    # ------------------------------------------------------------------ loop
    def start(self) -> None:
        """Initial contacts (pairs within the contact tolerance) and limits at t = 0."""
        world, cfg, n = self.sys.world, self.cfg, self.n
        crossings: list[_Crossing] = []
        if world is not None:
            sw = world.sweep(self.y[:n])
            self.diag.sweeps += 1
            self.note_min(sw.min_distance, sw.min_pair)
            bad = [
                (world.pairs[p], d) for p, d in zip(sw.pairs, sw.distances, strict=True) if d < 0
            ]
            if bad:
                raise InitialCollisionError([(p.piece1, p.piece2, d) for p, d in bad])
            self.last_d = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
            for p, d in self.last_d.items():
                if d <= cfg.contact_tolerance:
                    crossings.append(_Crossing("impact", ("pair", p), lambda t: 0.0, 0.0, 0.0))
        if cfg.joint_limits:
            for j in range(n):
                for side, lim in ((1, self.sys.upper[j]), (-1, self.sys.lower[j])):
                    if side * (lim - self.y[j]) <= 0.0:
                        crossings.append(
                            _Crossing("limit", ("limit", j, side), lambda t: 0.0, 0.0, 0.0)
                        )
        if crossings:
            self.y = self.handle(0.0, self.y, crossings)
        self.record_point(0.0, self.y)
        self.next_sample = 1
        self.stepper.reset(0.0, self.y)

    def step_limit(self) -> float:
        """Largest step keeping every point's motion within half the query margin [s]."""
        if self.sys.world is None:
            return self.cfg.max_step
        speed = REACH_BOUND * float(np.abs(self.y[self.n :]).sum())
        return min(self.cfg.max_step, 0.5 * self.cfg.margin / max(speed, 1e-9))

    def run(self) -> None:
        self.start()
        while self.t < self.duration - 1e-12:
            self.stepper.h_max = self.step_limit()
            seg = self.stepper.step(self.duration)
            y1 = seg.y1
            crossings = self.crossings(seg, y1)
            if not crossings:
                self.record(seg, seg.t1)
                self.t, self.y = seg.t1, y1
                if self.sys.world is not None:
                    self.last_d = self.pending_d
                    self.note_min(*self.pending_min)
                self.release_limits(self.y)
                continue
            t_star, at = self.locate(seg, crossings)
            y_star = seg(t_star)
            self.record(seg, t_star)
            self.record_point(t_star, y_star)
            y_new = self.handle(t_star, y_star, at)
            self.record_point(t_star, y_new)
            self.t, self.y = t_star, y_new
            if self.sys.world is not None:
                sw = self.sys.world.sweep(y_new[: self.n])
                self.diag.sweeps += 1
                self.last_d = dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
                self.note_min(sw.min_distance, sw.min_pair)
            self.diag.restarts += 1
            self.stepper.reset(t_star, y_new, h=max(self.stepper.h, 1e-6))

    def result(self) -> SimResult:
        n = self.n
        t = np.array(self.samples_t)
        Y = np.array(self.samples_y).reshape(len(t), 2 * n)
        q = np.array([self.sys.q_full(y[:n]) for y in Y])
        v = np.array([self.sys.v_full(y[n:]) for y in Y])
        nv = self.sys.full.nq
        tau = np.zeros((len(t), nv))
        energy = np.zeros(len(t))
        for k in range(len(t)):
            qk, vk = Y[k, :n], Y[k, n:]
            tau[k, self.sys.free] = self.torque(float(t[k]), qk, vk)
            energy[k] = self.energy(qk, vk)
        self.diag.steps = self.stepper.n_steps
        self.diag.rejected_steps = self.stepper.n_rejected
        self.diag.rhs_calls = self.stepper.n_rhs
        return SimResult(
            t=t,
            q=q,
            v=v,
            tau=tau,
            energy=energy,
            events=self.events,
            rest_time=rest_time(t, v, self.cfg.rest_speed),
            joint_names=self.sys.full.joint_names,
            config=self.cfg,
            diagnostics=self.diag,
        )


def _check_inputs(
    robot: Robot, q0: Any, v0: Any, duration: Any, config: SimConfig
) -> tuple[FloatArray, FloatArray]:
    config.validate()
    nq = robot.nq
    q = np.asarray(q0, dtype=float)
    v = np.asarray(v0, dtype=float)
    if q.shape != (nq,):
        raise ConfigurationError("q0", q.shape, f"an array of shape ({nq},) [rad]")
    if v.shape != (nq,):
        raise ConfigurationError("v0", v.shape, f"an array of shape ({nq},) [rad/s]")
    for name, arr in (("q0", q), ("v0", v)):
        if not np.all(np.isfinite(arr)):
            raise ConfigurationError(name, arr.tolist(), "finite values")
    if not isinstance(duration, (int, float)) or not math.isfinite(duration) or duration <= 0:
        raise ConfigurationError("duration", duration, "a finite positive time [s]")
    robot.check_within_limits(q, "q0")
    for name in config.locked_joints:
        robot.params.index(name)  # raises UnknownNameError listing the joints
    locked = [robot.params.index(nm) for nm in config.locked_joints]
    if np.any(v[locked] != 0.0):
        raise ConfigurationError("v0", v.tolist(), "zero velocity on the locked joints")
    return q, v


def simulate(
    robot: Robot,
    q0: Any,
    v0: Any,
    duration: float,
    *,
    controller: Controller | None = None,
    environment: Environment | None = None,
    config: SimConfig | None = None,
) -> SimResult:
    """Simulate the arm from (q0, v0) for ``duration`` seconds with exact contact events.

    Args:
        robot: The robot (:func:`packbot.load_robot`).
        q0: Initial joint positions [rad], shape (nq,), within the limits, collision free.
        v0: Initial joint velocities [rad/s], shape (nq,).
        duration: Simulated time [s].
        controller: Torque function ``tau(t, q, v)`` [N*m] (or an object with that call), in
            full coordinates; None means zero torque (a total collapse).
        environment: Static obstacles; None means the floor alone.
        config: Settings; None means ``SimConfig()``.

    Returns:
        The sampled trajectory, the event log and diagnostics.

    Raises:
        ConfigurationError: Bad input (names the field and what is expected).
        InitialCollisionError: The initial state penetrates (names the pairs and depths).
        ControllerError: The controller raised or returned bad torques (says when, and which
            joint).
        SimulationError: The run could not continue (e.g. step size underflow); its ``result``
            holds the trajectory up to then.
    """
    cfg = SimConfig() if config is None else config
    q, v = _check_inputs(robot, q0, v0, duration, cfg)
    wall = time.perf_counter()
    run = _Run(robot, q, v, float(duration), controller, environment, cfg)
    try:
        run.run()
    except StepSizeUnderflow as exc:
        run.diag.wall_time = time.perf_counter() - wall
        raise SimulationError(str(exc), exc.t, run.result()) from exc
    except SimulationError as exc:
        run.diag.wall_time = time.perf_counter() - wall
        if exc.result is None:
            exc.result = run.result() if run.samples_t else None
        raise
    run.diag.wall_time = time.perf_counter() - wall
    return run.result()
