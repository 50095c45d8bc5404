"""Identification from logged motion (packbot.identification) and the exciting trajectory.

The logs are synthetic: the torques a perturbed arm (masses, centres of mass, inertias, armature
and friction changed consistently) needs on an exciting trajectory, by inverse dynamics with its
friction. Every tolerance is stated; nothing depends on bit patterns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.control import ComputedTorque, ExcitingTrajectory, check_path, exciting_trajectory
from packbot.errors import ConfigurationError, PackbotError, ResourceNotFound, UnknownNameError
from packbot.identification import (
    Identification,
    identify,
    identify_csv,
    load_log,
    parameter_names,
    parameters,
    predict_torques,
    regressor,
    with_parameters,
)

#: Log sample spacing [s] (200 Hz: a real arm's controller logs at 100 Hz to 1 kHz).
DT = 0.005


def perturbed(robot: packbot.Robot, seed: int = 7) -> packbot.Robot:
    """The arm with each body's mass and inertia scaled by 0.7 to 1.3 (together, so the body
    stays consistent), its centre of mass moved up to 15 mm, and armature and friction scaled by
    0.6 to 1.4."""
    rng = np.random.default_rng(seed)
    x = parameters(robot)
    model = robot.model
    for j in range(model.njoints - 1):
        inertia = model.inertias[j + 1]
        s = 1.0 + 0.3 * rng.uniform(-1.0, 1.0)
        c = np.asarray(inertia.lever) + 0.015 * rng.uniform(-1.0, 1.0, 3)
        x[10 * j : 10 * j + 10] = pin.Inertia(
            inertia.mass * s, c, np.asarray(inertia.inertia) * s
        ).toDynamicParameters()
    nb = 10 * (model.njoints - 1)
    x[nb:] *= 1.0 + 0.4 * rng.uniform(-1.0, 1.0, len(x) - nb)
    return with_parameters(robot, x)


@pytest.fixture(scope="module")
def robot() -> packbot.Robot:
    return packbot.load_robot()


@pytest.fixture(scope="module")
def arm(robot: packbot.Robot) -> packbot.Robot:
    return perturbed(robot)


@pytest.fixture(scope="module")
def excitation(robot: packbot.Robot) -> ExcitingTrajectory:
    return exciting_trajectory(robot, 20.0, seed=1)


@pytest.fixture(scope="module")
def log(
    excitation: ExcitingTrajectory, arm: packbot.Robot
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, excitation.t_end + DT / 2, DT)
    q, v, a = excitation.sample(t)
    return t, q, v, predict_torques(arm, q, v, a)


@pytest.fixture(scope="module")
def held_out(
    robot: packbot.Robot, arm: packbot.Robot
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Another motion, from another centre pose: (q, v, a, the perturbed arm's torques)."""
    other = exciting_trajectory(robot, 10.0, seed=2, q_start="high", harmonics=4)
    q, v, a = other.sample(np.arange(0.0, other.t_end, 0.02))
    return q, v, a, predict_torques(arm, q, v, a)


def relative_rms(robot: packbot.Robot, motion: tuple[np.ndarray, ...]) -> float:
    q, v, a, tau = motion
    return float(np.linalg.norm(predict_torques(robot, q, v, a) - tau) / np.linalg.norm(tau))


@pytest.fixture(scope="module")
def noise_free(robot: packbot.Robot, log: tuple[np.ndarray, ...]) -> Identification:
    t, q, _, tau = log
    return identify(robot, t, q, tau=tau)


# --------------------------------------------------------------------------- the regressor


def test_regressor_reproduces_inverse_dynamics_with_armature_and_friction(
    robot: packbot.Robot, arm: packbot.Robot
) -> None:
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.params.lower, robot.params.upper, (5, 8))
    v, a = rng.normal(size=(5, 8)), rng.normal(size=(5, 8))
    for r in (robot, arm):
        tau = regressor(r, q, v, a) @ parameters(r)
        np.testing.assert_allclose(tau, predict_torques(r, q, v, a).ravel(), rtol=0, atol=1e-9)
    assert len(parameter_names(robot)) == len(parameters(robot)) == 10 * 8 + 3 * 8


def test_with_parameters_round_trips_and_refuses_an_unphysical_body(robot: packbot.Robot) -> None:
    x = parameters(robot)
    np.testing.assert_allclose(parameters(with_parameters(robot, x)), x, rtol=1e-12, atol=1e-15)
    bad = x.copy()
    bad[10] = -1.0  # link1's mass
    with pytest.raises(ConfigurationError, match="physically consistent"):
        with_parameters(robot, bad)
    bad = x.copy()
    bad[-1] = -0.1  # a negative Coulomb friction
    with pytest.raises(ConfigurationError, match="gripper_jaw.coulomb"):
        with_parameters(robot, bad)


# --------------------------------------------------------------------------- identification


def test_noise_free_log_predicts_a_held_out_motion_within_1e_3(
    robot: packbot.Robot, noise_free: Identification, held_out: tuple[np.ndarray, ...]
) -> None:
    nominal = relative_rms(robot, held_out)
    identified = relative_rms(noise_free.robot, held_out)
    assert nominal > 0.01  # the perturbation is visible
    assert identified < 1e-3
    assert noise_free.relative_residual < 1e-4
    assert 30 <= noise_free.rank < len(noise_free.names)
    assert np.isfinite(noise_free.condition_number) and noise_free.condition_number < 1e3


def test_identified_robot_is_physically_consistent_and_simulates(
    noise_free: Identification,
) -> None:
    ident = noise_free.robot
    for j in range(1, ident.model.njoints):
        inertia = ident.model.inertias[j]
        assert inertia.mass > 0
        moments = np.linalg.eigvalsh(np.asarray(inertia.inertia))
        assert moments[0] > 0 and moments[0] + moments[1] >= moments[2] * (1 - 1e-9)
    p = ident.params
    assert np.all(p.armature >= 0) and np.all(p.viscous >= 0) and np.all(p.coulomb >= 0)
    np.testing.assert_allclose(ident.model.armature, p.armature)
    np.testing.assert_allclose(p.rotor_inertia * p.gear_ratio**2, p.armature)
    assert ident.joint_names == packbot.load_robot().joint_names
    assert noise_free.parameter("link1.m") == pytest.approx(ident.model.inertias[2].mass)
    with pytest.raises(UnknownNameError):
        noise_free.parameter("link1.mass")
    config = packbot.SimConfig(locked_joints=("camera_tilt", "camera_pan", "gripper_roll"))
    q0 = ident.pose("stand")
    result = packbot.simulate(ident, q0, np.zeros(8), 0.05, config=config)
    assert np.all(np.isfinite(result.q[-1]))


def test_noisy_log_still_beats_the_nominal_model(
    robot: packbot.Robot,
    arm: packbot.Robot,
    log: tuple[np.ndarray, ...],
    held_out: tuple[np.ndarray, ...],
) -> None:
    t, q, _, tau = log
    rng = np.random.default_rng(3)
    rms = np.sqrt(np.mean(tau**2, axis=0))
    dq, dtau = rng.standard_normal(q.shape), rng.standard_normal(tau.shape)
    q_noisy = q + 1e-4 * dq  # encoder noise [rad]
    tau_noisy = tau + 0.01 * rms * dtau  # 1 % torque noise
    res = identify(robot, t, q_noisy, tau=tau_noisy)
    error = relative_rms(res.robot, held_out)
    assert error < 0.5 * relative_rms(robot, held_out)
    # gracefully: a tenth of the noise, a smaller error
    quiet = identify(robot, t, q + 1e-5 * dq, tau=tau + 0.001 * rms * dtau)
    assert relative_rms(quiet.robot, held_out) < 0.5 * error
    # the residual holds the torque noise (1 % of each joint's RMS torque) and the encoder
    # noise's share through the filtered acceleration (large on the light wrist joints)
    assert np.all(res.noise_std > 0.008 * rms) and np.all(res.noise_std < 0.5 * rms)
    assert np.all(np.isfinite(res.base_std)) and np.all(res.base_std > 0)


def test_standard_deviations_cover_the_true_base_parameters(
    robot: packbot.Robot, arm: packbot.Robot, log: tuple[np.ndarray, ...]
) -> None:
    # torque noise alone (exact angles): the least-squares standard deviations hold
    t, q, _, tau = log
    rng = np.random.default_rng(5)
    rms = np.sqrt(np.mean(tau**2, axis=0))
    res = identify(robot, t, q, tau=tau + 0.01 * rms * rng.standard_normal(tau.shape))
    z = np.abs(res.base_matrix @ parameters(arm) - res.base_estimate) / res.base_std
    assert np.mean(z < 2.0) > 0.85  # about 95 % for Gaussian errors
    assert np.max(z) < 6.0


def test_simulated_log_of_the_perturbed_arm(
    robot: packbot.Robot,
    arm: packbot.Robot,
    excitation: ExcitingTrajectory,
    held_out: tuple[np.ndarray, ...],
) -> None:
    # The perturbed arm simulated (stick-slip joint friction on) tracking the exciting
    # trajectory by computed torque, its 1 ms held commands logged as the torques: the log
    # holds what inverse dynamics does not (held commands, friction sticking at reversals).
    from scipy.interpolate import CubicSpline

    config = packbot.SimConfig(contact_mode="none", joint_friction=True, sample_dt=DT)
    ctrl = ComputedTorque(trajectory=excitation)
    res = packbot.simulate(
        arm,
        excitation.q_start.copy(),
        np.zeros(8),
        excitation.t_end,
        controller=ctrl,
        config=config,
    )
    # the samples on a uniform grid (the result adds one at each event)
    step = np.r_[np.diff(res.t) > 0, True]
    t = np.arange(0.0, res.t[-1], DT)
    q = CubicSpline(res.t[step], res.q[step])(t)
    tau = res.tau[np.searchsorted(res.t, t + 1e-9, side="right") - 1]
    fit = identify(robot, t, q, tau=tau)
    assert relative_rms(fit.robot, held_out) < 0.3 * relative_rms(robot, held_out)


def test_logged_velocities_and_motor_currents(
    robot: packbot.Robot,
    log: tuple[np.ndarray, ...],
    noise_free: Identification,
    held_out: tuple[np.ndarray, ...],
) -> None:
    t, q, v, tau = log
    kt = {name: 0.02 + 0.01 * k for k, name in enumerate(robot.joint_names)}  # [N*m/A]
    amps = tau / (robot.params.gear_ratio * np.array(list(kt.values())))
    res = identify(robot, t, q, v, currents=amps, torque_constant=kt)
    assert relative_rms(res.robot, held_out) < 1e-3
    assert res.samples == noise_free.samples


def test_csv_log(
    tmp_path: Path, robot: packbot.Robot, log: tuple[np.ndarray, ...], noise_free: Identification
) -> None:
    t, q, _, tau = log
    names = robot.joint_names
    header = ["time"] + [f"q_{j}" for j in names] + [f"tau_{j}" for j in names]
    path = tmp_path / "log.csv"
    np.savetxt(
        path,
        np.column_stack([t, q, tau]),
        delimiter=",",
        header=",".join(header),
        comments="",
        fmt="%.17g",
    )
    data = load_log(robot, path)
    assert data.v is None and data.currents is None and data.q.shape == (len(t), 8)
    res = identify_csv(robot, path)
    np.testing.assert_allclose(res.values, noise_free.values, rtol=1e-6, atol=1e-9)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda t, q, tau: (t, q[:-1], tau), "q"),
        (lambda t, q, tau: (t, q, tau[:, :7]), "tau"),
        (lambda t, q, tau: (t, np.where(np.arange(8) == 2, np.nan, q), tau), "q"),
        (lambda t, q, tau: (t, q, np.where(np.arange(8) == 0, np.inf, tau)), "tau"),
        (lambda t, q, tau: (t[:40], q[:40], tau[:40]), "t"),
        (lambda t, q, tau: (t**1.01, q, tau), "t"),
        (lambda t, q, tau: (t, q, None), "tau"),
    ],
)
def test_bad_logs_name_the_field(
    robot: packbot.Robot, log: tuple[np.ndarray, ...], change: object, field: str
) -> None:
    t, q, _, tau = log
    t2, q2, tau2 = change(t[:400], q[:400], tau[:400])  # type: ignore[operator]
    with pytest.raises(ConfigurationError) as info:
        identify(robot, t2, q2, tau=tau2)
    assert info.value.field == field
    assert isinstance(info.value, PackbotError)


def test_bad_options_name_the_option(robot: packbot.Robot, log: tuple[np.ndarray, ...]) -> None:
    t, q, _, tau = (x[:400] for x in log)
    cases = [
        (dict(tau=tau, currents=tau), "tau"),
        (dict(currents=tau), "torque_constant"),
        (dict(currents=tau, torque_constant=-1.0), "torque_constant"),
        (dict(tau=tau, window=0.01), "window"),
        (dict(tau=tau, polyorder=9), "polyorder"),
        (dict(tau=tau, prior_weight=0.0), "prior_weight"),
        (dict(tau=tau, weighted="yes"), "weighted"),
        (dict(tau=tau, torque_constant=0.1), "torque_constant"),
    ]
    for kwargs, field in cases:
        with pytest.raises(ConfigurationError) as info:
            identify(robot, t, q, **kwargs)  # type: ignore[arg-type]
        assert info.value.field == field, kwargs
    with pytest.raises(UnknownNameError):
        identify(robot, t, q, currents=tau, torque_constant={"elbow3": 0.1})
    with pytest.raises(packbot.errors.KeywordError):
        identify(robot, t, q, tau=tau, windw=0.2)  # type: ignore[call-arg]


def test_bad_csv_logs(tmp_path: Path, robot: packbot.Robot) -> None:
    names = robot.joint_names
    good = ["time"] + [f"q_{j}" for j in names] + [f"tau_{j}" for j in names]
    row = ",".join(["0.0"] * len(good))

    def write(header: list[str], rows: list[str]) -> Path:
        path = tmp_path / "bad.csv"
        path.write_text("\n".join([",".join(header), *rows]) + "\n")
        return path

    with pytest.raises(ConfigurationError) as info:
        load_log(robot, write([*good[:-1], "tau_gripper_jw"], [row]))
    assert "tau_gripper_jaw" in str(info.value) and "tau_gripper_jw" in str(info.value)
    with pytest.raises(ConfigurationError, match="tau_gripper_jaw"):
        load_log(robot, write(good[:-1], [",".join(["0.0"] * (len(good) - 1))]))
    with pytest.raises(ConfigurationError, match="line 3, column q_elbow1"):
        cells = ["0.0"] * len(good)
        cells[good.index("q_elbow1")] = "abc"
        load_log(robot, write(good, [row, ",".join(cells)]))
    with pytest.raises(ConfigurationError, match="line 2"):
        load_log(robot, write(good, [row + ",1.0"]))
    with pytest.raises(ConfigurationError, match="current_"):
        load_log(robot, write(good[: 1 + len(names)], [",".join(["0.0"] * (1 + len(names)))]))
    with pytest.raises(ResourceNotFound):
        load_log(robot, tmp_path / "missing.csv")


# --------------------------------------------------------------------------- the excitation


def test_exciting_trajectory_is_within_limits_collision_free_and_at_rest_at_its_ends(
    robot: packbot.Robot, excitation: ExcitingTrajectory
) -> None:
    p = robot.params
    t = np.arange(0.0, excitation.t_end + 1e-9, 0.01)
    q, v, a = excitation.sample(t)
    assert np.all(q >= p.lower) and np.all(q <= p.upper)
    assert np.all(np.abs(v) <= 0.8 * p.velocity * (1 + 1e-9))
    tau = predict_torques(robot, q, v, a)
    assert np.all(np.abs(tau) <= 0.8 * p.effort * 1.01)  # on a finer grid than the design's
    assert check_path(robot, q[::5]) is None
    for end in (0.0, excitation.t_end):
        qe, ve, ae = excitation(end)
        np.testing.assert_allclose(qe, excitation.q_start, atol=1e-9)
        np.testing.assert_allclose(ve, 0.0, atol=1e-9)
        np.testing.assert_allclose(ae, 0.0, atol=1e-9)
    assert np.all(np.ptp(q, axis=0) > 0.1)  # every joint moves
    assert excitation.condition_number < 1e3 and excitation.min_distance > 0


def test_exciting_trajectory_is_reproducible_and_a_controller_reference(
    robot: packbot.Robot, excitation: ExcitingTrajectory
) -> None:
    again = exciting_trajectory(robot, 20.0, seed=1)
    np.testing.assert_allclose(again.sin_coeffs, excitation.sin_coeffs, rtol=0, atol=1e-12)
    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    still = exciting_trajectory(
        robot, 10.0, seed=4, joints=["turret", "gripper_roll"], candidates=4
    )
    q, _, _ = still.sample(np.linspace(0.0, 10.0, 50))
    assert np.ptp(q[:, 1:6], axis=0).max() == 0.0 and np.ptp(q[:, 7]) == 0.0
    assert np.ptp(q[:, 0]) > 0.1 and np.ptp(q[:, 6]) > 0.1
    ctrl = ComputedTorque(trajectory=excitation)
    config = packbot.SimConfig(locked_joints=wrist, contact_mode="joint_clamp")
    q0 = excitation.q_start.copy()
    result = packbot.simulate(robot, q0, np.zeros(8), 0.3, controller=ctrl, config=config)
    q_ref, _, _ = excitation(0.3)
    arm = [0, 1, 2, 3]
    assert np.max(np.abs(result.q[-1][arm] - q_ref[arm])) < 0.02


def test_exciting_trajectory_bad_arguments(robot: packbot.Robot) -> None:
    for kwargs, field in [
        (dict(duration=0.1), "duration"),
        (dict(duration=10.0, harmonics=1), "harmonics"),
        (dict(duration=10.0, amplitude=-0.1), "amplitude"),
        (dict(duration=10.0, limit_fraction=1.5), "limit_fraction"),
        (dict(duration=10.0, q_start=[0.0] * 3), "q_start"),
    ]:
        with pytest.raises(ConfigurationError) as info:
            exciting_trajectory(robot, **kwargs)  # type: ignore[arg-type]
        assert info.value.field == field
    with pytest.raises(UnknownNameError):
        exciting_trajectory(robot, 10.0, joints=["elbow3"])
    with pytest.raises(UnknownNameError):
        exciting_trajectory(robot, 10.0, q_start="sitting")
