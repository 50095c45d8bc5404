"""The contact forces on the collapse's rest, against MuJoCo, and what recording them costs.

Prints four tables:

- the rest forces of the collapse (contact-normal mode, mu 0.5, wrist and camera locked, 3 s):
  each pair's summed normal force [N] as packbot records it (the analytic centre of the
  statically admissible set, docs/contact.md) and as MuJoCo (RK4 0.5 ms, its reference setting,
  ``mj_contactForce``) finds it at its own rest;
- the collapse's wall time [s] with the forces recorded (as ``simulate`` runs) and with the
  recorder's contact sampler replaced by one that records none, interleaved in one process,
  medians of ``--repeats`` runs each; the same for a window-heavy wrist-free random start
  (start 16 of ``benchmarks/robustness.py``, mu 0.5, e 0, 1.5 s, 1 ms samples: its window
  samples' forces are read from their steps' impulses), and for the report's law's collapse
  (``joint_clamp``, 3 s: its clamps' torques).

    python benchmarks/contact_forces.py [--repeats 9]
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np

import packbot
from packbot import recorder
from packbot.mujoco_model import WRIST_JOINTS, build_mujoco_model

MU = 0.5


def _collapse(robot: packbot.Robot) -> packbot.SimResult:
    cfg = packbot.SimConfig(contact_mode="normal", mu=MU, locked_joints=WRIST_JOINTS)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)


def _mujoco_forces(robot: packbot.Robot) -> dict[frozenset[str], float]:
    import mujoco

    q0 = robot.pose("drive")
    arm = build_mujoco_model(
        robot, locked_joints=WRIST_JOINTS, mu=MU, q_locked=q0, timestep=5e-4, integrator="rk4"
    )
    m = arm.model
    d = mujoco.MjData(m)
    d.qpos[:] = arm.to_qpos(q0)
    mujoco.mj_forward(m, d)
    for _ in range(round(3.0 / arm.timestep)):
        mujoco.mj_step(m, d)
    out: dict[frozenset[str], float] = {}
    f = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        mujoco.mj_contactForce(m, d, i, f)
        key = frozenset({m.geom(c.geom1).name, m.geom(c.geom2).name})
        out[key] = out.get(key, 0.0) + float(f[0])
    return out


def _windowed(robot: packbot.Robot) -> packbot.SimResult:
    from robustness import start_poses  # (the benchmark's poses; benchmarks/ on the path)

    cfg = packbot.SimConfig(contact_mode="normal", mu=MU, restitution=0.0, sample_dt=1e-3)
    q0 = start_poses(robot, 17, 2026, 2 * cfg.contact_tolerance)[16]
    return packbot.simulate(robot, q0, np.zeros(robot.nq), 1.5, config=cfg)


def _report(robot: packbot.Robot) -> packbot.SimResult:
    """The report's law's collapse (its clamp torques recorded), 3 s."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST_JOINTS)
    return packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)


def _none(drive: Any, law: Any) -> Any:
    return lambda t, y: None


def main(argv: list[str] | None = None) -> None:
    """Print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9, help="timed runs per variant")
    args = ap.parse_args(argv)
    robot = packbot.load_robot()
    res = _collapse(robot)
    mj = _mujoco_forces(robot)
    print("| pair at the collapse's rest | packbot [N] | MuJoCo RK4 0.5 ms [N] |")
    print("|---|---|---|")
    normal = res.contacts.pair_normal_force(len(res.t))[:, -1]
    for (_, p1, _, p2), fn in zip(res.contacts.pairs, normal, strict=True):
        if fn <= 0.0:
            continue
        key = frozenset({p1.replace("/", "__"), p2.replace("/", "__")})
        print(f"| {p1} - {p2} | {fn:.2f} | {mj.get(key, float('nan')):.2f} |")
    real = recorder.contact_sampler
    runs = (
        ("collapse, 3 s", _collapse),
        ("wrist-free start 16, 1.5 s", _windowed),
        ("the report's law's collapse, 3 s", _report),
    )
    for label, run in runs:
        times: dict[str, list[float]] = {"recorded": [], "not recorded": []}
        run(robot)  # (warm)
        for _ in range(args.repeats):
            for name in times:
                recorder.contact_sampler = real if name == "recorded" else _none  # type: ignore[assignment]
                t0 = time.perf_counter()
                run(robot)
                times[name].append(time.perf_counter() - t0)
        recorder.contact_sampler = real  # type: ignore[assignment]
        print()
        print(f"| {label} ({args.repeats} interleaved runs) | median wall time [s] | ratio |")
        print("|---|---|---|")
        base = statistics.median(times["not recorded"])
        for name, ts in times.items():
            med = statistics.median(ts)
            print(f"| contact forces {name} | {med:.4f} | {med / base:.2f} |")


if __name__ == "__main__":
    main()
