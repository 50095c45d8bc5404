"""What a simulation returns: :class:`SimResult`, its event log and diagnostics."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from packbot import result_file, result_store
from packbot.config import SimConfig
from packbot.contact_forces import ContactForce, ContactTable, joint_torque
from packbot.contact_impulses import ContactImpulse, ImpactTable
from packbot.errors import ConfigurationError, PackbotError, ResultFileError, UnknownNameError
from packbot.failures import Failure
from packbot.keywords import checked_arguments
from packbot.result_file import SAMPLE_ARRAYS, read_saved

if TYPE_CHECKING:
    import pandas as pd

    from packbot.environment import Environment
    from packbot.model import Robot
    from packbot.payload import Payload

__all__ = ["EVENT_KINDS", "RESULT_FORMAT", "Diagnostics", "Event", "ResultFileError", "SimResult"]

#: The format tag of a file written by :meth:`SimResult.save` (its version after the slash).
RESULT_FORMAT = result_file.RESULT_FORMAT
#: The arrays of a result, each saved as it is.
_ARRAYS = SAMPLE_ARRAYS


EventKind = Literal[
    "impact",
    "limit",
    "release",
    "secondary_intersection",
    "handoff",
    "engage",
    "disengage",
    "slip",
    "stick",
    "repatch",
    "painleve",
    "timestep",
    "resume",
    "failure",
    "freeze",
    "pick",
    "drop",
]
#: The kinds of event the simulator logs.
EVENT_KINDS: tuple[str, ...] = (
    "impact",  # a pair's signed distance fell to the contact tolerance: impact law applied
    "limit",  # a joint reached a position limit: the same impact law and clamp
    "release",  # an active contact or limit stop let go (separated, or its clamp would pull);
    # with relevant_joints: the clamp of that joint let go (the report's law: the joint moves
    # away from the contact, a clamp would do positive work), the pair stays in contact
    "secondary_intersection",  # an active, clamped pair penetrated anyway (report's self-diagnosis)
    "handoff",  # the same with SimConfig.handoff: its clamps released, the pair handed to the
    # contact-normal machinery (velocities before/after its restart's impulse)
    "engage",  # a clamped joint started to accelerate toward its contact: its lock engaged;
    # or a released clamp's joint turned toward its contact: the clamp is back in force
    "disengage",  # a locked joint's constraint torque would pull: its lock let go
    "slip",  # a joint held by static friction or a brake needed more than its holding torque;
    # normal mode: a sticking contact's friction force reached the cone (link1/link2: the pair)
    "stick",  # a sliding joint with Coulomb friction stopped and its holding torque suffices;
    # normal mode: a sliding contact stopped sliding (friction holds it)
    "repatch",  # normal mode: a pair in contact penetrated: its patch was recomputed
    "painleve",  # normal mode: no consistent contact forces (friction): a window follows
    "timestep",  # normal mode: events piled up, or no consistent mode: a window of time steps
    # starts (contact/timestep)
    "resume",  # normal mode: the window's contacts settled: event-driven integration resumes
    "failure",  # a joint failure was injected (link1: joint, link2: kind)
    "freeze",  # the impulse that stops a freezing joint (link1: joint; distance: its angle)
    "pick",  # the payload was picked up (generalized momentum kept)
    "drop",  # the payload was dropped
)


@checked_arguments
@dataclass(frozen=True)
class Event:
    """One entry of the event log.

    Attributes:
        t: Time [s].
        kind: One of :data:`EVENT_KINDS`.
        link1: Body 1 (distal) of the pair, or the joint name for a limit.
        link2: Body 2 (proximal, chassis or obstacle), or ``"upper"``/``"lower"`` for a limit.
        piece1: Convex piece on body 1 ("" for a limit).
        piece2: Convex piece on body 2 ("" for a limit).
        distance: Signed distance of the pair at the event [m] (limit: distance to the stop
            [rad]).
        relevant_joints: Joints the law acted on (impact: the relevant joints).
        v_before: Joint velocities before [rad/s], full coordinates, shape (nv,).
        v_after: Joint velocities after [rad/s], shape (nv,).
        energy_before: Total mechanical energy before [J].
        energy_after: Total mechanical energy after [J].
    """

    t: float
    kind: str
    link1: str = ""
    link2: str = ""
    piece1: str = ""
    piece2: str = ""
    distance: float = float("nan")
    relevant_joints: tuple[str, ...] = ()
    v_before: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    v_after: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    energy_before: float = float("nan")
    energy_after: float = float("nan")

    @property
    def energy_change(self) -> float:
        """Energy after minus before [J] (positive: the event added energy)."""
        return self.energy_after - self.energy_before


@checked_arguments
@dataclass
class Diagnostics:
    """Work done and invariants seen by a run.

    Attributes:
        steps: Accepted integration steps.
        rejected_steps: Rejected integration steps.
        rhs_calls: Right-hand-side evaluations.
        sweeps: Collision sweeps (one per accepted step, plus root finding).
        distance_queries: Single-pair distance evaluations during event location (and, in
            the contact-normal mode, the screen of contacts between step ends for the steps
            the loop takes; the compiled stretch's own are not counted).
        restarts: Integrator restarts (after events).
        wall_time: Wall-clock time of the run [s].
        min_distance: Smallest signed distance seen at any accepted step or sample [m]. In the
            contact-normal mode it is also the minimum over the motion between step ends to
            within ``PENETRATION_TOL / 20`` for every pair the screen of contacts between step
            ends proves clear (pairs outside the contact set, and pairs of it apart by more
            than ``PENETRATION_TOL`` at a step's end): each step is screened by conservative
            advancement on the pairs' distances, a pair it finds touching inside a step is an
            event; a screen that reaches its query cap proves nothing (docs/contact.md,
            "Contacts between step ends").
        min_distance_pair: Links of that pair, ``"link1/piece1 - link2/piece2"``.
        reset_energy_gain: Total energy the report's velocity resets added [J]: the sum, over
            the ``impact``, ``secondary_intersection`` and ``limit`` events, of each one's
            ``energy_after - energy_before`` where positive (the ``"zero"`` reset on a coupled
            arm can add kinetic energy; docs/simulator.md, "The impact law").
        windows: Time-stepping windows of the contact-normal mode (events piled up).
        window_steps: Time steps taken in them.
        window_energy_removed: Energy the windows' guard removed [J]: the sum over their steps
            of what a step would have gained beyond the applied torques' work
            (:mod:`packbot.contact.timestep`).
        projection_energy_removed: Energy the contact-normal mode's drift projections took
            from the kinetic energy [J]: a projection moves the arm out of the surfaces it was
            carried into, which would add the potential energy the motion into them had turned
            into kinetic; it scales the velocity to leave the energy as it was
            (:meth:`NormalContacts.neutral_velocity
            <packbot.contact.normal_contacts.NormalContacts.neutral_velocity>`).
    """

    steps: int = 0
    rejected_steps: int = 0
    rhs_calls: int = 0
    sweeps: int = 0
    distance_queries: int = 0
    restarts: int = 0
    wall_time: float = 0.0
    min_distance: float = float("inf")
    min_distance_pair: str = ""
    reset_energy_gain: float = 0.0
    windows: int = 0
    window_steps: int = 0
    window_energy_removed: float = 0.0
    projection_energy_removed: float = 0.0


@checked_arguments
@dataclass
class SimResult:
    """The outcome of :func:`packbot.simulate`.

    Attributes:
        t: Sample times [s], shape (N,): every ``sample_dt`` from the dense output, plus the
            instants just before and just after every event (equal times, pre first).
        q: Joint positions [rad], shape (N, nq), full model coordinates.
        v: Joint velocities [rad/s], shape (N, nv).
        tau: Applied motor torques [N*m], shape (N, nv): the command after the failures,
            saturation and motor lag (friction not included).
        energy: Total mechanical energy (kinetic incl. armature + potential) [J], shape (N,).
        events: The event log, in time order.
        rest_time: First time after which every joint speed stays below
            ``config.rest_speed`` to the end [s], or None.
        joint_names: Names of the columns of q, v, tau.
        config: The settings of the run.
        diagnostics: Work done and invariants seen.
        tau_cmd: Commanded torques [N*m], shape (N, nv) (a sampled-data controller's held
            command).
        tau_friction: Joint friction torques [N*m], shape (N, nv) (viscous + Coulomb; for a
            joint held by static friction or a brake, the holding torque).
        effort: Effective effort limits [N*m], shape (N, nv) (a weak joint's scaled).
        contacts: The contact forces of every sample (:class:`~packbot.contact_forces.
            ContactTable`; read them with :meth:`contacts_at`): the contact-normal mode's
            engaged contacts (inside a time-stepping window, its steps' mean forces), empty
            for the other modes.
        failures: The failures injected during the run.
        control_ticks: Number of ticks of a sampled-data controller.
        environment: The run's obstacles (None: a result built without one; ``simulate``
            gives the floor alone when it was called without an environment).
        payload: The run's payload, or None.
        scenario_text: The scenario file's text ("" for a run not made from a file).
        impacts: The restarts' contact impulses (:class:`~packbot.contact_impulses.
            ImpactTable`; read them with :meth:`impulses_at`): the contact-normal mode's.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    tau: NDArray[np.float64]
    energy: NDArray[np.float64]
    events: list[Event]
    rest_time: float | None
    joint_names: tuple[str, ...]
    config: SimConfig
    diagnostics: Diagnostics
    tau_cmd: NDArray[np.float64]
    tau_friction: NDArray[np.float64]
    effort: NDArray[np.float64]
    contacts: ContactTable = field(default_factory=ContactTable)
    failures: tuple[Failure, ...] = ()
    control_ticks: int = 0
    environment: Environment | None = None
    payload: Payload | None = None
    scenario_text: str = ""
    impacts: ImpactTable = field(default_factory=ImpactTable)

    @checked_arguments
    def events_of(self, *kinds: str) -> list[Event]:
        """The events of the given kinds (each one of :data:`EVENT_KINDS`).

        Raises:
            UnknownNameError: A kind that is not an event kind (a typo would give no events).
        """
        for kind in kinds:
            if kind not in EVENT_KINDS:
                raise UnknownNameError("event kind", kind, EVENT_KINDS)
        return [e for e in self.events if e.kind in kinds]

    @checked_arguments
    def joint(self, name: str) -> int:
        """Column index of a joint.

        Raises:
            UnknownNameError: No joint of that name.
        """
        if name not in self.joint_names:
            raise UnknownNameError("joint", name, self.joint_names)
        return self.joint_names.index(name)

    @checked_arguments
    def frame_positions(
        self, frame: str | None = None, robot: Robot | None = None
    ) -> NDArray[np.float64]:
        """World positions [m] of a frame's origin at every sample, shape (N, 3).

        Pinocchio's forward kinematics on :attr:`q` (full coordinates: a locked or frozen
        joint at its angle), in the world frame (``base_link``'s: x forward, z up).

        Args:
            frame: A frame of the model (a link, a joint or a tool frame such as
                ``"camera_optical"``); None: the robot's tool frame
                (:attr:`packbot.Robot.tool_frame`, PackBot's ``gripper_tool``).
            robot: The robot the run simulated; None: the shipped one
                (:func:`packbot.load_robot`, loaded once). A result does not store its model:
                a run of another URDF needs that robot here.

        Raises:
            UnknownNameError: ``frame`` is not a frame of the model (lists the valid ones).
            ConfigurationError: ``robot`` is not a Robot, or its joints are not the result's.
        """
        import pinocchio as pin

        robot = self._robot_of(robot)
        model = robot.model
        frame = robot.tool_frame if frame is None else frame
        if not isinstance(frame, str) or not model.existFrame(frame):
            raise UnknownNameError("frame", frame, sorted({str(f.name) for f in model.frames}))
        fid = model.getFrameId(frame)
        data = model.createData()
        q = np.asarray(self.q, dtype=np.float64)
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.framesForwardKinematics(model, data, qi)
            out[i] = data.oMf[fid].translation
        return out

    def _robot_of(self, robot: Robot | None) -> Robot:
        """The run's robot: ``robot`` checked against the result's joints, or the shipped one."""
        from packbot.model import Robot, _shipped_robot

        if robot is None:
            robot = _shipped_robot()
        elif not isinstance(robot, Robot):
            raise ConfigurationError("robot", robot, "None or a packbot.Robot")
        if tuple(robot.joint_names) != tuple(self.joint_names):
            raise ConfigurationError(
                "robot",
                list(robot.joint_names),
                f"a robot with the result's joints {list(self.joint_names)}",
            )
        return robot

    @checked_arguments
    def contacts_at(self, t: float, *, before: bool = False) -> list[ContactForce]:
        """The contacts at sample time t, each with its force (world frame).

        Conventions (:mod:`packbot.contact_forces`): ``force`` [N] acts on ``link2`` at
        ``point`` [m], ``link1`` receives its opposite; ``normal`` points from ``link1`` to
        ``link2``; a sticking pair's friction is an entry at its patch centre.

        Args:
            t: A sample time [s] (one of :attr:`t`, within 1e-9 s).
            before: At an event's instant (two samples share its time), the sample before it
                (default: the one after).

        Returns:
            The sample's contacts: empty where it had none, and where its forces are not
            known (:attr:`contacts_known` tells the two apart).

        Raises:
            ConfigurationError: ``t`` is not a sample time of the result.
        """
        k = self.sample_index(t, before=before)
        return self.contacts.at_sample(k)

    @checked_arguments
    def impulses_at(self, t: float) -> list[ContactImpulse]:
        """The contact impulses of the restarts at time t [s] (within 1e-12 s; world frame).

        Conventions (:mod:`packbot.contact_impulses`): ``impulse`` [N*s] acts on ``link2``
        at ``point``, ``link1`` receives its opposite. Every restart that applied an impulse
        has them (an ``impact`` event's, and a ``limit`` or ``repatch`` event's whose restart
        found a touching row approaching); empty where none did (a release, a stick).
        """
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not np.isfinite(t):
            raise ConfigurationError("t", t, "a finite time [s]")
        return [c for i in self.impacts.index(float(t)) for c in self.impacts.of(i)]

    @property
    def contacts_known(self) -> NDArray[np.bool_]:
        """Per sample, whether its contact forces are known, shape (N,) (a copy).

        False at a time-stepping window's opening instant (recorded before its first step):
        the contacts of such a sample are unknown, not absent (:meth:`contacts_at` gives none,
        :meth:`contact_torques`, :attr:`limit_torque` and :attr:`clamp_torque` NaN). Under the
        report's law (``joint_clamp``) a sample is known, its clamped pairs acting through
        :attr:`clamp_torque` alone.
        """
        known = self.contacts.known
        if len(known) != len(self.t):  # (a table without the mask: a result built by hand)
            return np.zeros(len(self.t), dtype=bool)
        return np.array(known, dtype=bool)

    @property
    def limit_torque(self) -> NDArray[np.float64]:
        """The joint position stops' torques [N*m] at every sample, shape (N, nv) (a copy).

        The torque each hard stop exerts on its joint: positive along +q, 0 off the stops,
        NaN where the forces are not known (:attr:`contacts_known`). With
        :meth:`contact_torques` it closes the equations of motion of the free joints:
        M(q) a + C(q, v) v + g(q) = tau + tau_friction + contact_torques + limit_torque +
        :attr:`clamp_torque`.
        """
        lim = self.contacts.limit_torque
        if lim.shape != self.q.shape:
            return np.full(self.q.shape, np.nan)
        return np.array(lim, dtype=np.float64)

    @property
    def clamp_torque(self) -> NDArray[np.float64]:
        """The report's law's clamp torques [N*m] at every sample, shape (N, nv) (a copy).

        Under the report's law (``contact_mode="joint_clamp"``, with or without ``handoff``) a
        pair in contact acts on the arm through clamps on the joints between its bodies, not
        as a force at a point: the torque each engaged clamp exerts on its joint (positive
        along +q), a joint clamped both ways and a handed-off problem's locked joints
        included; 0 where no clamp acts and in the other modes; NaN where the forces are not
        known (:attr:`contacts_known`). The handed-off pairs' own forces are contacts
        (:meth:`contacts_at`). Where only a position stop holds a joint its torque is the
        stop's (:attr:`limit_torque`); where a pair's clamp holds it too, the clamp's. The
        equations of motion of the free joints close with it: M(q) a + C(q, v) v + g(q) =
        tau + tau_friction + contact_torques + limit_torque + clamp_torque.
        """
        clamp = self.contacts.clamp_torque
        if clamp.shape != self.q.shape:
            out = np.zeros(self.q.shape)
            out[~self.contacts_known] = np.nan
            return out
        return np.array(clamp, dtype=np.float64)

    @checked_arguments
    def sample_index(self, t: float, *, before: bool = False) -> int:
        """The index in :attr:`t` of the sample at time t [s] (within 1e-9 s).

        Args:
            t: A sample time [s].
            before: Of two samples at one instant (an event's), the first (default: the last).

        Raises:
            ConfigurationError: No sample within 1e-9 s of t.
        """
        if isinstance(t, bool | np.bool_) or not isinstance(
            t, int | float | np.integer | np.floating
        ):
            raise ConfigurationError("t", t, "a sample time of the result [s] (a real number)")
        times = np.asarray(self.t, dtype=np.float64)
        tf = float(t)
        lo = int(np.searchsorted(times, tf - 1e-9, side="left"))
        hi = int(np.searchsorted(times, tf + 1e-9, side="right"))
        if not np.isfinite(tf) or lo >= hi:
            near = ""
            if len(times) and np.isfinite(tf):
                k = int(np.clip(np.searchsorted(times, tf), 0, len(times) - 1))
                near = f"; the nearest is t = {float(times[k])!r}"
            raise ConfigurationError("t", t, f"a sample time of the result (see result.t{near})")
        return lo if before else hi - 1

    @checked_arguments
    def contact_torques(self, robot: Robot | None = None) -> NDArray[np.float64]:
        """The joint torques the contact forces exert [N*m] at every sample, shape (N, nv).

        The sum over the contacts of J_b(x)^T f on body 2 and -J_b(x)^T f on body 1, with
        J_b(x) the world-frame Jacobian of body b's point x (zero for the chassis and the
        obstacles): the normal force at ``point`` on both bodies, the friction at each body's
        own material point (``point2``, ``point1``; :mod:`packbot.contact_forces`). The
        contacts' share of the equations of motion, in full coordinates (the joint stops'
        share is :attr:`limit_torque`). NaN rows where the forces are not known
        (:attr:`contacts_known`).

        Args:
            robot: The robot the run simulated; None: the shipped one.

        Raises:
            ConfigurationError: ``robot`` is not a Robot, or its joints are not the result's.
        """
        robot = self._robot_of(robot)
        model = robot.model
        data = model.createData()
        q = np.asarray(self.q, dtype=np.float64)
        out = np.zeros((len(q), model.nv))
        tab = self.contacts
        for k in np.unique(tab.sample).tolist():
            rows = range(*tab.rows_of(k).indices(len(tab)))
            found = [
                (tab.pairs[int(tab.pair[r])], tab.point[r], tab.point1[r], tab.point2[r],
                 tab.normal[r], tab.force[r])
                for r in rows
            ]  # fmt: skip
            out[k] = joint_torque(model, data, q[k], found)
        out[~self.contacts_known] = np.nan
        return out

    @checked_arguments
    def save(self, path: str | Path, *, extra: Mapping[str, str] | None = None) -> Path:
        """Write the whole result to one compressed ``.npz`` file, atomically.

        The file (see docs/simulator.md, "Saving and loading results") holds the arrays as
        they are (``t``, ``q``, ``v``, ``tau``, ``energy``, ``tau_cmd``, ``tau_friction``,
        ``effort``), the events' float fields and velocities as arrays, and the rest as JSON:
        the settings, environment, failures, payload, diagnostics, events' names, the
        scenario text, the joint names, packbot's version and the format tag
        :data:`RESULT_FORMAT`. Nothing is pickled. :meth:`load` gives back an equal result.
        For a reader with NumPy alone, ``joint_names``, ``scenario_text``, ``packbot_version``,
        ``config_json`` and ``rest_time`` [s] (NaN: none) are also stored as plain entries.

        Args:
            path: The file to write (written as given: no suffix is added).
            extra: Further plain text entries, name -> text (``packbot run`` adds
                ``scenario_name``); :meth:`load` ignores them.

        Returns:
            The path written.

        Raises:
            ConfigurationError: An ``extra`` name that the file's own entries use.
        """
        return result_store.write_result(self, path, extra)

    @classmethod
    @checked_arguments
    def load(cls, path: str | Path) -> SimResult:
        """Read a result written by :meth:`save`, checking the file before trusting it.

        The file is read with bounds (:mod:`packbot.result_file`): each entry's header first,
        then only the entries a result needs, each to exactly its size; every dtype, shape,
        count and value range is checked, and the JSON metadata's structure (docs/simulator.md,
        "Saving and loading results", lists the checks). The settings, environment, failures
        and payload are then rebuilt with their own constructors, so their checks run again.

        Args:
            path: The file.

        Raises:
            ResultFileError: The file is missing, is not a packbot result (no or another
                format tag), or is damaged or inconsistent (a missing, unknown, damaged or
                inconsistent entry): the error names the entry.
            ResultValueError: A stored setting, obstacle, failure or payload that its
                constructor refuses (both a ``ResultFileError`` and a ``ConfigurationError``).
        """
        saved = read_saved(path)
        return result_store.rebuild_result(saved, cls, Event, Diagnostics, EVENT_KINDS)

    @checked_arguments
    def to_dataframe(
        self, what: Literal["samples", "contacts", "impulses"] = "samples"
    ) -> pd.DataFrame:
        """The samples, the contacts or the impacts' impulses as a pandas DataFrame.

        Needs ``packbot[pandas]``.

        ``"samples"``: one row per sample, indexed by ``t`` [s]; columns ``q:<joint>`` [rad],
        ``v:<joint>`` [rad/s], ``tau:<joint>``, ``tau_cmd:<joint>``, ``tau_friction:<joint>``,
        ``effort:<joint>`` [N*m] and ``energy`` [J]. Two samples share a time at each event
        (before, then after).

        ``"contacts"``: one row per contact and sample (:attr:`contacts`), indexed by ``t``
        [s]; columns ``sample`` (the row of the samples), ``link1``, ``piece1``, ``link2``,
        ``piece2``, ``point_x`` ... ``point_z``, ``point1_*``, ``point2_*`` [m], ``normal_*``,
        ``force_*`` [N] (world frame, the force on link2), ``normal_force`` [N] and
        ``friction_force`` [N] (the tangential part's magnitude).

        ``"impulses"``: one row per contact and impact (:attr:`impacts`), indexed by the
        impact's ``t`` [s]; columns ``impact`` (its index), the pair's names and points as
        above, ``normal_*``, ``impulse_*`` [N*s] (on link2), ``normal_impulse`` and
        ``friction_impulse`` [N*s].

        Args:
            what: ``"samples"``, ``"contacts"`` or ``"impulses"``.

        Raises:
            PackbotError: pandas is not installed.
            ConfigurationError: ``what`` is none of them.
        """
        if what not in ("samples", "contacts", "impulses"):
            raise ConfigurationError("what", what, "'samples', 'contacts' or 'impulses'")
        try:
            import pandas as pd
        except ImportError as exc:
            raise PackbotError(
                'SimResult.to_dataframe needs pandas: pip install "packbot[pandas]"'
            ) from exc
        columns: dict[str, Any] = {}
        if what != "samples":
            impulses = what == "impulses"
            tab = self.impacts.rows if impulses else self.contacts
            times = self.impacts.t if impulses else self.t
            force = "impulse" if impulses else "force"
            names = [tab.pairs[int(k)] for k in tab.pair]
            columns["impact" if impulses else "sample"] = np.asarray(tab.sample)
            for k, key in enumerate(("link1", "piece1", "link2", "piece2")):
                columns[key] = [n[k] for n in names]
            for key in ("point", "point1", "point2", "normal", "force"):
                arr = np.asarray(getattr(tab, key))
                for k, axis in enumerate("xyz"):
                    columns[f"{force if key == 'force' else key}_{axis}"] = arr[:, k]
            fn = np.einsum("ij,ij->i", tab.force, tab.normal)
            columns[f"normal_{force}"] = fn
            columns[f"friction_{force}"] = np.linalg.norm(
                tab.force - fn[:, None] * tab.normal, axis=1
            )
            t = np.asarray(times)[np.asarray(tab.sample, dtype=np.intp)]
            return pd.DataFrame(columns, index=pd.Index(t, name="t"))
        for name in ("q", "v", "tau", "tau_cmd", "tau_friction", "effort"):
            arr = np.asarray(getattr(self, name))
            for k, joint in enumerate(self.joint_names):
                columns[f"{name}:{joint}"] = arr[:, k]
        columns["energy"] = np.asarray(self.energy)
        return pd.DataFrame(columns, index=pd.Index(np.asarray(self.t), name="t"))


def rest_time(t: NDArray[np.float64], v: NDArray[np.float64], speed: float) -> float | None:
    """First time after which every joint speed stays below ``speed`` [rad/s] to the end."""
    moving = np.flatnonzero(np.abs(v).max(axis=1) >= speed)
    if len(moving) == 0:
        return float(t[0])
    last = moving[-1]
    if last == len(t) - 1:
        return None
    return float(t[last + 1])
