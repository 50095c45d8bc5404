"""The contact-normal mode's step ends: what they keep and skip, against the full evaluation.

``ConstrainedDynamics._rest_accel`` (packbot.contact.normal_dynamics) keeps its last answer
while its inputs (q, a_free, M^-1, the joints' Coulomb friction) and the contact set are
unchanged: the step ends of a resting arm ask it again at the same state. At every call of a
collapse that comes to rest, the kept answer is compared with the cone problem solved from
scratch; a change of the contact set forgets it. The pairs whose events the step end does not
check (NormalLaw._pairs_to_check) are checked all the same at every step end: none has one.
"""

from __future__ import annotations

import numpy as np

import packbot
from packbot.contact.normal_dynamics import ConstrainedDynamics

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def _collapse() -> packbot.SimResult:
    robot = packbot.load_robot()
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)


def test_kept_rest_accel_equals_a_fresh_solve(monkeypatch) -> None:
    kept = ConstrainedDynamics._rest_accel
    calls = {"n": 0, "hits": 0}

    def checked(self, q, a_free, minv):
        before = self._rest_cache
        a = kept(self, q, a_free, minv)
        fresh = self._rest_accel_solve(q, a_free, minv)
        calls["n"] += 1
        if before is not None and self._rest_cache is before:  # answered from the cache
            calls["hits"] += 1
        if fresh is None:
            assert a is None
        else:
            assert a is not None
            np.testing.assert_array_equal(a, fresh)  # bit for bit
        return a

    monkeypatch.setattr(ConstrainedDynamics, "_rest_accel", checked)
    res = _collapse()
    assert res.rest_time is not None  # the arm came to rest: the step ends asked again
    assert calls["hits"] > 0
    assert calls["hits"] < calls["n"]


def test_same_run_with_and_without_the_kept_answer(monkeypatch) -> None:
    res_kept = _collapse()
    monkeypatch.setattr(ConstrainedDynamics, "_rest_accel", ConstrainedDynamics._rest_accel_solve)
    res_fresh = _collapse()
    np.testing.assert_array_equal(res_kept.t, res_fresh.t)
    np.testing.assert_array_equal(res_kept.q, res_fresh.q)
    assert [(e.t, e.kind) for e in res_kept.events] == [(e.t, e.kind) for e in res_fresh.events]
    assert res_kept.rest_time == res_fresh.rest_time


def test_a_changed_contact_set_forgets_the_kept_answer(monkeypatch) -> None:
    seen: list = []
    kept = ConstrainedDynamics._rest_accel

    def spy(self, q, a_free, minv):
        a = kept(self, q, a_free, minv)
        seen.append(self)
        return a

    monkeypatch.setattr(ConstrainedDynamics, "_rest_accel", spy)
    _collapse()
    contacts = seen[-1]
    assert contacts._rest_cache is not None
    version = contacts._version
    contacts._invalidate()
    assert contacts._rest_cache is None
    assert contacts._version == version + 1


def test_pairs_not_checked_have_no_event(monkeypatch) -> None:
    """At every step end of the collapse, each pair NormalLaw._pairs_to_check leaves out has no
    event when checked all the same (so leaving it out hides none)."""
    from packbot.contact.normal_law import NormalLaw

    chosen = NormalLaw._pairs_to_check
    counts = {"skipped": 0, "checked": 0}

    def every(self, pairs, distances):
        keep = list(chosen(self, pairs, distances))
        assert keep == sorted(keep)
        for i, (p_idx, d1) in enumerate(zip(pairs, distances, strict=True)):
            if i in keep:
                counts["checked"] += 1
                continue
            counts["skipped"] += 1
            d0 = self.last_d.get(p_idx, float("inf"))
            assert self._pair_crossings(("pair", p_idx), p_idx, None, d0, d1) == []
        return keep

    monkeypatch.setattr(NormalLaw, "_pairs_to_check", every)
    _collapse()
    assert counts["skipped"] > 0
    assert counts["checked"] > 0
