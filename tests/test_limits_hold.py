"""Limits hold inside time-stepping windows and through the drift projection (issue 38, item 4).

A window step's limit rows are the stops within ``LIMIT_GAP + h max(|v|, |v_f|)`` of the joints
at the step's start. A contact impulse inside the step can drive a joint faster than that, past
a stop that is not one of the rows: the step then hands back (the extension's status 5, or
Python's own check) and is solved again with the stops within ``h |v1|``, whose rows hold the
joint. Checked on real window steps: the step of a wrist-free run whose impulses change a
joint's speed the most is replayed with that joint's stop moved in between what the step's
start sees and where its impulses take the joint.

The restart's drift projection solves its position LCP on the touching rows (gap <=
TOUCH_GAP); a row just off (a stop 1.5e-5 rad away) that the move would take below zero joins
them and the LCP is solved again, and a stop not in the set that the move would pass joins the
set. Checked on every projection round of a wrist-free run made through Python (the compiled
stretch's own rounds are not observed).

An event-driven step (35 ms with the wrists locked) can carry a joint past its stop and back,
within it at both ends: the cubic Hermite of the joint's (q, v) at the step's ends flags the
extreme, the dense output confirms it and the event is located before it.
"""

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot.contact import normal_steps, timestep

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
        # (handed back at least once: a second round may add another stop, by rounding)
        assert held["native"] >= 1, held
    assert side * (held["q1"] - held["stop"]) <= ROW_TOL, held


PROJECTION = (59, 1.06)
"""A wrist-free start (mu 0, e 0) whose jaw, pressed on link 1, is projected toward its lower
stop again and again before a window (t 1.034-1.043 s): the touching rows alone moved it
1.4e-4 rad past the stop, 1.5e-5 rad off at the start."""


def test_the_drift_projection_moves_no_joint_past_a_stop(robot):
    """Every projection round made through Python leaves each joint within its stops (to
    1e-12 rad, where it started within them); the run holds projections where the touching
    rows alone would have moved a joint past a stop (their LCP solved in this test), so the
    check is not empty."""
    calls = []
    real = normal_steps.RestartSteps._project_round

    def watched(self, q, v, minv):
        q1 = real(self, q, v, minv)
        if q1 is not None and self.stops is not None:
            upper, lower = self.stops
            was = (q <= upper + 1e-12) & (q >= lower - 1e-12)
            past = np.maximum(q1 - upper, lower - q1)
            # the touching rows alone (the projection's former LCP), in the test
            Jn, _, gap, _, _ = self._problem(q, v)
            touch = gap <= normal_steps.TOUCH_GAP
            J = Jn[touch]
            mu = normal_steps._psd_lcp(J @ minv @ J.T, gap[touch])
            q_alone = q + minv @ J.T @ mu
            alone = np.maximum(q_alone - upper, lower - q_alone)
            calls.append((float(past[was].max(initial=-1.0)), float(alone[was].max(initial=-1.0))))
        return q1

    start, duration = PROJECTION
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0, sample_dt=1e-3)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(normal_steps.RestartSteps, "_project_round", watched)
        packbot.simulate(robot, start_pose(robot, start), np.zeros(robot.nq), duration, config=cfg)
    assert calls
    assert max(c[0] for c in calls) <= 1e-12, max(calls)
    assert max(c[1] for c in calls) > 1e-5, max(calls, key=lambda c: c[1])  # (not empty)


@pytest.mark.parametrize("path", ["native", "python"])
def test_a_stop_the_projection_would_pass_joins_the_set(robot, path):
    """The projection of the run that moves a joint the most is replayed with that joint's stop
    (not in the set) moved halfway along the move: the stop joins the set and holds the joint.
    On a round the extension made (it hands the round back, status 4) and on one Python made
    (the extension handed it back for its gap clipping, status 1)."""
    from packbot.contact.native import NativeRestart

    moves = []  # (|dq_j| [rad], call, joint, side)
    calls, statuses = [0], []
    real = normal_steps.RestartSteps._project_round
    native_round = NativeRestart.project_round

    def counted(*args, **kwargs):
        out = native_round(*args, **kwargs)
        statuses.append(out[0])
        return out

    def record(self, q, v, minv):
        statuses.clear()
        q1 = real(self, q, v, minv)
        calls[0] += 1
        native = statuses[:1] == [3]
        if q1 is not None and self.stops is not None and native == (path == "native"):
            dq = q1 - q
            free = [j for j in range(len(q)) if (j, 1 if dq[j] > 0 else -1) not in self.limits]
            j = max(free, key=lambda j: abs(dq[j]))
            moves.append((abs(float(dq[j])), calls[0] - 1, j, 1 if dq[j] > 0 else -1))
        return q1

    start, duration = PROJECTION
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0, sample_dt=1e-3)

    def run(hook):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(normal_steps.RestartSteps, "_project_round", hook)
            mp.setattr(NativeRestart, "project_round", counted)
            packbot.simulate(
                robot, start_pose(robot, start), np.zeros(robot.nq), duration, config=cfg
            )

    run(record)
    move, call, j, side = max(moves)
    assert move > 1e-6, max(moves)  # (a move the stop below sits inside, by move / 2)
    seen, held = [0], {}

    def replay(self, q, v, minv):
        k, seen[0] = seen[0], seen[0] + 1
        if k != call:
            return real(self, q, v, minv)
        upper, lower = self.stops
        lim = upper if side > 0 else lower
        was = float(lim[j])
        held["stop"] = lim[j] = float(q[j]) + side * 0.5 * move
        self.native.watch.set_limits(upper, lower)  # (the extension's copy of the stops)
        statuses.clear()
        try:
            q1 = real(self, q, v, minv)
        finally:
            lim[j] = was
            self.native.watch.set_limits(upper, lower)
        held["statuses"] = list(statuses)
        held["q1"], held["in_set"] = float(q1[j]), (j, side) in self.limits
        return q1

    run(replay)
    assert held, "the replay did not reach the projection"
    assert held["in_set"]
    assert side * (held["q1"] - held["stop"]) <= 1e-12, held
    assert held["statuses"][0] == (4 if path == "native" else 1), held


def test_limit_excursions_find_the_hermite_extreme_past_a_stop(robot):
    """The cubic Hermite of (q0, v0) = (0, +1) and (q1, v1) = (0, -1) over h = 0.01 s peaks at
    the step's middle at h / 4 = 2.5e-3 rad: a stop at 2e-3 rad is passed there, one at 3e-3
    rad is not; a joint at its stop at both ends is not a candidate (the step-end checks')."""
    from packbot.contact.native import native_rhs

    rhs = native_rhs(robot.model)
    n = robot.model.nv
    upper, lower = np.full(n, 1.0), np.full(n, -1.0)
    y0, y1 = np.zeros(2 * n), np.zeros(2 * n)
    y0[n + 2], y1[n + 2] = 1.0, -1.0  # (joint 2 out and back)
    upper[2] = 2e-3
    rhs.watch.set_limits(upper, lower)
    (j, side, s), *more = rhs.watch.limit_excursions(y0, y1, 0.01, 1e-9)
    assert (j, side, more) == (2, 1, []) and abs(s - 0.5) < 1e-12
    upper[2] = 3e-3
    rhs.watch.set_limits(upper, lower)
    assert rhs.watch.limit_excursions(y0, y1, 0.01, 1e-9) == []
    y0[n + 2], y1[n + 2] = -1.0, 1.0  # (and back the other way, past a lower stop)
    lower[2] = -2e-3
    rhs.watch.set_limits(upper, lower)
    assert [(j, side) for j, side, _ in rhs.watch.limit_excursions(y0, y1, 0.01, 1e-9)] == [(2, -1)]


def test_a_long_step_does_not_carry_a_joint_past_its_stop_and_back(robot):
    """Start 10 of the wrist-locked grid (mu 0.5, e 0.3): elbow1 went 5.5e-4 rad past its upper
    stop for 23 ms (t 0.704-0.728 s) inside 35 ms steps, back within it at both step ends,
    with no event. Now the excursion is an event: elbow1 stays within 1e-5 rad of its stop
    (the checks' bound; measured 1.0e-6 rad, the limit events' own tolerance)."""
    from packbot.mujoco_model import WRIST_JOINTS

    cfg = packbot.SimConfig(
        contact_mode="normal", mu=0.5, restitution=0.3, sample_dt=1e-3, locked_joints=WRIST_JOINTS
    )
    res = packbot.simulate(robot, start_pose(robot, 10), np.zeros(robot.nq), 0.75, config=cfg)
    j = robot.joint_names.index("elbow1")
    assert float(np.max(res.q[:, j] - robot.params.upper[j])) <= 1e-5
    # (the excursion's event: elbow1 reaches its stop, t 0.7042 s here)
    assert any(e.kind == "limit" and e.relevant_joints == ("elbow1",) for e in res.events)
