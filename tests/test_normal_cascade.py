"""The contact-normal mode on hard starts (issue 16): no event adds energy.

A slice of ``benchmarks/robustness.py``: random start poses of the collapse (seed 2026, the
benchmark's poses): the start whose impacts added energy must now gain none at any event, and
not penetrate beyond ``PENETRATION_TOL``.
"""

import numpy as np

import packbot
from packbot.collision import CollisionWorld
from packbot.contact.normal import PENETRATION_TOL
from packbot.mujoco_model import WRIST_JOINTS

#: Energy gained at one event beyond this counts as a gain [J] (the benchmark's GAIN_TOL).
GAIN_TOL = 1e-6


def start_pose(robot: packbot.Robot, k: int, seed: int = 2026) -> np.ndarray:
    """The k-th random start of ``benchmarks/robustness.py`` (clearance 2 mm)."""
    rng = np.random.default_rng(seed)
    world = CollisionWorld(robot)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    found = -1
    while True:
        q = rng.uniform(lo, hi)
        if not world.in_collision(q, tol=2e-3):
            found += 1
            if found == k:
                return q


def _check(res: packbot.SimResult) -> None:
    gains = [e.energy_after - e.energy_before for e in res.events]
    assert max(gains) <= GAIN_TOL, max(gains)
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    assert res.energy[-1] < res.energy[0]  # the collapse dissipates


def test_impacts_never_add_energy_with_the_wrist_locked(robot):
    """Start 1, wrist locked: its camera-head impacts on link 1 gained up to 2.5e-5 J."""
    q0 = start_pose(robot, 1)
    cfg = packbot.SimConfig(
        contact_mode="normal", mu=0.5, restitution=0.0, locked_joints=WRIST_JOINTS
    )
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), 0.7, config=cfg)
    assert len(res.events_of("impact")) > 10
    _check(res)
