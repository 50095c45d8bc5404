"""A time-stepping window's steps that keep their contact set, in one native call.

In a window (:mod:`packbot.contact.timestep`) most steps keep their contact set: the same pairs
and limits within reach, no stale patch, no bounce. Each is one native call already
(``MoreauJeanStepper._native_step``), but each also passes through Python around it: the
step's signature and the window's quiet count (``NormalLaw.advance``), the sweep at the step's
end and the energy guard (``MoreauJeanStepper._finish``), and the event loop's turn
(:mod:`packbot.integrator`: the law's watch, the samples, ``after_step``). The compiled
``ContactRhs.window_run`` takes such steps one after another with the same arithmetic: the
window step of ``_native_step``, the signature, the sweep through the compiled sweep's C entry
point (as the stretch of quiet steps does, :mod:`packbot.contact.stretch`), the energy guard
(their sums in numpy's order: the same floats).

It stops before a step it does not take (one ending at or after the window's step end, or one
the native step hands back: the stepper then takes it as before), or after a step it took but
does not keep: one leaving a pair deeper than the projection depth, or one that ends the window
(its quiet count reached with the window's least length behind it). That step comes back
*pending*, and the stepper finishes it (``MoreauJeanStepper.step(pending=...)``: its
projection, or the law's exit from the window). The steps kept and the step after them come
back to the loop as one :class:`StepChain`, whose samples are those the loop would have taken
step by step. Where the run is not offered (joint boxes, torques that vary over a step, a motor
lag, no collision world), the stepper takes the steps one by one.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact import timestep
from packbot.contact import window_impulses as wi
from packbot.contact.timestep import StepSegment
from packbot.ode import DenseSegment

if TYPE_CHECKING:
    from packbot.contact.timestep import MoreauJeanStepper

__all__ = ["MAX_STEPS", "NativeRun", "StepChain", "run_native"]

FloatArray = NDArray[np.float64]

#: The most steps one native call takes (the event loop reports its progress between calls).
MAX_STEPS = 2000

_NONE = np.zeros(0)  # (an empty argument: no guess, no limits)


@dataclass(frozen=True, slots=True)
class NativeRun:
    """What one native run of window steps did.

    Attributes:
        times: The start time and the end time of every step kept [s], (steps + 1,).
        states: The start state and the end state of every step kept, (steps + 1, 2 nv).
        removed: The energy the guard removed at the steps kept [J], in order (none: 0).
        quiet: The window's quiet count after them.
        signature: The last step's signature (``_PairLayout.signature``), or None (none
            kept).
        min_d: The smallest distance of the steps' start sweeps below the run's so far [m],
            and its pair; pair -1: none lower.
        min_pair: See ``min_d``.
        pending: The step taken and not kept, for ``MoreauJeanStepper.step(pending=...)``, or
            None.
    """

    times: list[float]
    states: FloatArray
    removed: FloatArray
    quiet: int
    signature: Any
    min_d: float
    min_pair: int
    pending: tuple[tuple[Any, ...], tuple[float, Any]] | None

    @property
    def steps(self) -> int:
        """The steps kept."""
        return len(self.times) - 1


class StepChain(DenseSegment):
    """Consecutive window steps [t_0, t_k] as one segment: each linear (:class:`StepSegment`).

    A time t is read from the step that would have recorded a sample at t in a step-by-step
    loop (:meth:`packbot.recorder.Recorder.record`: the first whose end + 1e-12 s reaches t),
    at t clamped to that step, so the samples are the same to the bit.
    """

    __slots__ = ("_ends", "_steps")

    def __init__(self, times: list[float], states: list[FloatArray]) -> None:
        """Steps from (times[i], states[i]) to (times[i + 1], states[i + 1])."""
        super().__init__(
            times[0], times[-1], times[-1] - times[0], states[0], states[-1],
            np.zeros((8, len(states[0]))),
        )  # fmt: skip
        self._steps = [
            StepSegment(times[i], times[i + 1], states[i], states[i + 1])
            for i in range(len(times) - 1)
        ]
        self._ends = [t1 + 1e-12 for t1 in times[1:]]

    def _step(self, t: float) -> StepSegment:
        i = bisect.bisect_left(self._ends, t)
        return self._steps[min(i, len(self._steps) - 1)]

    def __call__(self, t: float) -> FloatArray:
        """y(t), from the step that holds t (see the class)."""
        seg = self._step(t)
        return seg(min(max(t, seg.t0), seg.t1))

    def derivative(self, t: float) -> FloatArray:
        """The mean slope of the step that holds t [units of y per s]."""
        return self._step(t).derivative(t)


def run_native(
    stepper: MoreauJeanStepper,
    t: float,
    y: FloatArray,
    t_end: float,
    until: float,
    quiet: int,
    last: Any,
    min_d: float,
) -> NativeRun | None:
    """The window's steps from (t, y) that keep their contact set, in one native call.

    Only where ``MoreauJeanStepper._native_step`` would take the next step natively (fixed
    torques, no Coulomb direction outside the boxes, the last step's end sweep at y), without
    joint boxes (Coulomb friction or brakes: the samples' friction torques are each step's box
    impulses, read when the loop records them), and where the world has its compiled sweep.
    Afterwards the stepper is past the steps kept (its warm start, end sweep and end energy are
    theirs) and the world's pieces are owed at the last sweep's q.

    Args:
        stepper: The window's stepper.
        t: Time [s].
        y: State (q, v).
        t_end: The window's step end (the run's end or the next scheduled action) [s]: a step
            ending within 1e-12 s of it is not taken here.
        until: The window's earliest exit [s].
        quiet: Its quiet count at y.
        last: Its last step's signature (None: none).
        min_d: The run's smallest distance so far [m] (the law's ``diag.min_distance``).

    Returns:
        What the run did (possibly no step), or None: not offered.
    """
    contacts, n = stepper.contacts, stepper.n
    world = contacts.world
    rhs = stepper.native
    cached = stepper._next_sweep
    if (
        world is None
        or len(y) != 2 * n
        or not contacts.pairs
        or cached is None
        or cached[0] != y[:n].tobytes()
    ):
        return None
    torques = stepper.drive.step_torques(t, y)
    coul = stepper.drive.path.coulomb
    cj = np.flatnonzero(coul > 0.0)
    if torques is None or torques[2].any() or len(cj):
        # (joint boxes: each step's box torques are its samples' friction torques, which a
        # segment of several steps recorded at once would not keep)
        return None
    rhs.hold_torque(*torques)
    rhs.load_layout(contacts)
    lay = stepper._layout()
    rows = (lay.key, len(cj))
    guess, rho0 = stepper.impulses.guess(rows)
    cfg, sw = stepper.cfg, cached[2]
    limits = (stepper.sys.upper, stepper.sys.lower) if cfg.joint_limits else (_NONE, _NONE)
    valid, flags = _flags(last, lay.keys, list(contacts.limits), cj)
    end = stepper._end_energy
    has_e = end is not None and end[0] == y.tobytes()
    state = np.array(y, dtype=np.float64)
    out = rhs._rhs.window_run(
        world._native.api, state, t, t_end, t_end - 1e-12, stepper.h, until, quiet,
        timestep.QUIET_STEPS, valid, flags, sw.pairs, sw.distances, cached[1],
        int(sw.min_pair), float(sw.min_distance), stepper.reach, timestep.ACTIVE_GAP,
        limits[0], limits[1], timestep.LIMIT_GAP, contacts.mu, cfg.restitution,
        cfg.zeno_speed, wi.TOUCH_GAP, cj, np.ascontiguousarray(coul[cj]),
        _NONE if guess is None else guess, rho0, wi.CONIC_TOL, wi.CONIC_ITERATIONS,
        wi.RESIDUAL_OK, torques[0],
        has_e, end[1] if has_e and end is not None else 0.0, timestep.STEP_ANGLE,
        timestep.SWEEP_SLACK, timestep.PROJECT_DEPTH, timestep.IMPULSE_BAND, min_d, MAX_STEPS,
    )  # fmt: skip
    steps, pending = int(out["steps"]), int(out["status"]) == 1
    handed = int(out["handed"])
    # the step after the run, handed back by the native call: the stepper's own native step
    # from that state, of that size, would hand it back again (_native_step reads this)
    stepper._handed = (
        (state.tobytes(), float(out["h_handed"]), handed, out["vf_handed"]) if handed else None
    )
    if steps or pending:  # (the world's pieces are owed at the last native sweep's q)
        world.dispatch.owe()
    signature = None
    if steps:
        x = out["x"]
        stepper.native_steps += steps
        stepper.impulses.keep(rows, x, float(out["rho"]))
        m3 = len(x) - len(cj)
        stepper.joint_torque = np.zeros(n)
        stepper.joint_torque[cj] = x[m3:] / float(out["h_kept"])
        bound = stepper.h * coul[cj]
        signature = lay.signature(x, list(contacts.limits), contacts.mu, bound, cj)
        kept, ends = out["impulses"], [t, *out["times"].tolist()]
        for k in range(steps):  # (one contact set for all: the run stops where it changes)
            q0 = y[:n] if k == 0 else out["states"][k - 1, :n]
            stepper.forces.keep(ends[k], ends[k + 1], q0, kept[k])
        q_bytes = state[:n].tobytes()
        result = world.dispatch.result(out["swept"], out["dist"], out["best"], out["best_d"])
        stepper._next_sweep = (q_bytes, float(out["margin"]), result)
        stepper._end_energy = (state.tobytes(), float(out["e_last"])) if out["has_e"] else None
    fast = None
    if pending:
        x = out["p_x"]
        stepper.native_steps += 1
        stepper.impulses.keep(rows, x, float(out["p_rho"]))
        closest = (float(out["best_d"]), int(out["best"]))
        p_sw = world.dispatch.result(out["p_swept"], out["p_dist"], out["p_best"], out["p_best_d"])
        fast = (
            (out["vf"], out["v1"], out["q1"], x, float(out["p_residual"]), closest, cj, lay,
             tuple(out["p_energies"])),
            (float(out["p_margin"]), p_sw),
        )  # fmt: skip
    times = [t, *out["times"].tolist()]
    states = np.vstack([y[None, :], out["states"]]) if steps else y[None, :]
    return NativeRun(
        times, states, out["removed"], int(out["quiet"]), signature, float(out["min_d"]),
        int(out["min_pair"]), fast,
    )  # fmt: skip


def _flags(
    last: Any, keys: list[int], limits: list[tuple[int, int]], cj: NDArray[np.intp]
) -> tuple[bool, NDArray[np.int64]]:
    """A step's signature as the native run's flags: push and slide per pair, per limit, per box.

    Returns:
        (valid, flags): valid False when there is no signature, or it names a pair, limit or
        joint outside the set (then no step's signature equals it).
    """
    boxes = cj.tolist()
    if last is None:
        return False, np.zeros(2 * len(keys) + len(limits) + len(boxes), dtype=np.int64)
    push, slide, lim, slip = last
    valid = push <= set(keys) and slide <= set(keys) and lim <= set(limits) and slip <= set(boxes)
    flags = (
        [k in push for k in keys]
        + [k in slide for k in keys]
        + [k in lim for k in limits]
        + [j in slip for j in boxes]
    )
    return bool(valid), np.array(flags, dtype=np.int64).reshape(-1)
