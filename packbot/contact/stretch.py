"""A stretch of quiet steps of the contact-normal mode in one native call.

Most of the contact-normal mode's steps find nothing to do at their end: no event, no stale
patch, no mode to change. The event loop (:mod:`packbot.integrator`) takes each in Python: the
step-size control of :meth:`packbot.ode.RK45Stepper.step` around the native Dormand-Prince
attempt, the collision sweep at the step's end, the step end's screen
(:meth:`NativeWatch.end_check <packbot.contact.native.NativeWatch.end_check>`), the regular samples
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

A step whose only finding is a sliding contact's stale patch is re-patched in the stretch
itself, as :meth:`NormalContacts.repatch
<packbot.contact.normal_contacts.NormalContacts.repatch>` does it (the patches' material points,
the drift projection and its sweep's check, the modes kept or selected again, the stepper
restarted there), and the stretch goes on; :func:`adopt_repatches` then gives the contact set
the state the last one left (where the loop's re-patch would take a branch the native one does
not, the step is handed back).

Its steps are the loop's (the same native attempts, step-size control and step bound); the
samples' dense output is summed in another order than numpy's, to rounding.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact import native
from packbot.contact import normal_windows as windows
from packbot.contact.base import SampleClock
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_tolerances import (
    BAUMGARTE,
    FACE_ALIGN,
    FORCE_BAND,
    PATCH_TOL,
    PENETRATION_TOL,
    RESIDUAL_TOL,
    SLIDE_TOL,
    SPEED_BAND,
    STICK_BAND,
    STICK_SPEED,
    TOUCH_GAP,
)
from packbot.contact.timestep import StepSegment
from packbot.ode import DenseSegment, HermiteSegment, RK45Stepper

if TYPE_CHECKING:
    from packbot.contact.normal_law import NormalLaw

__all__ = [
    "PENDING",
    "REPATCHED",
    "LawInputs",
    "QuietStretch",
    "RepatchModes",
    "SampleClock",
    "Stretched",
    "adopt_repatches",
    "hold_at_rest",
    "law_stretch",
    "quiet_stretch",
    "repatch_modes",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: The native run's status for a step handed back to the loop (``src/native/stretch.hpp``).
PENDING = 1
#: The native run's status after a re-patch it took where the loop goes on (the stepper
#: restarted there, its derivative left to the next step).
REPATCHED = 8


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
class RepatchModes:
    """The contact set's modes, for the stretch's own re-patches (in the layout's pair order).

    Attributes:
        stick: Each pair's stick flag (1: sticking), (pairs,) uint8.
        on1: Whether each pair's normal is fixed in body 1, (pairs,) uint8.
        slip: Each pair's slip direction at onset, world, (pairs, 3).
        engaged: The engaged rows.
    """

    stick: NDArray[np.uint8]
    on1: NDArray[np.uint8]
    slip: FloatArray
    engaged: NDArray[np.int64]


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
        modes: The contact set's modes when the stretch may re-patch (None: it hands a stale
            patch's step back).
    """

    active: NDArray[np.int64]
    limits: NDArray[np.int64]
    lim_value: FloatArray
    crawl: FloatArray
    min_d: float
    modes: RepatchModes | None = None


class QuietStretch:
    """The compiled stretch of one law's native right-hand side and collision sweep.

    Args:
        rhs: The law's native right-hand side.
        api: The compiled collision sweep's C entry point (``Sweep.api()``).
        law: The law (its reach bounds, tolerances and step bound's constants).
        stepper: The loop's stepper (its tolerances).
        clock: The run's samples.
        crawl: The law's crawl rule, (steps, step [s]): the stepper crawls when that many
            accepted steps average less than that step
            (:data:`~packbot.contact.normal_windows.CRAWL_STEPS`,
            :data:`~packbot.contact.normal_windows.CRAWL_STEP`).
    """

    def __init__(
        self,
        rhs: native.NativeRhs,
        api: Any,
        law: NormalLaw,
        stepper: RK45Stepper,
        clock: SampleClock,
        crawl: tuple[int, float],
    ) -> None:
        crawl_steps, crawl_step = crawl
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
            crawl_steps=crawl_steps,
            crawl_step=crawl_step,
            sample_dt=clock.dt,
            duration=clock.duration,
            stiff_switch=True,
        )
        # the re-patch's constants: NormalContacts.repatch's (its refresh, projection and modes)
        self._run.set_repatch(
            tol=law.normal.tol,
            patch_tol=PATCH_TOL,
            face_align=FACE_ALIGN,
            slide_tol2=SLIDE_TOL**2,
            touch_gap=TOUCH_GAP,
            res_tol=RESIDUAL_TOL,
            mu=law.normal.mu,
            speed_band=SPEED_BAND,
            stick_speed=STICK_SPEED,
            force_band=FORCE_BAND,
            stick_band=STICK_BAND,
            baumgarte=BAUMGARTE,
            mode_res_tol=RESIDUAL_TOL,
        )
        self._no_modes = (
            np.zeros(0, dtype=np.uint8),
            np.zeros(0, dtype=np.uint8),
            np.zeros((0, 3)),
            np.zeros(0, dtype=np.int64),
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
        m = law.modes
        if m is None:
            self._run.set_modes(False, *self._no_modes)
        else:
            self._run.set_modes(True, m.stick, m.on1, m.slip, m.engaged)
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
                restarted=status == REPATCHED,
            )
        if out["repatches"] or out["spare"]:  # (its re-patches, or a hand-back's sweep)
            out["repatched"] = self._run.repatched()
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


def repatch_modes(law: NormalLaw) -> RepatchModes | None:
    """The contact set's modes when the law's stretch may re-patch, else None.

    Where :meth:`NormalLaw.after_step <packbot.contact.normal_law.NormalLaw.after_step>` would
    re-patch with the native steps only (:meth:`NormalContacts.repatch
    <packbot.contact.normal_contacts.NormalContacts.repatch>`'s refresh on the extension's
    materials, its projection's native round, its native mode selection): the contact set of
    its own class (no subclass's hooks), the projection checking the other pairs, and engaged
    rows. The law is the caller's to check: :meth:`NormalLaw.stretch
    <packbot.contact.normal_law.NormalLaw.stretch>` asks only as a law of its own class.
    """
    nc = law.normal
    if (
        type(nc) is not NormalContacts
        or not nc.engaged
        or not nc.check_others
        or nc.world is not law.world
    ):
        return None
    pairs = nc._pair_list
    return RepatchModes(
        stick=np.array([p.stick for p in pairs], dtype=np.uint8),
        on1=np.array([p.on1 for p in pairs], dtype=np.uint8),
        slip=np.array([p.slip_dir for p in pairs], dtype=np.float64).reshape(-1, 3),
        engaged=np.array(nc.engaged, dtype=np.int64),
    )


def adopt_repatches(law: NormalLaw, out: dict[str, Any]) -> None:
    """Take over a stretch's own re-patches (before the law keeps its steps' results).

    The contact set as :meth:`NormalContacts.repatch
    <packbot.contact.normal_contacts.NormalContacts.repatch>` leaves it after the last one:
    its patches rebuilt at that re-patch's q (the extension's materials give them again bit for
    bit), the modes selected there, the Painleve fallbacks counted, a friction given up
    logged; the restarts counted; the world's last sweep the last projection's. A re-patch
    handed back after its projection's sweep leaves that sweep for the loop's re-patch.
    """
    rp = out.get("repatched")
    if rp is None:
        return
    world = law.world
    spare = rp["spare"]
    if spare is not None:
        world.dispatch.keep_spare(spare[0][0], spare[1][0], spare[2][0], spare[3], spare[4])
    n = out["repatches"]
    if not n:
        return
    nc = law.normal
    nc.refresh(rp["q_patch"][0])
    for p, st, sd in zip(nc._pair_list, rp["stick"][0].tolist(), rp["slip"], strict=True):
        p.stick = bool(st)
        if not np.array_equal(sd, p.slip_dir):
            p.slip_dir = sd.copy()
    nc.engaged = rp["engaged"][0].tolist()
    nc.projection_energy_removed += rp["energy_removed"]
    law.diag.projection_energy_removed += rp["energy_removed"]
    for _ in range(rp["gave_up"]):
        log.warning("contact problem unsolved even with sticking contacts")
    law.diag.restarts += n
    if rp["relaid"]:  # (the extension's layout of another shape)
        law._native.forget_loaded()
    proj = rp["proj"]
    if proj is not None:  # (CollisionWorld.sweep(q, reuse=True) keeps it as the last sweep)
        world.dispatch.adopt(proj[0][0], proj[1][0], proj[2][0], proj[3], proj[4])


def quiet_stretch(
    law: NormalLaw,
    stepper: RK45Stepper,
    clock: SampleClock,
    last: QuietStretch | None,
    crawl: tuple[int, float],
) -> QuietStretch:
    """The law's compiled stretch (``last`` when it still fits).

    ``crawl`` is the law's crawl rule (:class:`QuietStretch`'s), read when a stretch is built.
    """
    rhs = law._native
    sweep = law.world._native
    api = sweep.api
    if last is not None and all(
        a is b for a, b in zip(last.key, (rhs, api, stepper, clock), strict=True)
    ):
        return last
    return QuietStretch(rhs, api, law, stepper, clock, crawl)


def law_stretch(
    law: NormalLaw,
    stepper: RK45Stepper,
    t_end: float,
    t_last: float,
    t_sched: float,
    clock: SampleClock,
    own: bool,
) -> Stretched | None:
    """The law's quiet steps from the stepper's state in one native call (:class:`QuietStretch`).

    Offered right after :meth:`NormalLaw.step_kernel
    <packbot.contact.normal_law.NormalLaw.step_kernel>` offered the native step (its modes and
    torques loaded), outside a window, with no conditional lock or Coulomb-sliding joint (their
    conditions are watched in Python) and with the compiled sweep; else None. An arm captured
    at rest is held there instead (the law's ``_hold_at_rest``: :func:`hold_at_rest`).

    Args:
        law: The contact-normal mode's law.
        stepper: The loop's stepper, at the loop's state.
        t_end: The stepper's steps end here at the latest [s].
        t_last: The run ends here [s].
        t_sched: The next scheduled action [s].
        clock: The run's regular samples.
        own: Whether the law's re-patches are the stretch's own (a law of NormalLaw's class:
            a subclass's hooks make its re-patches the loop's).
    """
    if law.normal.resting:
        return law._hold_at_rest(stepper, t_end)
    if not law._offered or law.window is not None or law.locks.conditional or law.drive.fdir.any():
        return None
    crawl = (windows.CRAWL_STEPS, windows.CRAWL_STEP)
    st = law._stretch = quiet_stretch(law, stepper, clock, law._stretch, crawl)
    stops = [(k[1], k[2]) for k in law.active if k[0] == "limit"]
    upper, lower = law.sys.upper, law.sys.lower
    inputs = LawInputs(
        active=np.array([k[1] for k in law.active if k[0] == "pair"], dtype=np.int64),
        limits=np.array(
            [(j, side, law._limit_held(j, side)) for j, side in stops], dtype=np.int64
        ).reshape(-1, 3),
        lim_value=np.array([upper[j] if side > 0 else lower[j] for j, side in stops]),
        crawl=np.array(law.triggers.steps, dtype=np.float64),
        min_d=law.diag.min_distance,
        modes=repatch_modes(law) if own else None,
    )
    law.world.dispatch.spare = None
    done, out = st.run(stepper, t_end, t_last, t_sched, clock, inputs)
    k = out["samples_before"]
    if out["repatches"] and k > 0:
        # the samples before its first re-patch, their forces read from the contact set as
        # the stretch found it (those after, from the set its last re-patch leaves)
        clock.record_states(done.samples[:k])
        done = dataclasses.replace(done, samples=done.samples[k:])
    adopt_repatches(law, out)
    if done.steps:
        _kept(law, stepper.y if done.pending is None else done.pending.y0, out)
        if out["repatches"]:
            law._ready = None  # (the modes and patches loaded again from the set's)
    if done.pending is not None:
        # its sweep, for the watch to reuse (the same numbers: Coal's warm-started GJK
        # would not give them bit for bit a second time)
        law.world.dispatch.adopt(
            done.pending.y1[: law.n],
            out["pending_pairs"][0],
            out["pending_dist"][0],
            out["pending_best"],
            out["pending_best_d"],
        )
    return done


def hold_at_rest(law: NormalLaw, stepper: RK45Stepper, t_end: float) -> Stretched | None:
    """The arm captured at rest, held there to t_end in one step (pending), or None.

    The rest capture (:meth:`NormalContacts.capture
    <packbot.contact.normal_steps.RestartSteps.capture>`) stops every joint and holds it
    until a mode condition says otherwise (``nrest``: the accelerations the arm would
    have without the hold). With the torques fixed (a held command, or none, and no motor
    lag: :meth:`~packbot.drive.Drive.step_torques`) nothing changes until the next
    controller tick or scheduled action: the stepper's steps from such a state keep it
    bit for bit, each one a right-hand side, a sweep and the checks at its end. One step
    to t_end does the same once; the loop watches it as any step (its end's sweep and
    conditions: the state's) and records its samples (the state). The stepper restarts at
    its end.

    Args:
        law: The contact-normal mode's law.
        stepper: The loop's stepper, at the loop's state.
        t_end: The step's end [s] (no controller tick before it).
    """
    t, y = stepper.t, stepper.y
    n = law.n
    if (
        t_end <= t
        or len(y) != 2 * n
        or y[n:].any()
        or law.locks.conditional
        or law.drive.fdir.any()
        or law.drive.step_torques(t, y) is None
    ):
        return None
    seg = StepSegment(t, t_end, y, y.copy())
    stepper.reset(t_end, seg.y1, h=stepper.h, defer=True)
    return Stretched(0, np.zeros((0, len(y))), seg)


def _kept(law: NormalLaw, y: FloatArray, out: dict[str, Any]) -> None:
    """Past a stretch's kept steps, ending at y: what watch and after_step keep.

    Args:
        law: The contact-normal mode's law.
        y: The last kept step's end (its modes still loaded: the native step's next start).
        out: The native call's results (:meth:`QuietStretch.run`).
    """
    law.triggers.steps.extend(out["hs"][0].tolist())
    law.diag.sweeps += out["steps"]
    law.note_min(out["min_d"], out["min_pair"])
    pairs, distances = out["last_pairs"][0], out["last_dist"][0]
    pairs.setflags(write=False)
    distances.setflags(write=False)
    law._pending_arr = law._last_arr = (pairs, distances)
    law._pending_d = law._last_d = None
    law._start_swept = out["repatches"] == 0  # (a re-patch's projection moves q)
    law._clear = law._ready = y
    law.world.dispatch.owe()  # (its pieces are owed at the last compiled sweep's q)
