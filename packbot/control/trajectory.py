"""Joint trajectories: quintic polynomial segments, minimum-jerk between rest states.

A quintic q(s), s = (t - t0) / T in [0, 1], meets position, velocity and acceleration at both
ends. Between two rest states (zero velocity and acceleration) it is the minimum-jerk
trajectory q0 + (q1 - q0) (10 s^3 - 15 s^4 + 6 s^5), whose peak speed is 15/8 |q1 - q0| / T and
peak acceleration 10 / sqrt(3) |q1 - q0| / T^2. :class:`JointTrajectory` chains segments through
waypoints and holds the last waypoint after the end (and the first before the start).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import MAX_WAYPOINTS, at_most, finite_number, real_array

__all__ = ["JointTrajectory", "QuinticSegment", "min_jerk_duration"]

FloatArray = NDArray[np.float64]

#: Largest time of a trajectory [s] (about 11 days: beyond any run's limits).
TIME_MAX = 1e6
#: Shortest segment [s]: the fastest control period (a shorter move cannot be tracked).
DURATION_MIN = 1e-6
#: Peak speed of a rest-to-rest minimum-jerk move, in units of |q1 - q0| / T.
MIN_JERK_PEAK_SPEED = 15.0 / 8.0
#: Peak acceleration of a rest-to-rest minimum-jerk move, in units of |q1 - q0| / T^2.
MIN_JERK_PEAK_ACCEL = 10.0 / np.sqrt(3.0)


def _vec(x: ArrayLike | None, n: int, field_name: str) -> FloatArray:
    if x is None:
        return np.zeros(n)
    return real_array(field_name, x, shape=(n,), expected=f"{n} finite numbers")


def _limits(x: ArrayLike, n: int, field_name: str, none: float) -> FloatArray:
    """Joint limits: n finite numbers, or ``none`` (-inf below, +inf above) where there is none."""
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError):
        arr = None  # (real_array names it)
    if arr is None or arr.shape != (n,):
        return _vec(x, n, field_name)
    open_ = arr == none
    out = _vec(np.where(open_, 0.0, arr), n, field_name)
    out[open_] = none
    return out


@checked_arguments
@dataclass(kw_only=True)
class QuinticSegment:
    """A quintic polynomial joint trajectory from (q0, v0, a0) at t0 to (q1, v1, a1) at t0 + T.

    Attributes:
        q0: Start position [rad], shape (n,).
        q1: End position [rad], shape (n,).
        t0: Start time [s].
        duration: Duration T [s], in [1e-6, 1e6].
        v0: Start velocity [rad/s] (default zero).
        v1: End velocity [rad/s] (default zero).
        a0: Start acceleration [rad/s^2] (default zero).
        a1: End acceleration [rad/s^2] (default zero).
    """

    q0: ArrayLike
    q1: ArrayLike
    t0: float = 0.0
    duration: float = 1.0
    v0: ArrayLike | None = None
    v1: ArrayLike | None = None
    a0: ArrayLike | None = None
    a1: ArrayLike | None = None
    _c: FloatArray = field(init=False, repr=False)
    # (q, 0, 0) after the end, computed once (a controller holding the end pose asks each tick)
    _end: tuple[FloatArray, FloatArray, FloatArray] | None = field(
        init=False, repr=False, compare=False, default=None
    )

    def __post_init__(self) -> None:
        self.validate()
        T = self.duration
        q0 = np.asarray(self.q0, dtype=float)
        n = q0.shape[0]
        q1 = _vec(self.q1, n, "trajectory.q1")
        v0, v1 = _vec(self.v0, n, "trajectory.v0") * T, _vec(self.v1, n, "trajectory.v1") * T
        a0, a1 = _vec(self.a0, n, "trajectory.a0") * T**2, _vec(self.a1, n, "trajectory.a1") * T**2
        # Coefficients of q(s) = sum c_k s^k (s in [0, 1]) from the six boundary conditions.
        d = q1 - q0
        c3 = 10 * d - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
        c4 = -15 * d + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
        c5 = 6 * d - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
        self._c = np.stack([q0, v0, 0.5 * a0, c3, c4, c5])
        if not np.all(np.isfinite(self._c)):
            raise ConfigurationError(
                "trajectory",
                f"duration={T:g} s",
                "boundary values whose polynomial coefficients are finite (they overflow)",
            )

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field."""
        expected = "a non-empty vector of finite angles [rad]"
        q0 = real_array("trajectory.q0", self.q0, ndim=1, expected=expected)
        if q0.size == 0:
            raise ConfigurationError("trajectory.q0", self.q0, expected)
        for fname in ("q1", "v0", "v1", "a0", "a1"):
            _vec(getattr(self, fname), q0.shape[0], f"trajectory.{fname}")
        finite_number("trajectory.t0", self.t0, low=-TIME_MAX, high=TIME_MAX, unit="s")
        finite_number(
            "trajectory.duration",
            self.duration,
            low=DURATION_MIN,
            high=TIME_MAX,
            unit="s",
            what="a segment duration",
        )

    @property
    def t1(self) -> float:
        """End time [s]."""
        return float(self.t0 + self.duration)

    def peek(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`__call__` without the copies of the held end (the caller must not modify them).

        For a controller that reads the reference at every tick of a long hold.
        """
        end = self._end
        if end is not None and t > self.t0 + self.duration:
            return end
        return self(t)

    def __call__(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q [rad], v [rad/s], a [rad/s^2]) at time t [s]; held constant outside [t0, t1]."""
        T = self.duration
        if t <= self.t0:
            s, moving = 0.0, t == self.t0
        elif t >= self.t1:
            if t > self.t1 and self._end is not None:
                q, v, a = self._end
                return q.copy(), v.copy(), a.copy()
            s, moving = 1.0, t == self.t1
        else:
            s, moving = (t - self.t0) / T, True
        c = self._c
        q = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))))
        if not moving:
            if s == 1.0:
                self._end = (q, np.zeros_like(q), np.zeros_like(q))
            return q.copy(), np.zeros_like(q), np.zeros_like(q)
        v = c[1] + s * (2 * c[2] + s * (3 * c[3] + s * (4 * c[4] + s * 5 * c[5])))
        a = 2 * c[2] + s * (6 * c[3] + s * (12 * c[4] + s * 20 * c[5]))
        return q, v / T, a / T**2


@checked_arguments
def min_jerk_duration(
    q0: ArrayLike,
    q1: ArrayLike,
    v_max: ArrayLike,
    a_max: ArrayLike | None = None,
    *,
    minimum: float = 0.1,
) -> float:
    """Shortest rest-to-rest minimum-jerk duration [s] within speed (and acceleration) limits.

    Args:
        q0: Start [rad].
        q1: End [rad].
        v_max: Speed limits [rad/s] (> 0).
        a_max: Acceleration limits [rad/s^2] (> 0), or None.
        minimum: Lower bound of the result [s].
    """
    d = np.abs(np.asarray(q1, dtype=float) - np.asarray(q0, dtype=float))
    T = max(minimum, float(np.max(MIN_JERK_PEAK_SPEED * d / np.asarray(v_max, dtype=float))))
    if a_max is not None:
        T = max(T, float(np.max(np.sqrt(MIN_JERK_PEAK_ACCEL * d / np.asarray(a_max, dtype=float)))))
    return T


@checked_arguments
class JointTrajectory:
    """Rest-to-rest minimum-jerk segments through waypoints.

    Args:
        waypoints: Positions [rad], shape (m, n) with m >= 2.
        times: Times of the waypoints [s], shape (m,), strictly increasing.
        lower: Optional lower joint limits [rad], shape (n,): every waypoint must be within
            (-inf: none, a continuous joint).
        upper: Optional upper joint limits [rad], shape (n,) (+inf: none).
        v_max: Optional speed limits [rad/s], shape (n,): every segment's peak speed within.

    Raises:
        ConfigurationError: Bad shapes, non-increasing times, a waypoint outside the limits or a
            segment too fast (names the waypoint or segment and the joint index).
    """

    def __init__(
        self,
        waypoints: ArrayLike,
        times: Sequence[float] | ArrayLike,
        *,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
        v_max: ArrayLike | None = None,
    ) -> None:
        expected = "an (m, n) array of finite angles [rad], m >= 2, n >= 1"
        if isinstance(waypoints, (list, tuple, np.ndarray)):
            at_most("trajectory.waypoints", waypoints, len(waypoints), MAX_WAYPOINTS, "waypoints")
        W = real_array("trajectory.waypoints", waypoints, ndim=2, expected=expected)
        if W.shape[0] < 2 or W.shape[1] < 1:
            raise ConfigurationError("trajectory.waypoints", W.shape, expected)
        expected = (
            f"{W.shape[0]} increasing times [s] within +/-{TIME_MAX:g} s, at least "
            f"{DURATION_MIN:g} s apart"
        )
        ts = real_array("trajectory.times", times, shape=(W.shape[0],), expected=expected)
        if np.any(np.abs(ts) > TIME_MAX) or np.any(np.diff(ts) < DURATION_MIN):
            raise ConfigurationError("trajectory.times", ts.tolist(), expected)
        n = W.shape[1]
        for name, lim, bad in (("lower", lower, lambda w, x: w < x), ("upper", upper, np.greater)):
            if lim is None:
                continue
            lim_a = _limits(lim, n, f"trajectory.{name}", -np.inf if name == "lower" else np.inf)
            hits = np.argwhere(bad(W, lim_a[None, :]))
            if len(hits):
                k, j = hits[0]
                raise ConfigurationError(
                    f"trajectory.waypoints[{k}][{j}]",
                    W[k, j],
                    f"within the {name} limit {lim_a[j]}",
                )
        self.waypoints = W
        self.times = ts
        self.segments = [
            QuinticSegment(q0=W[k], q1=W[k + 1], t0=float(ts[k]), duration=float(ts[k + 1] - ts[k]))
            for k in range(len(ts) - 1)
        ]
        if v_max is not None:
            vm = _vec(v_max, n, "trajectory.v_max")
            for k, seg in enumerate(self.segments):
                peak = MIN_JERK_PEAK_SPEED * np.abs(W[k + 1] - W[k]) / seg.duration
                over = np.flatnonzero(peak > vm * (1 + 1e-12))
                if len(over):
                    j = int(over[0])
                    raise ConfigurationError(
                        f"trajectory.times[{k + 1}]",
                        float(ts[k + 1]),
                        f"a later time: segment {k} peaks at {peak[j]:.3g} rad/s on joint {j}, "
                        f"above its limit {vm[j]:.3g} rad/s",
                    )

    @property
    def t_end(self) -> float:
        """Time of the last waypoint [s]."""
        return float(self.times[-1])

    def __call__(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(q [rad], v [rad/s], a [rad/s^2]) at time t [s]."""
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        k = min(max(k, 0), len(self.segments) - 1)
        return self.segments[k](t)
