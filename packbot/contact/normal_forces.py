"""The contact forces of the contact-normal mode at a state: what each patch point carries.

The forces are those of the problem the mode solves, read off its multipliers (nothing is
solved a second way):

* with the modes fixed (:meth:`~packbot.contact.normal_dynamics.ConstrainedDynamics.evaluate`),
  an engaged patch point's multiplier lambda is its normal force: the force on body 2 is
  ``lambda n``, plus ``-mu lambda s`` when its pair slips (s the point's sliding direction, as
  the force columns ``J_n - mu J_s`` have it); a sticking pair's two tangential multipliers
  are its friction force at the patch centre, ``lambda_1 t1 + lambda_2 t2``;
* at rest (the rest capture), the frictional problem of every touching row
  (:meth:`~packbot.contact.normal_dynamics.ConstrainedDynamics.rest_solution`): each touching
  point's force (t1, t2, n) in its cone; where that problem is statically indeterminate, the
  distribution deepest inside the cones (:mod:`packbot.contact.static_forces`).

A joint limit row is not a contact: its multiplier is the stop's torque on its joint
(``-side lambda``: an upper stop pushes toward -q), reported per joint beside the contacts.
With the modes fixed the records are the extension's (``ContactRhs.forces``,
``src/native/contact_rhs_forces.cpp``, on the rows of the evaluation); at rest they are built
here from the frictional problem's solution.
Conventions of the records: :mod:`packbot.contact_forces`. :class:`NormalReport` is the
mode's report of its forces at the samples (:class:`~packbot.contact.base.ForceReport`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.static_forces import analytic_centre
from packbot.contact_forces import PairNames, SampleContact, SampleForces

if TYPE_CHECKING:
    from packbot.contact.normal_contacts import NormalContacts
    from packbot.contact.normal_law import NormalLaw
    from packbot.contact.normal_patch import _Pair

__all__ = [
    "NormalReport",
    "RowForces",
    "mode_forces",
    "pair_frame",
    "pair_names",
    "pair_points",
    "rest_friction",
    "row_forces",
    "row_impulses",
]

FloatArray = NDArray[np.float64]


class RowForces(NamedTuple):
    """A contact set's forces at a state as its problem found them.

    Attributes:
        found: The contacts and the joint stops' torques (:func:`mode_forces`).
        beyond: The engaged rows after the patch and limit rows (a hand-off's clamp rows):
            row -> its normal multiplier [N*m].
        qc: The rows' generalized force C^T lambda [N*m], shape (nv,) (every row's; at rest
            with the joints' friction boxes' torques).
    """

    found: SampleForces
    beyond: dict[int, float]
    qc: FloatArray


def mode_forces(
    nc: NormalContacts,
    data: Any,
    q: FloatArray,
    v: FloatArray,
    a_free: FloatArray,
    minv: FloatArray,
) -> SampleForces:
    """The contacts and stop torques of the contact set's current mode at (q, v), world frame.

    Args:
        nc: The contact set.
        data: A Pinocchio data of the set's model for the placements (not the set's own).
        q: Configuration [rad].
        v: Velocity [rad/s].
        a_free: Unconstrained accelerations [rad/s^2] (with the locks' rows, as the law's).
        minv: M^-1 at q.

    Returns:
        (names, point, point1, point2 [m], normal, force on body 2 [N]) per contact point,
        and the joint stops' torques [N*m] (nv,).
    """
    return row_forces(nc, data, q, v, a_free, minv).found


def row_forces(
    nc: NormalContacts,
    data: Any,
    q: FloatArray,
    v: FloatArray,
    a_free: FloatArray,
    minv: FloatArray,
) -> RowForces:
    """:func:`mode_forces`, with the multipliers of the rows it does not place and C^T lambda.

    Same arguments as :func:`mode_forces`.
    """
    limit = np.zeros(nc.nv)
    if not nc.engaged:
        return RowForces(SampleForces([], limit), {}, np.zeros(nc.nv))
    pairs = nc._pair_list
    ev = None if nc.resting else nc.evaluate(q, v, a_free, minv, forces=True)
    if ev is None or ev.rest is not None:
        pin.forwardKinematics(nc.model, data, q)
        frames = [pair_frame(data, p) for p in pairs]
        return _rest_forces(nc, data, pairs, frames, q, a_free, minv)
    # the rows of the evaluation (its state): the extension's records of the plan's forces
    on1 = np.array([p.on1 for p in pairs], dtype=np.uint8)
    who, touch, p1, p2, normal, force, limit = nc._rows_rhs().forces(ev.lam, on1)
    names = [pair_names(p) for p in pairs]
    out: list[SampleContact] = [
        (names[i], touch[k], p1[k], p2[k], normal[k], force[k])
        for k, i in enumerate(who[:, 0].tolist())
    ]
    base = sum(len(p.local1) for p in pairs) + len(nc.limits)
    beyond = {r: float(ev.lam[e]) for e, r in enumerate(nc.engaged) if r >= base}
    assert ev.qc is not None  # (asked for)
    return RowForces(SampleForces(out, limit), beyond, ev.qc)


def row_impulses(
    nc: NormalContacts, data: Any, q: FloatArray, rows: NDArray[np.intp], P: FloatArray
) -> SampleForces:
    """An impact's impulses on its touching rows as records (:mod:`packbot.contact_impulses`).

    Args:
        nc: The contact set (its pairs and limits as the impact's rows had them).
        data: A Pinocchio data of the set's model for the placements (not the set's own).
        q: The impact's configuration [rad].
        rows: The touching rows (the pairs' points, then the limits).
        P: Their impulses (rows, 3), blocks (t1, t2, n) in the pair's contact frame [N*s];
            a limit row's normal part [N*m*s].

    Returns:
        Per touching point with a normal impulse, (names, point, point1, point2 [m], normal,
        impulse on body 2 [N*s]), world frame; in the limit slot the stops' impulses [N*m*s]
        (nv,), in the clamp slot a hand-off's clamp rows' (None: none).
    """
    limit = np.zeros(nc.nv)
    clamp = np.zeros(nc.nv)
    pairs = nc._pair_list
    start = _row_starts(pairs)
    m_p = start[-1] + len(pairs[-1].local1) if pairs else 0
    limits = list(nc.limits)
    pin.forwardKinematics(nc.model, data, q)
    out: list[SampleContact] = []
    placed: dict[int, tuple[FloatArray, tuple[FloatArray, FloatArray, FloatArray]]] = {}
    for r, block in zip(np.asarray(rows).tolist(), np.asarray(P, dtype=np.float64), strict=True):
        if r >= m_p + len(limits):  # a hand-off's clamp row: its Jacobian is -s e_j
            cl = nc.clamp_of_row(r)
            assert cl is not None  # (only the hand-off's set has rows beyond its limits)
            clamp[cl[0]] -= cl[1] * float(block[2])
            continue
        if r >= m_p:  # a limit row: its Jacobian is -side e_j
            j, side = limits[r - m_p]
            limit[j] -= side * float(block[2])
            continue
        if not block[2] > 0.0:
            continue
        i = int(np.searchsorted(start, r, side="right")) - 1
        p = pairs[i]
        if i not in placed:
            placed[i] = (pair_frame(data, p), pair_points(data, p))
        T, (touch, p1, p2) = placed[i]
        j = r - start[i]
        out.append((pair_names(p), touch[j], p1[j], p2[j], T[2].copy(), block @ T))
    return SampleForces(out, limit, clamp if clamp.any() else None)


def _stop_torques(
    nc: NormalContacts, pairs: list[_Pair], normal: dict[int, float], out: FloatArray
) -> None:
    """Add each engaged limit row's torque on its joint to ``out`` [N*m].

    Args:
        nc: The contact set.
        pairs: Its pairs (their patch points are the rows before the limits').
        normal: Row -> its normal multiplier [N*m] (limit rows and others).
        out: The torques per velocity index, (nv,).
    """
    m_p = sum(len(p.local1) for p in pairs)
    for i, ((j, side), _) in enumerate(nc.limits.items()):
        lam = normal.get(m_p + i)
        if lam is not None:  # the row's Jacobian is -side e_j
            out[j] -= side * lam


def _rest_forces(
    nc: NormalContacts,
    data: Any,
    pairs: list[_Pair],
    frames: list[FloatArray],
    q: FloatArray,
    a_free: FloatArray,
    minv: FloatArray,
) -> RowForces:
    """The resting arm's contacts: the frictional problem's force of every touching point."""
    limit = np.zeros(nc.nv)
    sol = nc.rest_solution(q, a_free, minv)
    if sol is None:
        return RowForces(SampleForces([], limit), {}, np.zeros(nc.nv))
    touch = sol.touch
    x = analytic_centre(sol.rows, sol.forces, sol.mu, sol.torque)
    start = _row_starts(pairs)
    owner: dict[int, tuple[int, int]] = {}
    for i, p in enumerate(pairs):
        for j in range(len(p.local1)):
            owner[start[i] + j] = (i, j)
    points: dict[int, tuple[FloatArray, FloatArray, FloatArray]] = {}
    out: list[SampleContact] = []
    _stop_torques(
        nc, pairs, {r: float(f3[2]) for r, f3 in zip(touch.tolist(), x, strict=True)}, limit
    )
    base = start[-1] + len(pairs[-1].local1) + len(nc.limits) if pairs else len(nc.limits)
    beyond: dict[int, float] = {}
    for r, f3 in zip(touch.tolist(), x, strict=True):
        if r not in owner:  # a limit row, or one beyond (a hand-off's clamp row)
            if r >= base:
                beyond[r] = float(f3[2])
            continue
        i, j = owner[r]
        if i not in points:
            points[i] = pair_points(data, pairs[i])
        T = frames[i]
        touch_at, p1, p2 = points[i]
        out.append((pair_names(pairs[i]), touch_at[j], p1[j], p2[j], T[2].copy(), f3 @ T))
    # (at rest the joints' friction boxes act too: with the rows' force, all that holds it)
    qc = sol.rows.T @ np.asarray(x, dtype=np.float64).ravel() + sol.friction
    return RowForces(SampleForces(out, limit), beyond, np.asarray(qc, dtype=np.float64))


def rest_friction(
    nc: NormalContacts, q: FloatArray, a_free: FloatArray, minv: FloatArray, friction: FloatArray
) -> FloatArray | None:
    """A resting arm's joint friction torques [N*m]: the rest problem's joint boxes, or None.

    At rest the joints' Coulomb friction and brakes are boxes of the rest capture's frictional
    problem (:meth:`~packbot.contact.normal_dynamics.ConstrainedDynamics.rest_solution`):
    their torques replace the sliding Coulomb torque ``-F_j s_j`` of ``friction``.

    Args:
        nc: The contact set.
        q: Configuration [rad].
        a_free: Unconstrained accelerations [rad/s^2] (as the set's rest condition has them).
        minv: M^-1 at q (as the rest condition has it).
        friction: The friction torques of the drive [N*m] (viscous and sliding Coulomb).

    Returns:
        The friction torques at rest, or None: the set does not rest, no joint has Coulomb
        friction, or the rest problem is not solved.
    """
    coul, fdir = nc.joint_coulomb, nc.joint_fdir
    if not (nc.resting and nc.engaged) or coul is None or fdir is None:
        return None
    sol = nc.rest_solution(q, a_free, minv)
    if sol is None:
        return None
    return np.asarray(friction + coul * fdir + sol.friction, dtype=np.float64)


def _row_starts(pairs: list[_Pair]) -> list[int]:
    """Each pair's first normal row (the rows are the patch points, pair after pair)."""
    out, k = [], 0
    for p in pairs:
        out.append(k)
        k += len(p.local1)
    return out


def pair_names(p: _Pair) -> PairNames:
    """The pair's (link1, piece1, link2, piece2)."""
    info = p.info
    return (info.link1, info.piece1, info.link2, info.piece2)


def pair_frame(data: Any, p: _Pair) -> FloatArray:
    """The pair's contact frame in the world: rows t1, t2, n (n from body 1 to body 2)."""
    R = data.oMi[p.info.joint1 if p.on1 else p.info.joint2].rotation
    return np.asarray(p.frame2 @ R.T, dtype=np.float64)


def pair_points(data: Any, p: _Pair) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The patch points [m], (K, 3) world: where they touch, body 1's and body 2's.

    They touch at the material point of the body not carrying the normal: the rows' exact
    derivative of the gap n . (p2 - p1) with n turning with its body acts there on both.
    """
    M1, M2 = data.oMi[p.info.joint1], data.oMi[p.info.joint2]
    a = np.asarray(p.local1 @ M1.rotation.T + M1.translation, dtype=np.float64)
    b = np.asarray(p.local2 @ M2.rotation.T + M2.translation, dtype=np.float64)
    return (b if p.on1 else a), a, b


class NormalReport:
    """The contact-normal mode's forces at a sample: its :class:`~packbot.contact.base.ForceReport`.

    One per phase of the law (built with its contact set): the contacts' placements for the
    records, and a resting arm's contacts found once per state and torque.

    Args:
        law: The law (its contact set, its window, its joint locks and holds).
    """

    def __init__(self, law: NormalLaw) -> None:
        self.law = law
        self._data = law.sys.model.createData()  # (the contact forces' placements)
        self._rest: tuple[Any, SampleForces | None] = (None, None)

    def held(self) -> tuple[int, ...]:
        """The joints held still (engaged and held locks), sorted."""
        return self.law.held()

    def friction(
        self, q: FloatArray, v: FloatArray, applied: FloatArray, friction: FloatArray
    ) -> FloatArray:
        """The friction torques [N*m] of the current mode.

        In a window, the last step's Coulomb and brake torques; at rest, the rest problem's
        (:func:`rest_friction`); otherwise the law's.
        """
        law = self.law
        w = law.window
        if w is not None:
            return np.asarray(friction + w.stepper.joint_torque, dtype=np.float64)
        nc, sys = law.normal, law.sys
        if nc.resting and nc.joint_coulomb is not None:  # the rest problem's joint boxes
            found = rest_friction(
                nc, q, self._a_free(q, v, applied + friction), sys.minv(q), friction
            )
            if found is not None:
                return found
        return law.friction(q, v, applied, friction)

    def _a_free(self, q: FloatArray, v: FloatArray, torque: FloatArray) -> FloatArray:
        """The free accelerations [rad/s^2] under ``torque`` [N*m] with the joint locks alone.

        (Not the compiled right-hand side's call: a call there would forget the step end it
        keeps for the step end's checks.)
        """
        law = self.law
        a_free = law.sys.aba(q, v, torque)
        if law.locks.any_locked:
            a_free = law.locks.accelerations(a_free, law.sys.minv(q))
        return a_free

    def contacts(
        self, q: FloatArray, v: FloatArray, tau: Callable[[], FloatArray], t: float = math.nan
    ) -> SampleForces | None:
        """The current mode's contact forces and stop torques at (q, v) (:func:`mode_forces`).

        Inside a time-stepping window, the mean forces of the step that holds the sample's time
        t [s] (:class:`~packbot.contact.window_forces.WindowForces`); None if no step kept
        holds t.
        """
        law = self.law
        nc, sys = law.normal, law.sys
        if law.window is not None:
            return law.window.stepper.forces.at(t)
        if not nc.engaged:
            return SampleForces([], np.zeros(sys.nv))
        # a resting arm's samples under one torque are one state: its contacts are found once
        torque = tau()
        key = (nc._version, q.tobytes(), torque.tobytes()) if nc.resting and not v.any() else None
        if key is not None and self._rest[0] == key:
            return self._rest[1]
        a_free = self._a_free(q, v, torque)
        kept = nc._last_eval  # (the step end's evaluation, kept for its own state)
        try:
            found = mode_forces(nc, self._data, q, v, a_free, sys.minv(q))
        finally:
            nc._last_eval = kept
        if key is not None:
            self._rest = (key, found)
        return found
