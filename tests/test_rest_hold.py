"""The contact-normal mode holds an arm captured at rest in one step.

:meth:`NormalLaw.stretch <packbot.contact.normal_law.NormalLaw.stretch>`: once the rest capture
has stopped every joint, with the torques fixed and no controller tick to come, the state cannot
change before the next scheduled action or the run's end; one step to there replaces the
stepper's steps of ``max_step``. The runs must be the same to the last bit (samples, events,
energies) with fewer steps, also when a failure ends the rest, and the hold must not be taken
where the state may change (a motor lag) or a controller tick comes first.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot.contact import normal_law
from packbot.contact.normal_contacts import NormalContacts
from packbot.control.base import Controller
from packbot.failures import Failure
from packbot.mujoco_model import WRIST_JOINTS


def _no_hold(self, stepper, t_end):
    """The law without the hold: None (the stepper takes its steps)."""
    return None


def _runs(robot, monkeypatch, duration, cfg, failures=(), q0=None):
    """The run from q0 (the drive pose) without the hold, then with it; the holds taken."""
    held = []
    hold = normal_law.NormalLaw._hold_at_rest

    def counted(self, stepper, t_end):
        st = hold(self, stepper, t_end)
        if st is not None:
            held.append((st.pending.t0, st.pending.t1))
        return st

    out = []
    for on in (False, True):
        # (off: the stepper's steps of max_step from the captured state)
        monkeypatch.setattr(normal_law.NormalLaw, "_hold_at_rest", counted if on else _no_hold)
        out.append(
            packbot.simulate(
                robot,
                robot.pose("drive") if q0 is None else q0,
                np.zeros(robot.nq),
                duration,
                config=cfg,
                failures=list(failures),
            )
        )
    return out[0], out[1], held


def _identical(a, b):
    for name in ("t", "q", "v", "energy"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)

    def log(res):
        ev = res.events
        return [(e.t, e.kind, e.piece1, e.piece2, e.energy_before, e.energy_after) for e in ev]

    assert log(b) == log(a)
    assert b.rest_time == a.rest_time
    assert b.diagnostics.min_distance == a.diagnostics.min_distance


@pytest.mark.parametrize(
    ("start", "mu", "locked"),
    [(None, 0.5, WRIST_JOINTS), (5, 1.2, ())],
    ids=["collapse-mu0.5", "wrist-free-start5-mu1.2"],
)
def test_an_arm_at_rest_is_held_in_one_step(robot, monkeypatch, start, mu, locked):
    """The collapse (5 s) and a wrist-free random start (3 s): the arm comes to rest, then
    one step to the end; the same run."""
    duration = 5.0 if start is None else 3.0
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=locked)
    q0 = None if start is None else start_pose(robot, start)
    off, on, held = _runs(robot, monkeypatch, duration, cfg, q0=q0)
    _identical(off, on)
    rest = on.rest_time
    assert rest is not None and rest < duration - 0.5
    # (the arm may be captured, move again and be captured anew: the last hold is to the end)
    assert held and held[0][0] >= rest and held[-1][1] == duration
    # the steps of max_step the stepper took after the last capture are gone
    saved = off.diagnostics.steps - on.diagnostics.steps
    assert saved >= int((duration - held[-1][0]) / cfg.max_step) - 1
    assert np.all(on.q[on.t > held[-1][0]] == on.q[-1])


def test_a_failure_ends_the_hold_on_its_time(robot, monkeypatch):
    """A joint that freezes at 3 s, the arm at rest since about 2 s: the hold ends at the
    failure's time, the failure is applied, the arm (still at rest) is held again to the end;
    the same run as the stepper's."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    fail = [Failure(joint="elbow2", kind="frozen", t=3.0)]
    off, on, held = _runs(robot, monkeypatch, 4.0, cfg, failures=fail)
    _identical(off, on)
    assert any(e.kind == "failure" and e.t == 3.0 for e in on.events)
    assert [t1 for _, t1 in held] == [3.0, 4.0]
    assert held[1][0] == 3.0


def test_no_hold_with_a_motor_lag(robot, monkeypatch):
    """The motors' lag states (the state's tail) evolve at rest: no hold, the same run."""
    cfg = packbot.SimConfig(
        contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS, motor_lag=0.01
    )
    off, on, held = _runs(robot, monkeypatch, 3.0, cfg)
    _identical(off, on)
    assert on.rest_time is not None  # (at rest, and yet not held)
    assert held == []


class _Zero(Controller):
    """A sampled controller whose command is always zero (1 ms ticks)."""

    def compute(self, t, q, v):
        return np.zeros(8)


def test_no_hold_with_a_controller_tick_to_come(robot, monkeypatch):
    """The collapse under a sampled controller holding a zero command: the arm is captured at
    rest as without it, but a tick comes before any step's end (the stepper steps over the
    ticks that keep the command): the loop offers no hold; the same run."""
    captured = []
    capture = NormalContacts.capture

    def noted(self, *args):
        out = capture(self, *args)
        captured.append(out is not None)
        return out

    hold = normal_law.NormalLaw._hold_at_rest
    calls = []

    def counted(self, stepper, t_end):
        calls.append(t_end)
        return hold(self, stepper, t_end)

    monkeypatch.setattr(NormalContacts, "capture", noted)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    res = []
    for on in (False, True):
        monkeypatch.setattr(normal_law.NormalLaw, "_hold_at_rest", counted if on else _no_hold)
        res.append(
            packbot.simulate(
                robot,
                robot.pose("drive"),
                np.zeros(robot.nq),
                3.0,
                config=cfg,
                controller=_Zero(),
            )
        )
    _identical(*res)
    assert any(captured)  # the arm is captured at rest
    assert calls == []
