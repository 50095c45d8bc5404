"""Identification from logged motion: prediction error against noise (docs/identification.md).

A perturbed arm (each body's mass and inertia scaled by 0.7 to 1.3 together, its centre of mass
moved up to 15 mm, armature and friction scaled by 0.6 to 1.4: the perturbation of
tests/test_identification.py) follows an exciting trajectory (20 s, seed 1) logged at 1 kHz:
joint angles with encoder noise (Gaussian, sigma_q [rad]) and joint torques with torque noise
(Gaussian, a fraction of each joint's RMS torque). ``packbot.identify`` fits the nominal model
to the log; the identified and the nominal models then predict the perturbed arm's torques on a
held-out motion (another exciting trajectory, from the "high" pose, 10 s, seed 2). The table:
the relative RMS prediction error (mean over three noise seeds) for three filter windows, the
fit's relative residual, condition number and time at the default window (0.5 s).

Run: ``python benchmarks/identification.py`` (about 2 minutes on 2 cores).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import pinocchio as pin

import packbot
from packbot.control import exciting_trajectory
from packbot.identification import identify, parameters, predict_torques, with_parameters

log = logging.getLogger("benchmarks.identification")

#: (encoder noise sigma_q [rad], torque noise [fraction of each joint's RMS torque])
NOISE = [(0.0, 0.0), (1e-5, 0.001), (1e-4, 0.01), (3e-4, 0.03), (1e-3, 0.1)]
WINDOWS = (0.2, 0.5, 1.0)  # Savitzky-Golay windows [s]
DEFAULT = 0.5  # identify's default window [s]: the residual, condition number and time
SEEDS = (3, 4, 5)
DT = 1e-3  # log spacing [s]


def perturbed(robot: packbot.Robot, seed: int = 7) -> packbot.Robot:
    """The perturbed arm of tests/test_identification.py."""
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


def main() -> None:
    """Print the table (Markdown)."""
    logging.basicConfig(level=logging.WARNING)
    robot = packbot.load_robot()
    arm = perturbed(robot)
    excitation = exciting_trajectory(robot, 20.0, seed=1)
    t = np.arange(0.0, excitation.t_end + DT / 2, DT)
    q, v, a = excitation.sample(t)
    tau = predict_torques(arm, q, v, a)
    rms = np.sqrt(np.mean(tau**2, axis=0))
    other = exciting_trajectory(robot, 10.0, seed=2, q_start="high", harmonics=4)
    qh, vh, ah = other.sample(np.arange(0.0, other.t_end, 0.01))
    tau_h = predict_torques(arm, qh, vh, ah)

    def error(r: packbot.Robot) -> float:
        return float(np.linalg.norm(predict_torques(r, qh, vh, ah) - tau_h) / np.linalg.norm(tau_h))

    lines = [
        f"exciting trajectory: condition number {excitation.condition_number:.3g}, "
        f"peak torque {excitation.peak_torque:.2f} of the limits, closest approach "
        f"{1e3 * excitation.min_distance:.1f} mm; nominal model's error on the held-out motion: "
        f"{error(robot):.4f}",
        "",
        "| encoder noise [rad] | torque noise [% RMS] | "
        + " | ".join(f"error, window {w:g} s" for w in WINDOWS)
        + " | relative residual | condition number | time per fit [s] |",
        "|---" * (5 + len(WINDOWS)) + "|",
    ]
    for sq, st in NOISE:
        errs: dict[float, list[float]] = {w: [] for w in WINDOWS}
        resid, cond, took = [], [], []
        for seed in SEEDS if sq or st else SEEDS[:1]:
            rng = np.random.default_rng(seed)
            qn = q + sq * rng.standard_normal(q.shape)
            taun = tau + st * rms * rng.standard_normal(tau.shape)
            for w in WINDOWS:
                t0 = time.perf_counter()
                res = identify(robot, t, qn, tau=taun, window=w)
                if w == DEFAULT:
                    took.append(time.perf_counter() - t0)
                    resid.append(res.relative_residual)
                    cond.append(res.condition_number)
                errs[w].append(error(res.robot))
        lines.append(
            f"| {sq:g} | {100 * st:g} | "
            + " | ".join(f"{np.mean(errs[w]):.2e}" for w in WINDOWS)
            + f" | {np.mean(resid):.2e} | {np.mean(cond):.0f} | {np.mean(took):.1f} |"
        )
        log.warning("noise %g rad, %g %%: done", sq, 100 * st)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
