"""Reconfigurable control: bring the tool to a target, and again after a joint fails.

:class:`ReconfigurableController` places a frame (default the tool frame) at a target position
[m] and holds it there:

1. Plan: inverse kinematics (:func:`~packbot.control.ik.solve_position_ik`, damped least squares
   on the joints that move the frame) from the current configuration, keeping only solutions
   that are collision free with a clearance and whose straight joint-space path is collision
   free; a minimum-jerk move to the solution within a fraction of the speed limits.
2. Track: computed torque (RNEA) on the controller's current model of the arm.
3. Watch: a momentum observer (:mod:`packbot.control.detector`) flags a failed joint from the
   commanded versus the measured motion; or the simulator tells the controller
   (:meth:`on_failure`, with ``simulate(..., inform_controller=True)``).
4. Reconfigure:

   - frozen joint: the model becomes ``pin.buildReducedModel`` of the arm locked at the measured
     angle; IK is solved again on the remaining joints and a new move starts from the measured
     state (its velocity included); the frozen joint is commanded zero torque;
   - loose joint: the joint is unactuated (zero command). A static pose then needs zero gravity
     torque on the loose joint, so the new goal is solved for jointly: the frame at the target
     and the loose joint at a *stable* equilibrium (d g_u / d q_u > 0), by bounded least
     squares (``scipy.optimize.least_squares``), keeping the loose joint at least
     ``loose_margin`` from its stops (room for the swing); the actuated joints follow it by
     collocated partial feedback linearisation (the loose joint's acceleration eliminated from
     the dynamics), with a swing damper. The swing psi is the loose joint's angle relative to
     its equilibrium, which moves with the actuated joints: psi' = v_u + G_uu^-1 G_ua v_a
     (G = dg/dq). Under PFL, psi'' = B a_a + ..., B = G_uu^-1 G_ua - M_uu^-1 M_ua. The joints
     that carry the loose joint (its pivot) track the planned move plus an offset delta,
     ``delta'' = -sway_damping B^T psi' - swing_return^2 delta - 2 swing_return delta'``,
     which adds about -sway_damping B B^T psi' to the swing's acceleration at its frequency
     while delta returns to zero at the slower ``swing_return`` rate. The damper shapes the
     tracking reference, so that the tracking loop does not cancel it. The loose goal moves
     only the loose joint and the joints that carry it and is collision free for swings of
     +/- ``swing_check``.

Other failure kinds (weak, stuck, brake) are logged and not reconfigured.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.collision import CollisionWorld
from packbot.control._common import (
    DEFAULT_GRAVITY,
    GainLike,
    check_gain_spec,
    controlled_frame,
    damping_ratio,
    frame_spec,
    loop_frequency,
    resolve_gains,
    resolve_vector3,
)
from packbot.control._goal_planner import GoalPlanner, ancestors
from packbot.control.base import Sensor
from packbot.control.detector import Detection, MomentumObserver, default_threshold
from packbot.control.model_based import ModelBasedController
from packbot.control.path_check import path_warning
from packbot.control.trajectory import MIN_JERK_PEAK_SPEED, QuinticSegment
from packbot.environment import Environment
from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import boolean, finite_number, integer

if TYPE_CHECKING:
    from packbot.failures import Failure
    from packbot.model import Robot

__all__ = ["ReconfigEvent", "ReconfigurableController"]

log = logging.getLogger(__name__)
#: What :func:`~packbot.control.path_check.path_warning` names when a planned move collides.
_MOVE = "the reconfigurable controller's planned move (straight in joint space) to its goal"

FloatArray = NDArray[np.float64]

#: Most IK restarts per plan (each is an IK solve and collision checks: milliseconds).
IK_SEEDS_MAX = 1000


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class ReconfigEvent:
    """An entry of the controller's log.

    Attributes:
        t: Time [s].
        kind: ``"plan"``, ``"detect"``, ``"informed"``, ``"replan"`` or ``"ignored"``.
        joint: Joint name ("" for the initial plan).
        detail: Human-readable detail (failure kind, IK error, residual).
        q_goal: The goal configuration planned [rad] (full coordinates), if any.
    """

    t: float
    kind: str
    joint: str = ""
    detail: str = ""
    q_goal: FloatArray | None = None


def _positive(x: object, field: str, unit: str) -> float:
    return finite_number(field, x, low=0.0, low_open=True, unit=unit)


class ReconfigurableController(ModelBasedController):
    """Hold a frame at a target position, re-planning with the remaining joints after a failure.

    Args:
        target: Target position of the frame [m], world frame, or a pose name (the frame's
            position at that pose).
        frame: The placed frame; None: the robot's tool frame (:attr:`packbot.Robot.tool_frame`,
            PackBot's ``gripper_tool``).
        speed_fraction: Moves peak at this fraction of each joint's speed limit [-], in (0, 1].
        min_move_time: Shortest move [s].
        omega: Natural frequency of the tracking loop [rad/s] (gains omega^2, 2 zeta omega),
            below the Nyquist rate pi / dt.
        zeta: Damping ratio of the tracking loop [-], in (0, 100].
        detect: Run the momentum-observer detector.
        reconfigure: Re-plan after a failure (False: keep the original plan; the baseline).
        observer_gain: Observer gain K_O [1/s], below 2 / dt (the residual's discrete update is
            an explicit Euler step of r' = K_O (tau_ext - r), stable for K_O dt < 2).
        threshold: Detection threshold [N*m] per joint (number, nv numbers or {joint: value});
            None: the joint's friction at its speed limit plus 1 % of its effort limit,
            coulomb + viscous * velocity + 0.01 * effort (from the parameter table).
        persistence: Time the residual must stay above the threshold [s].
        frozen_speed: A detected joint slower than this over the window is frozen [rad/s].
        clearance: Smallest signed distance accepted at a planned goal and along its path [m],
            in [0, 1].
        environment: Obstacles the planner avoids (None: the floor).
        ik_seeds: Random restarts of IK when the first solution is rejected, in [0, 1000].
        seed: Seed of the restarts (an integer >= 0).
        sway_damping: Gain of the loose-link swing damper [1/s].
        swing_return: Natural frequency at which the damper's offset of the pivot joints
            returns to the planned move [rad/s] (well below the swing's frequency; below pi /
            dt).
        swing_check: A planned rest of a loose joint must stay collision free (with the
            clearance) for any swing of the loose joint within +/- this angle [rad], in [0, pi].
        loose_margin: Smallest distance of a loose joint's planned rest angle to its stops
            [rad], in [0, pi].
        dt: Control period [s].
        sensor: Measurement model.
        gravity: Gravity the controller assumes [m/s^2].

    Attributes:
        events: The controller's log (:class:`ReconfigEvent`).
        failed: Failed joints found so far, index -> ``"frozen"`` or ``"loose"``.
        q_goal: The current goal [rad], full coordinates.
        observer: The detector (None before reset or if ``detect`` is False).
    """

    def __init__(
        self,
        *,
        target: str | Sequence[float] | FloatArray,
        frame: str | None = None,
        speed_fraction: float = 0.5,
        min_move_time: float = 0.5,
        omega: float = 20.0,
        zeta: float = 1.0,
        detect: bool = True,
        reconfigure: bool = True,
        observer_gain: float = 50.0,
        threshold: GainLike | None = None,
        persistence: float = 0.02,
        frozen_speed: float = 1e-3,
        clearance: float = 0.01,
        environment: Environment | None = None,
        ik_seeds: int = 30,
        seed: int = 0,
        sway_damping: float = 4.0,
        swing_return: float = 2.5,
        swing_check: float = 0.3,
        loose_margin: float = 0.5,
        dt: float = 1e-3,
        sensor: Sensor | None = None,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> None:
        super().__init__(dt=dt, sensor=sensor, gravity=gravity)
        if not (isinstance(target, str) and target):
            resolve_vector3(target, "controller.target", "3 finite coordinates [m] or a pose name")
        self.target_spec = target
        self.frame_spec = frame_spec("controller.frame", frame)
        self.frame = "" if frame is None else frame
        self.speed_fraction = finite_number(
            "controller.speed_fraction", speed_fraction, low=0.0, high=1.0, low_open=True
        )
        self.min_move_time = _positive(min_move_time, "controller.min_move_time", "s")
        self.omega = loop_frequency(omega, "controller.omega", self.dt)
        self.zeta = damping_ratio(zeta, "controller.zeta")
        self.detect = boolean("controller.detect", detect)
        self.reconfigure = boolean("controller.reconfigure", reconfigure)
        # The residual's update is an explicit Euler step of r' = K_O (tau_ext - r): stable for
        # K_O * dt < 2.
        self.observer_gain = finite_number(
            "controller.observer_gain",
            observer_gain,
            low=0.0,
            high=2.0 / self.dt,
            low_open=True,
            high_open=True,
            unit="1/s",
            what=f"an observer gain below 2 / dt (the residual's update is stable for "
            f"K_O * dt < 2; dt={self.dt:g} s)",
        )
        check_gain_spec(threshold, "controller.threshold", positive=True)
        self.threshold_spec = threshold
        self.persistence = _positive(persistence, "controller.persistence", "s")
        self.frozen_speed = _positive(frozen_speed, "controller.frozen_speed", "rad/s")
        self.clearance = finite_number(
            "controller.clearance", clearance, low=0.0, high=1.0, unit="m", what="a distance"
        )
        if environment is not None and not isinstance(environment, Environment):
            raise ConfigurationError(
                "controller.environment", environment, "None or a packbot.Environment"
            )
        self.environment = environment
        self.ik_seeds = integer("controller.ik_seeds", ik_seeds, low=0, high=IK_SEEDS_MAX)
        self.seed = integer("controller.seed", seed, low=0, what="an integer seed")
        self.sway_damping = finite_number(
            "controller.sway_damping", sway_damping, low=0.0, unit="1/s"
        )
        self.swing_return = loop_frequency(swing_return, "controller.swing_return", self.dt)
        self.swing_check = finite_number(
            "controller.swing_check", swing_check, low=0.0, high=math.pi, unit="rad"
        )
        self.loose_margin = finite_number(
            "controller.loose_margin", loose_margin, low=0.0, high=math.pi, unit="rad"
        )
        self.target = np.zeros(3)
        self.threshold = np.zeros(0)
        self.events: list[ReconfigEvent] = []
        self.failed: dict[int, str] = {}
        self.q_goal = np.zeros(0)
        self.observer: MomentumObserver | None = None
        self._world: CollisionWorld | None = None
        self._frame_id = -1
        self._pending: list[tuple[int, str]] = []
        self._tau_prev = np.zeros(0)
        self._free = np.zeros(0, dtype=int)  # joints of the tracking model (not frozen)
        self._loose = np.zeros(0, dtype=int)  # indices into the full q
        self._pivot = np.zeros(0, dtype=int)  # actuated joints that carry a loose joint
        self._track_model: pin.Model | None = None
        self._track_data: pin.Data | None = None
        self._traj: QuinticSegment | None = None
        self._delta = np.zeros(0)  # swing damper's offset of the free joints [rad]
        self._delta_v = np.zeros(0)  # its rate [rad/s]
        self._t_last: float | None = None
        self._rng = np.random.default_rng(seed)

    # ------------------------------------------------------------------ setup
    def prepare(self, robot: Robot) -> None:
        """Resolve the target, frame and thresholds; build the collision world."""
        super().prepare(robot)
        model, data = self._md()
        self.frame, self._frame_id = controlled_frame(model, robot, self.frame_spec)
        if isinstance(self.target_spec, str):
            pin.framesForwardKinematics(model, data, robot.pose(self.target_spec))
            self.target = data.oMf[self._frame_id].translation.copy()
        else:
            self.target = resolve_vector3(
                self.target_spec, "controller.target", "3 finite coordinates [m] or a pose name"
            )
        pp = robot.params
        default = default_threshold(pp)
        self.threshold = resolve_gains(robot, self.threshold_spec, "controller.threshold", default)
        if np.any(self.threshold <= 0):
            raise ConfigurationError("controller.threshold", self.threshold_spec, "values > 0")
        self._world = CollisionWorld(robot, self.environment)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Plan the move to the target from (q0, v0) on the healthy model."""
        self.prepare(robot)
        model, _ = self._md()
        n = robot.nq
        self.events = []
        self.failed = {}
        self._pending = []
        self._rng = np.random.default_rng(self.seed)
        self._free = np.arange(n)
        self._loose = np.zeros(0, dtype=int)
        self._track_model, self._track_data = model, model.createData()
        self._tau_prev = np.zeros(n)
        self._delta, self._delta_v, self._t_last = np.zeros(n), np.zeros(n), None
        self.observer = None
        if self.detect:
            self.observer = MomentumObserver(
                model,
                robot.params.effort,
                gain=self.observer_gain,
                threshold=self.threshold,
                persistence=self.persistence,
                frozen_speed=self.frozen_speed,
            )
            self.observer.reset(t0, np.asarray(q0, dtype=float), np.asarray(v0, dtype=float))
        q0 = np.asarray(q0, dtype=float)
        goal, detail = self._planner().solve_goal(q0, frozen=[])
        self._start_move(t0, q0, np.asarray(v0, dtype=float), goal)
        self.events.append(ReconfigEvent(t=t0, kind="plan", detail=detail, q_goal=goal.copy()))

    # ------------------------------------------------------------------ planning
    def _planner(self) -> GoalPlanner:
        """The goal planner on the healthy model, with the current settings and generator."""
        model, data = self._md()
        assert self._world is not None
        return GoalPlanner(
            model,
            data,
            self._world,
            self.frame,
            self.target,
            clearance=self.clearance,
            ik_seeds=self.ik_seeds,
            swing_check=self.swing_check,
            loose_margin=self.loose_margin,
            rng=self._rng,
        )

    def _start_move(self, t: float, q: FloatArray, v: FloatArray, goal: FloatArray) -> None:
        assert self.robot is not None
        vmax = self.speed_fraction * self.robot.params.velocity
        free = self._free
        movers = np.setdiff1d(free, self._loose)
        d = np.abs(goal - q)[movers]
        T = max(
            self.min_move_time, float(np.max(MIN_JERK_PEAK_SPEED * d / vmax[movers], initial=0))
        )
        if not len(self._loose):  # (a loose joint swings: its straight path is no plan)
            path_warning(self.robot, [q, goal], self.environment, _MOVE, self._world)
        self.q_goal = goal.copy()
        self._traj = QuinticSegment(q0=q[free], q1=goal[free], t0=t, duration=T, v0=v[free])

    # ------------------------------------------------------------------ failures
    def on_failure(self, failure: Failure, t: float) -> None:
        """The simulator reports a failure: reconfigure at the next tick (frozen, loose)."""
        assert self.robot is not None
        j = self.robot.params.index(failure.joint)
        if failure.kind in ("frozen", "loose"):
            self._pending.append((j, failure.kind))
        self.events.append(
            ReconfigEvent(t=t, kind="informed", joint=failure.joint, detail=failure.kind)
        )

    def _handle(self, t: float, j: int, kind: str, q: FloatArray, v: FloatArray) -> None:
        assert self.robot is not None
        name = self.robot.joint_names[j]
        if j in self.failed:
            return
        self.failed[j] = kind
        if self.observer is not None:
            self.observer.ignored[j] = True
        if not self.reconfigure:
            self.events.append(ReconfigEvent(t=t, kind="ignored", joint=name, detail=kind))
            return
        model, _ = self._md()
        frozen = sorted(i for i, k in self.failed.items() if k == "frozen")
        self._free = np.array([i for i in range(model.nq) if i not in frozen], dtype=int)
        self._loose = np.array(sorted(i for i, k in self.failed.items() if k == "loose"), dtype=int)
        self._pivot = np.array(
            [
                i
                for i in sorted(set().union(*(ancestors(model, int(k)) for k in self._loose)))
                if i not in self.failed
            ],
            dtype=int,
        )
        self._delta[:], self._delta_v[:], self._t_last = 0.0, 0.0, None
        if frozen:
            ids = [model.getJointId(self.robot.joint_names[i]) for i in frozen]
            red = pin.buildReducedModel(model, ids, q)
            red.gravity.linear = self.gravity.copy()
            self._track_model, self._track_data = red, red.createData()
        if kind == "loose":
            goal, detail = self._planner().solve_loose_goal(q, j, set(self.failed))
        else:
            goal, detail = self._planner().solve_goal(q, frozen)
        vv = v.copy()
        vv[frozen] = 0.0
        self._start_move(t, q, vv, goal)
        self.events.append(
            ReconfigEvent(t=t, kind="replan", joint=name, detail=f"{kind}: {detail}", q_goal=goal)
        )

    # ------------------------------------------------------------------ control
    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Detect, reconfigure if needed, and return the tracking torque [N*m]."""
        assert self.robot is not None
        if self.observer is not None:
            det: Detection | None = self.observer.update(t, q, v, self._tau_prev)
            if det is not None:
                name = self.robot.joint_names[det.joint]
                self.events.append(
                    ReconfigEvent(
                        t=t,
                        kind="detect",
                        joint=name,
                        detail=f"{det.motion_kind}: residual {det.residual:.3g} N*m since "
                        f"t = {det.t_onset:.4g} s",
                    )
                )
                self._pending.append((det.joint, det.motion_kind))
        while self._pending:
            j, kind = self._pending.pop(0)
            self._handle(t, j, kind, q, v)
        tau = self._track(t, q, v)
        for j in self.failed:
            tau[j] = 0.0  # a failed motor is not driven
        self._tau_prev = tau.copy()
        return tau

    def _track(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        assert self._traj is not None and self._track_model is not None
        model, data = self._track_model, self._track_data
        free = self._free
        qd, vd, ad = self._traj.peek(t)
        all_free = len(free) == len(q)  # (free is then arange(nq): q[free] is a copy of q)
        qr, vr = (q, v) if all_free else (q[free], v[free])
        kp, kd = self.omega**2, 2 * self.zeta * self.omega
        a = ad + kp * (qd - qr) + kd * (vd - vr)
        if len(self._loose) == 0:
            if all_free:
                return pin.rnea(model, data, qr, vr, a)
            tau = np.zeros(len(q))
            tau[free] = pin.rnea(model, data, qr, vr, a)
            return tau
        tau = np.zeros(len(q))
        # Collocated partial feedback linearisation: the loose joints' accelerations follow
        # from the actuated ones; a swing damper offsets the pivot joints' reference by delta.
        u = np.searchsorted(free, self._loose)
        act = np.setdiff1d(np.arange(len(free)), u)
        M = pin.crba(model, data, qr)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.nonLinearEffects(model, data, qr, vr)
        Muu = M[np.ix_(u, u)]
        Mau = M[np.ix_(act, u)]
        # Swing psi: the loose joints' angle relative to their equilibrium, which moves with the
        # actuated joints (dq_eq/dq_a = -G_uu^-1 G_ua, G = dg/dq): following the pivot
        # quasi-statically is not a swing. psi'' = B a_act + ..., B = G_uu^-1 G_ua - M_uu^-1 M_ua;
        # the damper accelerates the pivot joints by -k B^T psi' (psi'' gains -k B B^T psi').
        G = pin.computeGeneralizedGravityDerivatives(model, data, qr)
        Guu = G[np.ix_(u, u)]
        B = np.linalg.solve(Guu, G[np.ix_(u, act)]) - np.linalg.solve(Muu, Mau.T)
        swing = vr[u] + np.linalg.solve(Guu, G[np.ix_(u, act)] @ vr[act])
        pivot = np.isin(free[act], self._pivot)
        push = np.where(pivot, -self.sway_damping * B.T @ swing, 0.0)
        d, dv = self._delta[free[act]], self._delta_v[free[act]]
        wr = self.swing_return
        dd = push - wr**2 * d - 2.0 * wr * dv
        h_tick = 0.0 if self._t_last is None else max(t - self._t_last, 0.0)
        self._t_last = t
        dv = dv + h_tick * dd
        d = d + h_tick * dv
        self._delta[free[act]], self._delta_v[free[act]] = d, dv
        a_act = a[act] + dd + kp * d + kd * dv
        a_u = -np.linalg.solve(Muu, Mau.T @ a_act + h[u])
        tau[free[act]] = M[np.ix_(act, act)] @ a_act + Mau @ a_u + h[act]
        return tau
