"""A stretch of quiet steps of the contact-normal mode in one native call.

Most of the contact-normal mode's steps find nothing to do at their end: no event, no stale
patch, no mode to change. The event loop (:mod:`packbot.integrator`) takes each in Python: the
step-size control of :meth:`packbot.ode.RK45Stepper.step` around the native Dormand-Prince
attempt, the collision sweep at the step's end, the step end's screen
(:meth:`NativeRhs.end_check <packbot.contact.native.NativeRhs.end_check>`), the regular samples
due in the step, the crawl rule and the limit stops' release
(:meth:`NormalLaw.watch <packbot.contact.normal_law.NormalLaw.watch>` and ``after_step``). The
compiled ``Stretch`` (``src/native/stretch.hpp``, in ``packbot._native``) takes those steps one
after another with the same arithmetic, calling the compiled collision sweep through its C entry
point (``src/native/sweep_api.hpp``), and stops at the first step that has something for the
law: that step comes back *pending*, a :class:`~packbot.ode.DenseSegment` the loop watches as if
the stepper had just taken it. The steps are the stepper's: Dormand-Prince attempts, or, where
the stepper's stiffness test switches, the native Rosenbrock attempts (with their cubic Hermite
dense output), and a restart's derivative left to the first step is the kernel's first stage. A
stretch also ends, its steps all kept, at the run's end, at a scheduled action, or before a step
it cannot take (the kernel refused an attempt, or the step size underflowed): the loop then
takes that step itself.

The results are those of the step-by-step loop, to rounding: the step bound's dot product and
the samples' dense output are summed in another order than numpy's (``tests/test_stretch.py``
compares the two loops). :data:`ENABLED` switches the stretch off (the step-by-step loop).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from packbot.contact import native
from packbot.ode import DenseSegment, HermiteSegment, RK45Stepper

if TYPE_CHECKING:
    from packbot.contact.normal_law import NormalLaw

__all__ = [
    "ENABLED",
    "PENDING",
    "LawInputs",
    "QuietStretch",
    "SampleClock",
    "Stretched",
    "quiet_stretch",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Whether the contact-normal mode takes its quiet steps in one native call (read at every
#: stretch; tests and benchmarks switch it off to run the step-by-step loop).
ENABLED = True

#: The native run's status for a step handed back to the loop (``src/native/stretch.hpp``).
PENDING = 1


class SampleClock(Protocol):
    """The regular samples' clock of a run (:class:`packbot.recorder.Recorder` is one)."""

    dt: float  #: the interval of the regular samples [s]
    duration: float  #: the run's duration [s]
    next_sample: int  #: the index of the next regular sample (at ``next_sample * dt``)


@dataclass(frozen=True, slots=True)
class Stretched:
    """What a stretch did.

    Attributes:
        steps: Steps taken and kept (watched and accepted: the stepper and the law are past
            them).
        samples: The states of the regular samples due in them, in order, shape (m, n): the
            samples ``next_sample`` to ``next_sample + m - 1`` of the clock given.
        pending: The step after them, taken and not yet watched (the loop goes on with it from
            :meth:`~packbot.contact.base.ContactLaw.watch`), or None.
    """

    steps: int
    samples: FloatArray
    pending: DenseSegment | None


@dataclass(frozen=True, slots=True)
class LawInputs:
    """What a stretch's step checks read of the law (:meth:`QuietStretch.run`).

    Attributes:
        active: The contact set's active pairs (their indices in the collision world).
        limits: The active limit stops, (k, 3): joint index, side (+1 upper, -1 lower), held
            (1: the stop's lock is engaged, it does not release).
        lim_value: Their positions [rad], (k,).
        crawl: The last steps' sizes [s] (the crawl rule's window, oldest first).
        min_d: The smallest signed distance of the run so far [m].
    """

    active: NDArray[np.int64]
    limits: NDArray[np.int64]
    lim_value: FloatArray
    crawl: FloatArray
    min_d: float


class QuietStretch:
    """The compiled stretch of one law's native right-hand side and collision sweep.

    Args:
        rhs: The law's native right-hand side.
        api: The compiled collision sweep's C entry point (``Sweep.api()``).
        law: The law (its reach bounds, tolerances and step bound's constants).
        stepper: The loop's stepper (its tolerances).
        clock: The run's samples.
    """

    def __init__(
        self,
        rhs: native.NativeRhs,
        api: Any,
        law: NormalLaw,
        stepper: RK45Stepper,
        clock: SampleClock,
    ) -> None:
        from packbot.contact.normal_law import CRAWL_STEP, CRAWL_STEPS
        from packbot.contact.normal_tolerances import PENETRATION_TOL

        n = 2 * law.n
        atol = np.broadcast_to(np.asarray(stepper.atol, dtype=np.float64), (n,)).copy()
        #: what it was built for (compared by identity)
        self.key: tuple[object, ...] = (rhs, api, stepper, clock)
        self._n = n
        self._run = native.stretch(
            rhs,
            api,
            margin=law.world.margin,
            atol=atol,
            rtol=stepper.rtol,
            h_min=stepper.h_min,
            near=law.cfg.proximity_tolerance,
            pen_tol=PENETRATION_TOL,
            crawl_steps=CRAWL_STEPS,
            crawl_step=CRAWL_STEP,
            sample_dt=clock.dt,
            duration=clock.duration,
            stiff_switch=native.STIFF_ENABLED,
        )

    def run(
        self,
        stepper: RK45Stepper,
        t_end: float,
        t_last: float,
        t_sched: float,
        clock: SampleClock,
        law: LawInputs,
    ) -> tuple[Stretched, dict[str, Any]]:
        """Take the quiet steps from the stepper's state.

        The law's modes and torques are loaded (its ``step_kernel`` just offered the native
        step). Afterwards the stepper is past the steps kept (and the pending step, if any, is
        its last step); the law keeps its own bookkeeping from the native call's results.

        Args:
            stepper: The loop's stepper.
            t_end: No step beyond this time [s] (the loop's step end).
            t_last: The run ends here [s].
            t_sched: The next scheduled action [s].
            clock: The run's samples (read, not advanced: the caller records them).
            law: What the steps' checks read of the law.

        Returns:
            What the stretch did, and the native call's results (a dict: ``steps``, ``hs``
            (1, steps) their sizes [s], ``min_d`` and ``min_pair`` the smallest distance so far
            and its pair if a step lowered it (else -1), ``last_pairs`` and ``last_dist`` (1, k)
            the last kept step's sweep; with a pending step ``pending_pairs``,
            ``pending_dist``, ``pending_best`` and ``pending_best_d``, its sweep).
        """
        n = self._n
        Z = np.empty((8, n))
        Z[0] = stepper.y
        pending_f = stepper.f_pending  # (the first stage computes it)
        if not pending_f:
            Z[1] = stepper.f
        ctl = stepper.control()
        ay = ctl.ay.copy()
        y_pend, ay_pend = np.empty(n), np.empty(n)
        out = self._run.run(
            pending_f,
            Z,
            ay,
            stepper.t,
            ctl.h,
            ctl.max_factor,
            ctl.stiff_run,
            ctl.stiff,
            clock.next_sample,
            law.min_d,
            t_end,
            t_last,
            t_sched,
            law.active,
            law.limits,
            law.lim_value,
            law.crawl,
            y_pend,
            ay_pend,
        )
        status, steps = out["status"], out["steps"]
        pending = status == PENDING
        if steps:
            stepper.take(
                out["t"],
                Z[0].copy(),
                Z[1].copy(),
                ay.copy() if pending else ay,
                out["h"],
                steps=steps,
                rejected=out["rejected"],
                rhs_calls=out["rhs_calls"],
                stiff_steps=out["stiff_steps"],
                stiff_run=out["stiff_run"],
                stiff=out["stiff"],
            )
        if steps or pending:
            stepper.h_max = out["h_max"]  # (the last step's bound, as the loop set it for it)
        seg = None
        if pending:
            t0, t1 = out["t0"], out["t1"]
            implicit = out["pending_implicit"]
            kind = HermiteSegment if implicit else DenseSegment
            seg = kind(t0, t1, t1 - t0, Z[0], y_pend, Z)
            stepper.take(
                t1,
                y_pend,
                Z[7],
                ay_pend,
                out["h"],
                steps=1,
                rejected=out["pending_rejected"],
                rhs_calls=out["pending_rhs_calls"],
                stiff_steps=int(implicit),
                stiff_run=out["stiff_run"],
                stiff=out["stiff"],
            )
        return Stretched(steps, out["samples"], seg), out


def quiet_stretch(
    law: NormalLaw, stepper: RK45Stepper, clock: SampleClock, last: QuietStretch | None
) -> QuietStretch | None:
    """The law's compiled stretch (``last`` when it still fits), or None: none can be built.

    None when the stretch is switched off (:data:`ENABLED`), the law has no native right-hand
    side or its world no compiled sweep (or it is switched off,
    :data:`packbot.native_sweep.ENABLED`).
    """
    from packbot import native_sweep

    rhs = law._native
    sweep = law.world._native
    if not ENABLED or rhs is None or sweep is None or not native_sweep.ENABLED:
        return None
    api = sweep.api
    if last is not None and all(
        a is b for a, b in zip(last.key, (rhs, api, stepper, clock), strict=True)
    ):
        return last
    return QuietStretch(rhs, api, law, stepper, clock)
