"""Step-size control of :class:`packbot.ode.RK45Stepper`: the size of each step it tries.

The standard error control of Hairer, Norsett and Wanner, *Solving Ordinary Differential
Equations I*, 2nd ed., sec. II.4, and Hairer's stiffness test of DOPRI5, as pure functions on
floats and the stepper's arrays; the stepper keeps the control's state between steps
(:class:`ControlState`) and calls them in this order:

- :func:`initial_step`: the first step size after a (re)start without one given;
- :func:`landing`: each attempt shortened to land on ``t_end``, or stretched onto it;
- :func:`error_norm`: the attempt's scaled RMS error norm ``err`` (accepted when ``err < 1``);
- :func:`shrink_factor`: after a rejected attempt, the factor on the step size;
- :func:`next_step`: after an accepted step, the next step's size;
- :func:`stiffness_switch`: after an accepted step with a stiff kernel, whether the next steps
  are Dormand-Prince or Rosenbrock steps.

The factors are ``SAFETY * err**exponent`` clipped to ``[MIN_FACTOR, max_factor]``, with the
exponent -1/5 (:data:`ERROR_EXPONENT`) for Dormand-Prince's order-4 error estimator and -1/4
(:data:`ROS_ERROR_EXPONENT`) for the Rosenbrock step's order-3 one.

Units: times and step sizes in the units of the right-hand side's time argument (seconds in
packbot); ``atol`` in the units of ``y``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ControlState",
    "error_norm",
    "initial_step",
    "landing",
    "next_step",
    "shrink_factor",
    "stiffness_switch",
]

FloatArray = NDArray[np.float64]

#: Safety factor of the step-size controller [-].
SAFETY = 0.9
#: Smallest step-size factor after a rejection [-].
MIN_FACTOR = 0.2
#: Largest step-size growth on the first step after a (re)start [-].
MAX_FACTOR_FIRST = 5.0
#: Largest step-size growth once a step has been accepted since the last (re)start [-].
MAX_FACTOR = 10.0
#: Exponent of the error in the step-size factor: -1 / (order of the error estimator + 1).
ERROR_EXPONENT = -1.0 / 5.0
#: A step that would end within this fraction of itself before ``t_end`` is stretched onto it.
STRETCH = 0.01
#: Dormand-Prince steps count as stiff when their ``h |lambda|`` estimate exceeds this [-]
#: (the method's stability bound on the negative real axis is about 3.3; DOPRI5 uses 3.25).
STIFF_RATIO = 3.0
#: Successive stiff Dormand-Prince steps after which the stepper takes Rosenbrock steps [-].
STIFF_STEPS = 3
#: A Rosenbrock step whose next step size times its Jacobian's spectral radius is below this
#: hands back to Dormand-Prince (which is then stable at that step size) [-].
NONSTIFF_RATIO = 3.0
#: Exponent of the error in the Rosenbrock step-size factor: -1 / (embedded order 3 + 1).
ROS_ERROR_EXPONENT = -1.0 / 4.0
#: Largest step-size growth of a Rosenbrock step [-] (rodas.f's default).
ROS_MAX_FACTOR = 6.0


@dataclass(frozen=True, slots=True)
class ControlState:
    """A stepper's step-size control between two steps (:meth:`packbot.ode.RK45Stepper.control`).

    Attributes:
        h: The next step's size [s] (before the cap at ``h_max``).
        max_factor: The next step's growth cap [-] (:data:`MAX_FACTOR_FIRST` after a reset).
        stiff_run: Successive steps whose stiffness estimate exceeded :data:`STIFF_RATIO`.
        stiff: Whether the next steps are Rosenbrock steps.
        ay: ``|y|`` of the current state, shape (n,) (do not modify).
    """

    h: float
    max_factor: float
    stiff_run: int
    stiff: bool
    ay: FloatArray


def initial_step(
    rhs: Callable[[float, FloatArray], ArrayLike],
    t: float,
    y: FloatArray,
    f: FloatArray,
    ay: FloatArray,
    atol: float | FloatArray,
    rtol: float,
    h_max: float,
    inv_n: float,
) -> float:
    """Hairer's initial step size for an order-4 error estimator ("Solving ODEs I", sec. II.4).

    Calls ``rhs`` once (the caller counts it), at an explicit Euler step from (t, y).

    Args:
        rhs: Right-hand side ``rhs(t, y) -> dy/dt``.
        t: Time [s].
        y: State, shape (n,).
        f: ``rhs(t, y)``, shape (n,).
        ay: ``|y|``, shape (n,).
        atol: Absolute tolerance, scalar or shape (n,) [units of y].
        rtol: Relative tolerance [-].
        h_max: Largest step size [s].
        inv_n: ``1 / n``.

    Returns:
        The step size [s] (not capped at ``h_max``: the probe step is).
    """
    inv_sc = 1.0 / (atol + rtol * ay)
    v = y * inv_sc
    d0 = math.sqrt(float(np.dot(v, v)) * inv_n)
    v = f * inv_sc
    d1 = math.sqrt(float(np.dot(v, v)) * inv_n)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, h_max)
    f1 = np.asarray(rhs(t + h0, y + h0 * f), dtype=np.float64)
    v = (f1 - f) * inv_sc
    d2 = math.sqrt(float(np.dot(v, v)) * inv_n) / h0
    d = max(d1, d2)
    h1 = max(1e-6, h0 * 1e-3) if d <= 1e-15 else (0.01 / d) ** 0.2
    h = min(100.0 * h0, h1)
    if not math.isfinite(h):  # the probe rhs call returned inf/nan: start cautiously
        h = h0
    return h


def landing(t: float, h: float, t_end: float) -> tuple[float, float, float]:
    """An attempt of size h from t that never passes ``t_end`` nor leaves a sliver before it.

    Shortened to land exactly on ``t_end`` when it would pass it, or stretched by at most
    :data:`STRETCH` onto it (as Hairer's DOPRI5 does), else unchanged.

    Args:
        t: Start of the attempt [s].
        h: The step size the control asks for [s].
        t_end: Time [s] not to step beyond.

    Returns:
        ``(t_new, h, h_wanted)``: the attempt's end [s] and size [s], and ``h_wanted`` the size
        asked for when the attempt lands on ``t_end`` (-1.0 when it does not) [s].
    """
    t_new = t + h
    h_wanted = -1.0
    if t_new + STRETCH * h >= t_end:
        h_wanted = h
        t_new = t_end
        h = t_end - t
    return t_new, h, h_wanted


def error_norm(
    ev: FloatArray,
    ay0: FloatArray,
    ay1: FloatArray,
    rtol: float,
    atol: float | FloatArray,
    h: float,
    inv_n: float,
) -> float:
    """The scaled RMS norm of an attempt's error estimate, ``h * || ev / sc ||_rms``.

    With ``sc = atol + rtol * max(|y0|, |y1|)`` componentwise.

    Args:
        ev: The error estimate divided by h, ``sum_j e_j k_j``, shape (n,); overwritten.
        ay0: ``|y0|``, shape (n,).
        ay1: ``|y1|``, shape (n,).
        rtol: Relative tolerance [-].
        atol: Absolute tolerance, scalar or shape (n,) [units of y].
        h: The attempt's step size [s].
        inv_n: ``1 / n``.

    Returns:
        The error norm [-]: the attempt is accepted when it is < 1 (NaN: rejected).
    """
    sc = np.maximum(ay0, ay1)
    sc *= rtol
    sc += atol
    ev /= sc
    return h * math.sqrt(float(np.dot(ev, ev)) * inv_n)


def shrink_factor(err: float, exponent: float) -> float:
    """The step-size factor after a rejected attempt: ``SAFETY * err**exponent``, >= 0.2.

    Args:
        err: The attempt's error norm [-], >= 1 or NaN (then :data:`MIN_FACTOR`).
        exponent: :data:`ERROR_EXPONENT`, or :data:`ROS_ERROR_EXPONENT` for a Rosenbrock attempt.

    Returns:
        The factor [-] in [:data:`MIN_FACTOR`, 1).
    """
    fac = SAFETY * err**exponent
    if not fac > MIN_FACTOR:
        fac = MIN_FACTOR
    return fac


def next_step(
    h: float, err: float, exponent: float, max_factor: float, rejected: bool, h_wanted: float
) -> float:
    """The next step's size after an accepted step.

    ``h * SAFETY * err**exponent`` with the factor capped at ``max_factor``, and at 1 (no
    growth) after a rejected attempt of the same step. A step shortened to land on ``t_end``
    keeps the controller's proposal for the step it was before (at least ``h_wanted``).

    Args:
        h: The accepted step's size [s].
        err: Its error norm [-], in [0, 1).
        exponent: :data:`ERROR_EXPONENT`, or :data:`ROS_ERROR_EXPONENT` for a Rosenbrock step.
        max_factor: The growth cap [-]: :data:`MAX_FACTOR_FIRST` on the first step after a
            (re)start, :data:`MAX_FACTOR` after, :data:`ROS_MAX_FACTOR` for a Rosenbrock step.
        rejected: Whether an attempt of this step was rejected.
        h_wanted: The size asked for when the step was shortened onto ``t_end``, else -1.0 [s]
            (:func:`landing`).

    Returns:
        The next step's size [s] (before the cap at ``h_max``).
    """
    if err == 0.0:
        fac = max_factor
    else:
        fac = SAFETY * err**exponent
        if fac > max_factor:
            fac = max_factor
    if rejected:
        if fac > 1.0:
            fac = 1.0
    elif h_wanted > h:
        # The step was shortened to land on t_end: the controller's proposal still holds.
        h_next = h * fac
        h = h_wanted if h_wanted > h_next else h_next
        fac = 1.0
    return h * fac


def stiffness_switch(
    implicit: bool, stiff_run: int, h_next: float, estimate: float
) -> tuple[int, bool]:
    """Hairer's stiffness test of DOPRI5 after an accepted step: which kind of step is next.

    After :data:`STIFF_STEPS` successive Dormand-Prince steps whose ``h |lambda|`` estimate
    (``h ||k_7 - k_6|| / ||y_1 - y_6||``, the two stages at ``t + h``) exceeds
    :data:`STIFF_RATIO` (the explicit method held at its stability bound), the next steps are
    Rosenbrock steps, until the next step size times the Jacobian's spectral radius falls below
    :data:`NONSTIFF_RATIO`.

    Args:
        implicit: Whether the step was a Rosenbrock step.
        stiff_run: Successive stiff Dormand-Prince steps before it.
        h_next: The next step's size [s].
        estimate: After a Dormand-Prince step its ``h |lambda|`` estimate [-]; after a
            Rosenbrock step the spectral radius of its Jacobian [1/s].

    Returns:
        ``(stiff_run, stiff)``: the run after the step, and whether the next step is a
        Rosenbrock step.
    """
    if implicit:
        if h_next * estimate < NONSTIFF_RATIO:
            return 0, False
        return stiff_run, True
    if estimate > STIFF_RATIO:
        stiff_run += 1
        return stiff_run, stiff_run >= STIFF_STEPS
    return 0, False
