"""Time-stepping windows of the contact-normal mode: Moreau-Jean steps where events pile up.

Event-driven integration resolves every contact event exactly while events are few. Where they
pile up, it breaks down: an impulsive stick/slip or jam cascade that cycles through its modes at
one instant, an accumulation of impacts, a chattering slide (with the light wrist and camera
joints free, most random starts did, at the ``max_events`` guard). The event-driven literature's
answer (Acary & Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*, Springer 2008,
ch. 10 and 12) is to switch locally to time-stepping: integrate the window where events
accumulate with fixed steps, one complementarity problem per step and no event location, then
return to exact event-driven integration once the contacts have settled.

One step of :class:`MoreauJeanStepper` from (t, q, v) over h (the Moreau-Jean scheme with
theta = 1, i.e. symplectic Euler with impulses):

1. **Contact set**: every collision pair within ``d_act`` of touching (its patch: one row per
   point, as the event-driven mode builds them) and, with joint limits on, every joint within
   ``h |v_j| +`` :data:`LIMIT_GAP` of a limit. ``d_act`` = :data:`ACTIVE_GAP` plus twice the
   distance any point can travel in the step.
2. **Free velocity**: v_f = v + h a_free(t, q, v) (applied torques, gravity, Coriolis, viscous
   joint friction). Joint Coulomb friction and brakes are not in a_free: they are rows of the
   problem below.
3. **One complementarity problem** for the impulses x [N*s, N*m*s] (Pinocchio's ADMM,
   :func:`packbot.contact.lcp.solve_mixed_admm`), with u = J v+ the rows' velocities after the
   step and v+ = v_f + M^-1 J^T x:

   - per contact point, blocks (t1, t2, n): x in the Coulomb cone of friction mu, the De
     Saxce-shifted u + b in the dual cone, complementary. b_n = max(g, 0) / h lets an open gap
     g close within the step but not beyond; a touching point approaching faster than the Zeno
     speed gets Newton's law, b_n = e min(u_n-, 0) (u_n- its normal velocity before);
   - per limit row: x >= 0 (a cone of friction 0), the same b;
   - per joint with Coulomb friction or a brake (holding torque F_j [N*m]): |x_j| <= h F_j;
     v_j+ = 0 strictly inside (the joint sticks), v_j+ against x_j at the bound (it slips).

4. **Positions**: q+ = q (+) h v+; a pair left deeper than :data:`PROJECT_DEPTH` is projected
   out (the contact set's position-level LCP, :meth:`NormalContacts.project`).
5. **Energy**: the discrete step can add energy (symplectic Euler's energy error oscillates
   with the step, O(h)); a step whose energy change exceeds the work of the applied motor
   torques is scaled back, v+ <- s v+ with 0 <= s < 1 so that it does not (scaling keeps every
   row's sign: a stuck point stays stuck, a separating one separates). The energy removed this
   way is counted (:attr:`StepInfo.removed`, ``Diagnostics.window_energy_removed``): a
   modelling choice of the window, measured in docs/contact.md.

A step's *signature* is what the solution decided: the pairs and limits pushing, the pairs
sliding, the joints slipping. The law (:class:`~packbot.contact.normal.NormalLaw`) leaves the
window when the signature has held for :data:`QUIET_STEPS` steps (or the arm is free of
contacts, or at rest), and the event-driven restart takes over from that state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.lcp import solve_mixed_admm
from packbot.contact.pairs import REACH_BOUND
from packbot.ode import DenseSegment

if TYPE_CHECKING:
    from packbot.config import SimConfig
    from packbot.contact.normal import NormalContacts
    from packbot.drive import Drive
    from packbot.system import System

__all__ = [
    "ACTIVE_GAP",
    "LIMIT_GAP",
    "PROJECT_DEPTH",
    "QUIET_STEPS",
    "WINDOW_STEP",
    "MoreauJeanStepper",
    "StepInfo",
    "StepSegment",
]

FloatArray = NDArray[np.float64]

#: Time step of a window [s].
WINDOW_STEP = 5e-4
#: Pairs closer than this (plus the step's travel) take part in a step's problem [m].
ACTIVE_GAP = 1e-4
#: Joints closer than this (plus the step's travel) to a limit take part [rad].
LIMIT_GAP = 1e-4
#: A step that leaves a pair deeper than this is projected out [m].
PROJECT_DEPTH = 5e-6
#: The law leaves a window once a step's signature has held this many steps.
QUIET_STEPS = 20
#: A contact point pushes when its normal impulse exceeds this [N*s] (signatures).
IMPULSE_BAND = 1e-9
#: The steps' solver tolerance and iteration limit (Pinocchio's ADMM): a step's impulses need
#: no more (measured on the collapse with joint friction: median 0.4 ms a step; with 1e-10 and
#: 5,000 iterations, a few degenerate problems took 250 ms each for no visible difference).
ADMM_TOL = 1e-9
ADMM_ITERATIONS = 1000
#: Touching rows (gap below this [m]) approaching faster than the Zeno speed get restitution.
TOUCH_GAP = 1e-5


class StepSegment(DenseSegment):
    """One time step [t0, t1] of a window: q linear (its slope is v+), v linear between ends.

    The recorder samples it like an integrator step; q(t) is the scheme's own (q moves with
    the step's end velocity), v(t) a linear blend for the samples.
    """

    __slots__ = ()

    def __init__(self, t0: float, t1: float, y0: FloatArray, y1: FloatArray) -> None:
        """A step from (t0, y0) to (t1, y1)."""
        super().__init__(t0, t1, t1 - t0, y0, y1, np.zeros((8, len(y0))))

    def __call__(self, t: float) -> FloatArray:
        """y(t) by linear interpolation, exactly y0 at t0 and y1 at t1."""
        if t == self.t1:
            return self.y1.copy()
        if t == self.t0 or self.h <= 0.0:
            return self.y0.copy()
        th = (t - self.t0) / self.h
        return np.asarray(self.y0 + th * (self.y1 - self.y0), dtype=np.float64)

    def derivative(self, t: float) -> FloatArray:
        """The step's mean slope [units of y per s]."""
        return np.asarray((self.y1 - self.y0) / self.h, dtype=np.float64)


@dataclass
class StepInfo:
    """What one window step decided and did.

    Attributes:
        signature: The pairs pushing, the pairs sliding, the limits pushing and the joints
            slipping (a hashable summary; the window is quiet while it holds).
        rows: Contact rows (points and limits) in the step's problem.
        residual: The complementarity solution's scaled residual [-].
        removed: Energy the step's guard removed [J] (0 when the step did not gain).
        projected: Whether a penetrating pair was projected out.
        closest: The smallest signed distance [m] of the step's sweep (at its start) and its
            pair (-1: none within reach).
    """

    signature: tuple[frozenset[int], frozenset[int], frozenset[tuple[int, int]], frozenset[int]]
    rows: int
    residual: float
    removed: float
    projected: bool
    closest: tuple[float, int] = (math.inf, -1)


class MoreauJeanStepper:
    """Fixed time steps with one complementarity problem each (see the module docstring).

    Args:
        system: The phase's integrated system (model, mass matrix, energy, collision world).
        drive: The run's torques (its ``fdir`` must be zero: Coulomb friction is a row here).
        contacts: The contact set whose patches and rows the steps use (the law's own).
        config: Simulation settings (mu, restitution, zeno_speed, joint_limits, motor_lag).
        h: Time step [s].
    """

    def __init__(
        self,
        system: System,
        drive: Drive,
        contacts: NormalContacts,
        config: SimConfig,
        h: float = WINDOW_STEP,
    ) -> None:
        self.sys, self.drive, self.contacts, self.cfg = system, drive, contacts, config
        self.h = float(h)
        self.n = system.nv
        #: The last step's Coulomb and brake torques [N*m] (its box impulses / h).
        self.joint_torque = np.zeros(self.n)
        # model joint of each velocity index (revolute arm: one dof per joint)
        self.joint_of = np.zeros(self.n, dtype=np.intp)
        for j in range(1, system.model.njoints):
            iv = system.model.idx_vs[j]
            for k in range(system.model.nvs[j]):
                self.joint_of[iv + k] = j

    def step(
        self,
        t: float,
        y: FloatArray,
        t_end: float,
        energy: Callable[[FloatArray, FloatArray], float],
    ) -> tuple[StepSegment, StepInfo]:
        """One step from (t, y), not past t_end; the step and what it decided.

        Args:
            t: Time [s].
            y: State (q, v[, tau_m]).
            t_end: The step ends at min(t + h, t_end) [s].
            energy: Total mechanical energy [J] of (q, v).
        """
        sys, cfg, contacts, n = self.sys, self.cfg, self.contacts, self.n
        h = min(self.h, t_end - t)
        q, v, tail = y[:n], y[n : 2 * n], y[2 * n :]
        _, target, applied, _ = self.drive.torques(t, y)
        a_free = self.drive.free_accel(t, y)
        v_f = v + h * a_free
        minv = sys.minv(q)

        closest = self._update_set(q, v, v_f, h)
        Jn, _, gap, vn, extra = contacts._problem(q, v)
        m = len(gap)
        coul = self.drive.path.coulomb
        cj = np.flatnonzero(coul > 0.0)
        if m:
            J3, mus = contacts._frictional_rows(np.arange(m, dtype=np.intp), Jn, extra)
        else:
            J3, mus = np.zeros((0, n)), np.zeros(0)
        J = np.vstack([J3, np.eye(n)[cj]]) if len(cj) else J3
        x = np.zeros(len(J))
        residual = 0.0
        if len(J):
            g = J @ v_f
            b = np.maximum(gap, 0.0) / h
            bounce = (gap <= TOUCH_GAP) & (vn < -cfg.zeno_speed)
            b = b + np.where(bounce, cfg.restitution * np.minimum(vn, 0.0), 0.0)
            g[2 : 3 * m : 3] += b
            G = J @ minv @ J.T
            x, residual = solve_mixed_admm(
                sys.model,
                sys.data,
                G,
                g,
                mus,
                self.joint_of[cj],
                h * coul[cj],
                tol=ADMM_TOL,
                max_iterations=ADMM_ITERATIONS,
            )
        v1 = v_f + minv @ (J.T @ x) if len(J) else v_f
        # what the step decided, on the rows it solved (the projection below may change the set)
        sig = self._signature(x, m, mus, gap, len(cj), cj)
        self.joint_torque = np.zeros(n)
        self.joint_torque[cj] = x[3 * m :] / h
        q1 = np.asarray(pin.integrate(sys.model, q, h * v1), dtype=np.float64)

        projected = False
        world = contacts.world
        if contacts.pairs and world is not None:
            d_min = min(
                (world.pair_contact(q1, k).distance for k in contacts.pairs),
                default=math.inf,
            )
            if d_min < -PROJECT_DEPTH:
                contacts.refresh(q1)
                q1 = contacts.project(q1, v1, sys.minv(q1))
                projected = True

        # the energy guard
        e0 = energy(q, v)
        work = h * float(applied @ (0.5 * (v + v1)))
        e1 = energy(q1, v1)
        removed = 0.0
        excess = e1 - e0 - work
        if excess > 0.0:
            kin = 0.5 * float(v1 @ sys.mass_matrix(q1) @ v1)
            s = math.sqrt(max(0.0, kin - excess) / kin) if kin > 0.0 else 0.0
            v1 = s * v1
            removed = kin * (1.0 - s * s)

        if len(tail):
            lag = cfg.motor_lag
            tail = target + (tail - target) * math.exp(-h / lag) if lag > 0.0 else tail
        y1 = np.concatenate([q1, v1, tail])
        info = StepInfo(sig, m, residual, removed, projected, closest)
        return StepSegment(t, t + h, y, y1), info

    def _update_set(
        self, q: FloatArray, v: FloatArray, v_f: FloatArray, h: float
    ) -> tuple[float, int]:
        """The pairs and limits within reach of the step form the contact set.

        A pair already in the set keeps its patch while the patch describes the contact (its
        points have not slid apart and its smallest gap is the pair's distance:
        :meth:`NormalContacts.stale_pairs`, the event-driven mode's rule); a new or stale one
        is patched at q.

        Returns:
            The smallest signed distance of the sweep [m] and its pair (-1: none).
        """
        contacts, cfg, sys = self.contacts, self.cfg, self.sys
        speed = REACH_BOUND * max(float(np.abs(v).sum()), float(np.abs(v_f).sum()))
        d_act = ACTIVE_GAP + 2.0 * h * speed
        near: dict[int, float] = {}
        closest = (math.inf, -1)
        if contacts.world is not None:
            sw = contacts.world.sweep(q, margin=max(d_act, 1e-9))
            closest = (float(sw.min_distance), int(sw.min_pair))
            near = {
                int(k): float(d)
                for k, d in zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True)
                if d <= d_act
            }
        for k in list(contacts.pairs):
            if k not in near:
                contacts.remove_pair(k)
        redo = set(contacts.stale_pairs(q, v, near)) | (near.keys() - contacts.pairs.keys())
        for k in redo:
            contacts.add_pair(q, k, tol=d_act)
        if not cfg.joint_limits:
            return closest
        reach = LIMIT_GAP + h * np.maximum(np.abs(v), np.abs(v_f))
        for j in range(self.n):
            for side, lim in ((1, float(sys.upper[j])), (-1, float(sys.lower[j]))):
                if not math.isfinite(lim):
                    continue
                if side * (lim - q[j]) <= reach[j]:
                    if (j, side) not in contacts.limits:
                        contacts.add_limit(j, side, lim)
                elif (j, side) in contacts.limits:
                    contacts.remove_limit(j, side)
        return closest

    def _signature(
        self,
        x: FloatArray,
        m: int,
        mus: FloatArray,
        gap: FloatArray,
        nj: int,
        cj: NDArray[np.intp],
    ) -> tuple[frozenset[int], frozenset[int], frozenset[tuple[int, int]], frozenset[int]]:
        """Pairs pushing, pairs sliding, limits pushing, joints slipping."""
        contacts = self.contacts
        X = x[: 3 * m].reshape(-1, 3) if m else np.zeros((0, 3))
        pushing: set[int] = set()
        sliding: set[int] = set()
        limits: set[tuple[int, int]] = set()
        k = 0
        for key, p in contacts.pairs.items():
            K = len(p.local1)
            xs = X[k : k + K]
            k += K
            if float(xs[:, 2].sum()) > IMPULSE_BAND:
                pushing.add(key)
                ft = float(np.linalg.norm(xs[:, :2].sum(axis=0)))
                if contacts.mu > 0.0 and ft >= contacts.mu * float(xs[:, 2].sum()) * (1 - 1e-6):
                    sliding.add(key)
        for i, lk in enumerate(contacts.limits):
            if X[k + i, 2] > IMPULSE_BAND:
                limits.add(lk)
        slipping: set[int] = set()
        if nj:
            xj = x[3 * m :]
            bound = self.h * self.drive.path.coulomb[cj]
            slipping = {
                int(j)
                for j, xv, bd in zip(cj, xj, bound, strict=True)
                if abs(xv) >= bd * (1 - 1e-6)
            }
        return frozenset(pushing), frozenset(sliding), frozenset(limits), frozenset(slipping)
