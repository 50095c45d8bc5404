"""The restart's stop of residual slides (``RestartSteps.stop_slow``) never lifts a contact.

Friction stops a slide through a normal force: a velocity change that lifts a resting row off
(a tangential impulse with no normal impulse behind it) is outside every friction cone. In the
collapse (mu = 0.5, wrist locked) the least change stopping the elbow casing's slow slide on
the chassis lifted its resting point; the point fell back 0.53 ms later, an impact, and the
same stop and lift again: 33 impacts from t = 0.333 s until a cascade window.
"""

import numpy as np
import pytest

import packbot
from packbot.contact import normal_steps
from packbot.contact.normal_tolerances import SPEED_BAND, TOUCH_GAP
from packbot.mujoco_model import WRIST_JOINTS


@pytest.fixture(scope="module")
def collapse(robot):
    """The collapse's first 0.4 s (mu = 0.5, wrist locked) and every stop_slow call's rows."""
    calls: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    original = normal_steps.RestartSteps.stop_slow

    def recorded(self, q, v, minv):
        v_after = original(self, q, v, minv)
        Jn, _, gap, vn, _ = self._problem(q, v)
        resting = (gap <= TOUCH_GAP) & (vn <= SPEED_BAND)
        calls.append((Jn[resting] @ v, Jn[resting] @ v_after, v_after - v))
        return v_after

    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(normal_steps.RestartSteps, "stop_slow", recorded)
        res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.4, config=cfg)
    return res, calls


def test_no_stop_lifts_a_resting_row(collapse):
    _, calls = collapse
    made = [c for c in calls if np.abs(c[2]).max() > 0.0]
    assert made, "no slide was stopped: the test no longer covers stop_slow"
    for before, after, _ in made:
        assert before.max(initial=0.0) <= SPEED_BAND
        assert after.max(initial=0.0) <= SPEED_BAND, (before, after)


def test_the_casing_does_not_hop_on_the_chassis(collapse):
    res, _ = collapse
    hops = [
        e
        for e in res.events
        if e.kind == "impact"
        and {e.piece1, e.piece2} == {"link2/elbow1_casing", "base_link/body"}
        and 0.3 <= e.t <= 0.4
    ]
    assert len(hops) <= 2, [round(e.t, 5) for e in hops]
    gains = [e.energy_after - e.energy_before for e in res.events]
    assert max(gains) <= 1e-9
    assert -res.diagnostics.min_distance <= 1e-5
