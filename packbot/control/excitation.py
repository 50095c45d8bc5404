"""Exciting trajectories for identifying the arm's inertial parameters from logged motion.

:func:`exciting_trajectory` returns an :class:`ExcitingTrajectory`: per joint j a finite Fourier
series around a centre pose c_j (Swevers et al., 1997),

    q_j(t) = c_j + sum_{k=1..K} a_jk sin(k w t) + b_jk (cos(k w t) - 1),   w = 2 pi / T_p,

with T_p the period (the duration divided by ``periods``). Two linear constraints per joint,
``sum_k k a_jk = 0`` and ``sum_k k^2 b_jk = 0``, make the velocity and the acceleration zero at
t = 0, so every period starts and ends at rest at the centre pose: a controller can move the
arm there (a :class:`~packbot.control.JointTrajectory`), then track this reference
(:class:`~packbot.control.ComputedTorque`, :class:`~packbot.control.JointPD`) for the log.

The coefficients are chosen for a well-conditioned regressor: ``candidates`` random
coefficient sets (seeded), each scaled per joint into the joint's position and velocity limits
(times ``limit_fraction``) and as a whole into the effort limits (the nominal model's inverse
dynamics plus its friction, times ``limit_fraction``); the one whose regressor (Pinocchio's
joint-torque regressor, the identifiable columns of :func:`packbot.identification.regressor`,
equilibrated) has the smallest condition number is improved by a seeded random local search
(``refine`` steps), and the first of the best candidates whose path is collision-free
(:func:`~packbot.control.check_path` over the sampled path, against the environment and the
arm's own pieces) is returned. Every figure is checked on a grid of ``check_dt`` (0.05 s):
the limits at its points (a finer grid sees the motion within the limits, and within the
fraction but for a few per mil), the collisions along the straight joint-space segments between
them, from which the trajectory departs by at most a dt^2 / 8 (0.3 mrad at 1 rad/s^2).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from packbot.control.path_check import check_path
from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.model import Robot
from packbot.validation import MAX_SAMPLES, finite_number, integer, joint_names, real_array

if TYPE_CHECKING:
    from packbot.environment import Environment

__all__ = ["ExcitingTrajectory", "exciting_trajectory"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Grid spacing [s] of the limit and conditioning checks (the regressor's samples).
CHECK_DT = 0.05
#: Largest number of harmonics per joint.
MAX_HARMONICS = 20
#: Largest number of random candidates.
MAX_CANDIDATES = 1000


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class ExcitingTrajectory:
    """A periodic Fourier-series joint trajectory (a controller's reference).

    Calling it gives (q [rad], v [rad/s], a [rad/s^2]) at time t [s], each of shape (nq,);
    before t = 0 and after :attr:`t_end` it holds :attr:`q_start` at rest.

    Attributes:
        q_start: The centre pose, where each period starts and ends at rest [rad], (nq,).
        period: The period T_p [s].
        periods: Number of periods.
        sin_coeffs: a_jk [rad], shape (nq, K).
        cos_coeffs: b_jk [rad], shape (nq, K).
        condition_number: Condition number of the equilibrated regressor on the check grid.
        peak_torque: Largest |torque| / effort limit of the nominal model on the grid [-].
        min_distance: Smallest signed distance along the path [m] (on the check grid).
    """

    q_start: FloatArray
    period: float
    periods: int
    sin_coeffs: FloatArray
    cos_coeffs: FloatArray
    condition_number: float = float("nan")
    peak_torque: float = float("nan")
    min_distance: float = float("nan")
    _k: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_k", np.arange(1, self.sin_coeffs.shape[1] + 1, dtype=float))

    @property
    def t_end(self) -> float:
        """End time [s] (``periods * period``)."""
        return float(self.periods * self.period)

    @property
    def duration(self) -> float:
        """Duration [s] (:attr:`t_end`: the trajectory starts at t = 0)."""
        return self.t_end

    def sample(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q [rad], v [rad/s], a [rad/s^2]) at the times t [s], each of shape (len(t), nq)."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        inside = (ts >= 0.0) & (ts <= self.t_end)
        w = 2.0 * np.pi / self.period
        ph = np.outer(np.where(inside, ts, 0.0), w * self._k)  # (m, K)
        s, c = np.sin(ph), np.cos(ph)
        A, B, k = self.sin_coeffs, self.cos_coeffs, self._k
        q = self.q_start + s @ A.T + (c - 1.0) @ B.T
        v = (c * (w * k)) @ A.T - (s * (w * k)) @ B.T
        a = -(s * (w * k) ** 2) @ A.T - (c * (w * k) ** 2) @ B.T
        v[~inside] = 0.0
        a[~inside] = 0.0
        return q, v, a

    def __call__(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q [rad], v [rad/s], a [rad/s^2]) at time t [s], each of shape (nq,)."""
        q, v, a = self.sample([t])
        return q[0], v[0], a[0]


def _rest_basis(K: int) -> tuple[FloatArray, FloatArray]:
    """Orthonormal bases (K, K-1) of the sine and cosine coefficients that start at rest."""
    k = np.arange(1, K + 1, dtype=float)
    out = []
    for row in (k, k**2):
        _, _, vt = np.linalg.svd(row[None, :])
        out.append(vt[1:].T)
    return out[0], out[1]


def _scale_to_limits(
    traj: ExcitingTrajectory,
    grid: FloatArray,
    amp: FloatArray,
    vmax: FloatArray,
) -> ExcitingTrajectory:
    """Scale each joint's coefficients so its motion spans amp [rad] within vmax [rad/s]."""
    q, v, _ = traj.sample(grid)
    dq = np.max(np.abs(q - traj.q_start), axis=0)
    pv = np.max(np.abs(v), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.minimum(np.where(dq > 0, amp / dq, 0.0), np.where(pv > 0, vmax / pv, 0.0))
    return _with(traj, traj.sin_coeffs * s[:, None], traj.cos_coeffs * s[:, None])


def _with(
    traj: ExcitingTrajectory, A: FloatArray, B: FloatArray, **kw: float
) -> ExcitingTrajectory:
    return ExcitingTrajectory(
        q_start=traj.q_start,
        period=traj.period,
        periods=traj.periods,
        sin_coeffs=A,
        cos_coeffs=B,
        **kw,
    )


#: The score of a candidate outside the limits.
_INF = (float("inf"), float("inf"))


class _Scorer:
    """Condition number and peak torque of a trajectory on the check grid."""

    def __init__(self, robot: Robot, grid: FloatArray, columns: NDArray[np.intp]) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.grid = grid
        self.columns = columns
        p = robot.params
        self.viscous, self.coulomb, self.effort = p.viscous, p.coulomb, p.effort

    def torque_ratio(self, traj: ExcitingTrajectory) -> float:
        q, v, a = traj.sample(self.grid)
        peak = 0.0
        for qi, vi, ai in zip(q, v, a, strict=True):
            tau = pin.rnea(self.model, self.data, qi, vi, ai)
            tau = tau + self.viscous * vi + self.coulomb * np.sign(vi)
            peak = max(peak, float(np.max(np.abs(tau) / self.effort)))
        return peak

    def condition(self, traj: ExcitingTrajectory) -> tuple[float, float]:
        """(identifiable columns not excited, condition number of the excited ones).

        The identifiable columns the motion excites (QR with column pivoting of the
        equilibrated regressor, diagonal above 1e-8 of the first): a motion that leaves joints
        still excites fewer; sorted as a tuple, a motion that excites more always wins.
        """
        from packbot.identification import regressor

        q, v, a = traj.sample(self.grid)
        W = regressor(self.robot, q, v, a)[:, self.columns]
        norms = np.linalg.norm(W, axis=0)
        live = norms > 1e-12 * max(float(norms.max()), 1e-300)
        if not np.any(live):
            return _INF
        R = scipy.linalg.qr(W[:, live] / norms[live], mode="r", pivoting=True)[0]
        d = np.abs(np.diag(R))
        r = int(np.count_nonzero(d > 1e-8 * d[0]))
        sv = np.linalg.svd(R[:r, :r], compute_uv=False)
        return float(len(self.columns) - r), float(sv[0] / sv[-1])


@checked_arguments
def exciting_trajectory(
    robot: Robot,
    duration: float,
    *,
    seed: int = 0,
    q_start: ArrayLike | str = "stand",
    joints: tuple[str, ...] | list[str] | None = None,
    periods: int = 1,
    harmonics: int = 5,
    amplitude: float = 0.6,
    limit_fraction: float = 0.8,
    candidates: int = 24,
    refine: int = 40,
    environment: Environment | None = None,
    check_dt: float = CHECK_DT,
) -> ExcitingTrajectory:
    """An exciting joint trajectory: within limits, collision-free, a well-conditioned regressor.

    Args:
        robot: The robot (its nominal model scores the candidates).
        duration: Total duration [s] (``periods`` periods).
        seed: Seed of the random candidates and of the local search (same seed, same result).
        q_start: The centre pose [rad] (shape (nq,)) or a named pose; each joint's centre is
            moved into its limits by ``amplitude`` where it is closer to one.
        joints: The joints that move (the others hold ``q_start``); None: every joint.
        periods: Number of periods (a log of several periods can be averaged).
        harmonics: Harmonics K per joint (K >= 2).
        amplitude: Largest excursion of a joint from its centre [rad].
        limit_fraction: Fraction of the position range, velocity and effort limits used [-].
        candidates: Random coefficient sets scored.
        refine: Steps of the local search from the best candidate.
        environment: Obstacles of the collision check; None: the floor.
        check_dt: Grid spacing [s] of the checks.

    Returns:
        The trajectory, with its condition number, peak torque ratio and smallest distance.

    Raises:
        ConfigurationError: A bad argument (names it, its value and what is valid), or no
            collision-free candidate (then: smaller ``amplitude``, another ``q_start`` or seed).
        UnknownNameError: An unknown joint or pose.
    """
    T = finite_number("duration", duration, low=1.0, high=3600.0, unit="s", what="a duration")
    n_per = integer("periods", periods, low=1, high=100)
    K = integer("harmonics", harmonics, low=2, high=MAX_HARMONICS)
    amp = finite_number("amplitude", amplitude, low=0.0, low_open=True, high=np.pi, unit="rad")
    frac = finite_number("limit_fraction", limit_fraction, low=0.0, low_open=True, high=1.0)
    n_cand = integer("candidates", candidates, low=1, high=MAX_CANDIDATES)
    n_ref = integer("refine", refine, low=0, high=10_000)
    dt = finite_number("check_dt", check_dt, low=1e-3, high=1.0, unit="s")
    seed_i = integer("seed", seed, low=0, high=2**63 - 1)
    if T / dt > MAX_SAMPLES:
        raise ConfigurationError("check_dt", dt, f"at least {T / MAX_SAMPLES:g} s for {T:g} s")
    p = robot.params
    n = robot.nq
    if isinstance(q_start, str):
        q0 = robot.pose(q_start)
    else:
        q0 = real_array("q_start", q_start, shape=(n,), expected=f"{n} finite angles [rad]")
    moving = joint_names("joints", joints, p.names) if joints is not None else p.names
    mask = np.array([name in moving for name in p.names])
    lo, hi = p.sampling_bounds(q0)
    margin = np.where(mask, 0.5 * (1.0 - frac) * (hi - lo), 0.0)
    half = 0.5 * (hi - lo) - margin
    excursion = np.where(mask, np.minimum(amp, half), 0.0)
    centre = np.where(mask, np.clip(q0, lo + margin + excursion, hi - margin - excursion), q0)
    vmax = frac * p.velocity
    period = T / n_per
    grid = np.arange(0.0, period + 0.5 * dt, dt)
    from packbot.identification import identifiable_columns

    scorer = _Scorer(robot, grid, identifiable_columns(robot))
    rng = np.random.default_rng(seed_i)
    bs, bc = _rest_basis(K)
    decay = 1.0 / np.arange(1, K)  # lower harmonics carry more of the motion

    def draw(scale: float = 1.0) -> tuple[FloatArray, FloatArray]:
        zs = rng.standard_normal((n, K - 1)) * decay * scale
        zc = rng.standard_normal((n, K - 1)) * decay * scale
        return zs @ bs.T, zc @ bc.T

    base = ExcitingTrajectory(
        q_start=centre,
        period=period,
        periods=n_per,
        sin_coeffs=np.zeros((n, K)),
        cos_coeffs=np.zeros((n, K)),
    )

    def fit(A: FloatArray, B: FloatArray) -> tuple[ExcitingTrajectory, tuple[float, float]]:
        traj = _scale_to_limits(_with(base, A, B), grid, excursion, vmax)
        ratio = scorer.torque_ratio(traj)
        if ratio > frac:  # torques grow about with the square of the speed: shrink until within
            for _ in range(20):
                s = 0.95 * np.sqrt(frac / ratio)
                traj = _with(traj, traj.sin_coeffs * s, traj.cos_coeffs * s)
                ratio = scorer.torque_ratio(traj)
                if ratio <= frac:
                    break
            else:
                return traj, _INF
        return traj, scorer.condition(traj)

    scored = [fit(*draw()) for _ in range(n_cand)]
    scored.sort(key=lambda x: x[1])
    best, best_c = scored[0]
    for step in range(n_ref):  # local search: perturb the best, keep improvements
        dA, dB = draw(0.3 * (1.0 - step / max(n_ref, 1)) + 0.02)
        amp_now = max(float(np.max(np.abs(best.sin_coeffs))), 1e-9)
        cand, c = fit(best.sin_coeffs + amp_now * dA, best.cos_coeffs + amp_now * dB)
        if c < best_c:
            best, best_c = cand, c
    scored.insert(0, (best, best_c))
    from packbot.collision import CollisionWorld

    world = CollisionWorld(robot, environment)
    for traj, (missing, cond) in scored:
        if not np.isfinite(missing):
            continue
        q, _, _ = traj.sample(grid)
        found = check_path(robot, q, environment, world=world)
        if found is None:
            dmin = min(float(world.sweep(qi).min_distance) for qi in q)
            log.info(
                "exciting trajectory: condition number %.3g, peak torque %.2f of the limits, "
                "closest approach %.1f mm",
                cond,
                scorer.torque_ratio(traj),
                1e3 * dmin,
            )
            return _with(
                traj,
                traj.sin_coeffs,
                traj.cos_coeffs,
                condition_number=cond,
                peak_torque=scorer.torque_ratio(traj),
                min_distance=min(dmin, world.margin),
            )
        log.debug("exciting candidate (condition %.3g) collides: %s", cond, found)
    if not any(np.isfinite(c[0]) for _, c in scored):
        raise ConfigurationError(
            "limit_fraction",
            frac,
            "a fraction of the limits some candidate fits in (none stays within the effort "
            "limits: a larger fraction, a smaller amplitude or another q_start)",
        )
    raise ConfigurationError(
        "amplitude",
        amp,
        "an amplitude [rad], a q_start or a seed with a collision-free candidate (every one of "
        f"the {n_cand + 1} collides: try a smaller amplitude)",
    )
