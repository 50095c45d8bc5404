"""A weak motor's way back to the task: a posture it holds on the target, and a move it drives.

A weak joint (its effort limit scaled to s E_j) cannot hold a pose whose gravity torque exceeds
s E_j. The arm is redundant for a position task: turret, shoulder, elbow1 and elbow2 move
``gripper_tool`` (:func:`moving_joints`; the gripper roll's axis passes through the tool point
and the camera joints are on another branch: they move masses the weak joint carries, not the
tool), so the task's final point can often be reached by another posture, one whose gravity
torques every motor holds:

    minimise |p(q) - x*|^2 + w |(q - q_now) / v_max|^2
    subject to |g_i(q)| <= margin * L_i (every working joint), q within its limits,
               smallest signed distance >= POSTURE_CLEARANCE

with L_i the limit in force (the weak joint's estimated s E_j, the others' E_j), g the loaded
arm's gravity with a declared payload, and a light weight w preferring, among postures on the
target, the one reached soonest (:func:`holdable_reach`: SLSQP with Pinocchio's gravity
derivatives, frame Jacobian and the collision world's closest pair, from several seeds: the
measured state, the unconstrained inverse kinematics solution, elbow2 folded either way).
Where no posture holds the target, the nearest holdable one is returned and says so.

Getting there is the other half. At a weak joint's detection its link is usually falling (the
motor gave out while it moved): a plain joint-space quintic from the measured state asks the
weak motor for more than it has, at the start (to stop the fall) and wherever the link is
heavy, and slowing it down does not help. What still works is the strong joints: accelerating
the weak joint's axis changes the torque its link needs. :func:`plan_transition` shapes the move
as a quintic from the measured state (q0, v0) to the posture plus ``BUMPS`` Bernstein bumps
per moving joint (zero with their slope at the start, so the start's acceleration is free, and
with their slope and curvature at the end), and chooses the bumps (SLSQP, raising the smallest
slack; analytic gradients from ``pin.computeRNEADerivatives``, the joint Jacobians and the
closest pair's witness points) so that at ``SAMPLES`` points of the move:

- every working joint's inverse-dynamics torque ``pin.rnea(q, v, a)`` (the loaded model while
  the payload is held) is within ``PATH_MARGIN`` of its limit in force (the rest is the
  tracking loop's);
- every moving joint's speed is within its limit (or the measured speed, where that is higher)
  and its angle within its limits;
- the smallest signed distance of the collision world is at least ``CLEARANCE`` (or the
  start's, if that is smaller).

The move is then checked on a grid ``CHECK_FACTOR`` times finer (torques within
``CHECK_LIMIT`` of the limits, distances within ``CHECK_DISTANCE`` of the clearance). The
duration is the shortest of a ladder (from the min-jerk time at the speed limits, each
``DURATION_RATIO`` longer, at most ``MAX_DURATIONS`` of them) that gives a move passing both.
The move, a :class:`Transition`, is tracked by
:class:`~packbot.control.weak_joint.WeakJointTracker` (computed torque with the weak joint's
command clipped to its limit, the others' torques those of the acceleration it then has).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.control.context import ModelSwitch
from packbot.control.ik import solve_position_ik

if TYPE_CHECKING:
    from packbot.collision import CollisionWorld
    from packbot.control.context import RecoveryContext

__all__ = [
    "BUMPS",
    "HOLD_MARGIN",
    "PATH_MARGIN",
    "HoldableReach",
    "PlannedMove",
    "Transition",
    "holdable_reach",
    "moving_joints",
    "plan_transition",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Share of each limit the held posture's gravity torque may use [-].
HOLD_MARGIN = 0.8
#: Share of each limit the move's planned torque may use [-] (the rest is the feedback's).
PATH_MARGIN = 0.9
#: Polynomial bumps per joint shaping the move [-].
BUMPS = 4
#: Points of the move at which torques, speeds, limits and distances are constrained [-].
SAMPLES = 17
#: The planned move is checked at this many times the samples [-] ...
CHECK_FACTOR = 4
#: ... its torques within this share of each limit [-] (under 1: the tracking's margin) ...
CHECK_LIMIT = 0.97
#: ... and its distances within this of the clearance [m].
CHECK_DISTANCE = 2e-3
#: Smallest signed distance along the move [m] ...
CLEARANCE = 0.01
#: ... and at the held posture [m] (more: the move's last stretch has room).
POSTURE_CLEARANCE = 0.02
#: The first duration tried is this times the posture's distance in time at the speed limits
#: (a min-jerk move's peak speed is 1.875 times its mean) [-] ...
SPAN_FACTOR = 1.875
#: ... then each is this ratio longer [-] ...
DURATION_RATIO = 1.25
#: ... at most this many of them [-].
MAX_DURATIONS = 4
#: Shortest and longest planned move [s].
MIN_MOVE_TIME = 0.5
MAX_MOVE_TIME = 8.0
#: A shaped move is kept if no constraint is violated by more than this [-] (5 % of a limit,
#: 0.5 mm of clearance), then checked on the fine grid (CHECK_LIMIT, CHECK_DISTANCE).
FEASIBLE_SLACK = 0.05
#: The shaping stops raising the smallest slack at this [-].
SLACK_GOAL = 0.02
#: Largest bump amplitude [rad] (a Bernstein bump's peak is under 0.4 of it).
BUMP_MAX = 6.0
#: Iterations of each shaping [-].
MAX_ITER = 60
#: Weight of a posture's distance in time from the measured state at the speed limits,
#: against its squared distance from the target [cm^2 / s^2].
MOTION_WEIGHT = 0.01
#: Scale of the posture search's objective: squared metres to squared centimetres.
COST_SCALE = 1e4


# ---------------------------------------------------------------------------------- basis
def _basis(s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The move's basis at s in [0, 1]: start terms and the posture's and bumps' terms.

    Returns:
        ``start`` (3, 2, n): the weights of q0 and of v0 T (rows: value, d/ds, d2/ds2);
        ``phi``, ``dphi``, ``ddphi`` (n, 1 + BUMPS): the posture's weight (the quintic's
        10 s^3 - 15 s^4 + 6 s^5) and the bumps, the Bernstein polynomials
        C(D, i) s^i (1 - s)^(D - i) of degree D = BUMPS + 4 for i = 2 .. BUMPS + 1 (zero with
        their slope at s = 0, with their slope and curvature at s = 1), with their derivatives.
    """
    s = np.asarray(s, dtype=float)
    key = (s.tobytes(), BUMPS)
    hit = _BASIS_CACHE.get(key)
    if hit is not None:
        return hit
    P = np.polynomial.Polynomial
    h_p0 = P([1, 0, 0, -10, 15, -6])
    h_v0 = P([0, 1, 0, -6, 8, -3])
    h_p1 = P([0, 0, 0, 10, -15, 6])
    D = BUMPS + 4
    bumps = [math.comb(D, i) * P([0, 1]) ** i * P([1, -1]) ** (D - i) for i in range(2, D - 2)]
    start = np.array([[h(s) for h in (h_p0.deriv(r), h_v0.deriv(r))] for r in (0, 1, 2)])
    cols = [h_p1, *bumps]
    phi, dphi, ddphi = (np.stack([c.deriv(r)(s) for c in cols], axis=-1) for r in (0, 1, 2))
    out = (start, phi, dphi, ddphi)
    if len(_BASIS_CACHE) > 8:
        _BASIS_CACHE.clear()
    _BASIS_CACHE[key] = out
    return out


_BASIS_CACHE: dict[tuple[bytes, int], tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = {}


@dataclass(frozen=True, kw_only=True)
class Transition:
    """A shaped quintic move from a measured state to a posture (module docstring).

    q(t) = q0 h0(s) + v0 T h1(s) + sum_k Z[:, k] phi_k(s) on the ``joints``, s = (t - t0) / T;
    the other joints stay at q0 (their v0 counted, decaying to rest as h1 does).

    Attributes:
        q0: Start configuration [rad].
        v0: Start velocity [rad/s].
        t0: Start time [s].
        duration: Duration T [s].
        joints: Indices (into q) of the joints the move shapes.
        coeffs: Z: per joint, the posture's angle [rad] then the bumps' amplitudes [rad].
    """

    q0: FloatArray
    v0: FloatArray
    t0: float
    duration: float
    joints: tuple[int, ...]
    coeffs: FloatArray
    _rest: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        q1 = np.array(self.q0, dtype=float)
        q1[list(self.joints)] = self.coeffs[:, 0]
        object.__setattr__(self, "_rest", q1)

    @property
    def goal(self) -> FloatArray:
        """The posture at the end [rad] (a copy)."""
        return self._rest.copy()

    @property
    def t1(self) -> float:
        """End time [s]."""
        return self.t0 + self.duration

    def __call__(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position [rad], velocity [rad/s] and acceleration [rad/s^2] at time t [s]."""
        if t >= self.t1:
            return self._rest.copy(), np.zeros_like(self._rest), np.zeros_like(self._rest)
        s = max((t - self.t0) / self.duration, 0.0)
        q, v, a = _states(self, np.array([s]))
        return q[0], v[0], a[0]

    def states(self, n: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The move at n evenly spaced times: times [s], q, v, a (each (n, nq))."""
        s = np.linspace(0.0, 1.0, n)
        q, v, a = _states(self, s)
        return self.t0 + s * self.duration, q, v, a


def _states(tr: Transition, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    start, phi, dphi, ddphi = _basis(s)
    T = tr.duration
    q0 = np.asarray(tr.q0, dtype=float)
    v0 = np.asarray(tr.v0, dtype=float)
    j = list(tr.joints)
    out = []
    for r, (base_phi, scale) in enumerate(((phi, 1.0), (dphi, 1.0 / T), (ddphi, 1.0 / T**2))):
        x = np.outer(start[r, 0], q0) + np.outer(start[r, 1], v0 * T)
        other = np.ones(len(q0), dtype=bool)
        other[j] = False
        # the other joints: the posture's weight times their own angle (they end where they are)
        x[:, other] += np.outer(base_phi[:, 0], q0[other])
        x[:, j] += base_phi @ tr.coeffs.T
        out.append(x * scale)
    return out[0], out[1], out[2]


# ---------------------------------------------------------------------------------- posture
@dataclass(frozen=True, kw_only=True)
class HoldableReach:
    """A posture whose gravity torques the motors hold, as near the target as they allow.

    Attributes:
        q: The posture [rad].
        error_m: The frame's distance from the target [m].
        reaches: Whether it is on the target (within ``tolerance`` of :func:`holdable_reach`).
        gravity: Its gravity torques [N*m] (the model with the payload if one is declared).
        limits: The limits in force [N*m] (the weak joints' reduced).
        margin: The share of them the gravity torques were held within.
    """

    q: FloatArray
    error_m: float
    reaches: bool
    gravity: FloatArray
    limits: FloatArray
    margin: float

    def describe(self, names: Sequence[str], weak: Sequence[int]) -> str:
        """A sentence: the distance from the target and the weak joints' torques."""
        held = ", ".join(
            f"{names[j]} {abs(self.gravity[j]):.3g} of {self.limits[j]:.3g} N*m" for j in weak
        )
        where = (
            "on the target"
            if self.reaches
            else "the target is not reachable holdably: the nearest holdable posture"
        )
        return f"{where}, {self.error_m * 1000:.1f} mm from it (gravity {held})"


@dataclass
class _Problem:
    """What the posture search and the move's optimisation share."""

    context: RecoveryContext
    world: CollisionWorld
    models: ModelSwitch
    fid: int
    active: list[int]
    actuated: list[int]
    limits: FloatArray
    lower: FloatArray
    upper: FloatArray
    target: FloatArray
    shaped: list[int]
    kin: pin.Data


def _problem(
    context: RecoveryContext,
    limits: Mapping[int, float],
    fixed: Sequence[int],
    target: FloatArray | None,
    world: CollisionWorld | None,
) -> _Problem:
    from packbot.collision import CollisionWorld

    robot = context.robot
    models = ModelSwitch(context, context.gravity)
    model = models.base[0]
    rigid = {robot.params.index(n) for n in context.locked} | {int(i) for i in fixed}
    lim = np.asarray(robot.params.effort, dtype=float).copy()
    for j, value in limits.items():
        lim[int(j)] = float(value)
    chain = moving_joints(model, model.getFrameId(context.frame))
    active = [i for i in range(model.nq) if i not in rigid and i in chain]
    actuated = [i for i in range(model.nq) if i not in rigid]
    return _Problem(
        context=context,
        world=world if world is not None else CollisionWorld(robot, context.environment),
        models=models,
        fid=model.getFrameId(context.frame),
        active=active,
        actuated=actuated,
        limits=lim,
        lower=np.asarray(model.lowerPositionLimit, dtype=float) + 1e-3,
        upper=np.asarray(model.upperPositionLimit, dtype=float) - 1e-3,
        target=(context.final_point if target is None else np.asarray(target, dtype=float)),
        shaped=active,
        kin=robot.model.createData(),
    )


def _distance_and_gradient(
    world: CollisionWorld, q: FloatArray, data: pin.Data
) -> tuple[float, FloatArray]:
    """The smallest signed distance at q [m] and its gradient [m/rad] (the closest pair's).

    Pairs farther apart than the world's margin are not resolved: the distance is then the
    margin, with a zero gradient (a constraint below the margin is inactive there).
    """
    model = world.robot.model
    near = world.contacts(q)
    grad = np.zeros(model.nv)
    if not near:
        return float(world.margin), grad
    c = near[0]
    pin.computeJointJacobians(model, data, q)
    for joint, p, sign in ((c.pair.joint1, c.p1, -1.0), (c.pair.joint2, c.p2, 1.0)):
        if joint == 0:
            continue
        J = np.asarray(pin.getJointJacobian(model, data, joint, pin.WORLD))
        Jp = J[:3] - pin.skew(np.asarray(p, dtype=float)) @ J[3:]  # the point's velocity
        grad += sign * (np.asarray(c.normal, dtype=float) @ Jp)
    return float(c.distance), grad


def _gravity_rows(
    pb: _Problem, q: FloatArray, margin: float, t: float
) -> tuple[FloatArray, FloatArray]:
    """Rows margin L_i -/+ g_i(q) of the actuated joints (scaled by L_i), and their gradient."""
    model, data = pb.models.at(t)
    g = np.asarray(pin.computeGeneralizedGravity(model, data, q), dtype=float)
    dg = np.asarray(pin.computeGeneralizedGravityDerivatives(model, data, q), dtype=float)
    a = pb.actuated
    L = pb.limits[a]
    vals = np.concatenate([(margin * L - g[a]) / L, (margin * L + g[a]) / L])
    grads = np.concatenate([-dg[a] / L[:, None], dg[a] / L[:, None]])
    return vals, grads


def holdable_reach(
    context: RecoveryContext,
    q: FloatArray,
    limits: Mapping[int, float],
    *,
    fixed: Sequence[int] = (),
    target: FloatArray | None = None,
    t: float | None = None,
    margin: float = HOLD_MARGIN,
    tolerance: float = 1e-3,
    world: CollisionWorld | None = None,
) -> list[HoldableReach]:
    """Postures nearest the target whose gravity torques every motor holds (module docstring).

    Args:
        context: The run's context (robot, frame, payload, obstacles, locked joints).
        q: The measured configuration [rad] (a seed, and the fixed joints' angles).
        limits: Joint index -> its reduced effort limit [N*m] (the weak joints); the others
            keep their effort limit.
        fixed: Joints that do not move (frozen, stuck).
        target: The frame's target [m] (default: the task's final point).
        t: Time at which the posture is held [s] (the payload then; default the task's end).
        margin: Share of each limit the gravity torques may use.
        tolerance: A posture within this of the target [m] reaches it.
        world: The collision world (default: one of the context's environment).

    Returns:
        The distinct collision-free postures found, nearest the target first and, among those
        on it, the nearest the measured state (in time at the speed limits); empty if none
        holds within the margin.
    """
    from scipy.optimize import minimize  # lazy: scipy.optimize costs ~65 ms of import

    pb = _problem(context, limits, fixed, target, world)
    t_hold = float(context.task_t[-1]) if t is None else float(t)
    model, data = pb.models.at(t_hold)
    q = np.asarray(q, dtype=float)
    a = pb.active
    lo, hi = pb.lower[a], pb.upper[a]

    def full(x: FloatArray) -> FloatArray:
        qq = q.copy()
        qq[a] = x
        return qq

    vmax = np.asarray(context.robot.params.velocity, dtype=float)[a]

    def error(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        J = pin.computeFrameJacobian(model, data, full(x), pb.fid, pin.LOCAL_WORLD_ALIGNED)
        e = np.asarray(data.oMf[pb.fid].translation, dtype=float) - pb.target
        return e, np.asarray(J)[:3, a]

    def cost(x: FloatArray) -> tuple[float, FloatArray]:
        # [cm^2], and a posture the arm reaches sooner preferred (MOTION_WEIGHT per s^2 of
        # motion at the speed limits)
        e, J = error(x)
        m = (x - q[a]) / vmax
        return (
            float(COST_SCALE * e @ e + MOTION_WEIGHT * m @ m),
            2 * COST_SCALE * (J.T @ e) + 2 * MOTION_WEIGHT * m / vmax,
        )

    def cons(x: FloatArray) -> FloatArray:
        vals, _ = _gravity_rows(pb, full(x), margin, t_hold)
        d, _ = _distance_and_gradient(pb.world, full(x), pb.kin)
        return np.append(vals, (d - POSTURE_CLEARANCE) / CLEARANCE)

    def cons_jac(x: FloatArray) -> FloatArray:
        _, grads = _gravity_rows(pb, full(x), margin, t_hold)
        _, dd = _distance_and_gradient(pb.world, full(x), pb.kin)
        return np.vstack([grads[:, a], dd[a] / CLEARANCE])

    seeds = [q[a].copy()]
    chain = list(a)
    ik = solve_position_ik(  # a seed: the optimisation keeps its own clearance
        model, context.frame, pb.target, q, active=chain, collision_free=False
    )
    seeds.append(ik.q[a])
    # the arm folded the other way at elbow2 (its link pointing up from a lower elbow): the
    # branch where a weak elbow holds the frame far out
    for flip in (-1.0, 1.0):
        s = ik.q.copy()
        j2 = chain[-1] if chain else 0
        s[j2] = np.clip(flip * abs(s[j2]) + flip * 1.5, pb.lower[j2], pb.upper[j2])
        ik2 = solve_position_ik(
            model, context.frame, pb.target, s, active=chain, collision_free=False
        )
        seeds.append(ik2.q[a])
    found: list[HoldableReach] = []
    for x0 in seeds:
        res = minimize(
            cost,
            np.clip(x0, lo, hi),
            jac=True,
            method="SLSQP",
            bounds=list(zip(lo, hi, strict=True)),
            constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
            options={"maxiter": 200, "ftol": 1e-10},
        )
        x = np.clip(np.asarray(res.x, dtype=float), lo, hi)
        if np.min(cons(x)) < -1e-4:
            continue
        qq = full(x)
        if any(np.max(np.abs(qq - h.q)) < 1e-2 for h in found):
            continue
        err = float(np.linalg.norm(error(x)[0]))
        g = np.asarray(pin.computeGeneralizedGravity(model, data, qq), dtype=float)
        found.append(
            HoldableReach(
                q=qq,
                error_m=err,
                reaches=err <= tolerance,
                gravity=g,
                limits=pb.limits.copy(),
                margin=margin,
            )
        )
    # nearest the target first; among those on it, the one the arm reaches soonest
    found.sort(
        key=lambda h: (
            0.0 if h.reaches else h.error_m,
            float(np.max(np.abs(h.q - q)[a] / vmax)),
        )
    )
    return found


def moving_joints(model: pin.Model, fid: int) -> set[int]:
    """Indices (into q) of the joints that move a frame's origin.

    The joints that carry the frame, less those whose axis passes through its origin (their
    column of the frame's position Jacobian is zero: on the PackBot, the gripper roll). The
    camera joints are on another branch: they move masses, not the frame.
    """
    data = model.createData()
    parent = model.frames[fid].parentJoint
    chain = {model.joints[j].idx_q for j in model.supports[parent] if j > 0}
    lo = np.asarray(model.lowerPositionLimit, dtype=float)
    hi = np.asarray(model.upperPositionLimit, dtype=float)
    moving: set[int] = set()
    for w in (0.3, 0.5, 0.8):  # three configurations across the joints' ranges
        q = lo + w * (hi - lo)
        J = np.asarray(pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED))
        moving |= {i for i in chain if np.linalg.norm(J[:3, i]) > 1e-9}
    return moving


# ---------------------------------------------------------------------------------- move
@dataclass
class _MoveProblem:
    """The move's constraints at one duration, as functions of the bumps (module docstring)."""

    pb: _Problem
    q0: FloatArray
    v0: FloatArray
    goal: FloatArray
    t0: float
    T: float
    vcap: FloatArray
    dmin: float
    s: FloatArray = field(default_factory=lambda: np.linspace(0.0, 1.0, SAMPLES))
    _cache: tuple[bytes, tuple[FloatArray, FloatArray]] | None = None

    def transition(self, x: FloatArray) -> Transition:
        a = self.pb.active
        z = np.zeros((len(a), 1 + BUMPS))
        z[:, 0] = self.goal[a]
        z[:, 1:] = np.asarray(x, dtype=float).reshape(len(a), BUMPS)
        return Transition(
            q0=self.q0, v0=self.v0, t0=self.t0, duration=self.T, joints=tuple(a), coeffs=z
        )

    def evaluate(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The constraints' slacks at x and their Jacobian (the last one cached).

        Rows per sample: the working joints' torques against PATH_MARGIN of their limits (as
        a share of the limit), the moving joints' speeds (a share of the cap), their angles
        against their limits [rad] and the smallest distance above ``dmin`` [cm].
        """
        key = np.asarray(x, dtype=float).tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        pb = self.pb
        a, u = pb.active, pb.actuated
        _, phi, dphi, ddphi = _basis(self.s)
        q, v, acc = _states(self.transition(x), self.s)
        T = self.T
        L = pb.limits[u]
        vc = self.vcap[a]
        nq = len(self.q0)
        sel = np.eye(nq)[:, a]
        rows: list[FloatArray] = []
        jacs: list[FloatArray] = []
        for k, sk in enumerate(self.s):
            model, data = pb.models.at(self.t0 + sk * T)
            wq, wv, wa = phi[k, 1:], dphi[k, 1:] / T, ddphi[k, 1:] / T**2
            dtq, dtv, M = pin.computeRNEADerivatives(model, data, q[k], v[k], acc[k])
            tau = np.asarray(data.tau, dtype=float)
            M = np.triu(M) + np.triu(M, 1).T
            dtau = _outer(np.asarray(dtq)[:, a], wq) + _outer(np.asarray(dtv)[:, a], wv)
            dtau += _outer(M[:, a], wa)
            rows += [(PATH_MARGIN * L - tau[u]) / L, (PATH_MARGIN * L + tau[u]) / L]
            jacs += [-dtau[u] / L[:, None], dtau[u] / L[:, None]]
            if k == 0:
                continue  # the measured state: only its acceleration is chosen
            dq_dx = _outer(sel, wq)
            dv_dx = _outer(sel, wv)
            d, dd = _distance_and_gradient(pb.world, q[k], pb.kin)
            rows += [
                (vc - v[k, a]) / vc,
                (vc + v[k, a]) / vc,
                q[k, a] - pb.lower[a],
                pb.upper[a] - q[k, a],
                np.array([(d - self.dmin) / CLEARANCE]),
            ]
            jacs += [
                -dv_dx[a] / vc[:, None],
                dv_dx[a] / vc[:, None],
                dq_dx[a],
                -dq_dx[a],
                (dd @ dq_dx)[None, :] / CLEARANCE,
            ]
        out = (np.concatenate(rows), np.vstack(jacs))
        self._cache = (key, out)
        return out


def _outer(A: FloatArray, w: FloatArray) -> FloatArray:
    """d(A q)/dx where q_j = sum_k x[j, k] w[k]: out[r, j * K + k] = A[r, j] w[k]."""
    return (A[:, :, None] * w[None, None, :]).reshape(A.shape[0], -1)


@dataclass(frozen=True, kw_only=True)
class PlannedMove:
    """The outcome of :func:`plan_transition`.

    Attributes:
        transition: The move.
        error_m: The frame's distance from the target at its end [m].
        peak_torque_ratio: Largest planned |tau_i| / L_i over the working joints (checked at
            ``CHECK_FACTOR`` times the samples) [-].
        min_distance_m: Smallest signed distance along it (same check) [m].
        tried: The durations tried [s].
    """

    transition: Transition
    error_m: float
    peak_torque_ratio: float
    min_distance_m: float
    tried: tuple[float, ...] = ()


def _shape(mp: _MoveProblem, x0: FloatArray) -> tuple[FloatArray, float]:
    """Bumps that make the move feasible: SLSQP raising the smallest slack r to ``SLACK_GOAL``.

    Maximise r subject to every constraint >= r (from x0). Returns x and its smallest slack.
    """
    from scipy.optimize import minimize

    n = len(x0)
    x = np.clip(np.asarray(x0, dtype=float), -BUMP_MAX, BUMP_MAX)
    r0 = float(np.min(mp.evaluate(x)[0]))
    if r0 >= 0.0:
        return x, r0

    def cons(y: FloatArray) -> FloatArray:
        return mp.evaluate(y[:n])[0] - y[n]

    def cons_jac(y: FloatArray) -> FloatArray:
        J = mp.evaluate(y[:n])[1]
        return np.hstack([J, -np.ones((J.shape[0], 1))])

    res = minimize(
        lambda y: (-y[n], np.append(np.zeros(n), -1.0)),
        np.append(x, r0),
        jac=True,
        method="SLSQP",
        constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
        bounds=[*([(-BUMP_MAX, BUMP_MAX)] * n), (None, SLACK_GOAL)],
        options={"maxiter": MAX_ITER, "ftol": 1e-6},
    )
    x = np.asarray(res.x[:n], dtype=float)
    slack = float(np.min(mp.evaluate(x)[0]))
    log.debug("shaping T=%.2f s: %d iterations, slack %.3g (%s)", mp.T, res.nit, slack, res.message)
    return x, slack


def _check(pb: _Problem, tr: Transition) -> tuple[float, float]:
    """The planned move's largest torque ratio and smallest distance [m], on a fine grid."""
    times, q, v, acc = tr.states(CHECK_FACTOR * (SAMPLES - 1) + 1)
    peak, dist = 0.0, math.inf
    u = pb.actuated
    for k, (t, qk, vk, ak) in enumerate(zip(times, q, v, acc, strict=True)):
        model, data = pb.models.at(float(t))
        tau = np.asarray(pin.rnea(model, data, qk, vk, ak), dtype=float)
        peak = max(peak, float(np.max(np.abs(tau[u]) / pb.limits[u])))
        if k > 0:
            dist = min(dist, float(pb.world.closest(qk).distance))
    return peak, dist


def plan_transition(
    context: RecoveryContext,
    t0: float,
    q0: FloatArray,
    v0: FloatArray,
    goals: Sequence[FloatArray],
    limits: Mapping[int, float],
    *,
    fixed: Sequence[int] = (),
    target: FloatArray | None = None,
    world: CollisionWorld | None = None,
    durations: Sequence[float] | None = None,
) -> PlannedMove | None:
    """The shortest feasible move from (q0, v0) to one of the goals (module docstring).

    Args:
        context: The run's context.
        t0: Start time [s].
        q0: Measured configuration [rad].
        v0: Measured velocity [rad/s] (the fixed joints' taken as zero).
        goals: Postures to go to (e.g. :func:`holdable_reach`'s), in order of preference; at
            each duration the first for which a feasible move is found is taken.
        limits: Joint index -> its reduced effort limit [N*m] (the weak joints).
        fixed: Joints that do not move (frozen, stuck).
        target: The frame's target [m] (default: the task's final point), for the report.
        world: The collision world (default: one of the context's environment).
        durations: The durations to try [s], shortest first (default: from the min-jerk time
            at the speed limits, ``DURATION_RATIO`` apart, ``MAX_DURATIONS`` of them, none over
            ``MAX_MOVE_TIME``).

    Returns:
        The move, or None if none of the durations gives a feasible one.
    """
    pb = _problem(context, limits, fixed, target, world)
    robot = context.robot
    q0 = np.asarray(q0, dtype=float)
    v0 = np.array(v0, dtype=float)
    v0[[i for i in range(len(q0)) if i not in pb.active]] = 0.0
    goals = [np.asarray(g, dtype=float) for g in goals]
    vmax = np.asarray(robot.params.velocity, dtype=float)
    vcap = np.maximum(vmax, 1.05 * np.abs(v0))
    dmin = min(CLEARANCE, float(pb.world.closest(q0).distance) - 1e-3)
    if durations is None:
        a = pb.active
        span = min(float(np.max(np.abs(g - q0)[a] / vmax[a])) for g in goals)
        T = max(MIN_MOVE_TIME, SPAN_FACTOR * span)
        durations = []
        while T <= MAX_MOVE_TIME and len(durations) < MAX_DURATIONS:
            durations.append(T)
            T *= DURATION_RATIO
    tried: list[float] = []
    for T in durations:
        tried.append(float(T))
        for goal in goals:
            mp = _MoveProblem(
                pb=pb, q0=q0, v0=v0, goal=goal, t0=t0, T=float(T), vcap=vcap, dmin=dmin
            )
            x, slack = _shape(mp, np.zeros(len(pb.active) * BUMPS))
            if slack < -FEASIBLE_SLACK:
                continue
            tr = mp.transition(x)
            peak, dist = _check(pb, tr)
            if peak > CHECK_LIMIT or dist < dmin - CHECK_DISTANCE:
                log.debug("T=%.2f s: fine check %.3g of a limit, %.4g m", T, peak, dist)
                continue
            return PlannedMove(
                transition=tr,
                error_m=float(np.linalg.norm(_frame(pb, goal) - pb.target)),
                peak_torque_ratio=peak,
                min_distance_m=dist,
                tried=tuple(tried),
            )
    return None


def _frame(pb: _Problem, q: FloatArray) -> FloatArray:
    model, data = pb.models.base
    pin.framesForwardKinematics(model, data, q)
    return np.asarray(data.oMf[pb.fid].translation, dtype=float).copy()
