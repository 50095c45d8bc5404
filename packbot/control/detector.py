"""Detection of a failed joint from commanded versus measured motion: a momentum observer.

The generalized-momentum residual (De Luca and Mattone, 2003) estimates the joint torque that
the model does not explain:

    r(t) = K_O [ p(t) - p(0) - integral_0^t (tau_m + C(q, v)^T v - g(q) + r) ds ],  p = M(q) v,

which obeys r' = K_O (tau_ext - r): a first-order filter (time constant 1 / K_O) of the unexplained
torque tau_ext. The motor torque tau_m is the controller's own command, clipped to the effort
limits (what a healthy actuator applies). On a healthy arm r stays near zero (up to the sampling
error of the integral); after a failure the unexplained torque appears on the failed joint alone:

- frozen joint: the lock's constraint torque (it holds the joint against the command),
- loose joint: minus the command (the motor gives nothing),

so the residual also isolates the joint. A joint is declared failed when |r_i| exceeds
``threshold_i`` for ``persistence`` seconds without interruption; it is classified ``"frozen"``
if its measured speed stayed below ``frozen_speed`` over that window, ``"loose"`` otherwise.

Contacts with the joint-clamp law also produce joint-level constraint torques (a clamped joint
looks frozen while it stays clamped), and unmodelled friction or motor lag add residual: the
thresholds must exceed them (the reconfigurable controller's default, the friction torque of the
parameter table at the joint's speed limit plus 1 % of its effort limit, does).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import finite_number, real_array

__all__ = ["Detection", "MomentumObserver", "default_threshold"]

FloatArray = NDArray[np.float64]


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Detection:
    """A failure found by the observer.

    Attributes:
        joint: Index of the joint (into q).
        kind: ``"frozen"`` or ``"loose"``.
        t: Time of the detection [s].
        t_onset: Time the residual first exceeded the threshold [s].
        residual: The residual at detection [N*m].
    """

    joint: int
    kind: str
    t: float
    t_onset: float
    residual: float


def default_threshold(params: Any) -> FloatArray:
    """The default detection threshold per joint [N*m].

    The friction torque of the parameter table at the joint's speed limit plus 1 % of its
    effort limit.

    Args:
        params: The robot's joint parameters (``robot.params``).
    """
    return np.asarray(
        params.coulomb + params.viscous * params.velocity + 0.01 * params.effort, dtype=np.float64
    )


@checked_arguments
class MomentumObserver:
    """Generalized-momentum residual and a threshold/persistence detector.

    Args:
        model: Pinocchio model of the arm (armature and gravity set).
        effort: Effort limits [N*m], shape (nv,) (the command is clipped to them).
        gain: Observer gain K_O [1/s].
        threshold: Detection threshold per joint [N*m], shape (nv,).
        persistence: Time the residual must stay above the threshold [s].
        frozen_speed: Speed below which a detected joint is classified frozen [rad/s].
        viscous: Known viscous friction b_j [N*m*s/rad] (None: none); the observer adds
            -b_j v_j to the motor torque.
        coulomb: Known sliding Coulomb friction F_j [N*m] (None: none); -F_j sign(v_j) on a
            joint sliding faster than ``frozen_speed`` (a held joint's static friction is left
            to the threshold).
    """

    def __init__(
        self,
        model: pin.Model,
        effort: FloatArray,
        *,
        gain: float = 50.0,
        threshold: FloatArray,
        persistence: float = 0.02,
        frozen_speed: float = 1e-3,
        viscous: FloatArray | None = None,
        coulomb: FloatArray | None = None,
    ) -> None:
        for name, x, unit in (
            ("gain", gain, "1/s"),
            ("persistence", persistence, "s"),
            ("frozen_speed", frozen_speed, "rad/s"),
        ):
            finite_number(f"controller.observer_{name}", x, low=0.0, low_open=True, unit=unit)
        if not isinstance(model, pin.Model):
            raise ConfigurationError("observer.model", model, "a pinocchio.Model")
        n = model.nv
        self.model = model
        self.data = model.createData()
        self.effort = real_array(
            "observer.effort", effort, shape=(n,), expected=f"{n} finite effort limits [N*m]"
        )
        if np.any(self.effort < 0):
            raise ConfigurationError("observer.effort", effort, f"{n} effort limits >= 0 [N*m]")
        self.gain = float(gain)
        self.threshold = real_array(
            "observer.threshold", threshold, shape=(n,), expected=f"{n} finite thresholds [N*m]"
        )
        if np.any(self.threshold <= 0):
            raise ConfigurationError("observer.threshold", threshold, f"{n} thresholds > 0 [N*m]")
        self.persistence = float(persistence)
        self.frozen_speed = float(frozen_speed)
        self.viscous = (
            np.zeros(n)
            if viscous is None
            else real_array(
                "observer.viscous", viscous, shape=(n,), expected=f"{n} viscous coefficients"
            )
        )
        self.coulomb = (
            np.zeros(n)
            if coulomb is None
            else real_array(
                "observer.coulomb", coulomb, shape=(n,), expected=f"{n} Coulomb torques [N*m]"
            )
        )
        self._upper = np.triu(np.ones((n, n), dtype=bool))
        self._neg_effort = -self.effort
        self._rubs = bool(self.viscous.any() or self.coulomb.any())
        self._v_prev = np.zeros(n)
        self.residual = np.zeros(n)
        self.ignored = np.zeros(n, dtype=bool)
        self._integral = np.zeros(n)
        self._p0 = np.zeros(n)
        self._f_prev = np.zeros(n)
        self._t_prev: float | None = None
        self._onset = np.full(n, np.nan)
        self._pending = False  # some onset is set
        self._max_speed = np.zeros(n)

    def reset(self, t: float, q: FloatArray, v: FloatArray) -> None:
        """Start the observer at (q [rad], v [rad/s]) at time t [s]."""
        self._p0 = self._momentum(q, v)
        self._f_prev = self._drift(q, v)
        self._integral[:] = 0.0
        self._v_prev = np.array(v, dtype=float)
        self.residual[:] = 0.0
        self._t_prev = t
        self._onset[:] = np.nan
        self._pending = False
        self._max_speed[:] = 0.0

    def _drift(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """C(q, v)^T v - g(q) [N*m]: the momentum's rate of change besides the torques."""
        C = pin.computeCoriolisMatrix(self.model, self.data, q, v)
        return C.T @ v - pin.computeGeneralizedGravity(self.model, self.data, q)

    def _momentum(self, q: FloatArray, v: FloatArray) -> FloatArray:
        M = pin.crba(self.model, self.data, q)  # Pinocchio fills the upper triangle
        return np.where(self._upper, M, M.T) @ v

    def update(
        self, t: float, q: FloatArray, v: FloatArray, tau_prev: FloatArray
    ) -> Detection | None:
        """Advance the residual to time t with the torque held since the last update.

        Args:
            t: Time [s].
            q: Measured positions [rad].
            v: Measured velocities [rad/s].
            tau_prev: Torque commanded at the previous tick (held until now) [N*m]; entries of
                joints known to give no torque (loose) must be zero.

        Returns:
            The first new detection, or None.
        """
        if self._t_prev is None:
            self.reset(t, q, v)
            return None
        h = t - self._t_prev
        self._t_prev = t
        tau_m = np.minimum(np.maximum(tau_prev, self._neg_effort), self.effort)  # np.clip
        if self._rubs:
            # the known joint friction of a sliding joint, at the period's mean speed
            vm = 0.5 * (self._v_prev + v)
            sliding = np.abs(vm) > self.frozen_speed
            tau_m = tau_m - self.viscous * vm - np.where(sliding, self.coulomb * np.sign(vm), 0.0)
            self._v_prev = np.array(v, dtype=float)
        f = self._drift(q, v)
        # The held torque is exact over the period; the drift by the trapezoidal rule.
        self._integral += h * (tau_m + 0.5 * (f + self._f_prev) + self.residual)
        self._f_prev = f
        self.residual = r = self.gain * (self._momentum(q, v) - self._p0 - self._integral)
        over = np.abs(r) > self.threshold
        # (count_nonzero: a C call; ndarray.any goes through Python. The common case, nothing
        # over its threshold, skips the mask of the ignored joints.)
        if np.count_nonzero(over):
            over &= ~self.ignored
            quiet = not np.count_nonzero(over)
        else:
            quiet = True
        if quiet:  # nothing over its threshold: no onset pending, nothing due
            if self._pending:
                self._onset[:] = np.nan
                self._pending = False
            return None
        self._pending = True
        fresh = over & np.isnan(self._onset)
        self._onset[fresh] = t
        self._max_speed[fresh] = 0.0
        self._onset[~over] = np.nan
        self._max_speed = np.maximum(self._max_speed, np.abs(v))
        due = np.flatnonzero(over & (t - self._onset >= self.persistence - 1e-12))
        if len(due) == 0:
            return None
        j = int(due[np.argmax(np.abs(self.residual[due]) / self.threshold[due])])
        kind = "frozen" if self._max_speed[j] < self.frozen_speed else "loose"
        self.ignored[j] = True
        return Detection(
            joint=j, kind=kind, t=t, t_onset=float(self._onset[j]), residual=float(self.residual[j])
        )
