"""The ``packbot`` command line: subcommands, each importing what it needs when it runs.

Exit codes: 0 success, 1 failure of the task itself (a simulation that could not continue: the
message says what and when), 2 bad input (a message, no traceback).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from packbot.result import SimResult
    from packbot.scenario import Scenario

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
    if not (root / "urdf").is_dir():
        print(
            f"error: --root {root} has no urdf/ folder; pass the source checkout's root",
            file=sys.stderr,
        )
        return 2
    path = write_srdf(load_robot(), root, samples=args.samples, clearance=args.clearance)
    print(f"wrote {path}")
    return 0


class _Progress:
    """A progress bar in simulated time on stderr (only drawn on a terminal)."""

    def __init__(self, duration: float, label: str) -> None:
        self.duration = duration
        self.label = label
        self.last = -1.0

    def __call__(self, t: float) -> None:
        import time

        now = time.monotonic()
        if now - self.last < 0.1 and t < self.duration:
            return
        self.last = now
        frac = min(max(t / self.duration, 0.0), 1.0)
        n = int(30 * frac)
        sys.stderr.write(
            f"\r{self.label} [{'#' * n}{'.' * (30 - n)}] {t:7.3f} / {self.duration:g} s"
        )
        sys.stderr.flush()

    def close(self) -> None:
        sys.stderr.write("\n")
        sys.stderr.flush()


def _summary(res: SimResult, scenario: Scenario, duration: float, dist: Any) -> list[str]:
    import math

    import numpy as np

    cfg = res.config
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
    rtf = duration / d.wall_time if d.wall_time > 0 else math.inf
    lines = [
        f"{scenario.name}: {scenario.description}" if scenario.description else scenario.name,
        f"  contact_mode={cfg.contact_mode}, controller={scenario.controller}, "
        f"{len(scenario.failures)} failure(s), {duration:g} s",
        f"  rest time:        {rest}",
        f"  final angles:     {final} [rad]",
        f"  events:           {len(res.events)}"
        + (" (" + ", ".join(f"{n} {k}" for k, n in kinds.items()) + ")" if kinds else ""),
    ]
    kept = (
        f"{d.min_distance:.3e} m over the kept states ({d.min_distance_pair})"
        if math.isfinite(d.min_distance)
        else ""
    )
    if dist is not None:
        k = int(np.argmin(dist))
        sampled = f"{dist[k]:.3e} m at t = {res.t[k]:.3f} s (samples)"
        lines.append(f"  min distance:     {sampled}" + (f", {kept}" if kept else ""))
    elif kept:
        lines.append(f"  min distance:     {kept}")
    lines.append(f"  energy:           {res.energy[0]:.3f} J -> {res.energy[-1]:.3f} J")
    lines.append(f"  wall time:        {d.wall_time:.3f} s simulation ({rtf:.0f}x real time)")
    return lines


def _out_dir(out: str) -> Path | None:
    path = Path(out)
    if path.exists() and not path.is_dir():
        print(f"error: --out {path} exists and is not a directory", file=sys.stderr)
        return None
    path.mkdir(parents=True, exist_ok=True)
    return path


def _duration(value: float | None) -> bool:
    import math

    if value is None or (math.isfinite(value) and value > 0):
        return True
    print(
        f"error: invalid --duration {value}: expected a finite positive time [s]", file=sys.stderr
    )
    return False


def _run(
    scenario_name: str,
    out_arg: str | None,
    duration_arg: float | None,
    *,
    plot: bool,
    html: bool,
    view: bool,
) -> int:
    import time

    from packbot.errors import ConfigurationError, SimulationError
    from packbot.model import load_robot
    from packbot.scenario import load_scenario, run_scenario, save_run, write_outputs

    if not _duration(duration_arg):
        return 2
    wall0 = time.perf_counter()
    try:
        scenario = load_scenario(scenario_name)
    except ConfigurationError as exc:
        print(f"error: scenario {scenario_name}: {exc}", file=sys.stderr)
        return 2
    out = _out_dir(out_arg if out_arg is not None else f"out/{scenario.name}")
    if out is None:
        return 2
    robot = load_robot()
    scenario.validate(robot)
    duration = scenario.duration if duration_arg is None else float(duration_arg)
    bar = _Progress(duration, scenario.name) if sys.stderr.isatty() else None
    try:
        res = run_scenario(scenario, robot, duration=duration, progress=bar)
    except SimulationError as exc:
        if bar is not None:
            bar.close()
        print(f"error: the simulation of {scenario.name} failed: {exc}", file=sys.stderr)
        if exc.result is not None:
            partial = save_run(exc.result, scenario, out, f"{scenario.name}_partial")
            print(f"  the trajectory up to then: {partial['trajectory']}", file=sys.stderr)
        return 1
    if bar is not None:
        bar.close()
    paths: dict[str, Any] = dict(save_run(res, scenario, out))
    paths |= write_outputs(res, scenario, robot, out, plots=plot)
    dist = paths.pop("min_distance", None)
    if html or scenario.outputs.html:
        from packbot.viz import write_html

        paths["html"] = write_html(
            robot, res, out / f"{scenario.name}.html", environment=scenario.environment
        )
    print("\n".join(_summary(res, scenario, duration, dist)))
    print(f"  wrote ({time.perf_counter() - wall0:.2f} s in all):")
    for p in paths.values():
        print(f"    {p}")
    if view:
        from packbot.viz import start_viewer

        viewer = start_viewer(robot, environment=scenario.environment)
        viewer.play(res)  # once: the page replays it (Open Controls > Animations)
        print(f"viewer at {viewer.url} (Ctrl-C to quit)")
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass
        finally:
            viewer.close()
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    return _run(
        args.scenario, args.out, args.duration, plot=args.plot, html=args.html, view=args.view
    )


def _cmd_collapse(args: argparse.Namespace) -> int:
    name = "collapse" if args.mode == "joint_clamp" else "collapse_no_collisions"
    return _run(name, args.out, args.duration, plot=True, html=True, view=False)


def _cmd_list(args: argparse.Namespace) -> int:
    import numpy as np

    from packbot.params import POSES
    from packbot.resources import data_dir
    from packbot.scenario import list_scenarios, load_scenario

    print(f"scenarios ({data_dir('sims')}; run one with `packbot run NAME`):")
    for name in list_scenarios():
        try:
            desc = load_scenario(name).description
        except Exception as exc:  # list the others even if one is broken
            desc = f"(invalid: {exc})"
        print(f"  {name:<26} {desc}")
    print("")
    print("poses (`packbot show POSE`; joints not named are 0) [rad]:")
    for name, values in POSES.items():
        text = ", ".join(f"{j}={np.round(v, 3):g}" for j, v in values.items())
        print(f"  {name:<8} {text}")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    import time

    from packbot.model import load_robot
    from packbot.viz import start_viewer

    robot = load_robot()
    q = robot.pose(args.pose)
    viewer = start_viewer(robot, port=args.port)
    viewer.display(q)
    print(f"pose {args.pose!r} at {viewer.url} (Ctrl-C to quit)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    return 0


def _cmd_batch(args: argparse.Namespace) -> int:
    from packbot.batch import ProgressBar, run_batch
    from packbot.matrix import load_matrix

    matrix = load_matrix(args.matrix)
    bar = None if args.no_progress else ProgressBar()
    try:
        report = run_batch(
            matrix,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.timeout,
            progress=bar,
        )
    except KeyboardInterrupt:
        print(
            "\ninterrupted: the finished runs are kept; rerun the same command to finish",
            file=sys.stderr,
        )
        return 130
    print(f"matrix {matrix.name}: {report.describe()}")
    return 1 if report.failed else 0


def _cmd_regress(args: argparse.Namespace) -> int:
    from packbot.batch import ProgressBar
    from packbot.matrix import load_matrix
    from packbot.regress import default_golden_dir, golden_matrices, run_regression

    golden = Path(args.golden) if args.golden else default_golden_dir()
    names = [args.matrix] if args.matrix else golden_matrices(golden)
    if not names:
        print(f"error: no golden results in {golden} (create them with --update)", file=sys.stderr)
        return 2
    drift = False
    for name in names:
        matrix = load_matrix(name)
        out = None
        if args.out:
            out = Path(args.out) / matrix.name if len(names) > 1 else Path(args.out)
        try:
            result = run_regression(
                matrix,
                golden,
                out_dir=out,
                update=args.update,
                workers=args.workers,
                scheduler=args.scheduler,
                progress=None if args.no_progress else ProgressBar(),
            )
        except KeyboardInterrupt:
            print("\ninterrupted", file=sys.stderr)
            return 130
        print(result.text())
        drift = drift or (bool(result.drifts) and not args.update)
    return 1 if drift else 0


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
        "run",
        help="run a scenario (a name in sims/ or a TOML file): trajectory, event log, plots",
    )
    p.add_argument(
        "scenario", metavar="SCENARIO", help="scenario name (see `packbot list`) or path"
    )
    p.add_argument("--out", default=None, help="output directory (./out/<scenario name>)")
    p.add_argument("--plot", action="store_true", help="write the scenario's plots (PNG, SVG)")
    p.add_argument("--html", action="store_true", help="write the browser animation")
    p.add_argument("--view", action="store_true", help="play the result in a live viewer")
    p.add_argument("--duration", type=float, default=None, help="simulated time [s] instead")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("list", help="list the shipped scenarios and the named poses")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("show", help="show a named pose in a live viewer (meshcat)")
    p.add_argument("pose", nargs="?", default="drive", help="pose name (drive)")
    p.add_argument("--port", type=int, default=None, help="viewer port (any free one)")
    p.set_defaults(func=_cmd_show)

    p = sub.add_parser(
        "collapse",
        help="the report's collapse with its plots (the same as `packbot run collapse --plot`)",
    )
    p.add_argument("--out", default="out/collapse", help="output directory (./out/collapse)")
    p.add_argument(
        "--mode",
        choices=("joint_clamp", "none"),
        default="joint_clamp",
        help="contact mode: the report's law, or no collisions (joint_clamp)",
    )
    p.add_argument("--duration", type=float, default=None, help="simulated time [s] (5)")
    p.set_defaults(func=_cmd_collapse)
    p = sub.add_parser(
        "batch",
        help="run a scenario matrix (sims/matrices/) in parallel; rerun to resume",
    )
    p.add_argument("matrix", metavar="MATRIX", help="matrix name (sims/matrices/) or TOML file")
    p.add_argument("--out", required=True, help="output directory (resumed if it exists)")
    p.add_argument("--workers", type=int, default=None, help="processes (CPUs; 0: this one)")
    p.add_argument("--scheduler", default=None, help="Dask scheduler tcp://host:port, or 'local'")
    p.add_argument("--timeout", type=float, default=None, help="wall-time limit per run [s]")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_batch)

    p = sub.add_parser(
        "regress",
        help="run matrices and compare with golden results; exit 1 on drift",
    )
    p.add_argument(
        "matrix",
        metavar="MATRIX",
        nargs="?",
        default=None,
        help="matrix name or file (default: every matrix with golden results)",
    )
    p.add_argument("--golden", default=None, help="golden results folder (sims/golden)")
    p.add_argument("--out", default=None, help="keep the batch output here (default: temporary)")
    p.add_argument("--update", action="store_true", help="rewrite the golden files (on purpose)")
    p.add_argument("--workers", type=int, default=None, help="processes (CPUs; 0: this one)")
    p.add_argument("--scheduler", default=None, help="Dask scheduler tcp://host:port, or 'local'")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_regress)
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
