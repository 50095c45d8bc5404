"""Detection of a failed joint from commanded versus measured motion: a momentum observer.

The generalized-momentum residual (De Luca and Mattone, 2003) estimates the joint torque that
the model does not explain:

    r(t) = K_O [ p(t) - p(0) - integral_0^t (tau_m + C(q, v)^T v - g(q) + r) ds ],  p = M(q) v,

which obeys r' = K_O (tau_ext - r): a first-order filter (time constant 1 / K_O) of the unexplained
torque tau_ext. The motor torque tau_m is the controller's own command, clipped to the effort
limits (what a healthy actuator applies). On a healthy arm r stays near zero (up to the sampling
error of the integral); after a failure the unexplained torque appears on the failed joint alone,
so the residual also isolates the joint. A joint is declared failed when |r_i| exceeds
``threshold_i`` for ``persistence`` seconds without interruption.

**What the observer knows.** Everything declared about the arm enters its model, so that it is
not mistaken for a failure:

- the joints' viscous and sliding Coulomb friction (``viscous``, ``coulomb``), and the joints
  held rigid (``ignored``: never judged);
- a scheduled payload (``payload_model``, ``t_pick``, ``t_drop``): from its pick-up on, M(q),
  C and g are the model's with the payload's inertia (:func:`packbot.system.with_payload`);
  picking it up keeps the generalized momentum (as the simulator's plastic impact does), dropping
  it keeps the velocities (the momentum's jump is taken into p(0));
- contacts: the simulator knows their forces. Where it tells them (``update(...,
  tau_contact=, contact_impulse=)``: a contact-sensing controller's
  :attr:`~packbot.control.Controller.contact_torque` and ``contact_impulse``), the contacts'
  joint torque and the impacts' momentum enter the model, and the joints are judged during the
  contact too (under the report's law, the clamps' torques). Where it cannot, ``in_contact`` (a
  callable of the measured q, asked only when a residual is over its threshold) says whether
  the arm touches something: then no joint is judged, and not before ``contact_hold`` seconds
  after the last touch (five time constants: the contact's residual has decayed to 1 %). The
  suspended intervals are kept in :attr:`MomentumObserver.contact_intervals`.

**Classification.** Over the persistence window [t_onset, t] the mean unexplained torque is
estimated from the filter's own equation, tau_ext ~ mean(r) + (r(t) - r(t_onset)) / (K_O T)
(exact for a constant tau_ext, whatever the filter's lag), and the torque the motor actually gave
is a = mean(tau_m) + tau_ext. With c = mean(tau_m) the healthy motor's torque:

- ``"frozen"``: the joint's measured speed stayed below ``frozen_speed`` (a lock: a frozen joint
  or a brake that holds);
- ``"loose"``: |a| is below the joint's threshold or ``LOOSE_SHARE`` |c| (the motor gives
  nothing, up to the unmodelled part of the friction and the window's estimate);
- ``"weak"``: a has the command's sign and a smaller size; the estimated scale is |a| / E_j;
- ``"stuck"``: otherwise (the motor gives a torque of the other sign, or more than commanded);
  its estimated torque is a. Over a window of 20 ms in which the command hardly changes, a
  driver stuck at a torque of the command's sign and below it looks like a weak motor: it is
  reported weak;
- ``"brake"``: a joint flagged frozen that then moves more than ``BRAKE_SLIP`` from where it
  was locked (a brake that slipped): a second detection of that joint, with the brake torque
  estimated as |r|.

Contacts with the joint-clamp law also produce joint-level constraint torques (a clamped joint
looks frozen while it stays clamped) unless ``in_contact`` reports them; unmodelled friction or
motor lag add residual: the thresholds must exceed them (the default, the friction torque of the
parameter table at the joint's speed limit plus 1 % of its effort limit, does).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import finite_number, real_array

__all__ = ["DETECTED_KINDS", "Detection", "MomentumObserver", "default_threshold"]

FloatArray = NDArray[np.float64]

#: The kinds a detection reports.
DETECTED_KINDS: tuple[str, ...] = ("frozen", "loose", "weak", "stuck", "brake")
#: A motor giving less than this share of the healthy command (or less than the threshold) is
#: loose [-].
LOOSE_SHARE = 0.1
#: A joint flagged frozen that moves this far from its locked angle is a slipping brake [rad].
BRAKE_SLIP = 5e-3
#: Suspension after a contact, in observer time constants (the residual decays to e^-5).
CONTACT_HOLD_TIME_CONSTANTS = 5.0


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Detection:
    """A failure found by the observer.

    Attributes:
        joint: Index of the joint (into q).
        kind: One of :data:`DETECTED_KINDS`.
        t: Time of the detection [s].
        t_onset: Time the residual first exceeded the threshold [s].
        residual: The residual at detection [N*m].
        applied_nm: Estimated mean torque the motor gave over the window [N*m].
        commanded_nm: Mean healthy command (clipped to the effort limit) over the window [N*m].
        scale: ``"weak"``: the estimated effort scale |applied| / effort limit, in (0, 1]
            [-]; NaN otherwise.
        torque: ``"stuck"``: the estimated constant torque [N*m]; ``"brake"``: the estimated
            brake torque [N*m]; NaN otherwise.
        moving: Whether the joint moved over the window (faster than the frozen speed).
    """

    joint: int
    kind: str
    t: float
    t_onset: float
    residual: float
    applied_nm: float = math.nan
    commanded_nm: float = math.nan
    scale: float = math.nan
    torque: float = math.nan
    moving: bool = True

    @property
    def motion_kind(self) -> str:
        """``"frozen"`` for a joint that did not move, else ``"loose"`` (the two-way split)."""
        return "loose" if self.moving else "frozen"

    def describe(self) -> str:
        """The kind with its estimate, e.g. ``"weak (scale 0.26)"``."""
        if self.kind == "weak":
            return f"weak (scale {self.scale:.2f})"
        if self.kind in ("stuck", "brake"):
            return f"{self.kind} ({self.torque:.3g} N*m)"
        return self.kind


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
        payload_model: The model with a scheduled payload's inertia (same gravity), or None.
        t_pick: Time the payload is picked up [s] (the model's from then on).
        t_drop: Time it is dropped [s], or None.
        in_contact: Callable of the measured q [rad]: whether the arm touches something (None:
            never asked).
        contact_hold: Time after the last touch before joints are judged again [s] (None:
            :data:`CONTACT_HOLD_TIME_CONSTANTS` / gain).
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
        payload_model: pin.Model | None = None,
        t_pick: float = 0.0,
        t_drop: float | None = None,
        in_contact: Callable[[FloatArray], bool] | None = None,
        contact_hold: float | None = None,
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
        self.base_model = model
        self.base_data = model.createData()
        if payload_model is not None and (
            not isinstance(payload_model, pin.Model) or payload_model.nv != n
        ):
            raise ConfigurationError(
                "observer.payload_model", payload_model, f"None or a pinocchio.Model with nv {n}"
            )
        self.payload_model = payload_model
        self.payload_data = None if payload_model is None else payload_model.createData()
        self.t_pick = finite_number("observer.t_pick", t_pick, low=0.0, unit="s")
        self.t_drop = None if t_drop is None else finite_number("observer.t_drop", t_drop, unit="s")
        if in_contact is not None and not callable(in_contact):
            raise ConfigurationError("observer.in_contact", in_contact, "None or a callable(q)")
        self.in_contact = in_contact
        self.contact_hold = (
            CONTACT_HOLD_TIME_CONSTANTS / float(gain)
            if contact_hold is None
            else finite_number("observer.contact_hold", contact_hold, low=0.0, unit="s")
        )
        self.model, self.data = model, self.base_data
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
        #: Intervals [s] in which no joint was judged because the arm touched something.
        self.contact_intervals: list[tuple[float, float]] = []
        self._integral = np.zeros(n)
        self._p0 = np.zeros(n)
        self._f_prev = np.zeros(n)
        self._t_prev: float | None = None
        self._onset = np.full(n, np.nan)
        self._pending = False  # some onset is set
        self._max_speed = np.zeros(n)
        self._sum_r = np.zeros(n)
        self._sum_cmd = np.zeros(n)
        self._r_onset = np.zeros(n)
        self._locked_at: dict[int, float] = {}  # joints flagged frozen -> their angle
        self._contact_until = -math.inf
        self._tc_prev: FloatArray | None = None  # the last update's contact torque (known)

    # ------------------------------------------------------------------ model
    def _payload_held(self, t: float) -> bool:
        if self.payload_model is None:
            return False
        return t >= self.t_pick - 1e-12 and (self.t_drop is None or t < self.t_drop - 1e-12)

    def _select_model(self, t: float, q: FloatArray, v: FloatArray) -> None:
        """Switch to the payload's model at its pick-up and back at its drop."""
        held = self._payload_held(t)
        if held == (self.model is self.payload_model):
            return
        before = self._momentum(q, v)
        if held:
            assert self.payload_model is not None and self.payload_data is not None
            self.model, self.data = self.payload_model, self.payload_data
        else:
            self.model, self.data = self.base_model, self.base_data
        if not held:  # a drop keeps the velocities: the momentum jumps by (M_new - M_old) v
            self._p0 += self._momentum(q, v) - before
        self._f_prev = self._drift(q, v)

    def reset(self, t: float, q: FloatArray, v: FloatArray) -> None:
        """Start the observer at (q [rad], v [rad/s]) at time t [s]."""
        if self._payload_held(t):
            assert self.payload_model is not None and self.payload_data is not None
            self.model, self.data = self.payload_model, self.payload_data
        else:
            self.model, self.data = self.base_model, self.base_data
        self._p0 = self._momentum(q, v)
        self._f_prev = self._drift(q, v)
        self._integral[:] = 0.0
        self._v_prev = np.array(v, dtype=float)
        self.residual[:] = 0.0
        self._t_prev = t
        self._onset[:] = np.nan
        self._pending = False
        self._max_speed[:] = 0.0
        self._locked_at = {}
        self._tc_prev = None
        self._contact_until = -math.inf
        self.contact_intervals = []

    def _drift(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """C(q, v)^T v - g(q) [N*m]: the momentum's rate of change besides the torques."""
        C = pin.computeCoriolisMatrix(self.model, self.data, q, v)
        return C.T @ v - pin.computeGeneralizedGravity(self.model, self.data, q)

    def _momentum(self, q: FloatArray, v: FloatArray) -> FloatArray:
        M = pin.crba(self.model, self.data, q)  # Pinocchio fills the upper triangle
        return np.where(self._upper, M, M.T) @ v

    # ------------------------------------------------------------------ update
    def update(
        self,
        t: float,
        q: FloatArray,
        v: FloatArray,
        tau_prev: FloatArray,
        tau_contact: FloatArray | None = None,
        contact_impulse: FloatArray | None = None,
    ) -> Detection | None:
        """Advance the residual to time t with the torque held since the last update.

        Args:
            t: Time [s].
            q: Measured positions [rad].
            v: Measured velocities [rad/s].
            tau_prev: Torque commanded at the previous tick (held until now) [N*m]; entries of
                joints known to give no torque (loose) must be zero.
            tau_contact: The contacts' joint torque at t [N*m] (a contact-sensing
                controller's :attr:`~packbot.control.Controller.contact_torque`), or None: not
                known. Known, it enters the model (trapezoidal rule over the period) and the
                joints are judged during contact; not known, no joint is judged while the arm
                touches something (``in_contact``).
            contact_impulse: The impacts' joint impulse since the last update [N*m*s], or
                None (with ``tau_contact``: the momentum they changed enters the model).

        Returns:
            The first new detection, or None.
        """
        if self._t_prev is None:
            self.reset(t, q, v)
            return None
        h = t - self._t_prev
        self._t_prev = t
        if self.payload_model is not None:
            self._select_model(t, q, v)
        cmd = np.minimum(np.maximum(tau_prev, self._neg_effort), self.effort)  # np.clip
        tau_m = cmd
        if self._rubs:
            # the known joint friction of a sliding joint, at the period's mean speed
            vm = 0.5 * (self._v_prev + v)
            sliding = np.abs(vm) > self.frozen_speed
            tau_m = tau_m - self.viscous * vm - np.where(sliding, self.coulomb * np.sign(vm), 0.0)
            self._v_prev = np.array(v, dtype=float)
        f = self._drift(q, v)
        known = tau_contact is not None
        if known:
            tc = np.asarray(tau_contact, dtype=np.float64)
            prev = tc if self._tc_prev is None else self._tc_prev
            tau_m = tau_m + 0.5 * (tc + prev)
            self._tc_prev = tc
            if contact_impulse is not None:
                self._integral += np.asarray(contact_impulse, dtype=np.float64)
        else:
            self._tc_prev = None
        # The held torque is exact over the period; the drift by the trapezoidal rule.
        self._integral += h * (tau_m + 0.5 * (f + self._f_prev) + self.residual)
        self._f_prev = f
        self.residual = r = self.gain * (self._momentum(q, v) - self._p0 - self._integral)
        if self._locked_at:
            slipped = self._slipped(t, q)
            if slipped is not None:
                return slipped
        over = np.abs(r) > self.threshold
        # (count_nonzero: a C call; ndarray.any goes through Python. The common case, nothing
        # over its threshold, skips the mask of the ignored joints.)
        if np.count_nonzero(over):
            over &= ~self.ignored
            quiet = not np.count_nonzero(over)
        else:
            quiet = True
        # (known forces: the joints are judged, but not within contact_hold of a contact the
        # forces of which were unknown: its residual is still decaying)
        if not quiet and (t <= self._contact_until if known else self._touching(t, q)):
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
        self._sum_r[fresh] = 0.0
        self._sum_cmd[fresh] = 0.0
        self._r_onset[fresh] = r[fresh]
        self._onset[~over] = np.nan
        self._max_speed = np.maximum(self._max_speed, np.abs(v))
        grown = ~fresh  # the window's sums cover (t_onset, t]
        self._sum_r[grown] += h * r[grown]
        self._sum_cmd[grown] += h * cmd[grown]
        due = np.flatnonzero(over & (t - self._onset >= self.persistence - 1e-12))
        if len(due) == 0:
            return None
        j = int(due[np.argmax(np.abs(self.residual[due]) / self.threshold[due])])
        self.ignored[j] = True
        return self._classify(j, t, float(np.asarray(q)[j]))

    def _touching(self, t: float, q: FloatArray) -> bool:
        """Whether detection is suspended at t: the arm touches something, or did lately."""
        if self.in_contact is None:
            return False
        if self.in_contact(np.asarray(q, dtype=float)):
            if t > self._contact_until:
                self.contact_intervals.append((t, t))
            self._contact_until = t + self.contact_hold
            start = self.contact_intervals[-1][0]
            self.contact_intervals[-1] = (start, t)
            return True
        return t <= self._contact_until

    def _classify(self, j: int, t: float, angle: float) -> Detection:
        """The kind of joint j's failure from its window's torques (module docstring)."""
        onset = float(self._onset[j])
        span = max(t - onset, 1e-12)
        r = float(self.residual[j])
        ext = float(self._sum_r[j]) / span + (r - float(self._r_onset[j])) / (self.gain * span)
        cmd = float(self._sum_cmd[j]) / span
        applied = cmd + ext
        moving = bool(self._max_speed[j] >= self.frozen_speed)
        scale, torque = math.nan, math.nan
        if not moving:
            kind = "frozen"
            self._locked_at[j] = angle
        elif abs(applied) < max(float(self.threshold[j]), LOOSE_SHARE * abs(cmd)):
            kind = "loose"
        elif applied * cmd > 0 and abs(applied) < abs(cmd):
            kind = "weak"
            effort = float(self.effort[j])
            scale = min(max(abs(applied) / effort, 1e-3), 1.0) if effort > 0 else math.nan
        else:
            kind, torque = "stuck", applied
        return Detection(
            joint=j,
            kind=kind,
            t=t,
            t_onset=onset,
            residual=r,
            applied_nm=applied,
            commanded_nm=cmd,
            scale=scale,
            torque=torque,
            moving=moving,
        )

    def _slipped(self, t: float, q: FloatArray) -> Detection | None:
        """A joint flagged frozen that moved away from its locked angle: a brake."""
        for j, angle in self._locked_at.items():
            if abs(float(q[j]) - angle) > BRAKE_SLIP:
                del self._locked_at[j]
                r = float(self.residual[j])
                return Detection(
                    joint=j, kind="brake", t=t, t_onset=t, residual=r, torque=abs(r), moving=True
                )
        return None
