"""The contact forces of a run: one record per contact point and sample (world frame).

The contact law reports, at every sample, the forces of its current contact problem
(:meth:`packbot.contact.base.ForceReport.contacts`): in the contact-normal mode the
forces of the constrained dynamics' mode (each engaged patch point's normal force, with its
Coulomb friction when the pair slips; a sticking pair's friction force at its patch centre),
at rest the frictional problem the rest capture solved (per-point cones). What one contact is
(:class:`ContactForce`) and how a run keeps them all (:class:`ContactTable`: flat columns, one
row per contact and sample) live here; how the engine finds them lives with the law
(:mod:`packbot.contact.normal_forces`). Conventions (docs/contact.md, "Contact forces"):

* ``link1`` / ``piece1`` is the pair's body 1 (the distal body), ``link2`` / ``piece2`` its
  body 2 (proximal, the chassis or an obstacle), as in the event log;
* ``normal`` is the unit normal from body 1 to body 2 (world frame);
* ``force`` [N] (world frame) acts on body 2 at ``point``; body 1 receives its opposite there;
  its component along ``normal`` is the normal force (>= 0: a contact pushes), the rest is the
  friction force;
* ``point`` [m] (world frame) is where the bodies touch: the normal force (and a sticking
  pair's friction) acts there on both bodies. The engine's patch point is a pair of material
  points, ``point1`` on body 1 and ``point2`` on body 2, at most the contact tolerance apart;
  ``point`` is the one on the body that does not carry the normal (the gap's exact derivative
  puts the force there), and a sliding or resting point's friction acts at each body's own
  material point (body 2 at ``point2``, body 1 at ``point1``). A sticking pair's friction is
  one entry at its patch centre with no normal component (``point1 == point2 == point``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ContactForce",
    "ContactTable",
    "PairNames",
    "PairPoint",
    "SampleContact",
    "SampleForces",
    "joint_torque",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: A pair's names: (link1, piece1, link2, piece2).
PairNames = tuple[str, str, str, str]
#: One contact of one sample as the law reports it: names, point, point1, point2 [m], normal,
#: force [N].
SampleContact = tuple[PairNames, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]


class SampleForces(NamedTuple):
    """What the contact law reports of one sample's state.

    Attributes:
        contacts: Its contacts (:data:`SampleContact` each).
        limit_torque: The joint position stops' torques [N*m], shape (nv,): the torque each
            stop exerts on its joint (positive along +q; 0 off the stops).
        clamp_torque: The report's law's clamps' torques [N*m], shape (nv,) (positive along
            +q), or None: no clamp acts (zeros). Under the report's law (``joint_clamp``,
            ``handoff``) a contact's clamps hold the joints between its bodies: the torque
            each engaged clamp exerts on its joint (a limit stop under that law is a clamp
            too), a Cartesian force nowhere.
    """

    contacts: list[SampleContact]
    limit_torque: FloatArray
    clamp_torque: FloatArray | None = None


@dataclass(frozen=True, kw_only=True)
class PairPoint:
    """Where one contact of a pair acts (world frame; see the module for the conventions).

    Attributes:
        link1: Body 1 of the pair (distal).
        piece1: Its convex piece.
        link2: Body 2 of the pair (proximal, chassis or obstacle).
        piece2: Its convex piece.
        point: Where the bodies touch [m], world frame, shape (3,): the normal part acts there.
        point1: Body 1's material point [m] (its friction acts there), world, shape (3,).
        point2: Body 2's material point [m] (its friction acts there), world, shape (3,).
        normal: Unit contact normal from body 1 to body 2, world frame, shape (3,).
    """

    link1: str
    piece1: str
    link2: str
    piece2: str
    point: FloatArray
    point1: FloatArray
    point2: FloatArray
    normal: FloatArray

    @property
    def pair(self) -> str:
        """The pair as the diagnostics name it: ``"piece1 - piece2"`` (``link3/tube - ...``)."""
        return f"{self.piece1} - {self.piece2}"


@dataclass(frozen=True, kw_only=True)
class ContactForce(PairPoint):
    """One contact's force at one sample (world frame; see the module for the conventions).

    The pair and its points: :class:`PairPoint`.

    Attributes:
        force: Force on body 2 from body 1 [N], world frame, shape (3,) (body 1 receives
            ``-force``).
    """

    force: FloatArray

    @classmethod
    def from_sample(cls, contact: SampleContact) -> ContactForce:
        """The record of one contact as the law reports it."""
        (l1, p1, l2, p2), point, point1, point2, normal, force = contact
        return cls(
            link1=l1, piece1=p1, link2=l2, piece2=p2, point=point, point1=point1,
            point2=point2, normal=normal, force=force,
        )  # fmt: skip

    @property
    def normal_force(self) -> float:
        """The force's component along the normal [N] (>= 0: the contact pushes)."""
        return float(self.force @ self.normal)

    @property
    def friction_force(self) -> FloatArray:
        """The force's tangential part [N], world frame, shape (3,)."""
        return np.asarray(self.force - self.normal_force * self.normal, dtype=np.float64)


@dataclass(frozen=True)
class ContactTable:
    """Every contact of every sample of a run, as flat columns (one row per contact).

    Attributes:
        pairs: The pairs that were in contact at some sample, each (link1, piece1, link2,
            piece2), in the order they first appeared.
        sample: Index of each row's sample in the result's ``t``, shape (K,), non-decreasing.
        pair: Index of each row's pair in :attr:`pairs`, shape (K,).
        point: Where the bodies touch [m], world frame, shape (K, 3).
        point1: Body 1's material points [m], world frame, shape (K, 3).
        point2: Body 2's material points [m], world frame, shape (K, 3).
        normal: Unit normals from body 1 to body 2, world frame, shape (K, 3).
        force: Forces on body 2 [N], world frame, shape (K, 3).
        known: Per sample, whether the law could say its forces, shape (N,): False at a
            time-stepping window's opening instant (such a sample has no rows; its contacts
            are unknown, not absent).
        limit_torque: Per sample, the torque each joint position stop exerts on its joint
            [N*m], shape (N, nv) (positive along +q; 0 off the stops; NaN where not known).
        clamp_torque: Per sample, the torque each of the report's law's clamps exerts on its
            joint [N*m], shape (N, nv) (positive along +q; 0 where none acts, and in the
            other modes; NaN where not known); (0, 0): a table built without it (zeros).
    """

    pairs: tuple[PairNames, ...] = ()
    sample: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    pair: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    point: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    point1: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    point2: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    normal: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    force: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    known: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    limit_torque: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    clamp_torque: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))

    def __len__(self) -> int:
        """The number of rows (contacts over all samples)."""
        return len(self.sample)

    @classmethod
    def from_samples(cls, samples: Sequence[SampleForces | None], nv: int) -> ContactTable:
        """The table of what the law reported per sample (sample k: ``samples[k]``).

        Args:
            samples: Per sample, the law's report (None: it could not say).
            nv: The number of joint velocities (the limit torques' columns).
        """
        known = np.array([s is not None for s in samples], dtype=bool)
        limit = np.full((len(samples), nv), np.nan)
        clamp = np.full((len(samples), nv), np.nan)
        for k, s in enumerate(samples):
            if s is not None:
                limit[k] = s.limit_torque
                clamp[k] = 0.0 if s.clamp_torque is None else s.clamp_torque
        index: dict[PairNames, int] = {}
        rows_sample: list[int] = []
        rows_pair: list[int] = []
        pts: list[FloatArray] = []
        pt1: list[FloatArray] = []
        pt2: list[FloatArray] = []
        nrm: list[FloatArray] = []
        frc: list[FloatArray] = []
        for k, found in enumerate(samples):
            for names, point, point1, point2, normal, force in () if found is None else found[0]:
                rows_sample.append(k)
                rows_pair.append(index.setdefault(names, len(index)))
                pts.append(point)
                pt1.append(point1)
                pt2.append(point2)
                nrm.append(normal)
                frc.append(force)
        if not rows_sample:
            return cls(known=known, limit_torque=limit, clamp_torque=clamp)
        return cls(
            known=known,
            limit_torque=limit,
            clamp_torque=clamp,
            pairs=tuple(index),
            sample=np.array(rows_sample, dtype=np.int64),
            pair=np.array(rows_pair, dtype=np.int64),
            point=np.array(pts, dtype=np.float64).reshape(-1, 3),
            point1=np.array(pt1, dtype=np.float64).reshape(-1, 3),
            point2=np.array(pt2, dtype=np.float64).reshape(-1, 3),
            normal=np.array(nrm, dtype=np.float64).reshape(-1, 3),
            force=np.array(frc, dtype=np.float64).reshape(-1, 3),
        )

    def rows_of(self, k: int) -> slice:
        """The rows of sample k (a slice: the rows are ordered by sample)."""
        lo = int(np.searchsorted(self.sample, k, side="left"))
        hi = int(np.searchsorted(self.sample, k, side="right"))
        return slice(lo, hi)

    def at_sample(self, k: int) -> list[ContactForce]:
        """The contacts of sample k."""
        out = []
        for r in range(*self.rows_of(k).indices(len(self))):
            l1, p1, l2, p2 = self.pairs[int(self.pair[r])]
            out.append(
                ContactForce(
                    link1=l1,
                    piece1=p1,
                    link2=l2,
                    piece2=p2,
                    point=self.point[r].copy(),
                    point1=self.point1[r].copy(),
                    point2=self.point2[r].copy(),
                    normal=self.normal[r].copy(),
                    force=self.force[r].copy(),
                )
            )
        return out

    def pair_force(self, n_samples: int) -> FloatArray:
        """Per pair and sample, the magnitude of the pair's summed force [N], (pairs, N)."""
        out = np.zeros((len(self.pairs), n_samples, 3))
        np.add.at(out, (self.pair, self.sample), self.force)
        return np.asarray(np.linalg.norm(out, axis=2), dtype=np.float64)

    def pair_normal_force(self, n_samples: int) -> FloatArray:
        """Per pair and sample, the sum of its normal forces [N], shape (pairs, N)."""
        out = np.zeros((len(self.pairs), n_samples))
        fn = np.einsum("ij,ij->i", self.force, self.normal)
        np.add.at(out, (self.pair, self.sample), fn)
        return out


def joint_torque(
    model: Any, data: Any, q: FloatArray, contacts: Sequence[SampleContact]
) -> FloatArray:
    """The joint torque [N*m] the contacts exert on the arm at q, shape (model.nv,).

    Each force acts on body 2 and its opposite on body 1 (a body not in ``model``, the chassis
    or an obstacle, takes none): the normal part at ``point``, the friction at each body's own
    material point (see the module). The contacts' share of the equations of motion:
    M a + C v + g = tau + joint_torque(...).

    Args:
        model: The Pinocchio model the contacts' links are frames of (full coordinates).
        data: A data of ``model`` (its Jacobians are computed here at q).
        q: Configuration [rad], shape (model.nq,).
        contacts: (names, point, point1, point2, normal, force) per contact.
    """
    import pinocchio as pin

    out = np.zeros(model.nv)
    if not contacts:
        return out
    pin.computeJointJacobians(model, data, q)
    joints: dict[str, int] = {}
    for names, point, point1, point2, normal, force in contacts:
        f = np.asarray(force, dtype=np.float64)
        n = np.asarray(normal, dtype=np.float64)
        fn = float(f @ n) * n
        for link, sign, own in ((names[2], 1.0, point2), (names[0], -1.0, point1)):
            j = joints.get(link)
            if j is None:
                fid = model.getFrameId(link) if model.existFrame(link) else -1
                j = joints[link] = int(model.frames[fid].parentJoint) if fid >= 0 else 0
            if j == 0:
                continue
            J = np.asarray(pin.getJointJacobian(model, data, j, pin.LOCAL_WORLD_ALIGNED))
            J = J.reshape(6, model.nv)
            o = data.oMi[j].translation
            moment = np.cross(np.asarray(point) - o, fn) + np.cross(np.asarray(own) - o, f - fn)
            out += sign * (J[:3].T @ f + J[3:].T @ moment)
    return out
