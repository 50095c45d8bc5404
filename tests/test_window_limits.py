"""Limits hold inside time-stepping windows (issue 38, item 4).

A window step's limit rows are the stops within ``LIMIT_GAP + h max(|v|, |v_f|)`` of the joints
at the step's start. A contact impulse inside the step can drive a joint faster than that, past
a stop that is not one of the rows: the step then hands back (the extension's status 5, or
Python's own check) and is solved again with the stops within ``h |v1|``, whose rows hold the
joint. Checked on real window steps: the step of a wrist-free run whose impulses change a
joint's speed the most is replayed with that joint's stop moved in between what the step's
start sees and where its impulses take the joint.
"""

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot.contact import timestep

START, MU, E, DURATION = 25, 0.0, 0.3, 0.85
"""A wrist-free random start whose windows hold contact impulses that kick the wrist."""

ROW_TOL = 1e-7
"""How far past a stop a limit row lets q1 end [rad]: the window's impulses to the conic
solver's residual (RESIDUAL_OK on a velocity of ~1 rad/s, times h ~1e-3 s), far under the
stop's move here (> 1e-5 rad)."""


def _run(robot, before=None, after=None):
    """The run, with ``before(stepper, t, y, h)`` / ``after(stepper, t, y, h, seg)`` around
    every window step the stepper takes itself (not those a native run of steps took)."""
    real = timestep.MoreauJeanStepper.step

    def step(self, t, y, t_end, energy, pending=None):
        n = self.n
        h = min(self.h, timestep.STEP_ANGLE / max(float(np.abs(y[n : 2 * n]).sum()), 1e-300))
        h = min(h, t_end - t)
        mine = pending is None
        if mine and before is not None:
            before(self, t, y, h)
        try:
            seg, info = real(self, t, y, t_end, energy, pending)
        finally:
            if mine and after is not None:
                after(self, t, y, h, seg)
        return seg, info

    real_finish = timestep.MoreauJeanStepper._finish

    def finish(self, t, y, h, tail, target, applied, end, *args, **kwargs):
        self._test_vf = end[0]  # (the step's free velocity)
        self._test_native = end[3] is not None  # (the extension's step: its energies)
        return real_finish(self, t, y, h, tail, target, applied, end, *args, **kwargs)

    cfg = packbot.SimConfig(contact_mode="normal", mu=MU, restitution=E, sample_dt=1e-3)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(timestep.MoreauJeanStepper, "step", step)
        mp.setattr(timestep.MoreauJeanStepper, "_finish", finish)
        return packbot.simulate(
            robot, start_pose(robot, START), np.zeros(robot.nq), DURATION, config=cfg
        )


@pytest.mark.parametrize("path", ["native", "python"])
def test_a_kicked_joint_is_held_by_a_stop_the_step_did_not_start_near(robot, path):
    """The stop joins the step's rows and holds the joint: q1 within ROW_TOL of it. On the
    step the extension took (it hands the step back: status 5) and on one Python took."""
    kicks = []  # (slack [rad], t, joint, side, q_j [rad], the start's reach [rad])

    def record(stepper, t, y, h, seg):
        n = stepper.n
        q, v, v1 = y[:n], y[n : 2 * n], seg.y1[n : 2 * n]
        seen = timestep.LIMIT_GAP + h * np.maximum(np.abs(v), np.abs(stepper._test_vf))
        slack = h * np.abs(v1) - seen  # (> 0: q + h v1 passes what the start saw)
        j = int(np.argmax(slack))
        if stepper._test_native == (path == "native"):
            kicks.append((float(slack[j]), t, j, 1 if v1[j] > 0 else -1, float(q[j]), seen[j]))

    _run(robot, after=record)
    slack, t_kick, j, side, q_j, seen = max(kicks)
    assert slack > 1e-4, max(kicks)  # (a real kick: the stop below is passed by slack / 2)

    held = {}

    def move_stop(stepper, t, y, h):
        if t != t_kick:
            return
        lim = stepper.sys.upper if side > 0 else stepper.sys.lower
        held["was"] = float(lim[j])
        # beyond what the step's start sees, short of where its impulses take the joint
        held["stop"] = lim[j] = q_j + side * (seen + 0.5 * slack)
        held["misses"] = stepper.native_misses.get(5, 0)

    def restore(stepper, t, y, h, seg):
        if t != t_kick:
            return
        sys = stepper.sys
        (sys.upper if side > 0 else sys.lower)[j] = held["was"]
        held["q1"] = float(seg.y1[j])
        held["in_set"] = (j, side) in stepper.contacts.limits
        held["native"] = stepper.native_misses.get(5, 0) - held["misses"]

    _run(robot, before=move_stop, after=restore)
    assert "q1" in held, "the replay did not reach the kicked step"
    assert held["in_set"]
    if path == "native":
        assert held["native"] == 1, held
    assert side * (held["q1"] - held["stop"]) <= ROW_TOL, held
