"""Adaptive Dormand-Prince 5(4) integrator core of the event-driven simulator.

:class:`RK45Stepper` takes one accepted step at a time of the explicit embedded Runge-Kutta
pair of Dormand and Prince (the method of MATLAB's ``ode45`` and scipy's ``RK45``): the
5th-order solution is propagated (local extrapolation), the embedded 4th-order one estimates
the local error, and the last stage is the first stage of the next step (FSAL), so that an
accepted step costs 6 right-hand-side calls. The error control is the standard one of
Hairer, Norsett and Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., sec. II.4::

    err = || (y5 - y4) / (atol + rtol * max(|y0|, |y1|)) ||_rms
    h_new = h * min(fac_max, max(0.2, 0.9 * err**(-1/5)))

with ``fac_max = 5`` for the first step after a (re)start, 10 once a step has been accepted,
and 1 (no growth) for the step accepted right after a rejection.

Every accepted step is returned as a :class:`DenseSegment`, which evaluates the 4th-order
continuous extension of the method (Shampine 1986; the same polynomial as Hairer's DOPRI5
``CONTD5`` and scipy's ``RK45`` dense output) anywhere in the step. The simulator uses it to
evaluate event functions and :func:`locate_root` to find the instant an event function
changes sign, then restarts the stepper there with :meth:`RK45Stepper.restrict` or
:meth:`RK45Stepper.reset`.

Stiff stretches: with a compiled step (``kernel``) and its linearly implicit counterpart
(:class:`StiffKernel`: a RODAS4 attempt, Hairer and Wanner, *Solving Ordinary Differential
Equations II*, 2nd ed., sec. IV.7), :meth:`RK45Stepper.step` applies Hairer's stiffness test
of DOPRI5 to the Dormand-Prince steps (``h |lambda| ~ h ||k_7 - k_6|| / ||y_1 - y_6||``, the two
stages at ``t + h``): after :data:`STIFF_STEPS` steps in a row above :data:`STIFF_RATIO`, where
the explicit method is held at its stability bound, it takes Rosenbrock steps
(:class:`HermiteSegment`: the cubic Hermite interpolant on the step's ends) until the next step
size times the Jacobian's spectral radius falls below :data:`NONSTIFF_RATIO`, or the next reset.

Why not ``scipy.integrate.RK45``: its per-step and per-construction Python overhead (hundreds
of microseconds) dominates a right-hand side that costs a few microseconds, and the simulator
restarts after every contact event. This module keeps the per-step overhead to a few dozen
numpy calls on preallocated arrays (see ``benchmarks/ode.py``).

Units: times and step sizes are in the units of the right-hand side's time argument
(seconds in packbot); ``atol`` is in the units of ``y``.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from packbot.errors import ConfigurationError, PackbotError
from packbot.step_control import (
    ERROR_EXPONENT,
    MAX_FACTOR,
    MAX_FACTOR_FIRST,
    ROS_ERROR_EXPONENT,
    ControlState,
    error_norm,
    initial_step,
    landing,
    next_step,
    shrink_factor,
    stiffness_switch,
)
from packbot.step_control import MIN_FACTOR as MIN_FACTOR  # (importable from here as before)
from packbot.step_control import NONSTIFF_RATIO as NONSTIFF_RATIO
from packbot.step_control import ROS_MAX_FACTOR as ROS_MAX_FACTOR
from packbot.step_control import SAFETY as SAFETY
from packbot.step_control import STIFF_RATIO as STIFF_RATIO
from packbot.step_control import STIFF_STEPS as STIFF_STEPS
from packbot.step_control import STRETCH as STRETCH

__all__ = [
    "ControlState",
    "DenseSegment",
    "HermiteSegment",
    "RK45Stepper",
    "StepKernel",
    "StepSizeUnderflow",
    "StiffKernel",
    "locate_earliest",
    "locate_root",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
#: Signature of a right-hand side: ``rhs(t, y) -> dy/dt`` with ``y`` and the result of shape (n,).
RHS = Callable[[float, FloatArray], ArrayLike]
#: A compiled attempt of one step, ``kernel(h, Z, ay0, atol, rtol, y1, ay1) -> err``: the six
#: stages of a Dormand-Prince step of size h on the right-hand side the stepper would call
#: (``Z`` (8, n) holds ``[y0, f(y0)]`` on entry, ``[y0, k_0, ..., k_6]`` on return), ``y1`` the
#: 5th-order solution, ``ay1 = |y1|``, and the scaled RMS error norm of :meth:`RK45Stepper.step`
#: (``atol`` of shape (n,)); a negative return: the kernel could not (the stepper calls ``rhs``).
StepKernel = Callable[
    [float, FloatArray, FloatArray, FloatArray, float, FloatArray, FloatArray], float
]


@dataclass(frozen=True, slots=True)
class StiffKernel:
    """A compiled linearly implicit step for the stiff stretches of a step kernel's problem.

    The same right-hand side as the :data:`StepKernel` it goes with (the contact-normal mode's
    native step: :class:`packbot.contact.native.NativeRhs`).

    Attributes:
        attempt: One Rosenbrock attempt, ``attempt(h, Z, ay0, atol, rtol, y1, ay1) -> err``
            with the arguments of a :data:`StepKernel`: ``Z`` holds ``[y0, f(y0)]`` on entry;
            on return ``Z[2] = y1`` and, when ``err < 1`` (accepted), ``Z[7] = f(y1)``. The
            error norm is the embedded order-3 solution's (a negative return: the kernel
            could not; the stepper takes a Dormand-Prince attempt).
        stiffness: After a :data:`StepKernel` attempt: its estimate of ``h |lambda|`` [-]
            (Hairer's test, ``h ||k_7 - k_6|| / ||y_1 - y_6||``: the two stages at ``t + h``).
        radius: After an :attr:`attempt`: the spectral radius of its Jacobian df/dy [1/s].
    """

    attempt: StepKernel
    stiffness: Callable[[], float]
    radius: Callable[[], float]


# --- Dormand-Prince 5(4) tableau ----------------------------------------------------------------
# Stage times c_i (stage 7 is at t + h: it is f(t + h, y1), the FSAL stage).
_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
# Stage coefficients a_ij; row 6 is the 5th-order weights b_j (y1 = y0 + h * sum_j b_j k_j).
_A = np.array(
    [
        [0, 0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    ],
    dtype=np.float64,
)
# Error weights e_j = b_j - b*_j (5th minus embedded 4th order): y5 - y4 = h * sum_j e_j k_j.
_E = np.array(
    [-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40],
    dtype=np.float64,
)
# Continuous extension: y(t0 + theta*h) = y0 + h * sum_j k_j * sum_m P[j, m] * theta**(m + 1).
_P = np.array(
    [
        [
            1,
            -8048581381 / 2820520608,
            8663915743 / 2820520608,
            -12715105075 / 11282082432,
        ],
        [0, 0, 0, 0],
        [
            0,
            131558114200 / 32700410799,
            -68118460800 / 10900136933,
            87487479700 / 32700410799,
        ],
        [
            0,
            -1754552775 / 470086768,
            14199869525 / 1410260304,
            -10690763975 / 1880347072,
        ],
        [
            0,
            127303824393 / 49829197408,
            -318862633887 / 49829197408,
            701980252875 / 199316789632,
        ],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ],
    dtype=np.float64,
)

# The stepper keeps the step's data in one array Z of shape (8, n): Z[0] = y0, Z[1 + i] = k_i.
# Row s of _A8 holds the coefficients of stage s's argument on Z: [1, a_s0, ..., a_s6] (after
# multiplying the a's by h), so each stage argument is one small dot product.
_A8 = np.zeros((7, 8))
_A8[:, 1:] = _A
# Dense output on Z: y(t0 + theta*h) = [1, h*theta, h*theta^2, h*theta^3, h*theta^4] @ (_P8T @ Z).
_P8T = np.zeros((5, 8))
_P8T[0, 0] = 1.0
_P8T[1:, 1:] = _P.T

#: ``RK45Stepper.f`` while it is pending (a deferred reset).
_NO_F = np.empty(0)


class StepSizeUnderflow(PackbotError):
    """The step size needed for the requested accuracy fell below the stepper's ``h_min``.

    Usually the solution has a singularity or a discontinuity near ``t`` (a contact force that
    switches on inside a step, a division by a vanishing quantity in the right-hand side), or
    the problem is stiff there.

    Attributes:
        t: Time of the last accepted step, where the stepper is stuck [s].
        h: The rejected step size that fell below ``h_min`` [s].
        h_min: The smallest step size allowed [s] (at least 10 ulps of ``t``).
    """

    def __init__(self, t: float, h: float, h_min: float) -> None:
        self.t = t
        self.h = h
        self.h_min = h_min
        super().__init__(
            f"step size underflow at t={t!r}: the error control asked for h={h:.3g} < "
            f"h_min={h_min:.3g}. The right-hand side probably has a singularity or a "
            "discontinuity near this time (make a discontinuity an event and restart there), "
            "or the problem is stiff; check the model, loosen rtol/atol, or lower h_min"
        )


class DenseSegment:
    """One accepted step [t0, t1]: y(t) for t in [t0, t1] by the continuous extension.

    The interpolant is the 4th-order continuous extension of Dormand-Prince 5(4) (a quartic in
    ``theta = (t - t0) / h``) that matches y and dy/dt = f(t, y) at both ends, so that the
    interpolants of successive steps join with continuous first derivatives. Evaluation outside
    [t0, t1] extrapolates without warning and is inaccurate.

    Attributes:
        t0: Start time of the step [s].
        t1: End time of the step [s].
        h: Step size ``t1 - t0`` [s].
        y0: State at ``t0``, shape (n,) (do not modify).
        y1: State at ``t1``, shape (n,) (do not modify).
    """

    __slots__ = ("_Q", "_Z", "_hz", "h", "t0", "t1", "y0", "y1")

    def __init__(
        self, t0: float, t1: float, h: float, y0: FloatArray, y1: FloatArray, Z: FloatArray
    ) -> None:
        """Wrap the data of a step; called by :meth:`RK45Stepper.step`.

        Args:
            t0: Start time [s].
            t1: End time [s].
            h: Step size ``t1 - t0`` [s].
            y0: State at ``t0``, shape (n,).
            y1: State at ``t1``, shape (n,).
            Z: The step's stage array, shape (8, n): ``[y0, k_0, ..., k_6]``.
        """
        self.t0 = t0
        self.t1 = t1
        self.h = h
        self.y0 = y0
        self.y1 = y1
        self._Z = Z
        self._hz = h  # the step the interpolant was built on (longer in a truncated segment)
        self._Q: FloatArray | None = None

    def truncated(self, t: float) -> DenseSegment:
        """The step cut at t: the same interpolant on [t0, t] (y1 = y(t)).

        For a step the loop keeps only up to t (a controller tick inside it changed the
        command).

        Args:
            t: Time [s] in (t0, t1].
        """
        seg = type(self)(self.t0, t, t - self.t0, self.y0, self(t), self._Z)
        seg._hz = self._hz
        seg._Q = self._Q
        return seg

    def _coefficients(self) -> FloatArray:
        """Polynomial coefficients of the interpolant, shape (5, n), computed on first use."""
        Q = self._Q
        if Q is None:
            Q = self._Q = np.dot(_P8T, self._Z)
        return Q

    def __call__(self, t: float) -> FloatArray:
        """Evaluate the interpolant.

        Args:
            t: Time [s] in [t0, t1].

        Returns:
            y(t), a new array of shape (n,). Exactly ``y0`` at ``t0`` and ``y1`` at ``t1``.
        """
        if t == self.t1:
            return self.y1.copy()
        if t == self.t0:
            return self.y0.copy()
        Q = self._Q
        if Q is None:
            Q = self._coefficients()
        h = self._hz
        th = (t - self.t0) / h
        x = h * th
        x2 = x * th
        x3 = x2 * th
        return np.dot(np.array((1.0, x, x2, x3, x3 * th)), Q)

    def derivative(self, t: float) -> FloatArray:
        """Time derivative of the interpolant (a cubic, 3rd-order accurate).

        Args:
            t: Time [s] in [t0, t1].

        Returns:
            dy/dt at ``t``, a new array of shape (n,) [units of y per s].
        """
        Q = self._Q
        if Q is None:
            Q = self._coefficients()
        th = (t - self.t0) / self._hz
        th2 = th * th
        return np.dot(np.array((0.0, 1.0, 2.0 * th, 3.0 * th2, 4.0 * th2 * th)), Q)

    def sample(self, ts: ArrayLike) -> FloatArray:
        """Evaluate the interpolant at many times at once.

        Args:
            ts: Times [s] in [t0, t1], shape (m,).

        Returns:
            Array of shape (m, n): row i is y(ts[i]).
        """
        th = (np.asarray(ts, dtype=np.float64).reshape(-1) - self.t0) / self._hz
        V = np.empty((th.size, 5))
        V[:, 0] = 1.0
        V[:, 1] = self._hz * th
        for m in range(2, 5):
            V[:, m] = V[:, m - 1] * th
        return V @ self._coefficients()

    def __repr__(self) -> str:
        return f"DenseSegment(t0={self.t0!r}, t1={self.t1!r}, n={self.y0.shape[0]})"


class HermiteSegment(DenseSegment):
    """A Rosenbrock step [t0, t1]: y(t) by the cubic Hermite interpolant on its ends.

    The cubic that matches y and dy/dt = f(t, y) at both ends (3rd-order accurate), so that it
    joins the interpolants of its neighbours (either kind) with continuous first derivatives.
    ``Z`` holds ``[y0, f(y0), y1_step, ..., f(y1_step)]`` (rows 0, 1, 2 and 7; ``y1_step``
    the full step's end, also in a truncated segment).
    """

    __slots__ = ()

    def _coefficients(self) -> FloatArray:
        """The cubic's coefficients on the basis of :class:`DenseSegment` (the quartic's 0)."""
        Q = self._Q
        if Q is None:
            Z = self._Z
            h = self._hz
            y0, f0, y1, f1 = Z[0], Z[1], Z[2], Z[7]
            Q = np.zeros((5, Z.shape[1]))
            Q[0] = y0
            Q[1] = f0
            dy = (y1 - y0) / h
            Q[2] = 3.0 * dy - 2.0 * f0 - f1
            Q[3] = f0 + f1 - 2.0 * dy
            self._Q = Q
        return Q


class RK45Stepper:
    """Dormand-Prince 5(4) stepper with error control, FSAL and dense output; forward in time.

    Usage::

        stepper = RK45Stepper(rhs, rtol=1e-8, atol=1e-10)
        stepper.reset(0.0, y0)
        while stepper.t < t_final:
            seg = stepper.step(t_final)  # one accepted step [seg.t0, seg.t1]
            ...                          # look for events in seg; maybe stepper.restrict(...)

    The stepper holds no reference to ``t_end`` between calls, so successive calls may use
    different end times (the next output time, the next scheduled event).

    Attributes:
        t: Current time [s].
        y: Current state, shape (n,) (a fresh array after every step; do not modify).
        f: ``rhs(t, y)`` at the current state, shape (n,).
        h: Size of the next step to try [s].
        rtol: Relative tolerance [-].
        atol: Absolute tolerance, scalar or shape (n,) [units of y].
        h_max: Largest step size [s] (up to 1 % more for a step stretched onto ``t_end``).
        h_min: Smallest step size [s]; below it :meth:`step` raises :class:`StepSizeUnderflow`.
        n_steps: Accepted steps, cumulative over resets.
        n_rejected: Rejected step attempts, cumulative over resets.
        n_rhs: Right-hand-side calls, cumulative over resets (a deferred one counted at its
            reset).
        f_pending: Whether ``f`` is deferred to the next step (``reset(..., defer=True)``).
        stiff: Whether the next step with a :class:`StiffKernel` is a Rosenbrock attempt
            (:meth:`step`'s ``stiff``; False after a :meth:`reset`).
        n_stiff_steps: Accepted Rosenbrock steps, cumulative over resets.
    """

    def __init__(
        self,
        rhs: RHS,
        *,
        rtol: float,
        atol: float | ArrayLike,
        h_max: float = np.inf,
        h_min: float = 1e-12,
    ) -> None:
        """Create a stepper; call :meth:`reset` to give it an initial state.

        Args:
            rhs: Right-hand side ``rhs(t, y) -> dy/dt``: a float [s] and an array of shape (n,)
                to an array-like of shape (n,). It must not keep or modify ``y``.
            rtol: Relative tolerance [-], > 0 (in practice >= 1e-13).
            atol: Absolute tolerance [units of y], >= 0, a scalar or one per component; it must
                be > 0 for a component that can be exactly 0.
            h_max: Largest step size [s], > 0.
            h_min: Smallest step size [s], >= 0.

        Raises:
            ConfigurationError: A tolerance or step bound is out of range.
        """
        if not (rtol > 0.0 and math.isfinite(rtol)):
            raise ConfigurationError("rtol", rtol, "a finite number > 0 (e.g. 1e-6)")
        atol_arr = np.array(atol, dtype=np.float64)
        if atol_arr.ndim > 1 or not np.all(atol_arr >= 0.0) or not np.all(np.isfinite(atol_arr)):
            raise ConfigurationError(
                "atol", atol, "a finite number >= 0, or an array of them of shape (n,)"
            )
        if not h_max > 0.0:
            raise ConfigurationError("h_max", h_max, "a step size > 0 [s] (np.inf for no bound)")
        if not (0.0 <= h_min < h_max):
            raise ConfigurationError("h_min", h_min, f"a step size in [0, h_max={h_max!r}) [s]")
        self._rhs = rhs
        self.rtol = float(rtol)
        self.atol: float | FloatArray = float(atol_arr) if atol_arr.ndim == 0 else atol_arr
        self.h_max = float(h_max)
        self.h_min = float(h_min)
        self.n_steps = 0
        self.n_rejected = 0
        self.n_rhs = 0
        self.t = math.nan
        self.h = math.nan
        self.y: FloatArray = np.empty(0)
        self.f: FloatArray = np.empty(0)
        self.f_pending = False
        self._n = 0
        self._inv_n = 0.0
        self._ay: FloatArray = np.empty(0)  # |y|, reused by the error norm of the next step
        self._atol_vec: FloatArray = np.empty(0)  # atol of shape (n,), for a step kernel
        self._max_factor = MAX_FACTOR_FIRST
        self.stiff = False
        self.n_stiff_steps = 0
        self._stiff_run = 0  # successive stiff Dormand-Prince steps
        # Stage-coefficient buffer Ah = [1, h * a_s] and its per-stage row views.
        self._Ah = np.empty((7, 8))
        self._rows = [self._Ah[s, : s + 1] for s in range(7)]

    def reset(self, t: float, y: ArrayLike, h: float | None = None, *, defer: bool = False) -> None:
        """Restart at (t, y): forget the FSAL stage and choose the next step size.

        Costs 1 right-hand-side call if ``h`` is given, else 2 (Hairer's initial step
        selection, "Solving ODEs I", sec. II.4). The counters keep accumulating.

        Args:
            t: Time [s].
            y: State, shape (n,); copied. The dimension may change between resets.
            h: Next step size [s], > 0, or None to choose one (capped at ``h_max``).
            defer: With ``h`` given: the derivative at (t, y) is computed by the next
                :meth:`step` (by its ``first`` stage, or ``rhs`` there), not now; ``f`` is
                pending until then. Counted now. For a caller whose right-hand side is the
                same at that step (nothing it depends on changes in between).

        Raises:
            ConfigurationError: ``y`` is not a finite 1-d array, ``atol`` does not match its
                length, or ``h`` is not > 0.
        """
        y = np.array(y, dtype=np.float64)  # a private copy
        n = y.shape[0] if y.ndim == 1 else -1
        # (a finite sum: every entry finite, the cheap test; else the exact one)
        if n < 1 or not (math.isfinite(np.add.reduce(y)) or np.all(np.isfinite(y))):
            raise ConfigurationError("y", y, "a finite 1-d array with at least one element")
        atol = self.atol
        if not isinstance(atol, float) and atol.shape != (n,):
            raise ConfigurationError("atol", atol, f"a scalar or an array of shape ({n},)")
        if h is not None and not h > 0.0:
            raise ConfigurationError("h", h, "a step size > 0 [s], or None to choose one")
        t = float(t)
        self.n_rhs += 1
        if defer and h is not None:
            self.f_pending = True
            f = _NO_F
        else:
            self.f_pending = False
            f = np.array(self._rhs(t, y), dtype=np.float64)
            if f.shape != (n,):
                raise ConfigurationError("rhs(t, y)", f.shape, f"an array of shape ({n},)")
        self.t = t
        self.y = y
        self.f = f
        self._n = n
        self._inv_n = 1.0 / n
        ay = np.abs(y)
        self._ay = ay
        self._max_factor = MAX_FACTOR_FIRST
        self.stiff = False
        self._stiff_run = 0
        if h is None:
            atol, rtol, h_max = self.atol, self.rtol, self.h_max
            h = initial_step(self._rhs, t, y, f, ay, atol, rtol, h_max, self._inv_n)
            self.n_rhs += 1  # (the probe call)
        self.h = min(float(h), self.h_max)

    def control(self) -> ControlState:
        """The step-size control's state between steps (what :meth:`take` sets after others)."""
        return ControlState(self.h, self._max_factor, self._stiff_run, self.stiff, self._ay)

    def take(
        self,
        t: float,
        y: FloatArray,
        f: FloatArray,
        ay: FloatArray,
        h: float,
        *,
        steps: int,
        rejected: int,
        rhs_calls: int,
        stiff_steps: int,
        stiff_run: int,
        stiff: bool,
        restarted: bool = False,
    ) -> None:
        """Take over the state after steps taken elsewhere with this stepper's arithmetic.

        For a compiled loop of :meth:`step` calls with a kernel (the contact-normal mode's
        stretch of quiet steps, :mod:`packbot.contact.stretch`): the state it ended at and the
        counters of its steps; afterwards the stepper goes on as if :meth:`step` had taken
        them (the next step's size, its growth cap :data:`MAX_FACTOR`, the stiffness test's
        run).

        Args:
            t: Time [s].
            y: State, shape (n,) (kept, not copied).
            f: dy/dt at (t, y), shape (n,) (kept).
            ay: ``|y|``, shape (n,) (kept).
            h: The next step's size [s], > 0.
            steps: Accepted steps taken.
            rejected: Their rejected attempts.
            rhs_calls: Their right-hand-side calls (counted as :meth:`step` counts them).
            stiff_steps: Of them Rosenbrock steps.
            stiff_run: Successive steps whose stiffness estimate exceeded :data:`STIFF_RATIO`.
            stiff: Whether the next steps are Rosenbrock steps.
            restarted: The state was changed after the last step and the stepper restarted
                there (:meth:`reset` with ``h`` and ``defer``, counted in ``rhs_calls``): ``f``
                is pending and the next step's growth cap is :data:`MAX_FACTOR_FIRST`.
        """
        if steps == 0:
            return
        self.t = t
        self.y = y
        self.f = f
        self._ay = ay
        self.h = h
        self._max_factor = MAX_FACTOR
        self.f_pending = False
        self.n_steps += steps
        self.n_rejected += rejected
        self.n_rhs += rhs_calls
        self.n_stiff_steps += stiff_steps
        self._stiff_run = stiff_run
        self.stiff = stiff
        if restarted:
            self.f_pending = True
            self.f = _NO_F
            self._max_factor = MAX_FACTOR_FIRST

    def restrict(self, t_new: float, y_new: ArrayLike) -> None:
        """Accept a truncated step: continue from (t_new, y_new), keeping the current h as a hint.

        For an event located at ``t_new`` inside the last segment; ``y_new`` is the state there,
        possibly changed by the event (an impact). Same as ``reset(t_new, y_new, h=self.h)``.

        Args:
            t_new: Time [s].
            y_new: State, shape (n,); copied.
        """
        self.reset(t_new, y_new, self.h)

    def _stages(
        self, t: float, t_new: float, h: float, Z: FloatArray
    ) -> tuple[FloatArray, FloatArray, float]:
        """One attempt's stages by ``rhs`` into Z; (y_new, |y_new|, scaled error norm).

        Z holds [y0, k_0] on entry (rows 0, 1) and every stage on return (rows 2..7).
        """
        rhs = self._rhs
        Ah = self._Ah
        r1, r2, r3, r4, r5, r6 = self._rows[1:]
        c1, c2, c3, c4, c5 = _C[1:6]
        np.multiply(_A8, h, out=Ah)
        Ah[:, 0] = 1.0
        Z[2] = rhs(t + c1 * h, np.dot(r1, Z[:2]))
        Z[3] = rhs(t + c2 * h, np.dot(r2, Z[:3]))
        Z[4] = rhs(t + c3 * h, np.dot(r3, Z[:4]))
        Z[5] = rhs(t + c4 * h, np.dot(r4, Z[:5]))
        Z[6] = rhs(t + c5 * h, np.dot(r5, Z[:6]))
        y_new = np.dot(r6, Z[:7])
        Z[7] = rhs(t_new, y_new)
        ev = np.dot(_E, Z[1:])  # the error estimate h * sum_j e_j k_j, divided by h
        ay1 = np.abs(y_new)
        return y_new, ay1, error_norm(ev, self._ay, ay1, self.rtol, self.atol, h, self._inv_n)

    def step(
        self,
        t_end: float,
        kernel: StepKernel | None = None,
        first: Callable[[FloatArray], bool] | None = None,
        stiff: StiffKernel | None = None,
    ) -> DenseSegment:
        """Take one accepted step, never beyond ``t_end``.

        The step tried is the current ``h`` (capped at ``h_max``), shortened to land exactly on
        ``t_end`` when it would pass it (or stretched by at most 1 % onto ``t_end`` to avoid a
        sliver step, as Hairer's DOPRI5 does: so a step landing on ``t_end`` may exceed ``h_max``
        by up to 1 %). A rejected attempt is retried with a smaller step.

        Args:
            t_end: Time [s] not to step beyond, > ``t``.
            kernel: A compiled version of the step's stages on the same right-hand side
                (:data:`StepKernel`; the contact-normal mode's native step), or None: the
                stages call ``rhs``. The step-size control stays here; the results agree with
                the ``rhs`` stages to rounding.
            first: With ``kernel``, when ``f`` is pending (a deferred :meth:`reset`): the
                kernel's first stage, ``first(Z) -> ok`` writing ``rhs(t, Z[0])`` into
                ``Z[1]`` with the same arithmetic as ``rhs`` (False: ``rhs`` is called instead).
            stiff: With ``kernel``, its linearly implicit counterpart (:class:`StiffKernel`),
                or None. After :data:`STIFF_STEPS` successive kernel steps whose stiffness
                estimate exceeds :data:`STIFF_RATIO` (Dormand-Prince held at its stability
                bound), the steps are Rosenbrock attempts (:class:`HermiteSegment`; error
                exponent -1/4, growth up to :data:`ROS_MAX_FACTOR`) until the next step size
                times the Jacobian's spectral radius falls below :data:`NONSTIFF_RATIO`, or
                the next :meth:`reset`.

        Returns:
            The accepted step; afterwards ``self.t == segment.t1`` and ``self.y is segment.y1``.

        Raises:
            StepSizeUnderflow: The error control asked for a step below ``h_min``; the state
                stays at the last accepted step.
            ConfigurationError: ``t_end <= t``, :meth:`reset` was never called, or ``stiff`` is
                not a :class:`StiffKernel` or comes without ``kernel``.
        """
        t = self.t
        if not t_end > t:
            if t != t:
                raise ConfigurationError("t", t, "a state: call reset(t, y) before step()")
            raise ConfigurationError("t_end", t_end, f"a time > the current time t={t!r}")
        y = self.y
        h = self.h
        if h > self.h_max:
            h = self.h_max
        n = self._n
        Z = np.empty((8, n))
        Z[0] = y
        if self.f_pending:
            self.f_pending = False
            if kernel is None or first is None or not first(Z):
                f = np.array(self._rhs(t, y), dtype=np.float64)
                if f.shape != (n,):
                    raise ConfigurationError("rhs(t, y)", f.shape, f"an array of shape ({n},)")
                Z[1] = f
            self.f = Z[1]
        else:
            Z[1] = self.f
        rtol = self.rtol
        ay0 = self._ay
        if kernel is not None:
            atol_vec = self._atol_vec
            if atol_vec.shape[0] != n:
                atol_vec = self._atol_vec = np.broadcast_to(self.atol, (n,)).astype(np.float64)
        if stiff is not None and (kernel is None or not isinstance(stiff, StiffKernel)):
            raise ConfigurationError(
                "stiff", stiff, "None, or a StiffKernel given together with its kernel"
            )
        implicit = stiff is not None and self.stiff
        expo = ROS_ERROR_EXPONENT if implicit else ERROR_EXPONENT
        rejected = False
        while True:
            t_new, h, h_wanted = landing(t, h, t_end)
            if kernel is not None:
                y_new = np.empty(n)
                ay1 = np.empty(n)
                if implicit:
                    assert stiff is not None
                    err = stiff.attempt(h, Z, ay0, atol_vec, rtol, y_new, ay1)
                    if err < 0.0:  # the kernel could not: back to Dormand-Prince
                        implicit = self.stiff = False
                        self._stiff_run = 0
                        expo = ERROR_EXPONENT
                if not implicit:
                    err = kernel(h, Z, ay0, atol_vec, rtol, y_new, ay1)
                    if err < 0.0:  # (also not: a nan error is a rejection)
                        y_new, ay1, err = self._stages(t, t_new, h, Z)
            else:
                y_new, ay1, err = self._stages(t, t_new, h, Z)
            # (a Rosenbrock attempt: 5 stages, its Jacobian's 2 n at a step's first attempt)
            self.n_rhs += (5 if rejected else 5 + 2 * n) if implicit else 6
            if err < 1.0:
                break
            # Rejected (also when err is nan: the rhs returned inf/nan).
            self.n_rejected += 1
            rejected = True
            h *= shrink_factor(err, expo)
            h_floor = max(self.h_min, 10.0 * math.ulp(t))
            if h < h_floor:
                self.h = h
                raise StepSizeUnderflow(t, h, h_floor)
        # Accepted.
        max_factor = ROS_MAX_FACTOR if implicit else self._max_factor
        self.h = next_step(h, err, expo, max_factor, rejected, h_wanted)
        self._max_factor = MAX_FACTOR
        self.n_steps += 1
        if implicit:
            self.n_stiff_steps += 1
            self.n_rhs += 1  # f(y1), the accepted attempt's last stage
            seg: DenseSegment = HermiteSegment(t, t_new, t_new - t, y, y_new, Z)
        else:
            seg = DenseSegment(t, t_new, t_new - t, y, y_new, Z)
        if stiff is not None:
            estimate = stiff.radius() if implicit else stiff.stiffness()
            self._stiff_run, self.stiff = stiffness_switch(
                implicit, self._stiff_run, self.h, estimate
            )
        self.t = t_new
        self.y = y_new
        self.f = Z[7]
        self._ay = ay1
        return seg

    def __repr__(self) -> str:
        return (
            f"RK45Stepper(t={self.t!r}, h={self.h!r}, n={self._n}, rtol={self.rtol!r}, "
            f"steps={self.n_steps}, rejected={self.n_rejected}, rhs={self.n_rhs})"
        )


#: Machine epsilon of float64.
_EPS = 2.220446049250313e-16


def brentq(
    f: Callable[[float], float],
    a: float,
    b: float,
    *,
    xtol: float = 2e-12,
    rtol: float = 4.0 * _EPS,
    maxiter: int = 100,
) -> float:
    """Brent's root finder: a line-for-line port of SciPy's ``brentq`` (``Zeros/brentq.c``).

    The same iterates as :func:`scipy.optimize.brentq` (tests compare them), without importing
    ``scipy.optimize``, which takes about 0.2 s: a one-shot run such as ``packbot run collapse``
    locates a handful of events and would spend more time importing SciPy than simulating.

    Args:
        f: Continuous scalar function with ``f(a)`` and ``f(b)`` of opposite signs.
        a: One end of the bracket.
        b: The other end.
        xtol: Absolute tolerance on the root, > 0 (the bracket shrinks to ``xtol + rtol*|x|``).
        rtol: Relative tolerance, >= 4 machine epsilons.
        maxiter: Largest number of iterations, >= 0.

    Returns:
        A root estimate (an end of the final bracket; an exact zero if one was hit).

    Raises:
        ConfigurationError: A tolerance or ``maxiter`` is out of range, or ``f(a)`` and ``f(b)``
            have the same sign, or ``f`` returns NaN.
        PackbotError: No convergence within ``maxiter`` iterations.
    """
    if not xtol > 0.0:
        raise ConfigurationError("xtol", xtol, "a tolerance > 0")
    if not rtol >= 4.0 * _EPS:
        raise ConfigurationError("rtol", rtol, f"a relative tolerance >= {4.0 * _EPS!r}")
    if maxiter < 0:
        raise ConfigurationError("maxiter", maxiter, "an iteration count >= 0")

    def call(x: float) -> float:
        v = float(f(x))
        if math.isnan(v):
            raise ConfigurationError("f(x)", v, f"a number at x={x!r}, not NaN")
        return v

    xpre, xcur = float(a), float(b)
    xblk = fblk = spre = scur = 0.0
    fpre = call(xpre)
    fcur = call(xcur)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise ConfigurationError("(f(a), f(b))", (fpre, fcur), "values of opposite signs")
    for _ in range(maxiter):
        if fpre != 0.0 and fcur != 0.0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:  # interpolate
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:  # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry  # good short step
            else:
                spre = scur = sbis  # bisect
        else:
            spre = scur = sbis  # bisect
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = call(xcur)
    raise PackbotError(f"brentq: no convergence in {maxiter} iterations (last x={xcur!r})")


def locate_root(
    g: Callable[[float], float],
    t0: float,
    t1: float,
    g0: float,
    g1: float,
    *,
    xtol: float = 1e-10,
) -> float:
    """Locate a sign change of a continuous scalar function on a bracket, from the event side.

    ``g`` goes from positive at ``t0`` to non-positive at ``t1`` (typically an event function
    evaluated on a :class:`DenseSegment`). Returns the right end ``tb`` of a final bracket
    ``[ta, tb]`` with ``g(ta) > 0 >= g(tb)`` and ``tb - ta <= xtol`` (plus rounding), found by
    :func:`brentq` (SciPy's, ported); so ``g(tb) <= 0``: the caller restarts at or just after the
    crossing, on the event side. An exact zero counts as the event side. If ``g`` has several
    sign changes in [t0, t1], one of the crossings from > 0 to <= 0 is returned, not
    necessarily the earliest.

    Args:
        g: Continuous scalar function of time.
        t0: Left end of the bracket [s].
        t1: Right end of the bracket [s], > ``t0``.
        g0: ``g(t0)``, > 0.
        g1: ``g(t1)``, <= 0.
        xtol: Width of the final bracket [s], > 0.

    Returns:
        A time ``tb`` in (t0, t1] with ``g(tb) <= 0`` and ``g > 0`` within ``xtol`` before it [s].

    Raises:
        ConfigurationError: The arguments do not bracket a sign change.
    """
    if not t1 > t0:
        raise ConfigurationError("t1", t1, f"a time > t0={t0!r}")
    if not (g0 > 0.0 >= g1):
        raise ConfigurationError(
            "(g0, g1)", (g0, g1), "g0 > 0 >= g1: a sign change of the event function on [t0, t1]"
        )
    if not xtol > 0.0:
        raise ConfigurationError("xtol", xtol, "a time tolerance > 0 [s]")
    ts: list[float] = [t0, t1]  # every point where g was evaluated, and its value
    gs: list[float] = [g0, g1]

    def g_rec(t: float) -> float:
        if t == t0:
            return g0
        if t == t1:
            v = g1
        else:
            v = float(g(t))
            ts.append(t)
            gs.append(v)
        # brentq returns at once on an exact zero; a tiny negative value keeps it bracketing.
        return v if v != 0.0 else -1e-300

    rtol = 4.0 * float(np.finfo(np.float64).eps)
    r = brentq(g_rec, t0, t1, xtol=xtol, rtol=rtol)
    # brentq returns one end of its final bracket, [ta, tb] with g(ta) > 0 >= g(tb): a bracket
    # that starts with its positive end on the left keeps it there, and no point evaluated
    # earlier lies inside it. So it is the pair of neighbouring evaluated points with a falling
    # sign change that contains r.
    order = sorted(range(len(ts)), key=ts.__getitem__)
    best = math.inf
    ta, tb = t0, t1
    for i, j in itertools.pairwise(order):
        if gs[i] > 0.0 >= gs[j]:
            dist = max(ts[i] - r, r - ts[j], 0.0)
            if dist < best:
                best, ta, tb = dist, ts[i], ts[j]
    if best > 0.0 or tb - ta > 1.000001 * (xtol + rtol * abs(tb)):  # pragma: no cover
        log.warning(
            "locate_root: final bracket [%r, %r] of width %g does not meet xtol=%g",
            ta,
            tb,
            tb - ta,
            xtol,
        )
    return tb


def locate_earliest(
    gs: Sequence[Callable[[float], float]],
    g0s: Sequence[float],
    g1s: Sequence[float],
    t0: float,
    t1: float,
    *,
    xtol: float = 1e-10,
    at_tol: float = 1e-9,
    roots: Sequence[Callable[[float, float, float, float, float], float] | None] | None = None,
) -> tuple[float, list[int]]:
    """The earliest crossing of several event functions on one step, and the ones at it.

    The result of locating every function with :func:`locate_root` (one with ``g0 <= 0`` is
    on its event side at ``t0``: its time is ``t0``), taking the earliest time ``t_star`` and
    keeping the functions whose time is at most ``t_star + at_tol``, with fewer evaluations:
    the functions are taken in the order of their chords' zeros (the linear estimate of each
    crossing), and one whose value just after the earliest time found so far (at ``t_star +
    at_tol``, inside the step) is still positive is not located: a function with one falling
    sign change on the step crosses after that point, so it is neither earlier than
    ``t_star`` nor at it. One evaluation instead of a root find (about ten) for every
    crossing that is not at the event. A function that is not excluded so is located by
    :func:`locate_root` on the whole step, as before: the times compared are the same floats.
    For a function with several sign changes on the step, :func:`locate_root` returns one
    of them, not necessarily the earliest, and the two ways may then keep different ones.

    Args:
        gs: Event functions of time, each falling to <= 0 over the step.
        g0s: Their values at ``t0`` (<= 0: on the event side at the step start).
        g1s: Their values at ``t1``, <= 0.
        t0: Start of the step [s].
        t1: End of the step [s], > ``t0``.
        xtol: Width of :func:`locate_root`'s final bracket [s], > 0.
        at_tol: How much later than the earliest crossing a crossing still counts as at it
            [s], >= 0.
        roots: Per function, None or a native root finder ``root(t0, t1, g0, g1, xtol)``
            giving :func:`locate_root`'s answer in one call (NaN: :func:`locate_root` then).

    Returns:
        ``t_star`` [s] and the positions in ``gs`` of the functions crossing at it
        (ascending).

    Raises:
        ConfigurationError: No function given, the lengths differ, ``at_tol`` < 0,
            ``xtol`` <= 0, ``t1`` <= ``t0``, or a function with ``g0 > 0`` has ``g1 > 0`` (no
            sign change to locate), whether or not it is located.
    """
    n = len(gs)
    if n == 0:
        raise ConfigurationError("gs", n, "at least one event function")
    if len(g0s) != n or len(g1s) != n:
        raise ConfigurationError("(len(g0s), len(g1s))", (len(g0s), len(g1s)), f"both {n}")
    if not at_tol >= 0.0:
        raise ConfigurationError("at_tol", at_tol, "a time tolerance >= 0 [s]")
    # (locate_root's checks, made for every function: one tested away is not located)
    if not t1 > t0:
        raise ConfigurationError("t1", t1, f"a time > t0={t0!r}")
    if not xtol > 0.0:
        raise ConfigurationError("xtol", xtol, "a time tolerance > 0 [s]")
    for i, (g0, g1) in enumerate(zip(g0s, g1s, strict=True)):
        if g0 > 0.0 and not g1 <= 0.0:
            raise ConfigurationError(
                f"(g0s[{i}], g1s[{i}])",
                (g0, g1),
                "g0 > 0 >= g1 (or g0 <= 0): a sign change of the event function on [t0, t1]",
            )
    times: list[float | None] = [None] * n
    t_star = math.inf
    pending = []
    for i, g0 in enumerate(g0s):
        if g0 <= 0.0:
            times[i] = t0  # already on the event side at the step start
            t_star = t0
        else:
            pending.append(i)
    span = t1 - t0

    def chord(i: int) -> float:
        g0, g1 = float(g0s[i]), float(g1s[i])
        return t0 + span * (g0 / (g0 - g1)) if g0 - g1 > 0.0 else t1

    for i in sorted(pending, key=chord):
        t_hi = t_star + at_tol
        if t_hi < t1 and float(gs[i](t_hi)) > 0.0:
            continue  # still before its crossing just after t_star: neither earlier nor at it
        root = roots[i] if roots is not None else None
        tc = math.nan if root is None else float(root(t0, t1, g0s[i], g1s[i], xtol))
        if math.isnan(tc):
            tc = locate_root(gs[i], t0, t1, g0s[i], g1s[i], xtol=xtol)
        times[i] = tc
        t_star = min(t_star, tc)
    bound = t_star + at_tol
    return t_star, [i for i, tc in enumerate(times) if tc is not None and tc <= bound]
