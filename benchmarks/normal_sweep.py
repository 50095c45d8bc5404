"""Robustness of ``contact_mode="normal"``: the collapse over friction, restitution and tolerance.

For each setting this runs the collapse from "drive" (zero torque, wrist locked) in the normal
mode and prints whether it completes, its rest time, shoulder and elbow1 at the end [rad], the
number of events, the deepest penetration [m] and the wall time [s]; beside it, elbow1 of the
two MuJoCo references without sliding lift at the same mu (RK4 0.5 ms; Euler 0.1 ms with a
1 ms contact time constant; docs/contact.md, "MuJoCo as a reference").

Run: python benchmarks/normal_sweep.py [--duration S] [--quick]
(about 5 minutes for the full sweep on this 2-core machine, ``--timeout`` wall seconds at most
per run; ``--quick``: mu 0.3, 0.5 only.)
"""

from __future__ import annotations

import argparse
import logging
import os
import time
import warnings
from typing import Any

import numpy as np

import packbot
from packbot.mujoco_model import WRIST_JOINTS, build_mujoco_model, run_collapse

#: (label, SimConfig overrides) of the sweep; the base is mu = 0.5, e = 0, rtol = 1e-6.
SWEEP: tuple[tuple[str, dict[str, Any]], ...] = (
    ("mu 0.1", {"mu": 0.1}),
    ("mu 0.2", {"mu": 0.2}),
    ("mu 0.3", {"mu": 0.3}),
    ("mu 0.4", {"mu": 0.4}),
    ("mu 0.45", {"mu": 0.45}),
    ("mu 0.5", {}),
    ("mu 0.55", {"mu": 0.55}),
    ("mu 0.7", {"mu": 0.7}),
    ("mu 1.0", {"mu": 1.0}),
    ("e 0.1", {"restitution": 0.1}),
    ("e 0.3", {"restitution": 0.3}),
    ("e 0.5", {"restitution": 0.5}),
    ("rtol 1e-5", {"rtol": 1e-5}),
    ("rtol 1e-7", {"rtol": 1e-7}),
)
QUICK = ("mu 0.3", "mu 0.5")


class _Timeout(Exception):
    def __init__(self, t: float) -> None:
        super().__init__(t)
        self.t = t


def main(argv: list[str] | None = None) -> None:
    """Print the table (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument("--quick", action="store_true", help="only " + ", ".join(QUICK))
    ap.add_argument("--timeout", type=float, default=120.0, help="wall limit per run [s]")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore", message="contact_mode='normal' is experimental")
    logging.getLogger("packbot").setLevel(logging.ERROR)
    robot = packbot.load_robot()
    q0 = robot.pose("drive")
    i_s, i_e1 = (robot.joint_names.index(n) for n in ("shoulder", "elbow1"))
    head = (
        f"{'setting':<11}{'rest[s]':>8}{'shoulder':>9}{'elbow1':>8}{'events':>7}{'pen[m]':>9}"
        f"{'wall[s]':>8}{'MJ rk4':>8}{'MJ tau1':>8}"
    )
    print(f"normal-mode collapse, {args.duration:g} s (load {os.getloadavg()[0]:.2f})")
    print(head)
    print("-" * len(head))
    refs: dict[float, tuple[float, float]] = {}
    for label, over in SWEEP:
        if args.quick and label not in QUICK:
            continue
        kw: dict[str, Any] = {"mu": 0.5, **over}
        mu = float(kw["mu"])
        if mu not in refs:
            e1 = []
            for mj in (
                {"timestep": 5e-4, "integrator": "rk4"},
                {"timestep": 1e-4, "solref": (1e-3, 1.0)},
            ):
                arm = build_mujoco_model(robot, mu=mu, **mj)
                e1.append(float(run_collapse(arm, q0, args.duration).q_rest[i_e1]))
            refs[mu] = (e1[0], e1[1])
        cfg = packbot.SimConfig(
            contact_mode="normal", locked_joints=WRIST_JOINTS, max_events=20000, **kw
        )
        t0 = time.perf_counter()

        def guard(t: float, t0: float = t0) -> None:
            if time.perf_counter() - t0 > args.timeout:
                raise _Timeout(t)

        try:
            res = packbot.simulate(
                robot, q0, np.zeros(robot.nq), args.duration, config=cfg, progress=guard
            )
        except packbot.SimulationError as exc:
            print(f"{label:<11}failed at t = {exc.t:.4f} s: {str(exc)[:60]}")
            continue
        except _Timeout as exc:
            print(f"{label:<11}stopped after {args.timeout:g} s of wall time at t = {exc.t:.4f} s")
            continue
        wall = time.perf_counter() - t0
        rest = "-" if res.rest_time is None else f"{res.rest_time:.3f}"
        pen = max(0.0, -res.diagnostics.min_distance)
        q = res.q[-1]
        print(
            f"{label:<11}{rest:>8}{q[i_s]:9.4f}{q[i_e1]:8.4f}{len(res.events):7d}{pen:9.1e}"
            f"{wall:8.1f}{refs[mu][0]:8.4f}{refs[mu][1]:8.4f}"
        )
    print(
        "\nrest '-': still moving at the end. MJ rk4 / MJ tau1: elbow1 of MuJoCo RK4 0.5 ms and "
        "Euler 0.1 ms with a 1 ms time constant, same mu (e = 0)."
    )


if __name__ == "__main__":
    main()
