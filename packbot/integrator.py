"""The event-driven simulator: :func:`simulate`.

The loop, and only the loop: between events the smooth dynamics (Pinocchio ABA with armature,
then the contact law's current mode) are integrated by an adaptive Dormand-Prince 5(4) method
(:mod:`packbot.ode`). After every accepted step the contact law reports its event functions that
changed sign over the step (``ContactLaw.watch``); the earliest crossing is located on the step's
dense output to ``EVENT_XTOL`` seconds by root finding, the step is cut there, the law handles
the events of that instant (``ContactLaw.handle``), and the stepper restarts with a fresh step.
Without a crossing the step is accepted and the law told (``ContactLaw.after_step``: limit stops
released, sliding patches refreshed).

What the events are and what happens at each is the law's (:mod:`packbot.contact`: ``none``,
``joint_clamp``, ``normal``, ``handoff``); the loop never asks which law it holds. The scheduled
actions (:mod:`packbot.schedule`) cut the steps at their times: failure injections (``failure``,
and ``freeze`` for the impulse that stops a freezing joint), payload ``pick`` / ``drop``. The
ticks of a sampled-data :class:`~packbot.control.Controller` (not logged) cut a step only when
they change the held command (:mod:`packbot.ticks`). A frozen joint or a payload change starts a
new *phase*: the integrated model is rebuilt (``pin.buildReducedModel``, the payload's inertia
added), the law rebuilt on it and the contacts found again; the result stays in full coordinates.
Samples, events: :mod:`packbot.recorder`; torques: :mod:`packbot.drive`; order: docs/simulator.md.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot import recorder
from packbot.config import SimConfig
from packbot.contact import make_law
from packbot.contact.base import SETTLE, Crossing, StepSpan
from packbot.control.base import Controller
from packbot.drive import Drive, TorqueFunction
from packbot.environment import Environment
from packbot.errors import PackbotError, SimulationError
from packbot.failures import Failure
from packbot.impact_gain import warn_impact_gain
from packbot.inputs import check_inputs, warn_settings
from packbot.keywords import checked_arguments
from packbot.model import Robot
from packbot.ode import DenseSegment, RK45Stepper, StepSizeUnderflow, locate_earliest
from packbot.payload import Payload
from packbot.recorder import EventLog, Recorder, Sample, Samples, measure, measure_many
from packbot.result import Diagnostics, Event, SimResult, rest_time
from packbot.schedule import Schedule, freeze_impulse, momentum_kept
from packbot.system import System
from packbot.ticks import Ticks

__all__ = ["EVENT_XTOL", "TorqueFunction", "simulate"]

FloatArray = NDArray[np.float64]

#: Time resolution of event location [s].
EVENT_XTOL = 1e-10


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
        self.drive = Drive(robot, config, controller)
        self.ctrl_obj = self.drive.ctrl_obj
        self.inform = inform_controller
        self.progress = progress
        self.payload = payload
        self.payload_on = False
        self.failures_in: list[Failure] = []
        self.frozen: list[str] = []
        self.schedule = Schedule(failures, payload, self.ctrl_obj)
        self.events = EventLog(config.max_events)
        self.ticks = Ticks(self.schedule, self.drive, self.events)
        self.diag = Diagnostics()
        self.rec = Recorder(config.sample_dt, duration, self.measure, self.measure_many)
        self.stepper = RK45Stepper(
            self.rhs, rtol=config.rtol, atol=config.atol, h_max=config.max_step
        )
        self.t = 0.0
        self.build_phase(np.asarray(q0, dtype=float), np.asarray(v0, dtype=float))
        self.law = make_law(config, self.sys, self.drive, self.events, self.diag)
        self.rec.contacts = self.ticks.contacts = recorder.contact_sampler(self.drive, self.law)

    # ------------------------------------------------------------------ phases
    def build_phase(self, qf: FloatArray, vf: FloatArray, tau_mf: FloatArray | None = None) -> None:
        """(Re)build the integrated system and the torques from a full-coordinate state."""
        locked = tuple(self.cfg.locked_joints) + tuple(self.frozen)
        payload = self.payload if self.payload_on else None
        self.sys = System(
            self.robot, qf, self.cfg, self.environment, locked=locked, payload=payload
        )
        self.n = self.sys.nv
        self.drive.phase(self.sys, self.failures_in)
        parts = [self.sys.reduce(qf), self.sys.reduce(vf)]
        if self.drive.lag:
            parts.append(self.sys.reduce(np.zeros(self.robot.nq) if tau_mf is None else tau_mf))
        self.y = np.concatenate(parts)

    def rebuild(self, t: float, y: FloatArray) -> None:
        """A new phase from state y at t: model and law rebuilt, contacts found again."""
        qf, vf, tau_mf = self.full_state(y)
        self.build_phase(qf, vf, tau_mf)
        self.y = self.law.start(t, self.y, False, self.sys)

    def full_state(self, y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q, v, tau_m) in full coordinates from an integrated state."""
        n = self.n
        qf, vf = self.sys.q_full(y[:n]), self.sys.v_full(y[n : 2 * n])
        tau_m = np.zeros(self.robot.nq)
        if self.drive.lag:
            tau_m[self.sys.free] = y[2 * n :]
        return qf, vf, tau_m

    # ------------------------------------------------------------------ dynamics, samples
    def rhs(self, t: float, y: FloatArray) -> FloatArray:
        """The state's derivative: v, the law's accelerations (and the motor lag)."""
        n = self.n
        q, v = y[:n], y[n : 2 * n]
        _, target, applied, friction = self.drive.torques(t, y)
        a = self.law.torque_accel(q, v, applied + friction)
        if self.drive.lag:
            return np.concatenate([v, a, (target - y[2 * n :]) / self.cfg.motor_lag])
        return np.concatenate([v, a])

    def measure(self, t: float, y: FloatArray) -> Sample:
        """The sample of state y at t (see :func:`packbot.recorder.measure`)."""
        return measure(t, y, self.drive, self.law.forces().friction)

    def measure_many(self, ts: list[float], ys: list[FloatArray]) -> Samples | None:
        """The samples of several states at once (:func:`packbot.recorder.measure_many`)."""
        return measure_many(ts, ys, self.drive, self.law.forces().friction)

    # ------------------------------------------------------------------ loop
    def start(self) -> None:
        """Contacts and limits at t = 0, then the actions scheduled at t = 0."""
        self.y = self.law.start(0.0, self.y, check=True)
        if self.ctrl_obj is not None:
            qf, vf, _ = self.full_state(self.y)
            self.ctrl_obj.reset(self.robot, 0.0, qf.copy(), vf.copy())
        if self.schedule.next_time() <= 0.0:
            self.run_scheduled(0.0, record=False)
        self.rec.point(0.0, self.y)
        self.rec.next_sample = 1
        self.stepper.reset(0.0, self.y)

    def restart(self) -> None:
        """A fresh step from the current state (after an event or a changed state).

        The restart's derivative is left to the next step (nothing between a restart and it
        changes it; the contact-normal mode's native step computes it in its first stage).
        """
        self.stepper.reset(self.t, self.y, h=max(self.stepper.h, 1e-6), defer=True)

    def run(self) -> None:
        """Integrate to the duration, event by event."""
        self.start()
        law, stepper, rec = self.law, self.stepper, self.rec
        schedule, ticks, duration = self.schedule, self.ticks, self.duration
        t_last = duration - 1e-12  # (the run ends within 1e-12 s of its duration)
        while self.t < t_last:
            t, y = self.t, self.y
            t_sched = schedule.next_time()
            if t_sched <= t + 1e-12:  # an event landed on a scheduled time
                if self.run_scheduled(t):
                    self.restart()
                continue
            # A window lands on every tick, the stepper on those that change the command.
            t_far = min(duration, schedule.horizon(ticks.cut))
            span = StepSpan(
                t_far, min(duration, t_sched), t_sched, t_last, schedule.next_tick >= t_far, rec
            )
            seg = law.step(stepper, t, y, span)
            if seg is None:  # the steps taken are accepted (or the law takes the next ones)
                if stepper.t != t:
                    self.t, self.y = stepper.t, stepper.y
                    self.report_progress()
                continue
            crossings = law.watch(seg)
            t_star, at = self.locate(seg, crossings) if crossings else (seg.t1, [])
            # (no tick before the step's end or its first event: nothing to visit)
            changed = ticks.inside(seg, t_star, rec.record) if schedule.next_tick < t_star else None
            if changed is not None:
                self.cut_at_tick(seg, *changed)
            elif not crossings:
                t1 = seg.t1
                t_sched = schedule.next_time()
                on_schedule = t1 >= t_sched - 1e-12 and t1 < t_last
                # a sample on a scheduled time shows the state after the action (a held command)
                rec.record(seg, t1 - 1e-11 if on_schedule else t1)
                self.t, self.y = t1, seg.y1
                y_new = law.after_step(t1, seg.y1)
                if y_new is not None:  # the law changed the state (a re-patch)
                    self.y = y_new
                    self.diag.restarts += 1
                    self.restart()
                if on_schedule:
                    restart = self.run_scheduled(t1)
                    rec.record_due(t1, self.y)
                    if restart:
                        self.restart()
            else:
                y_star = seg(t_star)
                rec.record(seg, t_star)
                rec.point(t_star, y_star)
                y_new = law.handle(t_star, y_star, at)
                rec.point(t_star, y_new)
                self.t, self.y = t_star, y_new
                self.diag.restarts += 1
                self.restart()
            self.report_progress()
        rec.record_final(self.y)

    def cut_at_tick(self, seg: DenseSegment, t: float, tau: FloatArray) -> None:
        """The tick at t inside the step changes the command: the step is kept up to t.

        The law watches the part kept (an event there that the whole step hid, a double
        crossing, comes at the next step's start, as after any step).
        """
        kept = seg.truncated(t)
        self.law.watch(kept)
        self.rec.record(seg, t - 1e-11)
        self.t, self.y = t, kept.y1
        y_new = self.law.after_step(t, self.y)
        if y_new is not None:
            self.y = y_new
            self.diag.restarts += 1
        self.ticks.apply(t, tau)
        self.rec.record_due(t, self.y)
        self.restart()

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

    def locate(self, seg: DenseSegment, crossings: list[Crossing]) -> tuple[float, list[Crossing]]:
        """Earliest crossing time and the crossings within 10 EVENT_XTOL of it (locate_earliest)."""
        gs, g0s, g1s = zip(*((c.g, c.g0, c.g1) for c in crossings), strict=True)
        xtol, roots = EVENT_XTOL, [c.root for c in crossings]  # (roots: native root finders)
        t_star, idx = locate_earliest(
            list(gs), list(g0s), list(g1s), seg.t0, seg.t1, xtol=xtol, at_tol=10 * xtol, roots=roots
        )
        return t_star, [crossings[i] for i in idx]

    # ------------------------------------------------------------------ scheduled actions
    def run_scheduled(self, t: float, record: bool = True) -> bool:
        """Apply every action scheduled at t (within 1e-12 s): failures, payload, a tick.

        Args:
            t: Time [s].
            record: Keep samples of the states before and after a failure or payload change.

        Returns:
            Whether the dynamics changed: a failure, a payload change, a new held command.
        """
        due = self.schedule.due(t)
        if due and record:
            self.rec.point(t, self.y)  # the state before, for the plots
        for what in due:
            if isinstance(what, Failure):
                self.inject(t, what)
            else:
                self.payload_change(t, what)
        changed = bool(due)
        if self.schedule.tick_due(t):
            changed = self.ticks.tick(t, self.y) or changed
        if due and record:
            self.rec.point(t, self.y)
        return changed

    def inject(self, t: float, failure: Failure) -> None:
        """A joint fails at t: log it; a frozen joint is stopped by an impulse and merged."""
        qf, vf, _ = self.full_state(self.y)
        self.failures_in.append(failure)
        if self.inform and self.ctrl_obj is not None:
            self.ctrl_obj.on_failure(failure, t)
        n = self.n
        q, v = self.y[:n], self.y[n : 2 * n]
        e = self.sys.energy(q, v)
        self.log_action(Event(t, "failure", failure.joint, failure.kind), vf, vf, e, e)
        if failure.kind != "frozen":
            self.drive.set_failures(self.failures_in)
            self.y = self.law.handle(t, self.y, [SETTLE])
            return
        j = int(np.flatnonzero(self.sys.free == self.robot.params.index(failure.joint))[0])
        v_new, idx = freeze_impulse(self.sys, q, v, j, self.law.forces().held())
        moved = tuple(self.sys.names[i] for i in idx)
        ev = Event(t, "freeze", failure.joint, distance=float(qf[self.sys.free[j]]))
        ev = dataclasses.replace(ev, relevant_joints=moved)
        self.log_action(ev, vf, self.sys.v_full(v_new), e, self.sys.energy(q, v_new))
        self.frozen.append(failure.joint)
        y = self.y.copy()
        y[n : 2 * n] = v_new
        self.rebuild(t, y)

    def payload_change(self, t: float, what: str) -> None:
        """Pick up (an inelastic impact: generalized momentum kept) or drop the payload."""
        n = self.n
        q, v = self.y[:n], self.y[n : 2 * n]
        e0 = self.sys.energy(q, v)
        vf0 = self.sys.v_full(v)
        momentum = self.sys.mass_matrix(q) @ v
        self.payload_on = what == "pick"
        self.rebuild(t, self.y)
        q, v = self.y[:n], self.y[n : 2 * n]
        if what == "pick":
            v = momentum_kept(self.sys, q, momentum)
            self.y = self.y.copy()
            self.y[n : 2 * n] = v
            self.y = self.law.handle(t, self.y, [SETTLE])
        ev = Event(t, what, str(self.payload.frame) if self.payload else "", "")
        self.log_action(ev, vf0, self.sys.v_full(v), e0, self.sys.energy(q, v))

    def log_action(
        self, ev: Event, v_before: FloatArray, v_after: FloatArray, e0: float, e1: float
    ) -> None:
        """Log a scheduled action's event with the velocities [rad/s] and energies [J] around it."""
        ev = dataclasses.replace(ev, v_before=v_before, v_after=v_after)
        self.events.log(dataclasses.replace(ev, energy_before=e0, energy_after=e1), count=False)

    def result(self) -> SimResult:
        """The run's result (also the partial result of a run that stopped)."""
        t, q, v, tau_cmd, tau, tau_fr, effort, energy = self.rec.arrays()
        st, d = self.stepper, self.diag
        d.steps, d.rejected_steps, d.rhs_calls = st.n_steps, st.n_rejected, st.n_rhs
        return SimResult(
            t=t,
            q=q,
            v=v,
            tau=tau,
            energy=energy,
            events=list(self.events),
            rest_time=rest_time(t, v, self.cfg.rest_speed),
            joint_names=self.robot.joint_names,
            config=self.cfg,
            diagnostics=self.diag,
            tau_cmd=tau_cmd,
            tau_friction=tau_fr,
            effort=effort,
            contacts=self.rec.contact_table(self.drive.robot.model.nv),
            impacts=self.events.impact_table(self.drive.robot.model.nv),
            failures=tuple(self.failures_in),
            control_ticks=self.schedule.ticks,
            environment=Environment() if self.environment is None else self.environment,
            payload=self.payload,
        )


@checked_arguments
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
            time ``t``; a joint may fail again later (:func:`~packbot.failures.check_sequence`),
            none on a joint in ``config.locked_joints``.
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
    q, v, t_end, failure_list = check_inputs(
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
    warn_settings(cfg)
    if payload is not None:
        payload = payload.held_in(robot.tool_frame)
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
            exc.result = run.result() if run.rec.samples_t else None
        raise
    run.diag.wall_time = time.perf_counter() - wall
    return warn_impact_gain(run.result())  # (the report's law: energy gained at impacts)
