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
