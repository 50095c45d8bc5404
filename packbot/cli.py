"""The ``packbot`` command line: subcommands, each importing what it needs when it runs.

Exit codes: 0 success, 1 failure of the task itself, 2 bad input (a message, no traceback).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main"]

log = logging.getLogger("packbot")


def _cmd_info(args: argparse.Namespace) -> int:
    import numpy as np
    import pinocchio as pin

    from packbot.model import load_robot

    robot = load_robot(args.urdf)
    m, p = robot.model, robot.params
    out = [f"PackBot EOD model: {robot.urdf_path}", f"nq = {m.nq}, nv = {m.nv}", ""]
    out.append(
        f"{'joint':<13}{'lower':>8}{'upper':>8}{'vel':>7}{'effort':>8}{'ratio':>7}"
        f"{'armature':>10}{'viscous':>9}{'coulomb':>9}   [rad, rad/s, N*m, kg*m^2, N*m*s/rad]"
    )
    for i, name in enumerate(p.names):
        out.append(
            f"{name:<13}{p.lower[i]:8.3f}{p.upper[i]:8.3f}{p.velocity[i]:7.2f}{p.effort[i]:8.1f}"
            f"{p.gear_ratio[i]:7.0f}{p.armature[i]:10.5f}{p.viscous[i]:9.3f}{p.coulomb[i]:9.3f}"
        )
    out.append("")
    out.append(f"{'body':<18}{'mass [kg]':>10}   centre of mass in body frame [m]")
    total = 0.0
    for i, inertia in enumerate(m.inertias):
        body = "base_link (fixed)" if i == 0 else m.names[i] + " ->"
        total += inertia.mass
        c = " ".join(f"{v:7.3f}" for v in inertia.lever)
        out.append(f"{body:<18}{inertia.mass:10.3f}   {c}")
    out.append(f"{'total':<18}{total:10.3f}")
    out.append(f"collision pieces: {robot.collision_model.ngeoms} convex")
    out.append("")
    data = m.createData()
    tool = m.getFrameId("gripper_tool")
    out.append(f"{'pose':<8} q [rad] in joint order; gripper tool position in base_link [m]")
    for name, q in robot.poses.items():
        pin.framesForwardKinematics(m, data, q)
        xyz = " ".join(f"{v:6.3f}" for v in data.oMf[tool].translation)
        out.append(f"{name:<8} {np.array2string(q, precision=3, suppress_small=True)}  tool: {xyz}")
    print("\n".join(out))
    return 0


def _cmd_generate_model(args: argparse.Namespace) -> int:
    from packbot.resources import repo_root
    from packbot.urdfgen import generate

    root = Path(args.root) if args.root else repo_root()
    if root is None:
        print("error: not in a source checkout; pass --root DIR", file=sys.stderr)
        return 2
    paths = generate(root, check=args.check)
    if args.check:
        if paths:
            print("out of date (run `packbot generate-model`):")
            print("\n".join(f"  {p}" for p in paths))
            return 1
        print("generated model files are up to date")
        return 0
    print(f"wrote {len(paths)} files under {root}")
    return 0


def _cmd_generate_srdf(args: argparse.Namespace) -> int:
    from packbot.model import load_robot
    from packbot.resources import repo_root
    from packbot.srdfgen import write_srdf

    root = Path(args.root) if args.root else repo_root()
    if root is None:
        print("error: not in a source checkout; pass --root DIR", file=sys.stderr)
        return 2
    path = write_srdf(load_robot(), root, samples=args.samples, clearance=args.clearance)
    print(f"wrote {path}")
    return 0


def _cmd_collapse(args: argparse.Namespace) -> int:
    import csv
    import math
    import time

    import numpy as np

    from packbot.collision import CollisionWorld
    from packbot.config import SimConfig
    from packbot.errors import SimulationError
    from packbot.integrator import simulate
    from packbot.model import load_robot
    from packbot.plots import plot_distance, plot_energy, plot_joints, sample_distances

    duration = float(args.duration)
    if not (math.isfinite(duration) and duration > 0):
        print(
            f"error: invalid --duration {args.duration}: expected a finite positive time [s]",
            file=sys.stderr,
        )
        return 2
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        print(f"error: --out {out} exists and is not a directory", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    wall0 = time.perf_counter()
    robot = load_robot()
    # The joints the report's model had as solid parts (unlocked, with zero torque and no
    # friction yet, they would swing forever).
    locked = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cfg = SimConfig(contact_mode=args.mode, locked_joints=locked)
    try:
        res = simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)
    except SimulationError as exc:
        print(f"error: the simulation failed: {exc}", file=sys.stderr)
        return 1
    world = CollisionWorld(robot)
    dist = sample_distances(res, world)
    plot_joints(res, path=out / "collapse_joints")
    plot_distance(res, world, path=out / "collapse_distance", distances=dist)
    plot_energy(res, path=out / "collapse_energy")
    np.savez(
        out / "collapse.npz",
        t=res.t,
        q=res.q,
        v=res.v,
        tau=res.tau,
        energy=res.energy,
        joint_names=np.array(res.joint_names),
    )
    with (out / "collapse_events.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "time_s",
                "kind",
                "link1",
                "link2",
                "piece1",
                "piece2",
                "distance_m_or_rad",
                "relevant_joints",
                "energy_before_J",
                "energy_after_J",
                "energy_change_J",
            ]
        )
        for e in res.events:
            w.writerow(
                [
                    f"{e.t:.10f}",
                    e.kind,
                    e.link1,
                    e.link2,
                    e.piece1,
                    e.piece2,
                    f"{e.distance:.6g}",
                    " ".join(e.relevant_joints),
                    f"{e.energy_before:.6f}",
                    f"{e.energy_after:.6f}",
                    f"{e.energy_change:.6f}",
                ]
            )
    d = res.diagnostics
    final = "  ".join(
        f"{n}={res.q[-1, res.joint(n)]:+.4f}" for n in ("turret", "shoulder", "elbow1", "elbow2")
    )
    kinds: dict[str, int] = {}
    for e in res.events:
        kinds[e.kind] = kinds.get(e.kind, 0) + 1
    rest = (
        f"not at rest (some joint speed >= {cfg.rest_speed:g} rad/s at the end)"
        if res.rest_time is None
        else f"{res.rest_time:.4f} s (all joint speeds < {cfg.rest_speed:g} rad/s after it)"
    )
    k = int(np.argmin(dist))
    rtf = duration / d.wall_time if d.wall_time > 0 else math.inf
    print(f"collapse from the drive pose, zero torque, contact_mode={args.mode}, {duration:g} s")
    print(f"  rest time:        {rest}")
    print(f"  final angles:     {final} [rad]")
    print(
        f"  events:           {len(res.events)}"
        + (" (" + ", ".join(f"{n} {k_}" for k_, n in kinds.items()) + ")" if kinds else "")
    )
    kept = f", {d.min_distance:.3e} m over the kept states" if math.isfinite(d.min_distance) else ""
    print(f"  min distance:     {dist[k]:.3e} m at t = {res.t[k]:.3f} s (samples){kept}")
    print(f"  energy:           {res.energy[0]:.3f} J -> {res.energy[-1]:.3f} J")
    print(
        f"  wall time:        {d.wall_time:.3f} s simulation ({rtf:.0f}x real time), "
        f"{time.perf_counter() - wall0:.2f} s in all"
    )
    print(
        f"  wrote:            {out}/collapse_{{joints,distance,energy}}.{{png,svg}}, "
        "collapse.npz, collapse_events.csv"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="packbot",
        description="Simulate the iRobot PackBot EOD manipulator: kinematics, dynamics, "
        "collisions and joint failures.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("info", help="print the model's joints, limits, masses and named poses")
    p.add_argument("--urdf", default=None, help="a URDF to load instead of the shipped one")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser(
        "generate-model",
        help="regenerate urdf/ and docs/parameters.md from packbot/params.py",
    )
    p.add_argument("--check", action="store_true", help="only report files that are out of date")
    p.add_argument("--root", default=None, help="repository root (default: this checkout)")
    p.set_defaults(func=_cmd_generate_model)

    p = sub.add_parser(
        "generate-srdf",
        help="sample the joint space and write urdf/packbot_eod.srdf (link pairs not to test)",
    )
    p.add_argument("--samples", type=int, default=20000, help="random configurations (20000)")
    p.add_argument("--clearance", type=float, default=0.05, help="'never' below this [m] (0.05)")
    p.add_argument("--root", default=None, help="repository root (default: this checkout)")
    p.set_defaults(func=_cmd_generate_srdf)

    p = sub.add_parser(
        "collapse",
        help="the report's collapse: zero torque from the drive pose; plots, data, event log",
    )
    p.add_argument("--out", default="out/collapse", help="output directory (./out/collapse)")
    p.add_argument(
        "--mode",
        choices=("joint_clamp", "none"),
        default="joint_clamp",
        help="contact mode: the report's law, or no collisions (joint_clamp)",
    )
    p.add_argument("--duration", type=float, default=5.0, help="simulated time [s] (5)")
    p.set_defaults(func=_cmd_collapse)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from packbot.errors import PackbotError

    try:
        return int(args.func(args))
    except PackbotError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
