"""Which MuJoCo setting is a reference for Coulomb sliding: lift test and collapse rest pose.

For each MuJoCo setting (integrator, step, ``solref`` time constant, cone, ``impratio``,
``noslip_iterations``) this prints

- ``lift``: :func:`packbot.mujoco_model.sliding_lift`, the largest upward speed of a sphere
  sliding on a plane (slide joints x and z) divided by mu times its launch speed (Coulomb's law:
  0; MuJoCo's default Euler setting with a time constant of two steps: about 0.8);
- the collapse from "drive" (zero torque, wrist locked, mu = 0.5, ``--duration`` s): rest time,
  shoulder, elbow1, elbow2 at the end [rad], deepest penetration [m], wall time [s].

Compare with the normal mode's rest pose (docs/contact.md, "MuJoCo as a reference"): settings
with a small lift rest close to it, the default setting does not.

Run: python benchmarks/mujoco_reference.py [--duration S] [--ours]
(``--ours`` also runs ``contact_mode="normal"`` once, about 15 s of wall time.)
"""

from __future__ import annotations

import argparse
import os
from typing import Any

import numpy as np

import packbot
from packbot.mujoco_model import WRIST_JOINTS, build_mujoco_model, run_collapse, sliding_lift

#: (label, build_mujoco_model keywords, MjModel.opt overrides) of the settings compared.
SETTINGS: tuple[tuple[str, dict[str, Any], dict[str, Any]], ...] = (
    ("euler 0.5 ms (default)", {"timestep": 5e-4}, {}),
    ("euler 0.1 ms", {"timestep": 1e-4}, {}),
    ("euler 1 ms", {"timestep": 1e-3}, {}),
    ("euler 0.5 ms impratio 10", {"timestep": 5e-4}, {"impratio": 10.0}),
    ("euler 0.5 ms impratio 100", {"timestep": 5e-4}, {"impratio": 100.0}),
    ("euler 0.5 ms pyramidal", {"timestep": 5e-4}, {"cone": "pyramidal"}),
    ("euler 0.5 ms noslip 10", {"timestep": 5e-4}, {"noslip_iterations": 10}),
    ("implicitfast 0.5 ms", {"timestep": 5e-4, "integrator": "implicitfast"}, {}),
    ("rk4 1 ms", {"timestep": 1e-3, "integrator": "rk4"}, {}),
    ("rk4 0.5 ms", {"timestep": 5e-4, "integrator": "rk4"}, {}),
    ("rk4 0.25 ms", {"timestep": 2.5e-4, "integrator": "rk4"}, {}),
    ("euler 0.5 ms tau 2 ms", {"timestep": 5e-4, "solref": (2e-3, 1.0)}, {}),
    ("euler 0.1 ms tau 1 ms", {"timestep": 1e-4, "solref": (1e-3, 1.0)}, {}),
    ("euler 0.05 ms tau 1 ms", {"timestep": 5e-5, "solref": (1e-3, 1.0)}, {}),
)


def _apply(model: Any, opt: dict[str, Any]) -> None:
    import mujoco

    for key, value in opt.items():
        if key == "cone":
            value = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}[value]
        setattr(model.opt, key, value)


def _lift(build: dict[str, Any], opt: dict[str, Any]) -> str:
    if opt:  # sliding_lift takes only the build settings; opt overrides need a model of their own
        return "-"
    return f"{sliding_lift(**build):.2f}"


def main(argv: list[str] | None = None) -> None:
    """Print the table (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3.0, help="collapse duration [s]")
    ap.add_argument("--ours", action="store_true", help="also run the normal mode once")
    args = ap.parse_args(argv)
    robot = packbot.load_robot()
    i_s, i_e1, i_e2 = (robot.joint_names.index(n) for n in ("shoulder", "elbow1", "elbow2"))
    q0 = robot.pose("drive")
    head = (
        f"{'MuJoCo setting':<28}{'lift':>6}{'rest[s]':>9}{'shoulder':>9}{'elbow1':>8}"
        f"{'elbow2':>8}{'pen[m]':>10}{'wall[s]':>8}"
    )
    print(f"collapse, mu = 0.5, {args.duration:g} s (load {os.getloadavg()[0]:.2f})")
    print(head)
    print("-" * len(head))

    def row(label: str, lift: str, rest: float | None, q: np.ndarray, pen: float, wall: float):
        r = "-" if rest is None else f"{rest:.3f}"
        print(
            f"{label:<28}{lift:>6}{r:>9}{q[i_s]:9.4f}{q[i_e1]:8.4f}{q[i_e2]:8.4f}{pen:10.2e}"
            f"{wall:8.2f}"
        )

    if args.ours:
        cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
        import time

        t0 = time.perf_counter()
        res = packbot.simulate(robot, q0, np.zeros(robot.nq), args.duration, config=cfg)
        pen = max(0.0, -res.diagnostics.min_distance)
        row("ours: normal mode", "0", res.rest_time, res.q[-1], pen, time.perf_counter() - t0)
    for label, build, opt in SETTINGS:
        arm = build_mujoco_model(robot, mu=0.5, **build)
        _apply(arm.model, opt)
        run = run_collapse(arm, q0, args.duration)
        row(label, _lift(build, opt), run.rest_time, run.q_rest, run.max_penetration, run.wall_time)
    print(
        "\nlift: max upward speed / (mu v0) of a sphere sliding on a plane (0 for Coulomb "
        "sliding); '-': not measured for opt overrides. tau: solref time constant."
    )


if __name__ == "__main__":
    main()
