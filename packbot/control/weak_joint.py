"""A weak motor: a posture it can hold, and a move there within its reduced effort.

A weak joint j (its effort limit scaled to s E_j, a degraded motor) cannot hold a pose whose
gravity torque exceeds s E_j: the link sags however it is commanded. What still works is a
posture whose gravity torque the weakened motor holds with margin:

    minimise |p(q) - x*|^2  subject to  |g_j(q)| <= margin * s E_j,
                                     |q_i - q_i(now)| <= MAX_MOTION, q within its limits

(:func:`holdable_posture`: SLSQP from the measured state and from the unconstrained inverse
kinematics solution, over the joints that move the frame, each within ``MAX_MOTION`` of where it
is; collision-free candidates kept; with a declared payload the gravity torques are the loaded
arm's). :class:`WeakJointTracker` brakes to rest (:func:`stop_point`), then goes there by one
quintic segment, slow enough that the planned inverse-dynamics torque of the weak joint stays
within its reduced limit (or, where gravity alone exceeds it on the way, adds no more than
:data:`DYNAMIC_ALLOWANCE`), and tracks it by computed torque with the weak joint's command
clipped to its reduced limit (the others' torques those of the acceleration it then has).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control._common import DEFAULT_GRAVITY, damping_ratio, loop_frequency
from packbot.control.context import ModelSwitch
from packbot.control.ik import solve_position_ik
from packbot.control.model_based import ModelBasedController
from packbot.control.trajectory import MIN_JERK_PEAK_SPEED, QuinticSegment
from packbot.control.weak_transition import HOLD_MARGIN, Transition
from packbot.errors import ConfigurationError
from packbot.validation import finite_number

if TYPE_CHECKING:
    from packbot.control.context import RecoveryContext
    from packbot.model import Robot

__all__ = ["HOLD_MARGIN", "WeakJointTracker", "holdable_posture"]

FloatArray = NDArray[np.float64]

#: Where gravity alone exceeds the weak limit on the way, the move may add this share of the
#: limit to it [-] (a slower move adds less; the sag is then gravity's, not the plan's).
DYNAMIC_ALLOWANCE = 0.05
#: Deceleration of the braking segment before the move [rad/s^2].
STOP_DECEL = 3.0
#: Its shortest and longest duration [s].
MIN_STOP_TIME = 0.05
MAX_STOP_TIME = 1.0
#: Longest planned move [s].
MAX_MOVE_TIME = 8.0
#: Points of the straight joint-space way to the posture whose gravity torque is bounded [-].
PATH_POINTS = (0.25, 0.5, 0.75, 1.0)
#: Largest motion of a joint to the held posture [rad].
MAX_MOTION = 0.6
#: Weight of the motion to a posture against its distance from the target [cm^2/rad^2].
MOTION_WEIGHT = 1.0
#: Clearance of a held posture from collisions [m].
CLEARANCE = 0.01


def stop_point(q: FloatArray, v: FloatArray) -> tuple[FloatArray, float]:
    """Where a moving arm comes to rest by braking every joint at :data:`STOP_DECEL`.

    Returns:
        The configuration [rad] at rest and the braking time [s] (one quintic segment from
        (q, v) to rest: its mean speed half the start's).
    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    T = min(max(float(np.max(np.abs(v))) / STOP_DECEL, MIN_STOP_TIME), MAX_STOP_TIME)
    return q + 0.5 * v * T, T


def _gravity(model: pin.Model, data: pin.Data, q: FloatArray) -> FloatArray:
    return np.asarray(pin.computeGeneralizedGravity(model, data, q), dtype=float)


def holdable_posture(
    context: RecoveryContext,
    q: FloatArray,
    limits: Mapping[int, float],
    *,
    fixed: Sequence[int] = (),
    target: FloatArray | None = None,
    t: float = 0.0,
    margin: float = HOLD_MARGIN,
) -> tuple[FloatArray | None, str]:
    """The posture nearest the target whose weak joints' gravity torques are within margin.

    Args:
        context: The run's context (robot, frame, payload, obstacles, locked joints).
        q: The measured configuration [rad] (the start, and the fixed joints' angles).
        limits: Weak joint index -> its reduced effort limit [N*m].
        fixed: Joints that do not move (frozen, stuck, locked).
        target: The frame's target [m] (default: the task's final point).
        t: Time of the plan [s] (the payload held then, or later, counts).
        margin: Share of each limit the posture's gravity torque may use.

    Returns:
        The posture [rad] (None if no collision-free one holds within the margin) and a
        sentence: the frame's distance from the target [mm] and the weak joints' gravity
        torques against their limits, or why none was found.
    """
    from scipy.optimize import minimize  # lazy: scipy.optimize costs ~65 ms of import

    from packbot.collision import CollisionWorld

    robot = context.robot
    switch = ModelSwitch(context, context.gravity)
    models = [switch.at(t), switch.at(float(context.task_t[-1]))]
    model, data = models[0]
    fid = model.getFrameId(context.frame)
    x_star = context.final_point if target is None else np.asarray(target, dtype=float)
    rigid = {robot.params.index(n) for n in context.locked} | set(fixed)
    parent = model.frames[fid].parentJoint
    chain = sorted(model.joints[j].idx_q for j in model.supports[parent] if j > 0)
    active = [i for i in chain if i not in rigid]
    q = np.asarray(q, dtype=float)
    # a nearby posture: a weak arm's large moves are long and pass through loads it cannot hold
    lo = np.maximum(np.asarray(model.lowerPositionLimit)[active] + 1e-3, q[active] - MAX_MOTION)
    hi = np.minimum(np.asarray(model.upperPositionLimit)[active] - 1e-3, q[active] + MAX_MOTION)
    weak = sorted(limits)

    def full(x: FloatArray) -> FloatArray:
        qq = q.copy()
        qq[active] = x
        return qq

    def error(x: FloatArray) -> FloatArray:
        pin.framesForwardKinematics(model, data, full(x))
        return np.asarray(data.oMf[fid].translation - x_star, dtype=float)

    x_start = np.clip(q[active], lo, hi)

    def cost(x: FloatArray) -> float:
        # [cm^2], and a posture near the start preferred (1 rad of motion weighs as 1 mm)
        return float(1e4 * error(x) @ error(x) + MOTION_WEIGHT * (x - x_start) @ (x - x_start))

    g_start = np.abs(_gravity(*models[0], q))

    def slack(x: FloatArray) -> FloatArray:
        # held at the goal within the margin; on the straight joint-space way there, never
        # more than at the start (the move is quasi-statically within the weak motor's reach)
        out = []
        for s_ in PATH_POINTS:
            xs = x_start + s_ * (x - x_start)
            for mdl, dat in models:
                g = _gravity(mdl, dat, full(xs))
                for j in weak:
                    cap = margin * limits[j] if s_ == 1.0 else max(margin * limits[j], g_start[j])
                    out += [cap - g[j], cap + g[j]]
        return np.asarray(out) / max(limits.values())

    seeds = [x_start]
    ik = solve_position_ik(  # a seed: the optimisation keeps its own clearance
        model, context.frame, x_star, q, active=active, collision_free=False
    )
    seeds.append(np.clip(ik.q[active], lo, hi))
    world = CollisionWorld(robot, context.environment)
    best: tuple[float, FloatArray] | None = None
    for x0 in seeds:
        res = minimize(
            cost,
            x0,
            method="SLSQP",
            bounds=list(zip(lo, hi, strict=True)),
            constraints=[{"type": "ineq", "fun": slack}],
            options={"maxiter": 200, "ftol": 1e-10},
        )
        x = np.clip(np.asarray(res.x, dtype=float), lo, hi)
        if np.min(slack(x)) < -1e-6 or world.closest(full(x)).distance < CLEARANCE:
            continue
        c = cost(x)
        if best is None or c < best[0]:
            best = (c, x)
    if best is None:
        return None, "no collision-free posture found that the weak motor holds"
    goal = full(best[1])
    g = _gravity(*models[-1], goal)
    held = ", ".join(f"{robot.joint_names[j]} {abs(g[j]):.3g} of {limits[j]:.3g} N*m" for j in weak)
    dist = float(np.linalg.norm(error(best[1])))
    return goal, f"posture {dist * 1000:.1f} mm from the target, gravity {held}"


class WeakJointTracker(ModelBasedController):
    """Move to a held posture within a weak motor's reduced effort, then hold it.

    Args:
        context: The run's context.
        goal: The posture to reach [rad] (e.g. :func:`holdable_posture`'s).
        limits: Weak joint name -> its reduced effort limit [N*m] (its command is clipped to
            it).
        held: Joints that do not move (frozen, stuck): commanded zero, their speed taken as
            zero.
        omega: Natural frequency of the tracking loop [rad/s].
        zeta: Its damping ratio [-].
        speed_fraction: The move's peak joint rates within this fraction of the speed limits.
        dt: Control period [s].
        gravity: Gravity the controller assumes [m/s^2].
        transition: A planned move from the state at reset to ``goal``
            (:func:`packbot.control.weak_transition.plan_transition`'s), tracked instead of
            braking to rest and planning a quintic. None: those.

    Attributes:
        stop: The braking segment from the measured state to rest (set at reset; None with a
            ``transition``).
        segment: The planned move from there (set at reset; None with a ``transition``).
        transition: The planned move given.
    """

    def __init__(
        self,
        *,
        context: RecoveryContext,
        goal: FloatArray,
        limits: Mapping[str, float],
        held: Sequence[str] = (),
        omega: float = 20.0,
        zeta: float = 1.0,
        speed_fraction: float = 1.0,
        dt: float = 1e-3,
        gravity: Sequence[float] = DEFAULT_GRAVITY,
        transition: Transition | None = None,
    ) -> None:
        super().__init__(dt=dt, gravity=gravity)
        self.context = context
        self.goal = np.array(goal, dtype=float)
        if transition is not None and not isinstance(transition, Transition):
            raise ConfigurationError("transition", transition, "None or a Transition")
        self.transition = transition
        for name, lim in limits.items():
            finite_number(f"limits.{name}", lim, low=0.0, low_open=True, unit="N*m")
        self.limit_names = dict(limits)
        self.held_names = tuple(held)
        self.omega = loop_frequency(omega, "omega", self.dt)
        self.zeta = damping_ratio(zeta, "zeta")
        self.speed_fraction = finite_number(
            "speed_fraction", speed_fraction, low=0.0, high=1.0, low_open=True
        )
        self.stop: QuinticSegment | None = None
        self.segment: QuinticSegment | None = None
        self._models: ModelSwitch | None = None
        self._weak = np.zeros(0, dtype=int)
        self._limit = np.zeros(0)
        self._held = np.zeros(0, dtype=int)

    def prepare(self, robot: Robot) -> None:
        """Bind to a robot: models (with the payload), the weak and held joints."""
        super().prepare(robot)
        if self.goal.shape != (robot.nq,):
            raise ConfigurationError("goal", self.goal.shape, f"{robot.nq} angles [rad]")
        self._models = ModelSwitch(self.context, self.gravity)
        idx = robot.params.index
        self._weak = np.array([idx(n) for n in self.limit_names], dtype=int)
        self._limit = np.array(list(self.limit_names.values()), dtype=float)
        self._held = np.array(sorted(idx(n) for n in self.held_names), dtype=int)

    def on_reset(self, robot: Robot, t0: float, q0: FloatArray, v0: FloatArray) -> None:
        """Plan the move from the measured state (or take the transition given)."""
        self.prepare(robot)
        if self.transition is not None:
            self.stop = self.segment = None
            return
        q0 = np.asarray(q0, dtype=float)
        v0 = np.array(v0, dtype=float)
        v0[self._held] = 0.0
        goal = self.goal.copy()
        goal[self._held] = q0[self._held]
        q_stop, t_stop = stop_point(q0, v0)
        self.stop = QuinticSegment(q0=q0, q1=q_stop, t0=t0, duration=t_stop, v0=v0)
        self.segment = self._plan(t0 + t_stop, q_stop, np.zeros_like(v0), goal)

    def _plan(self, t0: float, q0: FloatArray, v0: FloatArray, goal: FloatArray) -> QuinticSegment:
        """The shortest move (stepped by 25 %) whose weak joints' planned torque is allowed."""
        assert self.robot is not None and self._models is not None
        model, data = self._models.at(t0)
        vmax = self.speed_fraction * self.robot.params.velocity
        T = max(0.2, float(np.max(MIN_JERK_PEAK_SPEED * np.abs(goal - q0) / vmax)))
        s = np.linspace(0.0, 1.0, 41)
        seg = QuinticSegment(q0=q0, q1=goal, t0=t0, duration=T, v0=v0)
        while T <= MAX_MOVE_TIME:
            seg = QuinticSegment(q0=q0, q1=goal, t0=t0, duration=T, v0=v0)
            ok = True
            for si in s:
                qd, vd, ad = seg(t0 + si * T)
                tau = np.asarray(pin.rnea(model, data, qd, vd, ad))[self._weak]
                g = _gravity(model, data, qd)[self._weak]
                allowed = np.maximum(self._limit, np.abs(g) + DYNAMIC_ALLOWANCE * self._limit)
                if np.any(np.abs(tau) > allowed):
                    ok = False
                    break
            if ok:
                break
            T *= 1.25
        return seg

    def compute(self, t: float, q: FloatArray, v: FloatArray) -> FloatArray:
        """Computed torque on the move, the weak joints' commands within their limits.

        Where a weak joint's torque would exceed its limit, it gets the limit and the others'
        torques are those of the acceleration it then has (row j of M a + h = tau): the other
        joints still follow their references, whatever the weak one does.
        """
        assert self._models is not None
        model, data = self._models.at(t)
        if self.transition is not None:
            qd, vd, ad = self.transition(t)
        else:
            assert self.segment is not None and self.stop is not None
            qd, vd, ad = (self.stop if t < self.stop.t1 else self.segment)(t)
        kp, kd = self.omega**2, 2 * self.zeta * self.omega
        a = ad + kp * (qd - q) + kd * (vd - v)
        vv = np.array(v, dtype=float)
        vv[self._held] = 0.0
        a[self._held] = 0.0
        qq = np.asarray(q, dtype=float)
        tau = np.array(pin.rnea(model, data, qq, vv, a), dtype=float)
        w = self._weak
        over = np.abs(tau[w]) > self._limit
        if np.any(over):
            M = pin.crba(model, data, qq)
            M = np.triu(M) + np.triu(M, 1).T
            j = w[over]
            clipped = np.clip(tau[j], -self._limit[over], self._limit[over])
            # the weak joints' accelerations that their clipped torques give
            da = np.linalg.solve(M[np.ix_(j, j)], clipped - tau[j])
            tau += M[:, j] @ da
            tau[j] = clipped
        tau[self._held] = 0.0
        return tau
