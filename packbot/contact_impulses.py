"""The impulses of a run's impacts: one record per contact point and impact (world frame).

An *impact* here is every restart of the contact-normal mode that applied an impulse: at an
``impact`` event, and at any other event (a limit reached, a re-patch) whose restart found a
touching row approaching. The restart solves one problem for the impulses of every
touching row (:meth:`~packbot.contact.normal_steps.RestartSteps.impulse`: Newton's law with
restitution, Coulomb's cone); the velocities jump by M^-1 J^T P. What one contact's impulse is
(:class:`ContactImpulse`) and how a run keeps them (:class:`ImpactTable`) live here; the
conventions are the contact forces' (:mod:`packbot.contact_forces`), with impulses [N*s] for
forces [N]:

* ``impulse`` [N*s] (world frame) acts on body 2 (``link2``) at ``point``; body 1 receives its
  opposite; its component along ``normal`` (from body 1 to body 2) is the normal impulse (>= 0),
  the rest is the friction impulse, which acts at each body's own material point;
* a joint on its position stop takes its stop's impulse [N*m*s] (per joint, positive along +q).

With them M(q) (v+ - v-) = sum J^T P + the stops' impulses at the impact's configuration q (the
drift projection's), v- and v+ the velocities just before and after the impulse. The restart
then stops the slow slides (``stop_slow``: velocities below the stick speed) and may capture a
rest (every velocity to zero): those last changes of the event's velocities are not in the
records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from packbot.contact_forces import ContactTable, PairPoint, SampleForces

__all__ = ["ContactImpulse", "ImpactTable"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class ContactImpulse(PairPoint):
    """One contact's impulse at one impact (world frame; see the module for the conventions).

    The pair and its points: :class:`~packbot.contact_forces.PairPoint`.

    Attributes:
        impulse: Impulse on body 2 from body 1 [N*s], world frame, shape (3,).
    """

    impulse: FloatArray

    @property
    def normal_impulse(self) -> float:
        """The impulse's component along the normal [N*s] (>= 0)."""
        return float(self.impulse @ self.normal)


@dataclass(frozen=True)
class ImpactTable:
    """Every impact of a run with its contacts' impulses.

    Attributes:
        t: The time of each impact [s] (each restart that applied an impulse), shape (I,),
            non-decreasing.
        rows: Its contacts as a :class:`~packbot.contact_forces.ContactTable` whose sample
            index is the impact's index in :attr:`t`, whose ``force`` column holds the
            impulses [N*s], whose ``limit_torque`` holds the stops' impulses [N*m*s], shape
            (I, nv), and whose ``clamp_torque`` the clamps' (:attr:`clamp_impulse`).
    """

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    rows: ContactTable = field(default_factory=ContactTable)

    def __len__(self) -> int:
        """The number of impacts."""
        return len(self.t)

    @classmethod
    def from_log(cls, log: Sequence[tuple[float, SampleForces]], nv: int) -> ImpactTable:
        """The table of the impacts a law logged, each (t [s], its contacts' impulses).

        Args:
            log: Per impact its time and its records (force slots: impulses [N*s]; the limit
                slot: the stops' impulses [N*m*s], full coordinates).
            nv: The number of joint velocities.
        """
        t = np.array([t for t, _ in log], dtype=np.float64)
        return cls(t=t, rows=ContactTable.from_samples([s for _, s in log], nv))

    @property
    def limit_impulse(self) -> FloatArray:
        """The stops' impulses [N*m*s] per impact and joint, shape (I, nv).

        (0, 0) for an empty table built without its joints.
        """
        return np.asarray(self.rows.limit_torque, dtype=np.float64)

    @property
    def clamp_impulse(self) -> FloatArray:
        """The report's law's clamps' impulses [N*m*s] per impact and joint, shape (I, nv).

        A hand-off's restart (:mod:`packbot.contact.handoff`): the joint impulse its clamped
        joints received (positive along +q); 0 in the other modes. (0, 0) for an empty table
        built without its joints.
        """
        clamp = self.rows.clamp_torque
        if clamp.shape[0] != len(self.t):  # (a table built without the column: zeros)
            return np.zeros_like(self.rows.limit_torque)
        return np.asarray(clamp, dtype=np.float64)

    def of(self, i: int) -> list[ContactImpulse]:
        """The contacts' impulses of impact i.

        Args:
            i: The impact's index in :attr:`t`.

        Returns:
            Its records, one per touching point with a normal impulse.
        """
        return [
            ContactImpulse(
                link1=c.link1,
                piece1=c.piece1,
                link2=c.link2,
                piece2=c.piece2,
                point=c.point,
                point1=c.point1,
                point2=c.point2,
                normal=c.normal,
                impulse=c.force,
            )
            for c in self.rows.at_sample(i)
        ]

    def index(self, t: float) -> list[int]:
        """The impacts at a time, in order.

        Args:
            t: Time [s]; an impact within 1e-12 s of it counts.

        Returns:
            Their indices in :attr:`t`.
        """
        lo = int(np.searchsorted(self.t, t - 1e-12, side="left"))
        hi = int(np.searchsorted(self.t, t + 1e-12, side="right"))
        return list(range(lo, hi))
