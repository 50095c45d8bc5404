"""The simulator's sampled-data controller loop: ticks, zero-order hold, failure notices."""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control import Controller, Sensor
from packbot.failures import Failure

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


class Recorder(Controller):
    """Gravity compensation at the measured q, recording what it is given."""

    def on_reset(self, robot, t0, q0, v0):
        self.data = robot.model.createData()
        self.calls = []
        self.failures = []

    def compute(self, t, q, v):
        self.calls.append((t, q.copy(), v.copy()))
        return pin.computeGeneralizedGravity(self.robot.model, self.data, q) + 0.1 * t

    def on_failure(self, failure, t):
        self.failures.append((t, failure))


def test_ticks_every_dt_with_a_zero_order_hold(robot):
    ctrl = Recorder(dt=0.004)
    cfg = packbot.SimConfig(locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("high"), np.zeros(8), 0.1, controller=ctrl, config=cfg)
    times = np.array([c[0] for c in ctrl.calls])
    np.testing.assert_allclose(times, 0.004 * np.arange(len(times)), atol=1e-12)
    assert len(times) == 25 and res.control_ticks == 25  # t = 0 ... 0.096
    # Held between ticks: the command at each sample is the one of the last tick before it.
    for t, cmd in zip(res.t, res.tau_cmd, strict=True):
        k = min(int(np.floor(t / 0.004 + 1e-9)), len(times) - 1)  # no tick at the end
        assert cmd[0] == pytest.approx(0.1 * times[k], abs=1e-12)
    # The controller holds the arm: gravity compensation on exact measurements.
    assert np.abs(res.q[-1] - res.q[0]).max() < 1e-3


def test_noisy_sensor_is_seeded_and_quantised(robot):
    def run(seed):
        ctrl = Recorder(dt=0.01, sensor=Sensor(resolution=1e-3, noise_q=2e-3, seed=seed))
        packbot.simulate(
            robot,
            robot.pose("high"),
            np.zeros(8),
            0.05,
            controller=ctrl,
            config=packbot.SimConfig(locked_joints=WRIST),
        )
        return np.array([c[1] for c in ctrl.calls])

    a, b, c = run(1), run(1), run(2)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0
    np.testing.assert_allclose(a / 1e-3, np.round(a / 1e-3), atol=1e-9)


@pytest.mark.parametrize("inform", [True, False])
def test_failure_notice_reaches_the_controller_only_when_asked(robot, inform):
    ctrl = Recorder(dt=0.01)
    fail = Failure(joint="elbow1", kind="frozen", t=0.05)
    packbot.simulate(
        robot,
        robot.pose("high"),
        np.zeros(8),
        0.1,
        controller=ctrl,
        config=packbot.SimConfig(locked_joints=WRIST),
        failures=[fail],
        inform_controller=inform,
    )
    assert ctrl.failures == ([(0.05, fail)] if inform else [])


def test_controller_errors_name_the_time(robot):
    class Broken(Controller):
        def compute(self, t, q, v):
            if t > 0.02:
                raise RuntimeError("lost encoder")
            return np.zeros(8)

    with pytest.raises(packbot.ControllerError, match="lost encoder") as exc:
        packbot.simulate(
            robot,
            robot.pose("high"),
            np.zeros(8),
            0.1,
            controller=Broken(dt=0.01),
            config=packbot.SimConfig(locked_joints=WRIST),
        )
    assert exc.value.t == pytest.approx(0.03)


def test_bad_controller_is_refused(robot):
    with pytest.raises(packbot.ConfigurationError, match="controller"):
        packbot.simulate(robot, robot.pose("high"), np.zeros(8), 0.1, controller=42)
