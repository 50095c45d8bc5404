"""The contact-normal mode's step-end screen against the Python checks it stands in for.

After a native step, ``NormalLaw.watch`` asks the extension once (``normal_watch.end_code``:
``NativeWatch.end_check``) which of its checks can find something: the pairs' events, the
modes' conditions, the refresh of a sliding contact's stale patch; only those run. At every
step end of real runs (the collapse with and without friction, an arm with every joint free),
each check is run all the same and must agree with the screen: a clear screen only where the
Python checks find nothing. A run without the screen is the same run, bit for bit; the step
kernel that skips the load after a clear step end has the current modes loaded.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

import packbot
from packbot.contact import native, normal_watch
from packbot.contact.normal_law import NormalLaw


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def _collapse(mu: float, duration: float, wrist: bool = True) -> packbot.SimResult:
    robot = packbot.load_robot()
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST if wrist else ())
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(8), duration, config=cfg)


@pytest.mark.parametrize(
    ("mu", "duration", "wrist"), [(0.5, 5.0, True), (0.0, 5.0, True), (0.5, 1.0, False)]
)
def test_a_clear_screen_only_where_the_python_checks_find_nothing(
    monkeypatch, mu, duration, wrist
) -> None:
    seen: Counter[str] = Counter()
    screened = normal_watch.screened_crossings

    def checked(self, seg, y1, sw, code):
        out = screened(self, seg, y1, sw, code)
        if code < 0:
            seen["not screened"] += 1
            return out
        # what the Python checks find at this step end
        pair_events = self._swept_crossings(seg, sw)
        limit_events = self.stops.crossings(seg, y1, self.active)
        q, v = y1[: self.n], y1[self.n : 2 * self.n]
        beyond = bool(((q >= self.sys.upper) | (q <= self.sys.lower)).any())
        ev = self._native.end_eval(self.normal, y1)
        assert ev is not None  # the screen was at the native step's end
        nc = self.normal
        refresh = nc.sliding(q, v) and nc.stale(q, v, self.pending_d)
        assert bool(code & 1) == bool(pair_events)
        assert bool(code & 2) == (not ev.cond >= 0.0)
        assert bool(code & 8) == beyond
        if not code & 8:
            assert limit_events == []
        if not code & 4:
            assert not refresh
        else:
            seen["refresh"] += 1
            seen["refresh needed"] += refresh
        if code == 0:
            seen["clear"] += 1
            assert out == []
        seen["limits"] += bool(code & 8)
        return out

    monkeypatch.setattr(normal_watch, "screened_crossings", checked)
    res = _collapse(mu, duration, wrist)
    assert res.diagnostics.steps > 100
    assert seen["clear"] > 0
    # the refresh bit is exact but where a slide speed is within 1e-9 of the stick speed
    assert seen["refresh needed"] == seen["refresh"]
    if mu > 0.0 and wrist:  # the collapse: most step ends are clear
        assert seen["clear"] > res.diagnostics.steps // 2
    if not wrist:  # the free wrist comes to its stops
        assert seen["limits"] > 0


@pytest.mark.parametrize("mu", [0.5, 0.0])
def test_the_same_run_without_the_screen(monkeypatch, mu) -> None:
    duration = 5.0 if mu > 0.0 else 1.0
    screened = _collapse(mu, duration)
    monkeypatch.setattr(native.NativeWatch, "end_check", lambda self, *a: -1)
    full = _collapse(mu, duration)
    for k in ("t", "q", "v", "tau", "energy"):
        np.testing.assert_array_equal(getattr(screened, k), getattr(full, k))
    assert [(e.t, e.kind, e.piece1, e.piece2) for e in screened.events] == [
        (e.t, e.kind, e.piece1, e.piece2) for e in full.events
    ]
    assert screened.diagnostics.steps == full.diagnostics.steps
    assert screened.diagnostics.sweeps == full.diagnostics.sweeps


def test_a_skipped_load_finds_the_current_modes_loaded(monkeypatch) -> None:
    kernel = NormalLaw.step_kernel
    n = Counter[str]()

    def checked(self, t, y):
        skipped = y is self._ready
        k = kernel(self, t, y)
        if skipped and k is not None:
            n["skipped"] += 1
            nc, rhs = self.normal, self._native
            assert rhs._layout_id is nc._layout()
            assert rhs._plan_id is nc._plan()
        elif k is not None:
            n["loaded"] += 1
        return k

    monkeypatch.setattr(NormalLaw, "step_kernel", checked)
    _collapse(0.5, 5.0)
    assert n["skipped"] > n["loaded"] > 0


def test_the_screen_answers_only_at_the_last_native_steps_end(monkeypatch) -> None:
    got: list[tuple[NormalLaw, np.ndarray]] = []
    screened = normal_watch.screened_crossings

    def keep(self, seg, y1, sw, code):
        out = screened(self, seg, y1, sw, code)
        if self._clear is y1:
            got.append((self, y1))
        return out

    monkeypatch.setattr(normal_watch, "screened_crossings", keep)
    _collapse(0.5, 0.5)
    law, y1 = got[-1]
    rhs = law._native
    active = np.array([k[1] for k in law.active if k[0] == "pair"], dtype=np.int64)
    sw = law.world.sweep(y1[: law.n], reuse=True)
    args = (sw.pairs, sw.distances, active, law.cfg.proximity_tolerance, 1e-4)
    assert rhs.watch.end_check(y1, *args) >= 0  # the step's end: screened
    lay = law.normal._layout()
    with pytest.raises(ValueError, match="one entry per pair"):
        rhs._rhs.set_conditions(lay.offset0, np.append(lay.slide_tol2, 1e-6), 0.0, 0.0, 0.0)
    other = y1.copy()
    other[0] += 1e-9
    assert rhs.watch.end_check(other, *args) == -1  # not the step's end
    rhs.accel(y1[: law.n], y1[law.n :], np.zeros(law.n), True)  # another call since
    assert rhs.watch.end_check(y1, *args) == -1
    with pytest.raises(ValueError):
        rhs._rhs.end_check(y1, sw.pairs, sw.distances[:-1], active, 0.0, 0.0)


@pytest.mark.parametrize("mode", ["normal", "joint_clamp"])
def test_the_kept_distances_are_the_sweep_at_the_kept_state(monkeypatch, mode) -> None:
    """The kept distances (made a dict only when read) are the pairs' at each accepted step."""
    from packbot.contact.stops import JointStops

    after = JointStops.after_step
    n = Counter[str]()

    def checked(self, t, y):
        y_new = after(self, t, y)
        if y_new is None:
            # (the sweep at y is the step end's, kept: a fresh one may differ in the last bits)
            sw = self.world.sweep(y[: self.n], reuse=True)
            assert self.last_d == dict(zip(sw.pairs.tolist(), sw.distances.tolist(), strict=True))
            fresh = self.world.sweep(y[: self.n].copy())
            assert sorted(self.last_d) == sorted(fresh.pairs.tolist())
            np.testing.assert_allclose(
                [self.last_d[p] for p in fresh.pairs.tolist()], fresh.distances, atol=1e-12
            )
            n["checked"] += 1
        return y_new

    monkeypatch.setattr(JointStops, "after_step", checked)
    robot = packbot.load_robot()
    cfg = packbot.SimConfig(contact_mode=mode, mu=0.5, locked_joints=WRIST)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert n["checked"] > 50


def test_the_screens_inputs_of_a_wrong_size_raise() -> None:
    """set_limits, set_keys and end_check check their arrays' sizes (no read out of bounds)."""
    rhs = native.native_rhs(packbot.load_robot().model)
    assert rhs is not None
    nv, none = rhs.nv, np.zeros(0, dtype=np.int64)
    for upper, lower in [(np.zeros(nv), np.zeros(nv - 1)), (np.zeros(nv + 1), np.zeros(nv + 1))]:
        with pytest.raises(ValueError, match="nv entries"):
            rhs.watch.set_limits(upper, lower)
    rhs.watch.set_limits(np.zeros(0), np.zeros(0))  # (none: no limit screened)
    with pytest.raises(ValueError, match="keys"):  # no layout loaded: no pair
        rhs._rhs.set_keys(np.zeros(3, dtype=np.int64))
    y = np.zeros(2 * nv)
    with pytest.raises(ValueError, match="one length"):
        rhs.watch.end_check(y, np.zeros(2, dtype=np.int64), np.zeros(1), none, 1e-3, 1e-4)
    assert rhs.watch.end_check(y, none, np.zeros(0), none, 1e-3, 1e-4) == -1  # no step yet
