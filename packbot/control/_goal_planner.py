"""Goal planning of the reconfigurable controller: where to send the arm, healthy or failed.

:class:`GoalPlanner` finds the goal configuration of
:class:`~packbot.control.reconfig.ReconfigurableController` (full coordinates [rad]):

- :meth:`GoalPlanner.solve_goal`: inverse kinematics for the frame at the target with the frozen
  joints locked at their current angles (``pin.buildReducedModel``), restarted from random seeds
  until a solution is collision free with the clearance and so is its straight joint-space path;
  the closest point if none is;
- :meth:`GoalPlanner.solve_loose_goal`: the frame at the target and a loose joint at a stable
  equilibrium (zero gravity torque, d g_u / d q_u > 0), by bounded least squares, the loose joint
  at least ``loose_margin`` from its stops and collision free for swings of +/- ``swing_check``.

A planner is a snapshot of the controller's settings and shares its random generator, so that
successive plans draw successive seeds.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.collision import CollisionWorld
from packbot.continuous_joints import sampling_bounds
from packbot.control.ik import solve_position_ik

__all__ = ["GoalPlanner", "ancestors", "frame_joints"]

#: The controller's logger: its planning warnings are the controller's.
log = logging.getLogger("packbot.control.reconfig")

FloatArray = NDArray[np.float64]


def frame_joints(model: pin.Model, frame: str) -> list[int]:
    """Indices (into q of ``model``) of the joints that move ``frame``."""
    fid = model.getFrameId(frame)
    parent = model.frames[fid].parentJoint
    return sorted(model.joints[j].idx_q for j in model.supports[parent] if j > 0)


def ancestors(model: pin.Model, j: int) -> set[int]:
    """Indices (into q) of the joints that carry joint ``j`` (``j`` excluded)."""
    jid = model.getJointId(model.names[1 + j])
    return {model.joints[i].idx_q for i in model.supports[jid] if 0 < i != jid}


class GoalPlanner:
    """Goals placing a frame at a target, collision free, on the healthy or a failed arm.

    Args:
        model: The controller's model of the healthy arm.
        data: Its data.
        world: Collision world of the arm and its obstacles.
        frame: The placed frame.
        target: Target position of the frame [m], world frame.
        clearance: Smallest signed distance accepted at a goal and along its path [m].
        ik_seeds: Random restarts when the first solution is rejected.
        swing_check: Swing of a loose joint its rest must stay collision free for [rad].
        loose_margin: Smallest distance of a loose joint's rest angle to its stops [rad].
        rng: Generator of the restarts' seeds.
    """

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        world: CollisionWorld,
        frame: str,
        target: FloatArray,
        *,
        clearance: float,
        ik_seeds: int,
        swing_check: float,
        loose_margin: float,
        rng: np.random.Generator,
    ) -> None:
        self.model, self.data, self.world = model, data, world
        self.frame, self.target = frame, target
        self.clearance, self.ik_seeds = clearance, ik_seeds
        self.swing_check, self.loose_margin = swing_check, loose_margin
        self.rng = rng

    def _clear(self, q_full: FloatArray) -> bool:
        return not self.world.in_collision(q_full, self.clearance)

    def _swing_clear(self, q_full: FloatArray, loose: int, samples: int = 9) -> bool:
        """Collision free with the loose joint anywhere within +/- swing_check of q_full."""
        for dq in np.linspace(-self.swing_check, self.swing_check, samples):
            qq = q_full.copy()
            qq[loose] += dq
            if not self._clear(qq):
                return False
        return True

    def _path_clear(self, qa: FloatArray, qb: FloatArray, samples: int = 20) -> bool:
        return all(self._clear(qa + s * (qb - qa)) for s in np.linspace(0.0, 1.0, samples)[1:])

    def _candidates(
        self, q: FloatArray, active: list[int], lower: FloatArray, upper: FloatArray
    ) -> Iterator[FloatArray]:
        """Seeds: the current configuration, then random ones (active joints only)."""
        yield q.copy()
        for _ in range(self.ik_seeds):
            s = q.copy()
            lo, hi = sampling_bounds(lower, upper, q)
            s[active] = self.rng.uniform(lo[active], hi[active])
            yield s

    def solve_goal(self, q: FloatArray, frozen: list[int]) -> tuple[FloatArray, str]:
        """IK for the target with the frozen joints at their current angles.

        Args:
            q: Current configuration [rad], full coordinates.
            frozen: Indices (into q) of the frozen joints.

        Returns:
            The goal [rad] (full coordinates) and a detail for the controller's log.
        """
        model = self.model
        if frozen:
            ids = [model.getJointId(model.names[1 + j]) for j in frozen]
            red = pin.buildReducedModel(model, ids, q)
        else:
            red = model
        keep = np.array([j for j in range(model.nq) if j not in frozen], dtype=int)
        active = frame_joints(red, self.frame)
        lower = np.asarray(red.lowerPositionLimit)
        upper = np.asarray(red.upperPositionLimit)

        def full(qr: FloatArray) -> FloatArray:
            out = q.copy()
            out[keep] = qr
            return out

        best: tuple[float, FloatArray, float] | None = None
        fallback: tuple[float, FloatArray] | None = None
        for k, seed in enumerate(self._candidates(q[keep], active, lower, upper)):
            res = solve_position_ik(  # the clearance and the path are checked below
                red, self.frame, self.target, seed, active=active, tol=1e-4, collision_free=False
            )
            if fallback is None or res.error < fallback[0]:
                fallback = (res.error, res.q)
            if not res.success:
                continue
            qf = full(res.q)
            if not (self._clear(qf) and self._path_clear(q, qf)):
                continue
            cost = float(np.max(np.abs(qf - q)))
            if best is None or cost < best[0]:
                best = (cost, qf, res.error)
            if k == 0:
                break  # the solution nearest the current configuration is taken as is
        if best is not None:
            return best[1], f"IK error {best[2] * 1000:.3g} mm, {len(active)} joints"
        assert fallback is not None
        log.warning("no collision-free IK solution for the target; going to the closest point")
        return full(fallback[1]), f"target out of reach: IK error {fallback[0] * 1000:.3g} mm"

    def solve_loose_goal(
        self, q: FloatArray, loose: int, failed: set[int]
    ) -> tuple[FloatArray, str]:
        """Goal with the loose joint at a stable equilibrium and the frame at the target.

        Args:
            q: Current configuration [rad], full coordinates.
            loose: Index (into q) of the loose joint.
            failed: Indices of the failed joints (``loose`` among them); the others stay still.

        Returns:
            The goal [rad] (full coordinates; ``q`` if no equilibrium is found) and a detail
            for the controller's log.
        """
        model, data = self.model, self.data
        fid = model.getFrameId(self.frame)
        # The loose joint and the joints that carry it place the frame (the others keep their
        # angles); if the loose joint does not carry the frame, all the frame's joints do.
        moving = set(frame_joints(model, self.frame))
        carry = ancestors(model, loose) | {loose}
        movers = moving & carry if loose in moving else moving | {loose}
        active = sorted(j for j in movers if j not in failed or j == loose)
        lower = np.asarray(model.lowerPositionLimit)[active]
        upper = np.asarray(model.upperPositionLimit)[active]
        k_loose = active.index(loose)
        room = 0.5 * (upper[k_loose] - lower[k_loose])
        lower[k_loose] += min(self.loose_margin, room - 1e-6)
        upper[k_loose] -= min(self.loose_margin, room - 1e-6)
        g_scale = 10.0  # [N*m per m]: weight of the equilibrium residual

        def resid(x: FloatArray) -> FloatArray:
            qq = q.copy()
            qq[active] = x
            pin.framesForwardKinematics(model, data, qq)
            g = pin.computeGeneralizedGravity(model, data, qq)[loose]
            return np.concatenate([data.oMf[fid].translation - self.target, [g / g_scale]])

        def stable(qq: FloatArray) -> bool:
            h = 1e-5
            qp, qm = qq.copy(), qq.copy()
            qp[loose] += h
            qm[loose] -= h
            gp = pin.computeGeneralizedGravity(model, data, qp)[loose]
            gm = pin.computeGeneralizedGravity(model, data, qm)[loose]
            return bool((gp - gm) / (2 * h) > 0)

        from scipy.optimize import least_squares  # lazy: scipy.optimize costs ~65 ms of import

        best: tuple[float, FloatArray] | None = None
        for seed in self._candidates(
            q, active, np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
        ):
            x0 = np.clip(seed[active], lower + 1e-9, upper - 1e-9)
            sol = least_squares(resid, x0, bounds=(lower, upper), xtol=1e-10, ftol=1e-12)
            qq = q.copy()
            qq[active] = sol.x
            r = resid(sol.x)
            if abs(r[3]) * g_scale > 1e-3 or not stable(qq) or not self._swing_clear(qq, loose):
                continue
            err = float(np.linalg.norm(r[:3]))
            if best is None or err < best[0] - 1e-6:
                best = (err, qq)
            if err < 1e-4:
                break
        if best is None:
            log.warning("no stable collision-free equilibrium of the loose joint; holding")
            return q.copy(), "no stable equilibrium found: holding"
        return best[1], f"stable equilibrium, frame error {best[0] * 1000:.3g} mm"
