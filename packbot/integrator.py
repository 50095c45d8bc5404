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
  with the current geometry); with ``SimConfig.handoff`` the pair is instead handed to the
  contact-normal machinery (a ``handoff`` event; :mod:`packbot.contact.handoff`);
- ``engage`` / ``disengage``: a clamped joint's sign condition changes (it starts to accelerate
  toward its contact, or its lock torque would pull); see :mod:`packbot.contact.locks`;
- ``slip`` / ``stick``: a joint held by static friction or a brake needs more than its holding
  torque (it slips), or a sliding joint's speed crosses zero (it sticks if the holding torque is
  within the bound); see :mod:`packbot.actuators`.

Scheduled events cut the steps at their times: failure injections (``failure``, and ``freeze``
for the impulse that stops a freezing joint), payload ``pick`` / ``drop``, and the ticks of a
sampled-data :class:`~packbot.control.Controller` (not logged). A frozen joint or a payload change
starts a new *phase*: the integrated model is rebuilt (``pin.buildReducedModel``, the payload's
inertia added) and the contacts are found again; the result stays in full coordinates.

Inside a step the set of engaged locks is fixed, so the right-hand side is smooth and the steps
stay long. A step never moves any point of the arm by more than half the query margin (a bound
from the joint speeds), so a pair cannot pass from outside the margin through contact within a
step unseen.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.actuators import TorquePath
from packbot.collision import PairInfo
from packbot.config import SimConfig
from packbot.contact import JointLocks, clamp_directions, impact_reset, relevant_joints
from packbot.contact.handoff import HandoffContacts
from packbot.contact.locks import TORQUE_BAND
from packbot.contact.normal import PENETRATION_TOL, NormalContacts
from packbot.control.base import Controller
from packbot.environment import Environment
from packbot.errors import (
    ConfigurationError,
    ControllerError,
    InitialCollisionError,
    PackbotError,
    SimulationError,
    UnknownNameError,
)
from packbot.failures import Failure, validate_failures
from packbot.model import Robot
from packbot.ode import DenseSegment, RK45Stepper, StepSizeUnderflow, locate_root
from packbot.payload import Payload
from packbot.result import Diagnostics, Event, SimResult, rest_time
from packbot.system import System
from packbot.validation import (
    CONTROL_DT_MIN,
    MAX_SAMPLES,
    MAX_STEPS,
    V0_MAX,
    boolean,
    finite_number,
    joint_names,
    real_array,
)

__all__ = ["EVENT_XTOL", "TorqueFunction", "check_arguments", "check_initial_state", "simulate"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
#: A continuous-time controller: joint torques [N*m] (shape (nv,), full coordinates) from
#: t [s], q [rad], v [rad/s]; a smooth, stateless function.
TorqueFunction = Callable[[float, FloatArray, FloatArray], Any]
#: Joint speed below which a joint with Coulomb friction counts as stopped (it may stick) [rad/s].
STICK_SPEED = 1e-9

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
    """One simulation run: the state of the event loop.

    The state vector is y = (q, v) of the integrated joints, followed by the motor torques
    tau_m when ``config.motor_lag > 0``.
    """

    def __init__(
        self,
        robot: Robot,
        q0: FloatArray,
        v0: FloatArray,
        duration: float,
        controller: Controller | TorqueFunction | None,
        environment: Environment | None,
        config: SimConfig,
        failures: Sequence[Failure] = (),
        payload: Payload | None = None,
        inform_controller: bool = False,
        progress: Callable[[float], None] | None = None,
    ) -> None:
        self.cfg = config
        self.duration = duration
        self.robot = robot
        self.environment = environment
        self.ctrl_obj = controller if isinstance(controller, Controller) else None
        self.ctrl_fn = None if isinstance(controller, Controller) else controller
        self.inform = inform_controller
        self.progress = progress
        self.payload = payload
        self.payload_on = False
        self.failures_in: list[Failure] = []
        self.frozen: list[str] = []
        self.lag = config.motor_lag > 0.0
        nv_full = robot.nq
        self.tau_hold_full = np.zeros(nv_full)  # the held command of a sampled-data controller
        # Scheduled actions, (time, order, what): failures first, then the payload, then ticks.
        self.schedule: list[tuple[float, int, Any]] = [(f.t, 0, f) for f in failures]
        if payload is not None:
            self.schedule.append((payload.t_pick, 1, "pick"))
            if payload.t_drop is not None:
                self.schedule.append((payload.t_drop, 1, "drop"))
        self.schedule.sort(key=lambda x: (x[0], x[1]))
        self.next_tick = 0.0 if self.ctrl_obj is not None else math.inf
        self.ticks = 0
        self.events: list[Event] = []
        self.diag = Diagnostics()
        self.samples: list[tuple[Any, ...]] = []  # (q, v, tau_cmd, tau, tau_friction, effort, E)
        self.samples_t: list[float] = []
        self.next_sample = 0
        self.stepper = RK45Stepper(
            self.rhs, rtol=config.rtol, atol=config.atol, h_max=config.max_step
        )
        self.t = 0.0
        tau_m0 = np.zeros(nv_full)
        self.build_phase(np.asarray(q0, dtype=float), np.asarray(v0, dtype=float), tau_m0)

    # ------------------------------------------------------------------ phases
    def build_phase(self, qf: FloatArray, vf: FloatArray, tau_mf: FloatArray) -> None:
        """(Re)build the integrated system from a full-coordinate state; contacts are cleared."""
        cfg = self.cfg
        locked = tuple(cfg.locked_joints) + tuple(self.frozen)
        payload = self.payload if self.payload_on else None
        self.sys = System(self.robot, qf, cfg, self.environment, locked=locked, payload=payload)
        self.n = self.sys.nv
        self.path = TorquePath.build(self.robot.params, self.sys.free, cfg, self.failures_in)
        self.locks = JointLocks()
        self.active: dict[tuple[Any, ...], _Active] = {}
        self.fdir = np.zeros(self.n)  # sliding direction of each joint with Coulomb friction
        self.tau_zero = np.zeros(self.n)
        self.zero_full = np.zeros(self.robot.nq)
        self.tau_hold = self.sys.reduce(self.tau_hold_full)
        parts = [self.sys.reduce(qf), self.sys.reduce(vf)]
        if self.lag:
            parts.append(self.sys.reduce(tau_mf))
        self.y = np.concatenate(parts)
        self.last_d: dict[int, float] = {}  # pair -> distance at the last kept state [m]
        self.pending_d: dict[int, float] = {}  # the same at the end of the step being checked
        self.pending_min: tuple[float, int] = (math.inf, -1)
        self.normal: NormalContacts | None = None
        if cfg.contact_mode == "normal":
            self.normal = NormalContacts.from_config(
                self.sys.model, self.sys.data, self.sys.world, cfg
            )
        # Hand-off (joint_clamp mode): pairs handed to the normal machinery, the clamps as rows.
        self.mixed: HandoffContacts | None = None
        if cfg.handoff and self.sys.world is not None:
            self.mixed = HandoffContacts.from_config(
                self.sys.model,
                self.sys.data,
                self.sys.world,
                cfg,
                check_others=False,  # its other pairs are the joint_clamp mode's
            )

    @property
    def mixed_on(self) -> bool:
        """Whether a handed-off pair is in contact (the clamps are then rows of its problem)."""
        return self.mixed is not None and bool(self.mixed.pairs)

    def full_state(self, y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q, v, tau_m) in full coordinates from an integrated state."""
        n = self.n
        qf, vf = self.sys.q_full(y[:n]), self.sys.v_full(y[n : 2 * n])
        tau_m = np.zeros(self.robot.nq)
        if self.lag:
            tau_m[self.sys.free] = y[2 * n :]
        return qf, vf, tau_m

    # ------------------------------------------------------------------ dynamics
    def command(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Commanded torque on the integrated joints [N*m]."""
        if self.ctrl_fn is not None:
            qf, vf = self.sys.q_full(q), self.sys.v_full(v)
            try:
                raw = self.ctrl_fn(t, qf, vf)
            except Exception as exc:
                raise ControllerError(f"raised {type(exc).__name__}: {exc}", t) from exc
            return self.check_torque(raw, t)[self.sys.free]
        if self.ctrl_obj is not None:
            return self.tau_hold
        return self.tau_zero

    def check_torque(self, raw: Any, t: float) -> FloatArray:
        """The controller's torque [N*m] as a float array of shape (nq,), or ControllerError."""
        nq = self.robot.nq
        try:
            tau = np.asarray(raw)
        except Exception as exc:  # a ragged list, an object numpy cannot take
            raise ControllerError(f"returned {type(raw).__name__}, not {nq} torques", t) from exc
        if tau.dtype.kind not in "iuf":  # complex, bool, strings, objects
            raise ControllerError(
                f"returned {tau.dtype} values, not real torques (shape ({nq},), float)", t
            )
        tau = tau.astype(float)
        if tau.shape != (nq,):
            raise ControllerError(f"returned shape {tau.shape}, expected ({nq},)", t)
        if not np.all(np.isfinite(tau)):
            bad = self.robot.joint_names[int(np.flatnonzero(~np.isfinite(tau))[0])]
            raise ControllerError(f"returned a non-finite torque for joint {bad!r}", t, bad)
        return tau

    def torques(
        self, t: float, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(command, motor target, applied motor torque, friction) [N*m] at (t, y)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        cmd = self.command(t, q, v)
        path = self.path
        if cmd is self.tau_zero and not self.lag and path.passive:  # the collapse: fast path
            return cmd, cmd, cmd, path.friction(v, self.fdir) if path.rubs else cmd
        target = self.path.target(cmd)
        tau_m = y[2 * n :] if self.lag else target
        return cmd, target, self.path.applied(tau_m), self.path.friction(v, self.fdir)

    def free_accel(self, t: float, y: FloatArray) -> FloatArray:
        n = self.n
        _, _, applied, friction = self.torques(t, y)
        return self.sys.aba(y[:n], y[n : 2 * n], applied + friction)

    def rhs(self, t: float, y: FloatArray) -> FloatArray:
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        _, target, applied, friction = self.torques(t, y)
        a = self.sys.aba(q, v, applied + friction)
        if self.locks.any_locked:
            a = self.locks.accelerations(a, self.sys.minv(q))
        if self.normal is not None and self.normal.engaged:
            a = self.normal.evaluate(q, v, a, self.sys.minv(q)).a
        if self.mixed is not None and self.mixed.constrained:
            a = self.mixed.evaluate(q, v, a, self.sys.minv(q)).a
        if self.lag:
            return np.concatenate([v, a, (target - y[2 * n :]) / self.cfg.motor_lag])
        return np.concatenate([v, a])

    def lock_conditions(self, t: float, y: FloatArray) -> dict[tuple[str, int], float]:
        a = self.free_accel(t, y)
        minv = self.sys.minv(y[: self.n]) if self.locks.any_locked else None
        return self.locks.conditions(a, minv)

    # ------------------------------------------------------------------ recording
    def record(self, seg: DenseSegment, t_end: float) -> None:
        dt = self.cfg.sample_dt
        while True:
            ts = self.next_sample * dt
            if ts > t_end + 1e-12 or ts > self.duration + 1e-12:
                break
            self.record_point(ts, seg(min(max(ts, seg.t0), seg.t1)))
            self.next_sample += 1

    def record_due(self, t: float, y: FloatArray) -> None:
        """Keep the regular samples due at t (within 1e-12 s) from the state y at t."""
        dt = self.cfg.sample_dt
        while self.next_sample * dt <= min(t, self.duration) + 1e-12:
            self.record_point(self.next_sample * dt, y)
            self.next_sample += 1

    def record_final(self) -> None:
        """Keep the final state as a sample if the last one is earlier (within 1e-12 s).

        The regular samples fall on multiples of ``sample_dt``; when it does not divide the
        duration (or exceeds it) the last of them is before the end, and the final state is
        kept here, at t = duration (the last interval is then shorter). A run whose duration
        is a multiple of ``sample_dt`` already ends on a sample and is unchanged.
        """
        if not self.samples_t or self.samples_t[-1] < self.duration - 1e-12:
            self.record_point(self.duration, self.y)

    def record_point(self, t: float, y: FloatArray) -> None:
        """Keep a sample: full q, v, the torques and the energy at (t, y)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        cmd, _, applied, friction = self.torques(t, y)
        if self.locks.held:
            friction = friction.copy()
            a_free = self.sys.aba(q, v, applied + friction)
            _, lam = self.locks.torques(a_free, self.sys.minv(q))
            for j in self.locks.held:
                friction[j] = lam[j]
        qf, vf, _ = self.full_state(y)
        zero = self.zero_full  # shared by the samples of a torque-free run (never written)
        free = self.sys.free
        if cmd is self.tau_zero and applied is cmd and friction is cmd:
            cmd_f = app_f = fr_f = zero
        else:
            cmd_f, app_f, fr_f = zero.copy(), zero.copy(), zero.copy()
            cmd_f[free], app_f[free], fr_f[free] = cmd, applied, friction
        if self.ctrl_obj is not None:
            cmd_f = self.tau_hold_full.copy()
        eff = self.robot.params.effort.copy()
        eff[free] = self.path.effort
        self.samples_t.append(t)
        self.samples.append((qf, vf, cmd_f, app_f, fr_f, eff, self.energy(q, v)))

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
                handed = self.mixed is not None and p_idx in self.mixed.pairs
                if self.normal is not None or handed:  # handed: a handed-off pair
                    out.extend(self._normal_pair_crossing(key, p_idx, seg, d0, d1))
                elif key in self.active:
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
        if self.normal is not None and not self.normal.empty:
            out.extend(self._mode_crossings(self.normal, seg, y1))
        if self.mixed_on:
            assert self.mixed is not None
            out.extend(self._mode_crossings(self.mixed, seg, y1))
        if self.locks.held or any(len(s) == 1 for s in self.locks.signs.values()):
            cond1 = self.lock_conditions(seg.t1, y1)
            bad = [k for k, g in cond1.items() if g < 0.0]
            if bad:
                cond0 = self.lock_conditions(seg.t0, seg.y0)
                for k in bad:

                    def gl(t: float, k: tuple[str, int] = k) -> float:
                        return self.lock_conditions(t, seg(t))[k]

                    kind, j = k
                    if kind == "hold":
                        kind = "slip"
                    else:
                        kind = "disengage" if j in self.locks.engaged else "engage"
                    out.append(_Crossing(kind, ("lock", j), gl, cond0.get(k, 1.0), cond1[k]))
        sliding = np.flatnonzero(self.fdir * y1[n : 2 * n] < -STICK_SPEED)
        for j in sliding.tolist():

            def gs(t: float, j: int = j) -> float:
                return float(self.fdir[j] * seg(t)[n + j])

            g0 = float(self.fdir[j] * seg.y0[n + j])
            out.append(_Crossing("stick", ("stick", j), gs, g0, float(self.fdir[j] * y1[n + j])))
        return out

    def _normal_pair_crossing(
        self, key: tuple[Any, ...], p_idx: int, seg: DenseSegment, d0: float, d1: float
    ) -> list[_Crossing]:
        """Pair events of the normal mode: touch at d = 0, re-patch, leave the contact set."""
        cfg = self.cfg
        if key not in self.active:
            if d1 <= 0.0:
                return [self._pair_crossing("impact", key, p_idx, seg, d0, d1, lambda d: d)]
            return []
        if d1 > cfg.proximity_tolerance:
            return [
                self._pair_crossing(
                    "release", key, p_idx, seg, d0, d1, lambda d: cfg.proximity_tolerance - d
                )
            ]
        if d1 < -PENETRATION_TOL:
            return [
                self._pair_crossing(
                    "repatch", key, p_idx, seg, d0, d1, lambda d: d + PENETRATION_TOL
                )
            ]
        return []

    def _contact_conditions(
        self, contacts: NormalContacts, t: float, y: FloatArray
    ) -> dict[tuple[Any, ...], tuple[str, float]]:
        """Mode conditions of a contact problem (normal mode or hand-off) at state y."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        ev = contacts.evaluate(q, v, self.free_accel(t, y), self.sys.minv(q))
        return contacts.conditions(ev)

    def _mode_crossings(
        self, contacts: NormalContacts, seg: DenseSegment, y1: FloatArray
    ) -> list[_Crossing]:
        """Mode conditions of a contact problem that changed sign over the step."""
        cond1 = self._contact_conditions(contacts, seg.t1, y1)
        bad = [k for k, (_, g) in cond1.items() if g < 0.0]
        if not bad:
            return []
        cond0 = self._contact_conditions(contacts, seg.t0, seg.y0)
        out = []
        for k in bad:

            def gn(t: float, k: tuple[Any, ...] = k) -> float:
                return self._contact_conditions(contacts, t, seg(t))[k][1]

            g0 = cond0[k][1] if k in cond0 else 1.0
            out.append(_Crossing(cond1[k][0], ("mode", *k), gn, g0, cond1[k][1]))
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
        if self.normal is not None:
            return self.handle_normal(t, y, crossings)
        if self.mixed is not None and (
            self.mixed_on or any(c.kind == "secondary_intersection" for c in crossings)
        ):
            return self.handle_mixed(t, y, crossings)
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        flip: int | None = None
        stick: list[int] = []
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
            elif c.kind == "slip":
                j = c.key[1]
                lam = self.hold_torque(t, self.with_v(y, v), j)
                self.locks.set_held({k: b for k, b in self.locks.held.items() if k != j})
                self.fdir[j] = -math.copysign(1.0, lam)
                self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
            elif c.kind == "stick":
                j = c.key[1]
                v[j] = 0.0
                self.fdir[j] = 0.0
                stick.append(j)
            else:  # engage / disengage
                flip = c.key[1]
                self.log_event(t, c.kind, q, v, v, None, joints=(self.sys.names[flip],), joint=flip)
        y_new = self.with_v(y, v)
        self.settle_modes(t, y_new, flip=flip, candidates=stick, log_stick=True)
        return y_new

    def handle_normal(self, t: float, y: FloatArray, crossings: list[_Crossing]) -> FloatArray:
        """Events of the normal mode: update the contact set, then impulse and modes."""
        normal, world = self.normal, self.sys.world
        assert normal is not None
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        tail = y[2 * n :]
        logged: list[tuple[str, PairInfo | None, float, tuple[str, ...]]] = []
        for c in sorted(crossings, key=lambda c: c.key[0] != "mode"):
            key = c.key
            if key[0] == "pair":
                assert world is not None
                p_idx = key[1]
                info = world.pairs[p_idx]
                d = self.distance(p_idx, y)
                if c.kind == "release":  # left the contact set (all its rows were free)
                    self.active.pop(key, None)
                    normal.remove_pair(p_idx)
                    log.debug("t=%.6f: pair %s left the contact set", t, info.piece1)
                    continue
                if normal.add_pair(q, p_idx):
                    self.active[key] = _Active(info, [])
                logged.append((c.kind, info, d, ()))
            elif key[0] == "limit":
                _, j, side = key
                lim = self.sys.upper[j] if side > 0 else self.sys.lower[j]
                normal.add_limit(j, side, lim)
                self.active[key] = _Active(None, [])
                logged.append(("limit", None, float(side * (lim - q[j])), (self.sys.names[j],)))
            else:  # ("mode", "nrow"/"nfric"/"nrest", index)
                if key[1] == "nrest":  # the resting arm starts moving again
                    logged.append((c.kind, None, math.nan, ()))
                elif key[1] == "nrow":
                    owner, lim_key = normal.row_owner(key[2])
                    joints: tuple[str, ...] = ()
                    if lim_key is not None:
                        joints = (self.sys.names[lim_key[0]],)
                    logged.append((c.kind, owner, math.nan, joints))
                else:
                    logged.append((c.kind, normal.pairs[key[2]].info, math.nan, ()))

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        q, v_new, mode_events = normal.restart(q, v, a_free, self.sys.minv(q))
        self._sync_normal_pairs()
        for kind, info, d, joints in logged:
            self.log_event(t, kind, q, v, v_new, info, d=d, joints=joints)
        for me in mode_events:
            if any(me.kind == k and me.pair == i for k, i, _, _ in logged):
                continue
            self.log_event(t, me.kind, q, v_new, v_new, me.pair)
        return np.concatenate([q, v_new, tail])

    def _sync_normal_pairs(self) -> None:
        """Pairs that the drift projection put in the contact set become active pairs.

        :meth:`NormalContacts.project` adds a pair it made penetrate (as an impact would):
        its events are then those of a pair in contact (re-patch, release).
        """
        assert self.normal is not None
        for k, p in self.normal.pairs.items():
            self.active.setdefault(("pair", k), _Active(p.info, []))

    # ------------------------------------------------------------------ hand-off (mixed)
    def apply_clamps(self) -> None:
        """Give the clamps of the active contacts to the hand-off rows or to the joint locks."""
        clamps = [cl for a in self.active.values() for cl in a.clamps]
        if self.mixed_on:
            assert self.mixed is not None
            self.mixed.set_clamps(clamps)
            self.locks.set_clamps(())
        else:
            if self.mixed is not None:
                self.mixed.set_clamps(())
            self.locks.set_clamps(clamps)

    def settle_mixed(self, t: float, y: FloatArray) -> None:
        """Hand-off: the modes of the mixed problem at (t, y) (no impulse: v is kept)."""
        mixed = self.mixed
        assert mixed is not None
        n, tail = self.n, y[2 * self.n :]
        q, v = y[:n], y[n : 2 * n]
        self.apply_clamps()
        mixed.refresh(q)
        mixed.select_modes(q, v, self.free_accel(t, y), self.sys.minv(q))
        if not mixed.pairs:  # the refresh dropped the last pair: the locks take the clamps
            self.apply_clamps()
            self.settle_modes(t, np.concatenate([q, v, tail]))

    def mixed_sliding(self, y: FloatArray) -> bool:
        """Whether a handed-off pair slides (its patch must follow)."""
        assert self.mixed is not None
        return self.mixed.sliding(y[: self.n], y[self.n : 2 * self.n])

    def refresh_mixed(self) -> None:
        """Hand-off: re-patch sliding handed-off pairs after an accepted step (not logged)."""
        mixed = self.mixed
        assert mixed is not None
        n, t = self.n, self.t
        q, v, tail = self.y[:n], self.y[n : 2 * n], self.y[2 * n :]

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        q = mixed.repatch(q, v, a_free, self.sys.minv(q))
        self.y = np.concatenate([q, v, tail])
        self.diag.restarts += 1
        self.stepper.reset(t, self.y, h=max(self.stepper.h, 1e-6))

    def handle_mixed(self, t: float, y: FloatArray, crossings: list[_Crossing]) -> FloatArray:
        """Events with ``handoff``: a secondary intersection hands its pair over.

        The handed-off pairs follow the normal mode (re-patch, leave the set beyond the
        proximity tolerance, row and friction mode changes); the other pairs and the limit
        stops follow the report's law (impact, limit, release: their clamps). Then, while a
        handed-off pair is in contact, one restart of the mixed problem (drift correction,
        impulse, modes) with the clamps as rows; otherwise the joint locks take the clamps.
        """
        mixed, world = self.mixed, self.sys.world
        assert mixed is not None and world is not None
        n = self.n
        q, v = y[:n], y[n : 2 * n].copy()
        tail = y[2 * n :]
        handed: list[tuple[PairInfo, float]] = []
        logged: list[tuple[str, PairInfo | None, float, tuple[str, ...], int | None]] = []
        order = {"release": 0, "secondary_intersection": 1}
        for c in sorted(crossings, key=lambda c: order.get(c.kind, 2)):
            key = c.key
            if key[0] == "pair":
                p_idx = key[1]
                info = world.pairs[p_idx]
                d = self.distance(p_idx, y)
                if p_idx in mixed.pairs:  # a handed-off pair
                    if c.kind == "release":
                        self.active.pop(key, None)
                        mixed.remove_pair(p_idx)
                        logged.append(("release", info, d, (), None))
                    else:  # repatch
                        mixed.add_pair(q, p_idx)
                        logged.append((c.kind, info, d, (), None))
                elif c.kind == "release":
                    act = self.active.pop(key, None)
                    if act is not None:
                        self.log_event(t, "release", q, v, v, info, d=d)
                elif c.kind == "secondary_intersection" and mixed.add_pair(q, p_idx):
                    self.active[key] = _Active(info, [])  # its clamps are released
                    handed.append((info, d))
                else:  # an impact (or a secondary intersection without a patch): the law
                    v = self.impact(t, q, v, p_idx, c.kind)
            elif key[0] == "limit":
                v = self.limit(t, q, v, key[1], key[2])
            elif key[0] == "mode":
                if key[1] == "nrow" and (cl := mixed.clamp_of_row(key[2])) is not None:
                    j = cl[0]
                    logged.append((c.kind, None, math.nan, (self.sys.names[j],), j))
                elif key[1] == "nrow":
                    owner, _ = mixed.row_owner(key[2])
                    logged.append((c.kind, owner, math.nan, (), None))
                elif key[1] == "nfric":
                    logged.append((c.kind, mixed.pairs[key[2]].info, math.nan, (), None))
                else:  # nrest: the resting arm starts moving again
                    logged.append((c.kind, None, math.nan, (), None))
            else:  # a lock's engage/disengage at the instant of a hand-off: re-solved below
                j = key[1]
                logged.append((c.kind, None, math.nan, (self.sys.names[j],), j))
        self.apply_clamps()
        if not self.mixed_on:  # the last handed-off pair left: the report's law alone
            for kind, info, d, joints, jnt in logged:
                self.log_event(t, kind, q, v, v, info, d=d, joints=joints, joint=jnt)
            y_new = self.with_v(y, v)
            self.settle_modes(t, y_new)
            return y_new

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        q, v_new, mode_events = mixed.restart(q, v, a_free, self.sys.minv(q))
        for info, d in handed:
            joints = tuple(self.sys.names[i] for i in np.flatnonzero(v_new != v))
            self.log_event(t, "handoff", q, v, v_new, info, d=d, joints=joints)
        for kind, info, d, joints, jnt in logged:
            self.log_event(t, kind, q, v, v_new, info, d=d, joints=joints, joint=jnt)
        for me in mode_events:
            if any(me.kind == k and me.pair == i for k, i, _, _, _ in logged):
                continue
            self.log_event(t, me.kind, q, v_new, v_new, me.pair)
        return np.concatenate([q, v_new, tail])

    def with_v(self, y: FloatArray, v: FloatArray) -> FloatArray:
        """The state y with its velocities replaced."""
        out = y.copy()
        out[self.n : 2 * self.n] = v
        return out

    def hold_torque(self, t: float, y: FloatArray, j: int) -> float:
        """The torque [N*m] joint j's lock needs at (t, y) with the current locked set (and j)."""
        n = self.n
        a_free = self.free_accel(t, y)
        held = dict(self.locks.held)
        if j not in held:
            self.locks.set_held({**held, j: 0.0})
        _, lam = self.locks.torques(a_free, self.sys.minv(y[:n]))
        self.locks.set_held(held)
        return lam[j]

    def settle_modes(
        self,
        t: float,
        y: FloatArray,
        *,
        flip: int | None = None,
        candidates: Sequence[int] = (),
        log_stick: bool = False,
    ) -> None:
        """Set the clamps, the engaged locks and the friction holds consistent at (t, y).

        Args:
            t: Time [s].
            y: State (its velocities already reset).
            flip: A clamped joint whose mode an event just changed (see JointLocks).
            candidates: Joints with Coulomb friction that just stopped: they stick if the
                holding torque is within their bound, else they slide on in the direction of
                the net torque.
            log_stick: Log a ``stick`` event for each candidate that sticks.
        """
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        if self.mixed_on:  # the clamps are rows of the hand-off problem
            self.settle_mixed(t, y)
            return
        self.locks.set_clamps(cl for a in self.active.values() for cl in a.clamps)
        bound = self.path.coulomb
        held = {j: b for j, b in self.locks.held.items() if bound[j] > 0}
        self.locks.set_held(held)
        for j in np.flatnonzero(bound > 0).tolist():  # directions of the sliding joints
            if j not in held and j not in candidates:
                if abs(v[j]) > STICK_SPEED:
                    self.fdir[j] = math.copysign(1.0, v[j])
                elif self.fdir[j] == 0.0:
                    candidates = [*candidates, j]
        if not (self.locks.signs or self.locks.held or candidates):
            return
        minv = self.sys.minv(q)
        if self.locks.signs:
            self.locks.solve_engaged(self.free_accel(t, y), minv, flip=flip)
        if candidates:
            for j in candidates:
                self.fdir[j] = 0.0
            trial = {**self.locks.held, **{j: float(bound[j]) for j in candidates}}
            self.locks.set_held(trial)
            _, lam = self.locks.torques(self.free_accel(t, y), minv)
            keep = dict(self.locks.held)
            for j in candidates:
                signs = self.locks.signs.get(j, set())
                # a contact clamp may supply the torque: both ways (bilateral), or pushing
                pushes = len(signs) == 2 or (len(signs) == 1 and -next(iter(signs)) * lam[j] >= 0)
                if abs(lam[j]) <= bound[j] + 0.5 * TORQUE_BAND or pushes:
                    if log_stick:
                        self.log_event(
                            t, "stick", q, v, v, None, joints=(self.sys.names[j],), joint=j
                        )
                else:
                    keep.pop(j)
                    self.fdir[j] = -math.copysign(1.0, lam[j])
                    self.log_event(t, "slip", q, v, v, None, joints=(self.sys.names[j],), joint=j)
            self.locks.set_held(keep)
            if self.locks.signs:
                self.locks.solve_engaged(self.free_accel(t, y), minv, flip=flip)

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
        self, q: FloatArray, v: FloatArray, rel: NDArray[np.intp], rule: str | None = None
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        """Apply the reset rule on ``rel``, widened where it would push a clamped joint.

        The widening takes in every clamped joint that the impulse would set moving toward its
        own contact: one simultaneous impact, not a cascade of secondary ones.

        Returns:
            The new velocities and the joints acted on.
        """
        cfg = self.cfg
        rule = cfg.reset_rule if rule is None else rule
        minv = self.sys.minv(q) if rule == "momentum" else None
        acted = np.array(sorted(set(rel.tolist())), dtype=np.intp)
        clamps = [cl for a in self.active.values() for cl in a.clamps]
        for _ in range(self.n + 1):
            v_new = impact_reset(v, acted, cfg.restitution, rule, minv)
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
            # A limit stop is a hard stop on this joint alone: a joint-space impulse on it (the
            # "momentum" law, never adding energy for e <= 1), whatever reset_rule says (the
            # report's "zero" rule is its law for link collisions; on a stop it can add energy).
            v_new, acted = self.reset(q, v, np.array([j]), rule="momentum")
            if side * v_new[j] < 0.0:  # it bounced (e > 0): it leaves the stop, nothing to clamp
                self.active.pop(("limit", j, side))
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
            # Left the stop (an engaged lock would keep a receding joint's speed: work done).
            held = self.normal is not None and self.normal.limit_engaged(j, side)
            if side * (lim - y[j]) > 1e-6 and not held:
                if self.normal is not None:
                    self.normal.remove_limit(j, side)
                self.active.pop(key)
                energy = self.energy(y[:n], y[n : 2 * n])
                self.events.append(
                    Event(
                        self.t,
                        "release",
                        self.sys.names[j],
                        "upper" if side > 0 else "lower",
                        distance=float(side * (lim - y[j])),
                        relevant_joints=(self.sys.names[j],),
                        v_before=self.sys.v_full(y[n : 2 * n]),
                        v_after=self.sys.v_full(y[n : 2 * n]),
                        energy_before=energy,
                        energy_after=energy,
                    )
                )
                self.apply_clamps()

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
        joint: int | None = None,
    ) -> None:
        e0 = self.energy(q, v0)
        e1 = e0 if v1 is v0 else self.energy(q, v1)
        self.events.append(
            Event(
                t,
                kind,
                pair.link1 if pair else (self.sys.names[joint] if joint is not None else ""),
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
    def initial_contacts(self, t: float, check: bool) -> None:
        """Contacts (pairs within the contact tolerance) and limit stops at (t, self.y).

        Args:
            t: Time [s].
            check: Raise :class:`InitialCollisionError` if a pair penetrates (run start).
        """
        world, cfg, n = self.sys.world, self.cfg, self.n
        crossings: list[_Crossing] = []
        if world is not None:
            sw = world.sweep(self.y[:n])
            self.diag.sweeps += 1
            self.note_min(sw.min_distance, sw.min_pair)
            bad = [
                (world.pairs[p], d) for p, d in zip(sw.pairs, sw.distances, strict=True) if d < 0
            ]
            if bad and check:
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
            self.y = self.handle(t, self.y, crossings)
        else:
            self.settle_modes(t, self.y)

    def start(self) -> None:
        """Contacts and limits at t = 0, then the actions scheduled at t = 0."""
        self.initial_contacts(0.0, check=True)
        if self.ctrl_obj is not None:
            qf, vf, _ = self.full_state(self.y)
            self.ctrl_obj.reset(self.robot, 0.0, qf.copy(), vf.copy())
        if self.next_scheduled() <= 0.0:
            self.run_scheduled(0.0, record=False)
        self.record_point(0.0, self.y)
        self.next_sample = 1
        self.stepper.reset(0.0, self.y)

    def next_scheduled(self) -> float:
        """Time of the next scheduled action (failure, payload, control tick) [s]."""
        t_next = self.schedule[0][0] if self.schedule else math.inf
        return min(t_next, self.next_tick)

    def run_scheduled(self, t: float, record: bool = True) -> None:
        """Apply every action scheduled at t (within 1e-12 s): failures, payload, a tick.

        Args:
            t: Time [s].
            record: Keep samples of the states before and after a failure or payload change.
        """
        changed = False
        while self.schedule and self.schedule[0][0] <= t + 1e-12:
            _, _, what = self.schedule.pop(0)
            if not changed and record:
                self.record_point(t, self.y)  # the state before, for the plots
            changed = True
            if isinstance(what, Failure):
                self.inject(t, what)
            else:
                self.payload_change(t, what)
        if self.next_tick <= t + 1e-12:
            assert self.ctrl_obj is not None
            qf, vf, _ = self.full_state(self.y)
            try:
                raw = self.ctrl_obj.step(t, qf.copy(), vf.copy())
            except ControllerError:
                raise
            except Exception as exc:
                raise ControllerError(f"raised {type(exc).__name__}: {exc}", t) from exc
            self.tau_hold_full = self.check_torque(raw, t).copy()
            self.tau_hold = self.sys.reduce(self.tau_hold_full)
            self.ticks += 1
            self.next_tick = self.ticks * self.ctrl_obj.dt
        if changed and record:
            self.record_point(t, self.y)

    def inject(self, t: float, failure: Failure) -> None:
        """A joint fails at t: log it; a frozen joint is stopped by an impulse and merged."""
        qf, vf, _ = self.full_state(self.y)
        self.failures_in.append(failure)
        if self.inform and self.ctrl_obj is not None:
            self.ctrl_obj.on_failure(failure, t)
        e = self.energy(self.y[: self.n], self.y[self.n : 2 * self.n])
        self.events.append(
            Event(
                t,
                "failure",
                failure.joint,
                failure.kind,
                v_before=vf,
                v_after=vf,
                energy_before=e,
                energy_after=e,
            )
        )
        if failure.kind != "frozen":
            self.path = TorquePath.build(
                self.robot.params, self.sys.free, self.cfg, self.failures_in
            )
            self.settle_modes(t, self.y)
            return
        # Freezing: the impulse that stops joint j, with the engaged and held locks kept still
        # (their velocities are zero and stay zero); the arm keeps its generalized momentum
        # (M dv = S^T p, p the joint impulses [N*m*s]).
        n = self.n
        j = int(np.flatnonzero(self.sys.free == self.robot.params.index(failure.joint))[0])
        q, v = self.y[:n], self.y[n : 2 * n].copy()
        idx = np.array(sorted({j, *self.locks.locked}), dtype=int)
        minv = self.sys.minv(q)
        p = np.linalg.solve(minv[np.ix_(idx, idx)], v[idx])
        v_new = v - minv[:, idx] @ p
        v_new[idx] = 0.0
        e1 = self.energy(q, v_new)
        self.events.append(
            Event(
                t,
                "freeze",
                failure.joint,
                "",
                distance=float(qf[self.sys.free[j]]),
                relevant_joints=tuple(self.sys.names[i] for i in idx),
                v_before=vf,
                v_after=self.sys.v_full(v_new),
                energy_before=e,
                energy_after=e1,
            )
        )
        self.frozen.append(failure.joint)
        self.rebuild(t, self.with_v(self.y, v_new))

    def payload_change(self, t: float, what: str) -> None:
        """Pick up (an inelastic impact: generalized momentum kept) or drop the payload."""
        n = self.n
        q, v = self.y[:n], self.y[n : 2 * n]
        e0 = self.energy(q, v)
        vf0 = self.sys.v_full(v)
        momentum = self.sys.mass_matrix(q) @ v
        self.payload_on = what == "pick"
        self.rebuild(t, self.y)
        q, v = self.y[:n], self.y[n : 2 * n]
        if what == "pick":
            v = np.asarray(np.linalg.solve(self.sys.mass_matrix(q), momentum), dtype=np.float64)
            self.y = self.with_v(self.y, v)
            self.settle_modes(t, self.y)
        self.events.append(
            Event(
                t,
                what,
                self.payload.frame if self.payload else "",
                "",
                v_before=vf0,
                v_after=self.sys.v_full(v),
                energy_before=e0,
                energy_after=self.energy(q, v),
            )
        )

    def rebuild(self, t: float, y: FloatArray) -> None:
        """A new phase from state y at t: model rebuilt, contacts found again."""
        qf, vf, tau_mf = self.full_state(y)
        self.build_phase(qf, vf, tau_mf)
        self.initial_contacts(t, check=False)

    def refresh_sliding(self) -> None:
        """Normal mode: re-patch sliding contacts after an accepted step (no event logged)."""
        assert self.normal is not None
        n, t = self.n, self.t
        q, v, tail = self.y[:n], self.y[n : 2 * n], self.y[2 * n :]

        def a_free(qq: FloatArray, vv: FloatArray) -> FloatArray:
            return self.free_accel(t, np.concatenate([qq, vv, tail]))

        q = self.normal.repatch(q, v, a_free, self.sys.minv(q))
        self._sync_normal_pairs()
        self.y = np.concatenate([q, v, tail])
        self.diag.restarts += 1
        self.stepper.reset(t, self.y, h=max(self.stepper.h, 1e-6))

    def step_limit(self) -> float:
        """Largest step keeping every point's motion within half the query margin [s]."""
        if self.sys.world is None:
            return self.cfg.max_step
        speed = REACH_BOUND * float(np.abs(self.y[self.n : 2 * self.n]).sum())
        return min(self.cfg.max_step, 0.5 * self.cfg.margin / max(speed, 1e-9))

    def run(self) -> None:
        self.start()
        while self.t < self.duration - 1e-12:
            self.stepper.h_max = self.step_limit()
            t_sched = self.next_scheduled()
            if t_sched <= self.t + 1e-12:  # an event landed on a scheduled time
                self.run_scheduled(self.t)
                self.stepper.reset(self.t, self.y, h=max(self.stepper.h, 1e-6))
                continue
            seg = self.stepper.step(min(self.duration, t_sched))
            y1 = seg.y1
            crossings = self.crossings(seg, y1)
            if not crossings:
                on_schedule = seg.t1 >= t_sched - 1e-12 and seg.t1 < self.duration - 1e-12
                # A sample on a scheduled time shows the state after the action (a new held
                # command applies from its tick on).
                self.record(seg, seg.t1 - 1e-11 if on_schedule else seg.t1)
                self.t, self.y = seg.t1, y1
                if self.sys.world is not None:
                    self.last_d = self.pending_d
                    self.note_min(*self.pending_min)
                self.release_limits(self.y)
                n = self.n
                # A sliding contact's patch is rebuilt only once it is stale (slid SLIDE_TOL
                # or its gap off the pair's distance): its rows stay valid until then.
                if self.normal is not None and self.normal.sliding(y1[:n], y1[n : 2 * n]):
                    if self.normal.stale(y1[:n], y1[n : 2 * n], self.last_d):
                        self.refresh_sliding()
                elif self.mixed_on and self.mixed_sliding(y1):
                    assert self.mixed is not None
                    if self.mixed.stale(y1[:n], y1[n : 2 * n], self.last_d):
                        self.refresh_mixed()
                if on_schedule:
                    self.run_scheduled(self.t)
                    self.record_due(self.t, self.y)
                    self.stepper.reset(self.t, self.y, h=max(self.stepper.h, 1e-6))
                self.report_progress()
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
            self.report_progress()
        self.record_final()

    def report_progress(self) -> None:
        """Call the progress callback; an error it raises stops the run as a SimulationError.

        A PackbotError it raises (a wall-time limit, Ctrl-C in ``packbot run``) passes as it is;
        KeyboardInterrupt too.
        """
        if self.progress is None:
            return
        try:
            self.progress(self.t)
        except PackbotError:
            raise
        except Exception as exc:
            raise SimulationError(
                f"the progress callback raised {type(exc).__name__}: {exc}", self.t
            ) from exc

    def result(self) -> SimResult:
        t = np.array(self.samples_t)
        cols = [np.array([s[k] for s in self.samples], dtype=float) for k in range(7)]
        q, v, tau_cmd, tau, tau_fr, effort, energy = cols
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
            joint_names=self.robot.joint_names,
            config=self.cfg,
            diagnostics=self.diag,
            tau_cmd=tau_cmd,
            tau_friction=tau_fr,
            effort=effort,
            failures=tuple(self.failures_in),
            control_ticks=self.ticks,
        )


def _check_inputs(
    robot: Any,
    q0: Any,
    v0: Any,
    duration: Any,
    config: Any,
    failures: Any,
    payload: Any,
    controller: Any,
    environment: Any,
    inform_controller: Any,
    progress: Any,
) -> tuple[FloatArray, FloatArray, float, tuple[Failure, ...]]:
    """Check every argument of :func:`simulate`; return (q0, v0, duration, failures) normalised.

    Besides each argument's type and range, the limits that protect the machine are checked
    here, where the duration is known (docs/simulator.md, "Inputs: checks, ranges and limits").
    """
    if not isinstance(robot, Robot):
        raise ConfigurationError("robot", robot, "a packbot.Robot (from packbot.load_robot())")
    if not isinstance(config, SimConfig):
        raise ConfigurationError("config", config, "None or a packbot.SimConfig")
    config.validate()  # a SimConfig can be changed after its construction
    duration = finite_number(
        "duration", duration, low=0.0, low_open=True, unit="s", what="a finite positive time"
    )
    n_samples = duration / config.sample_dt
    if n_samples > MAX_SAMPLES:
        raise ConfigurationError(
            "sample_dt",
            config.sample_dt,
            f"a sampling interval >= duration / {MAX_SAMPLES:,} = {duration / MAX_SAMPLES:.3g} s "
            f"for duration={duration:g} s (at most {MAX_SAMPLES:,} samples per run: each "
            "takes about 1.7 kB of memory while the run lasts)",
        )
    if duration / config.max_step > MAX_STEPS:
        raise ConfigurationError(
            "max_step",
            config.max_step,
            f"a step >= duration / {MAX_STEPS:,} = {duration / MAX_STEPS:.3g} s for "
            f"duration={duration:g} s (a run may not force more than {MAX_STEPS:,} steps)",
        )
    if isinstance(failures, (Failure, str, bytes, Mapping)) or not isinstance(
        failures, (list, tuple)
    ):
        raise ConfigurationError("failures", failures, "a list of packbot.Failure")
    failures = tuple(failures)
    validate_failures(failures, robot.joint_names)
    locked = joint_names("locked_joints", config.locked_joints, robot.joint_names)
    frozen = [f.joint for f in failures if f.kind == "frozen"]
    if len(set(locked) | set(frozen)) >= robot.nq:
        what = "locked_joints" if len(locked) >= robot.nq else "locked_joints and frozen failures"
        raise ConfigurationError(
            "locked_joints",
            locked,
            f"at least one joint left free ({what} cover all {robot.nq} joints)",
        )
    n_free = robot.nq - len(locked)
    bound = 1.0 / math.sqrt(n_free)
    if config.relevant_threshold >= bound:
        raise ConfigurationError(
            "relevant_threshold",
            config.relevant_threshold,
            f"a fraction < 1/sqrt({n_free}) = {bound:.4g} with {n_free} free joints (the "
            f"largest of {n_free} components of J_n is at least ||J_n|| / sqrt({n_free}), so "
            "below this bound every contact has a relevant joint)",
        )
    for f in failures:
        if f.kind == "brake" and config.handoff:
            raise ConfigurationError(
                "failures",
                f"{f.joint}: brake",
                "no brake failure with handoff=True (joint holds and contact forces are not yet "
                "solved as one problem)",
            )
        if f.kind == "brake" and config.contact_mode == "normal":
            raise ConfigurationError(
                "failures",
                f"{f.joint}: brake",
                "no brake failure with contact_mode='normal' (joint holds and contact forces "
                "are not yet solved as one problem)",
            )
        if f.joint in locked:
            raise ConfigurationError(
                "failures", f.joint, "a joint that is not in config.locked_joints"
            )
    if payload is not None:
        if not isinstance(payload, Payload):
            raise ConfigurationError("payload", payload, "a packbot.Payload or None")
        payload.validate()
        if not robot.model.existFrame(payload.frame):
            raise UnknownNameError(
                "frame", payload.frame, [str(f.name) for f in robot.model.frames]
            )
    if environment is not None:
        if not isinstance(environment, Environment):
            raise ConfigurationError("environment", environment, "None or a packbot.Environment")
        environment.validate()
    if isinstance(controller, Controller):
        dt = finite_number(
            "controller.dt",
            getattr(controller, "dt", None),
            low=CONTROL_DT_MIN,
            unit="s",
            what="a control period (a Controller subclass must call Controller.__init__)",
        )
        if duration / dt > MAX_STEPS:
            raise ConfigurationError(
                "controller.dt",
                controller.dt,
                f"a control period >= duration / {MAX_STEPS:,} = {duration / MAX_STEPS:.3g} s "
                f"for duration={duration:g} s (at most {MAX_STEPS:,} control ticks per run: "
                "each cuts an integration step)",
            )
    elif controller is not None and (not callable(controller) or isinstance(controller, type)):
        raise ConfigurationError(
            "controller",
            controller,
            "None, a packbot.control.Controller or a function tau(t, q, v)",
        )
    boolean("inform_controller", inform_controller)
    if progress is not None and not callable(progress):
        raise ConfigurationError("progress", progress, "None or a function progress(t)")
    nq = robot.nq
    q = real_array(
        "q0", q0, shape=(nq,), expected=f"an array of shape ({nq},) [rad]", shape_error_value=True
    )
    v = real_array(
        "v0", v0, shape=(nq,), expected=f"an array of shape ({nq},) [rad/s]", shape_error_value=True
    )
    fast = np.flatnonzero(np.abs(v) > V0_MAX)
    if len(fast):
        raise ConfigurationError(
            "v0",
            "; ".join(f"{robot.joint_names[i]}={v[i]:g}" for i in fast),
            f"joint speeds within +/-{V0_MAX:g} rad/s (50 times the fastest joint's velocity "
            "limit; more is a unit mistake: deg/s or rpm)",
        )
    robot.check_within_limits(q, "q0")
    idx = [robot.params.index(nm) for nm in locked]
    if np.any(v[idx] != 0.0):
        raise ConfigurationError("v0", v.tolist(), "zero velocity on the locked joints")
    return q, v, duration, failures


def check_arguments(
    robot: Robot,
    q0: Any,
    v0: Any,
    duration: float,
    *,
    controller: Controller | TorqueFunction | None = None,
    environment: Environment | None = None,
    config: SimConfig | None = None,
    failures: Sequence[Failure] = (),
    payload: Payload | None = None,
    inform_controller: bool = False,
    progress: Callable[[float], None] | None = None,
) -> None:
    """Check :func:`simulate`'s arguments as it does before a run, without running it.

    Everything but the initial collision check (which needs the collision world): types,
    ranges, names, and the limits that protect the machine. Used to refuse a bad scenario before
    anything is written.

    Raises:
        ConfigurationError: A bad argument (see :func:`simulate`).
        UnknownNameError: An unknown locked joint, failed joint or payload frame.
    """
    _check_inputs(
        robot,
        q0,
        v0,
        duration,
        SimConfig() if config is None else config,
        failures,
        payload,
        controller,
        environment,
        inform_controller,
        progress,
    )


def check_initial_state(
    robot: Robot,
    q0: Any,
    *,
    environment: Environment | None = None,
    config: SimConfig | None = None,
) -> None:
    """Raise if the initial configuration penetrates, as :func:`simulate` does at its start.

    Builds the same collision world as the run (its locked joints, its environment) and tests
    every pair at q0; nothing with ``contact_mode="none"``. Call it after :func:`check_arguments`
    (the arguments are assumed valid).

    Raises:
        InitialCollisionError: A pair penetrates at q0 (names the pairs and depths).
    """
    cfg = SimConfig() if config is None else config
    q = np.asarray(q0, dtype=float)
    system = System(robot, q, cfg, environment, locked=tuple(cfg.locked_joints))
    world = system.world
    if world is None:
        return
    sw = world.sweep(system.reduce(q))
    bad = [(world.pairs[p], d) for p, d in zip(sw.pairs, sw.distances, strict=True) if d < 0]
    if bad:
        raise InitialCollisionError([(p.piece1, p.piece2, d) for p, d in bad])


def simulate(
    robot: Robot,
    q0: Any,
    v0: Any,
    duration: float,
    *,
    controller: Controller | TorqueFunction | None = None,
    environment: Environment | None = None,
    config: SimConfig | None = None,
    failures: Sequence[Failure] = (),
    payload: Payload | None = None,
    inform_controller: bool = False,
    progress: Callable[[float], None] | None = None,
) -> SimResult:
    """Simulate the arm from (q0, v0) for ``duration`` seconds with exact contact events.

    Args:
        robot: The robot (:func:`packbot.load_robot`).
        q0: Initial joint positions [rad], shape (nq,), within the limits, collision free.
        v0: Initial joint velocities [rad/s], shape (nq,), each within +/-100 rad/s.
        duration: Simulated time [s].
        controller: None (zero command: a total collapse), a sampled-data
            :class:`~packbot.control.Controller` (ticks every ``controller.dt``, zero-order
            hold), or a smooth, stateless torque function ``tau(t, q, v)`` [N*m] evaluated at
            every right-hand side. Full coordinates. The command passes through the failure
            and actuator models (:mod:`packbot.actuators`).
        environment: Static obstacles; None means the floor alone.
        config: Settings; None means ``SimConfig()``.
        failures: Joint failures (:class:`~packbot.failures.Failure`), each injected at its
            time ``t`` (at most one per joint, none on a joint in ``config.locked_joints``).
        payload: A payload held in the gripper from ``payload.t_pick`` to ``payload.t_drop``.
        inform_controller: Call ``controller.on_failure(failure, t)`` at each injection (the
            scenario tells the controller; otherwise it must detect the failure itself).
        progress: Called with the simulated time [s] after every accepted step. An exception
            it raises stops the run: a PackbotError (or KeyboardInterrupt) as it is, any other
            as a SimulationError holding the result up to then.

    Returns:
        The sampled trajectory, the event log and diagnostics. Samples are at multiples of
        ``config.sample_dt``, before and after every event, and at t = duration (the final
        state is always a sample).

    Raises:
        ConfigurationError: Bad input (names the field and what is expected), checked before
            the run: every argument's type and range, and the limits that protect the machine
            (at most 500,000 samples, ``duration / config.sample_dt``; at most 1,000,000
            control ticks, ``duration / controller.dt``, or forced steps, ``duration /
            config.max_step``; see docs/simulator.md).
        UnknownNameError: An unknown locked joint, failed joint or payload frame.
        InitialCollisionError: The initial state penetrates (names the pairs and depths).
        ControllerError: The controller raised or returned bad torques (says when, and which
            joint).
        SimulationError: The run could not continue (e.g. step size underflow); its ``result``
            holds the trajectory up to then.
    """
    cfg = SimConfig() if config is None else config
    q, v, t_end, failure_list = _check_inputs(
        robot,
        q0,
        v0,
        duration,
        cfg,
        failures,
        payload,
        controller,
        environment,
        inform_controller,
        progress,
    )
    if cfg.contact_mode == "normal" and cfg.mu == 0.0:
        log.warning(
            "contact_mode='normal' with mu = 0: frictionless contact on faceted pieces can chatter "
            "(an impact every few ms) and an arm may never come to rest (docs/contact.md, "
            "'Open problems')"
        )
    wall = time.perf_counter()
    run = _Run(
        robot,
        q,
        v,
        t_end,
        controller,
        environment,
        cfg,
        failures=failure_list,
        payload=payload,
        inform_controller=bool(inform_controller),
        progress=progress,
    )
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
