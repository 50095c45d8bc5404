"""The report's law and energy: the velocity resets' gain is logged.

Issue 16, item 4, on real simulation output: ``Diagnostics.reset_energy_gain`` is the sum of
the positive ``energy_after - energy_before`` of the reset events (``impact``,
``secondary_intersection``, ``limit``): the report's ``zero`` reset on a coupled arm adds
kinetic energy, and that gain is the report's own, kept and logged; ``reset_rule="momentum"``
never gains energy at an event.
"""

from __future__ import annotations

import numpy as np
import pytest

import packbot

RESETS = ("impact", "secondary_intersection", "limit")
WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def robot() -> packbot.Robot:
    return packbot.load_robot()


def _collapse(robot: packbot.Robot, e: float, rule: str = "zero") -> packbot.SimResult:
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp", restitution=e, reset_rule=rule, locked_joints=WRIST
    )
    return packbot.simulate(robot, robot.poses["drive"], np.zeros(robot.nq), 1.0, config=cfg)


def _reset_changes(res: packbot.SimResult) -> list[float]:
    return [e.energy_after - e.energy_before for e in res.events if e.kind in RESETS]


@pytest.mark.parametrize("e", [0.0, 1.0])
def test_logged_reset_gain_is_the_events_energy_changes_summed(robot, e) -> None:
    res = _collapse(robot, e)
    changes = _reset_changes(res)
    assert changes and all(np.isfinite(c) for c in changes)  # every impact has its energies
    gain = res.diagnostics.reset_energy_gain
    assert gain == pytest.approx(sum(c for c in changes if c > 0.0), rel=1e-12, abs=1e-12)
    if e == 0.0:  # the report's collapse: the first impact's zero reset adds 0.265 J
        assert gain == pytest.approx(0.265, abs=1e-3)
    else:  # e = 1: the zero reset on a coupled arm adds tens of joules, logged
        assert gain > 10.0


def test_momentum_reset_never_gains_energy_at_an_event(robot) -> None:
    res = _collapse(robot, 0.5, rule="momentum")
    assert len(res.events_of("impact")) >= 3
    for e in res.events:
        assert e.energy_after <= e.energy_before + 1e-9, e
    assert res.diagnostics.reset_energy_gain <= 1e-9
