"""What a run keeps: its samples and its event log.

:class:`EventLog` is the run's event list with its limit: an event that counts toward
``SimConfig.max_events`` and takes the log past it stops the run (a ``SimulationError``, the
partial result kept). The loop writes its scheduled events there (``failure``, ``freeze``,
``pick``, ``drop``) and the contact law writes its own, as it happens, like a counter in the
run's :class:`~packbot.result.Diagnostics`: the log is a list, not a call back into the loop.

:class:`Recorder` keeps the samples: the regular ones at multiples of ``sample_dt`` (taken on
each accepted step's dense output), the states just before and after every event and
scheduled action, and the final state, in arrays allocated up front (the regular samples'
number is known from the duration; events add a few and enlarge the arrays by halves). What
one sample holds is measured by the function it is built with (full q and v, the torques, the
energy: :func:`measure`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.drive import Drive
from packbot.errors import SimulationError
from packbot.ode import DenseSegment
from packbot.result import Event

__all__ = ["EventLog", "Recorder", "Sample", "measure"]

FloatArray = NDArray[np.float64]
#: One sample: full q [rad], v [rad/s], commanded, applied and friction torques [N*m],
#: effort limits [N*m] and the energy [J].
Sample = tuple[Any, ...]


class EventLog(list[Event]):
    """The run's events, in order, with the run's limit on their number.

    The limit is on the log's length; only an event logged with ``count=True`` (a contact or
    mode event) checks it, and stops the run when the log is longer than ``max_events``.

    Args:
        max_events: ``SimConfig.max_events``.
    """

    def __init__(self, max_events: int) -> None:
        super().__init__()
        self.max_events = max_events

    def log(self, event: Event, count: bool = True) -> None:
        """Append an event; one that counts and takes the log past the limit stops the run.

        Args:
            event: The event.
            count: Check the limit (contact and mode events do; a limit stop, its release and
                the scheduled actions are appended without the check, as they always were).

        Raises:
            SimulationError: More than ``max_events`` events (a Zeno sequence or chattering).
        """
        self.append(event)
        if count and len(self) > self.max_events:
            raise SimulationError(
                f"more than max_events={self.max_events} events (a Zeno sequence or "
                "chattering contact?)",
                event.t,
            )


def measure(
    t: float,
    y: FloatArray,
    drive: Drive,
    held: Callable[[FloatArray, FloatArray, FloatArray, FloatArray], FloatArray],
) -> Sample:
    """The sample of state y at t: full q, v, the torques, the effort limits and the energy.

    Args:
        t: Time [s].
        y: Integrated state (q, v[, tau_m]).
        drive: The run's torques (its system is the current phase's).
        held: The contact law's :meth:`~packbot.contact.base.ContactLaw.friction`: the
            friction column with each held joint's holding torque.
    """
    sys = drive.sys
    n = sys.nv
    q, v = y[:n], y[n : 2 * n]
    cmd, _, applied, friction = drive.torques(t, y)
    friction = held(q, v, applied, friction)
    qf, vf = sys.qv_full(y)
    zero = drive.zero_full  # shared by the samples of a torque-free run (never written)
    free = sys.free
    # The arrays may be shared (the recorder copies them into its columns).
    if cmd is drive.tau_zero and applied is cmd and friction is cmd:
        cmd_f = app_f = fr_f = zero
    else:
        app_f, fr_f = zero.copy(), zero.copy()
        app_f[free], fr_f[free] = applied, friction
        if drive.ctrl_obj is None:
            cmd_f = zero.copy()
            cmd_f[free] = cmd
    if drive.ctrl_obj is not None:
        cmd_f = drive.hold_full
    return (qf, vf, cmd_f, app_f, fr_f, drive.effort_full(), sys.energy(q, v))


class Recorder:
    """The samples of one run, in preallocated arrays.

    The regular samples number ``duration / sample_dt + 1``, known up front: the arrays are
    allocated for them (and a few event samples) at the first sample, one array per column
    (t, q, v, tau_cmd, tau, tau_friction, effort, E), and grow by half their size when events
    add more. No Python object is kept per sample; :meth:`arrays` hands back the filled rows.

    Args:
        sample_dt: Interval of the regular samples [s].
        duration: The run's duration [s].
        measure: The sample at (t, y).
    """

    #: Rows allocated beyond the regular samples and the final state (event samples).
    EXTRA_ROWS = 64

    def __init__(
        self, sample_dt: float, duration: float, measure: Callable[[float, FloatArray], Sample]
    ) -> None:
        self.dt = sample_dt
        self.duration = duration
        self.measure = measure
        self.next_sample = 0
        self._n = 0  # rows filled
        self._capacity = int(duration / sample_dt) + 2 + self.EXTRA_ROWS
        self._t: FloatArray = np.empty(0)
        self._cols: list[FloatArray] = []  # (q, v, tau_cmd, tau, tau_friction, effort, E)

    def __len__(self) -> int:
        """The number of samples kept."""
        return self._n

    @property
    def samples_t(self) -> list[float]:
        """The times of the samples kept so far [s] (a copy, in order)."""
        return self._t[: self._n].tolist()

    def record(self, seg: DenseSegment, t_end: float) -> None:
        """Keep the regular samples due up to t_end from a step's dense output."""
        dt = self.dt
        while True:
            ts = self.next_sample * dt
            if ts > t_end + 1e-12 or ts > self.duration + 1e-12:
                break
            self.point(ts, seg(min(max(ts, seg.t0), seg.t1)))
            self.next_sample += 1

    def record_due(self, t: float, y: FloatArray) -> None:
        """Keep the regular samples due at t (within 1e-12 s) from the state y at t."""
        dt = self.dt
        while self.next_sample * dt <= min(t, self.duration) + 1e-12:
            self.point(self.next_sample * dt, y)
            self.next_sample += 1

    def record_final(self, y: FloatArray) -> None:
        """Keep the final state y as a sample if the last one is earlier (within 1e-12 s).

        The regular samples fall on multiples of ``sample_dt``; when it does not divide the
        duration (or exceeds it) the last of them is before the end, and the final state is
        kept here, at t = duration (the last interval is then shorter). A run whose duration
        is a multiple of ``sample_dt`` already ends on a sample and is unchanged.
        """
        if self._n == 0 or self._t[self._n - 1] < self.duration - 1e-12:
            self.point(self.duration, y)

    def point(self, t: float, y: FloatArray) -> None:
        """Keep the sample of state y at t (nothing kept if measuring it raises)."""
        sample = self.measure(t, y)
        n = self._n
        if n == len(self._t):
            self._grow(sample)
        self._t[n] = t
        for col, value in zip(self._cols, sample, strict=True):
            col[n] = value
        self._n = n + 1

    def _grow(self, sample: Sample) -> None:
        """Allocate the arrays (first sample: their row shapes from it), or enlarge them."""
        if not self._cols:
            size = self._capacity
            self._t = np.empty(size)
            self._cols = [np.empty((size, *np.shape(x))) for x in sample]
            return
        size = len(self._t) + max(len(self._t) // 2, self.EXTRA_ROWS)
        old = [self._t, *self._cols]
        new = [np.empty((size, *a.shape[1:])) for a in old]
        for a, b in zip(old, new, strict=True):
            b[: self._n] = a[: self._n]
        self._t, self._cols = new[0], new[1:]

    def arrays(self) -> list[FloatArray]:
        """t, then the columns of the samples: q, v, tau_cmd, tau, tau_friction, effort, E.

        Each has one row per sample: the filled rows of its allocation (a view when the rows
        left over are few, a copy otherwise, so that a run stopped early does not keep its whole
        allocation); with no sample, each is empty, shape (0,). Rows kept later are not in it.
        """
        n = self._n
        if not self._cols:
            return [np.zeros(0) for _ in range(8)]
        few = len(self._t) - n <= n // 4 + self.EXTRA_ROWS
        return [a[:n] if few else a[:n].copy() for a in (self._t, *self._cols)]
