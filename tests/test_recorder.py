"""The Recorder keeps samples in preallocated arrays that grow when events add samples."""

import numpy as np
import pytest

from packbot.recorder import Recorder


def _measure(t, y):
    """A sample like packbot.recorder.measure's: six (3,) arrays and a float."""
    q = np.array([t, 2 * t, y[0]])
    return (q, -q, q + 1, q + 2, q + 3, np.full(3, 7.0), float(10 * t))


def test_samples_beyond_the_allocation_are_all_kept_in_order():
    rec = Recorder(0.1, 1.0, _measure)
    capacity = int(1.0 / 0.1) + 2 + Recorder.EXTRA_ROWS
    times = np.linspace(0.0, 1.0, 3 * capacity + 5)  # far more than allocated: two growths
    for k, t in enumerate(times):
        rec.point(float(t), np.array([float(k)]))
    t, q, v, cmd, tau, fr, eff, energy = rec.arrays()
    assert len(rec) == len(times) and rec.samples_t == times.tolist()
    np.testing.assert_array_equal(t, times)
    assert q.shape == (len(times), 3) and energy.shape == (len(times),)
    np.testing.assert_array_equal(q[:, 2], np.arange(len(times)))
    np.testing.assert_array_equal(v, -q)
    np.testing.assert_array_equal(fr, q + 3)
    np.testing.assert_array_equal(eff, 7.0)
    np.testing.assert_array_equal(energy, 10 * times)
    for a in (t, q, v, cmd, tau, fr, eff, energy):
        assert a.dtype == np.float64 and a.flags.c_contiguous


def test_arrays_hold_only_the_filled_rows():
    rec = Recorder(0.01, 2.0, _measure)  # room for 266 samples
    for t in (0.0, 0.01, 0.02):
        rec.point(t, np.zeros(1))
    t, q, *_ = rec.arrays()  # a run stopped early: copies, not the whole allocation
    assert t.tolist() == [0.0, 0.01, 0.02] and q.shape == (3, 3)
    assert t.flags.owndata and q.flags.owndata
    rec.point(0.03, np.zeros(1))  # a later sample does not change arrays already handed out
    assert len(t) == 3 and len(rec.arrays()[0]) == 4
    for k in range(4, 220):  # nearly full: views of the allocation, no copy
        rec.point(0.01 * k, np.zeros(1))
    t, q, *_ = rec.arrays()
    assert len(t) == 220 and not t.flags.owndata and not q.flags.owndata
    np.testing.assert_array_equal(t, 0.01 * np.arange(220))


def test_regular_samples_and_the_final_state():
    rec = Recorder(0.25, 0.6, _measure)
    rec.point(0.0, np.zeros(1))
    rec.next_sample = 1
    rec.record_due(0.6, np.ones(1))  # 0.25 and 0.5 are due
    rec.record_final(np.ones(1))  # 0.6 is not a multiple of 0.25: the final state is kept
    rec.record_final(np.ones(1))  # once
    assert rec.samples_t == [0.0, 0.25, 0.5, 0.6]


def test_no_sample_gives_empty_arrays_and_a_failed_measure_keeps_nothing():
    def broken(t, y):
        raise RuntimeError("cannot measure")

    rec = Recorder(0.1, 1.0, broken)
    with pytest.raises(RuntimeError):
        rec.point(0.0, np.zeros(1))
    assert len(rec) == 0 and not rec.samples_t
    assert [a.shape for a in rec.arrays()] == [(0,)] * 8


def test_a_steps_samples_measured_at_once_are_the_samples_one_by_one(robot):
    """measure_many (the columns of a step's samples at once, the energies in one compiled
    call) gives measure's numbers (the compiled energies to rounding): a
    torque-free collapse, friction with a held command; with a torque function it declines
    (each sample is measured alone)."""
    import packbot
    from packbot import integrator
    from packbot.control.base import Controller
    from packbot.recorder import measure, measure_many

    class Held(Controller):
        def compute(self, t, q, v):
            tau = np.zeros(8)
            tau[1] = 20.0 * np.sin(3.0 * t)
            return tau

    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cases = [
        (packbot.SimConfig(contact_mode="joint_clamp", locked_joints=wrist), None),
        (packbot.SimConfig(contact_mode="none", joint_friction=True), Held(dt=0.01)),
    ]
    for cfg, ctrl in cases:
        run = integrator._Run(robot, robot.pose("drive"), np.zeros(8), 1.0, ctrl, None, cfg)
        run.start()
        while run.stepper.t < 0.3:
            seg = run.stepper.step(1.0)
            ts = list(np.linspace(seg.t0, seg.t1, 4))
            ys = [seg(t) for t in ts]
            cols = measure_many(ts, ys, run.drive, run.law.forces().friction)
            assert cols is not None
            for i, (t, y) in enumerate(zip(ts, ys, strict=True)):
                one = measure(t, y, run.drive, run.law.forces().friction)
                for block, value in zip(cols, one, strict=True):
                    row = np.broadcast_to(block, (len(ts), *np.shape(value)))[i]
                    if block is cols[-1]:  # the energy: (v^T M) v summed in the extension's
                        np.testing.assert_allclose(row, value, rtol=1e-14)  # order (rounding)
                    else:  # (the same numbers, copied into the columns)
                        np.testing.assert_array_equal(row, value)
    run = integrator._Run(
        robot,
        robot.pose("drive"),
        np.zeros(8),
        1.0,
        lambda t, q, v: np.zeros(8),
        None,
        packbot.SimConfig(contact_mode="none"),
    )
    run.start()
    seg = run.stepper.step(1.0)
    assert (
        measure_many([seg.t0, seg.t1], [seg.y0, seg.y1], run.drive, run.law.forces().friction)
        is None
    )
