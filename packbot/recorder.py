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

import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from packbot.contact_forces import ContactTable, SampleForces
from packbot.contact_impulses import ImpactTable
from packbot.drive import Drive
from packbot.errors import ModelError, SimulationError
from packbot.ode import DenseSegment
from packbot.result import Event

if TYPE_CHECKING:
    from packbot.contact.base import ContactLaw
    from packbot.contact.native import NativeRhs
    from packbot.system import System

__all__ = ["EventLog", "Recorder", "Sample", "contact_sampler", "measure", "measure_many"]

FloatArray = NDArray[np.float64]
#: One sample: full q [rad], v [rad/s], commanded, applied and friction torques [N*m],
#: effort limits [N*m] and the energy [J].
Sample = tuple[Any, ...]
#: Several samples at once: the same columns, each an array with one row per sample, or one
#: row shared by all of them (broadcast).
Samples = list[Any]


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
        #: The impacts' contact impulses, each (t [s], the records: impulses [N*s] in the force
        #: slots, the stops' impulses [N*m*s] in the limit slot, full coordinates)
        #: (:class:`~packbot.contact_impulses.ImpactTable`).
        self.impulses: list[tuple[float, SampleForces]] = []

    def impact_table(self, nv: int) -> ImpactTable:
        """The impacts' impulses logged (``nv``: the full model's velocity dimension)."""
        return ImpactTable.from_log(self.impulses, nv)

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
        held: The contact law's :meth:`ForceReport.friction
            <packbot.contact.base.ForceReport.friction>`: the friction column with each held
            joint's holding torque.
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


def contact_sampler(
    drive: Drive, law: ContactLaw
) -> Callable[[float, FloatArray], SampleForces | None]:
    """The contact forces of a state: the law's current mode's, under the drive's torques.

    Args:
        drive: The run's torques (applied and friction: what the right-hand side integrates).
        law: The run's contact law (its :meth:`ForceReport.contacts
            <packbot.contact.base.ForceReport.contacts>`).

    Returns:
        (t [s], integrated state y) -> the contacts of that sample and its stops' torques in
        full coordinates (None: the law cannot say).
    """

    def sample(t: float, y: FloatArray) -> SampleForces | None:
        n = drive.sys.nv

        def tau() -> FloatArray:
            _, _, applied, friction = drive.torques(t, y)
            return np.asarray(applied + friction, dtype=np.float64)

        found = law.forces().contacts(y[:n], y[n : 2 * n], tau, t)
        if found is None or n == n_full:
            return found
        # (the stops' and clamps' torques in full coordinates: a failure's locked joints' 0)
        return SampleForces(
            found.contacts,
            drive.sys.v_full(found.limit_torque),
            None if found.clamp_torque is None else drive.sys.v_full(found.clamp_torque),
        )

    n_full = drive.robot.model.nv
    return sample


#: System -> its compiled model for the samples' energies (None: a joint type the extension does
#: not rebuild, e.g. a continuous joint in the ``none`` mode, which has no collision world),
#: built at a phase's first batch of samples.
_COMPILED: weakref.WeakKeyDictionary[System, NativeRhs | None] = weakref.WeakKeyDictionary()


def _compiled(sys: System) -> NativeRhs | None:
    """The compiled model of ``sys`` for the samples' energies, or None (its joint types).

    Raises:
        PackbotError: The extension ``packbot._native`` is not built.
    """
    try:
        return _COMPILED[sys]
    except KeyError:
        pass
    from packbot.contact import native  # (the contact laws import this module)

    rhs: NativeRhs | None
    try:
        rhs = native.native_rhs(sys.model)
    except ModelError:  # (then the system's energies, row by row, as a single sample's)
        rhs = None
    _COMPILED[sys] = rhs
    return rhs


def measure_many(
    ts: list[float],
    ys: list[FloatArray],
    drive: Drive,
    held: Callable[[FloatArray, FloatArray, FloatArray, FloatArray], FloatArray],
) -> Samples | None:
    """The samples of the states ys at the times ts, column by column (:func:`measure`'s).

    The same numbers as :func:`measure` row by row (the torques of each state computed the
    same way), with the full coordinates and the columns filled for all rows at once. The
    energies come from the compiled extension in one call (the same to rounding:
    :meth:`NativeRhs.energies <packbot.contact.native.NativeRhs.energies>`), or from the
    system row by row for a model whose joints the extension does not rebuild. None with a
    torque function (a controller called at each sample, which may raise: the samples before
    it are kept one by one).

    Args:
        ts: Times [s].
        ys: Integrated states (q, v[, tau_m]), one per time.
        drive: The run's torques (its system is the current phase's).
        held: The contact law's :meth:`ForceReport.friction
            <packbot.contact.base.ForceReport.friction>`.
    """
    if drive.ctrl_fn is not None:
        return None
    sys = drive.sys
    n = sys.nv
    k = len(ts)
    free = sys.free
    zero = drive.zero_full
    nq = len(zero)
    Y = np.array(ys)
    qf = np.empty((k, nq))
    qf[:] = sys.q_locked
    qf[:, free] = Y[:, :n]
    vf = np.zeros((k, nq))
    vf[:, free] = Y[:, n : 2 * n]
    tau_zero = drive.tau_zero
    y0 = ys[0]
    cmd, _, applied, friction = drive.torques(ts[0], y0)
    if not drive.lag and held(y0[:n], y0[n : 2 * n], applied, friction) is friction:
        # Without a torque function or a motor lag the command and the applied torque are the
        # same at every state (a held command, or none): the state enters through the friction
        # only, -viscous v - coulomb s (ActuatorPath.friction, s the drive's sliding
        # directions, fixed between events), or not at all (friction is the command: none).
        # The law passing the first state's friction through (no held joint) passes them all.
        # The rows at once: the same numbers as row by row.
        shared = cmd is tau_zero and applied is cmd and friction is cmd
        fric: Any = (
            friction if friction is cmd else drive.path.friction(Y[:, n : 2 * n], drive.fdir)
        )
        rows_cmd: Any = cmd
        rows_app: Any = applied
    else:
        rows = []
        shared = True
        for t, y in zip(ts, ys, strict=True):
            cmd, _, applied, friction = drive.torques(t, y)
            friction = held(y[:n], y[n : 2 * n], applied, friction)
            shared = shared and cmd is tau_zero and applied is cmd and friction is cmd
            rows.append((cmd, applied, friction))
        rows_cmd = [r[0] for r in rows]
        rows_app = [r[1] for r in rows]
        fric = [r[2] for r in rows]
    cmd_f: Any = zero
    app_f: Any = zero
    fr_f: Any = zero
    if not shared:
        app_f, fr_f = np.zeros((k, nq)), np.zeros((k, nq))
        app_f[:, free] = rows_app
        fr_f[:, free] = fric
        if drive.ctrl_obj is None:
            cmd_f = np.zeros((k, nq))
            cmd_f[:, free] = rows_cmd
    if drive.ctrl_obj is not None:
        cmd_f = drive.hold_full
    rhs = _compiled(sys)
    if rhs is not None:
        energy: Any = rhs.energies(Y[:, :n], Y[:, n : 2 * n])
    else:
        energy = [sys.energy(y[:n], y[n : 2 * n]) for y in ys]
    return [qf, vf, cmd_f, app_f, fr_f, drive.effort_full(), energy]


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
        measure_many: The samples at several (t, y) at once (:func:`measure_many`'s columns;
            None: that function cannot, they are measured one by one), or None.
        contacts: The contact forces of the sample at (t, y) (the law's
            :meth:`ForceReport.contacts <packbot.contact.base.ForceReport.contacts>`), or None:
            none kept.
    """

    #: Rows allocated beyond the regular samples and the final state (event samples).
    EXTRA_ROWS = 64

    def __init__(
        self,
        sample_dt: float,
        duration: float,
        measure: Callable[[float, FloatArray], Sample],
        measure_many: Callable[[list[float], list[FloatArray]], Samples | None] | None = None,
        contacts: Callable[[float, FloatArray], SampleForces | None] | None = None,
    ) -> None:
        self.dt = sample_dt
        self.duration = duration
        self.measure = measure
        self.measure_many = measure_many
        self.next_sample = 0
        self._n = 0  # rows filled
        self._capacity = int(duration / sample_dt) + 2 + self.EXTRA_ROWS
        self._t: FloatArray = np.empty(0)
        self._cols: list[FloatArray] = []  # (q, v, tau_cmd, tau, tau_friction, effort, E)
        self.contacts = contacts
        self._contacts: list[SampleForces | None] = []  # per sample kept, the law's report

    def __len__(self) -> int:
        """The number of samples kept."""
        return self._n

    @property
    def samples_t(self) -> list[float]:
        """The times of the samples kept so far [s] (a copy, in order)."""
        return self._t[: self._n].tolist()

    def record(self, seg: DenseSegment, t_end: float) -> None:
        """Keep the regular samples due up to t_end from a step's dense output.

        They are measured at once (``measure_many``) when the recorder has it.
        """
        dt = self.dt
        k = self.next_sample
        lim = min(t_end, self.duration) + 1e-12
        if k * dt > lim:  # (most steps: no sample due)
            return
        times = []
        while True:
            ts = k * dt
            if ts > t_end + 1e-12 or ts > self.duration + 1e-12:
                break
            times.append(ts)
            k += 1
        if not times:
            return
        t0, t1 = seg.t0, seg.t1
        self._keep(times, [seg(min(max(ts, t0), t1)) for ts in times])

    def record_states(self, ys: FloatArray) -> None:
        """Keep the next regular samples from their states ys, shape (m, n), in order.

        The states at ``next_sample * dt``, ``(next_sample + 1) * dt``, ... (a stretch of
        steps taken at once evaluated its dense outputs there: :mod:`packbot.contact.stretch`),
        measured at once as :meth:`record` does.
        """
        k, dt = self.next_sample, self.dt
        if len(ys):
            self._keep([(k + i) * dt for i in range(len(ys))], list(ys))

    def _keep(self, times: list[float], ys: list[FloatArray]) -> None:
        """Keep the regular samples ys at times, the next ones due (measured at once if it can)."""
        if self.measure_many is not None and self._cols:
            samples = self.measure_many(times, ys)
            if samples is not None:
                found = [self._contacts_of(ts, y) for ts, y in zip(times, ys, strict=True)]
                self._rows(times, samples)
                self._contacts += found
                self.next_sample += len(times)
                return
        for ts, y in zip(times, ys, strict=True):
            self.point(ts, y)
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
        found = self._contacts_of(t, y)
        n = self._n
        if n == len(self._t):
            self._grow(sample)
        self._t[n] = t
        for col, value in zip(self._cols, sample, strict=True):
            col[n] = value
        self._contacts.append(found)
        self._n = n + 1

    def _contacts_of(self, t: float, y: FloatArray) -> SampleForces | None:
        """The law's report of the sample of state y at t (None: unknown, or none asked)."""
        return None if self.contacts is None else self.contacts(t, y)

    def contact_table(self, nv: int) -> ContactTable:
        """The contacts of the samples kept, as one table (:class:`ContactTable`)."""
        return ContactTable.from_samples(self._contacts[: self._n], nv)

    def _rows(self, times: list[float], samples: Samples) -> None:
        """Keep several samples (the first one was kept before: the arrays exist)."""
        n = self._n
        k = len(times)
        while n + k > len(self._t):
            self._grow(())
        self._t[n : n + k] = times
        for col, block in zip(self._cols, samples, strict=True):
            col[n : n + k] = block
        self._n = n + k

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
