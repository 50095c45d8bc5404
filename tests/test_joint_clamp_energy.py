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


# ------------------------------------------------------------------ a clamp never does work
def _work_between_events(res: packbot.SimResult) -> list[float]:
    """Energy change [J] over each interval between event instants (no torque, no friction:
    the work of the clamps, plus the integration error)."""
    out, prev, t_prev = [], res.energy[0], 0.0
    for e in res.events:
        if e.t > t_prev:
            out.append(e.energy_before - prev)
        prev, t_prev = e.energy_after, e.t
    out.append(res.energy[-1] - prev)
    return out


def _shoulder_drop(robot: packbot.Robot, e: float) -> packbot.SimResult:
    """The shoulder alone, falling from 'stand' until the fixed finger lands on the floor."""
    locked = tuple(n for n in robot.joint_names if n != "shoulder")
    cfg = packbot.SimConfig(contact_mode="joint_clamp", restitution=e, locked_joints=locked)
    return packbot.simulate(robot, robot.poses["stand"], np.zeros(robot.nq), 1.5, config=cfg)


def test_elastic_shoulder_drop_keeps_its_energy(robot) -> None:
    """e = 1: the finger bounces off the floor twice in 1.5 s. The reset turns the shoulder
    (one joint: v <- -v keeps the energy); its clamp, on a joint now moving away from the floor,
    is released at once (a ``release`` naming the shoulder), so gravity slows the shoulder and
    the energy stays the start's. (A clamp that held the receding shoulder at a_j = 0 made it
    climb at its rebound speed until the pair separated: +0.37 J in 1.5 s.)"""
    res = _shoulder_drop(robot, 1.0)
    impacts = res.events_of("impact")
    assert len(impacts) == 2
    for hit in impacts:
        assert hit.relevant_joints == ("shoulder",) and hit.link2 == "floor"
        assert hit.energy_after == pytest.approx(hit.energy_before, abs=1e-9)
        (released,) = [e for e in res.events_of("release") if e.t == hit.t]
        assert released.relevant_joints == ("shoulder",)  # the clamp, not the pair
        assert (released.piece1, released.piece2) == (hit.piece1, hit.piece2)
    assert np.abs(res.energy - res.energy[0]).max() < 1e-6
    assert max(_work_between_events(res)) < 1e-6


def test_released_clamp_comes_back_when_its_joint_turns(robot) -> None:
    """e = 0.2: the second rebound is too small to leave the proximity tolerance; the shoulder
    turns back toward the floor while the pair is active, and its clamp is back in force at
    that instant (an ``engage`` at zero speed): the lock holds it there and does no work."""
    res = _shoulder_drop(robot, 0.2)
    sh = res.joint("shoulder")
    (engage,) = res.events_of("engage")
    assert engage.relevant_joints == ("shoulder",)
    assert abs(engage.v_before[sh]) < 1e-6  # it turned: zero speed
    later = res.t > engage.t
    assert np.abs(res.v[later, sh]).max() < 1e-6  # held from then on
    assert np.ptp(res.energy[later]) < 1e-6
    assert max(_work_between_events(res)) < 1e-6


@pytest.mark.parametrize(
    ("rule", "clamp", "e"),
    [("zero", "velocity", 0.2), ("zero", "jacobian", 0.2), ("momentum", "jacobian", 0.5)],
)
def test_rebounding_collapse_runs_and_its_clamps_do_no_work(robot, rule, clamp, e) -> None:
    """The 3 s collapse settings that the release alone sent to ``max_events`` (a pair
    rebounding from d = 0 was found again at the step's start, the same instant for ever):
    they run, the clamps never do positive work between events (the report's zero reset may
    gain at an event: logged), and the clamps released on rebound come back."""
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp",
        restitution=e,
        reset_rule=rule,
        clamp_rule=clamp,
        locked_joints=WRIST,
        max_events=2000,
    )
    res = packbot.simulate(robot, robot.poses["drive"], np.zeros(robot.nq), 3.0, config=cfg)
    assert res.t[-1] == pytest.approx(3.0)
    assert max(_work_between_events(res)) < 1e-6
    assert [x for x in res.events_of("release") if x.relevant_joints]  # a clamp released
    assert res.events_of("engage")
    changes = _reset_changes(res)
    gain = res.diagnostics.reset_energy_gain
    assert gain == pytest.approx(sum(c for c in changes if c > 0.0), rel=1e-12, abs=1e-12)
    if rule == "momentum":
        assert gain <= 1e-9
    assert res.diagnostics.min_distance > -1e-6


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_limit_stops_never_hold_a_joint_leaving_them(robot, e) -> None:
    """The collapse without collisions, 1 s: the arm falls onto its limit stops. A stop's
    clamp on a joint that an impulse turned away from it lets go at once, and a joint
    bouncing off its stop that comes back is a new ``limit`` event (its impulse), not the old
    stop found again at the step's start. Before, with e = 0.5, a stop held a leaving joint
    for a whole step (+0.29 J) and elbow1 ended 3.8 mrad beyond its upper stop."""
    cfg = packbot.SimConfig(contact_mode="none", restitution=e, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.poses["drive"], np.zeros(robot.nq), 1.0, config=cfg)
    assert len(res.events_of("limit")) >= 3
    assert max(_work_between_events(res)) < 1e-4
    for e_ in res.events_of("limit"):
        assert e_.energy_after <= e_.energy_before + 1e-9  # the stops' momentum impulse
    upper = robot.model.upperPositionLimit[None, :]
    lower = robot.model.lowerPositionLimit[None, :]
    assert (res.q - upper).max() < 1e-8 and (lower - res.q).max() < 1e-8
