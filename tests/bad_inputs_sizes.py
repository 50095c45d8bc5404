"""Bad-input catalogue, category ``sizes``: every size a user can ask for, just past its bound.

The bounds are those of ``packbot/validation.py`` (docs/simulator.md, "Limits"): sampled
configurations, scan angles, volume points, IK iterations, obstacles, convex vertices,
occlusion targets, trajectory waypoints, matrix runs, study-matrix cells, workers, TOML nesting
and file size, name lengths. Each is asked for one past the bound (and some far past it), through
the API, scenario and matrix files and the command line; each must be refused at once with a
message naming the field and the bound. Huge values in other fields must give a short message
(the value shortened: ``list of 1,000,000 items: ...``). The cases that could run long if the
bound were lost are guarded (a subprocess with a timeout).
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np

import packbot
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.validation import (
    MAX_CONFIG_SAMPLES,
    MAX_CONVEX_POINTS,
    MAX_IK_ITERATIONS,
    MAX_MATRIX_RUNS,
    MAX_NAME_LENGTH,
    MAX_OBSTACLES,
    MAX_OCCLUSION_TARGETS,
    MAX_SCAN_SAMPLES,
    MAX_STUDY_CELLS,
    MAX_TOML_BYTES,
    MAX_TOML_DEPTH,
    MAX_VOLUME_POINTS,
    MAX_WAYPOINTS,
    MAX_WORKERS,
)

NQ = 8
LONG = "x" * (MAX_NAME_LENGTH + 1)
MILLION = 1_000_000


def _boxes(n: int) -> tuple[packbot.Obstacle, ...]:
    return tuple(
        packbot.Obstacle(
            name=f"b{i}", kind="box", size=(0.1, 0.1, 0.1), xyz=(3 + 0.2 * (i % 50), i // 50, 0.05)
        )
        for i in range(n)
    )


def _sphere(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(n, 3))
    return 0.2 * pts / np.linalg.norm(pts, axis=1)[:, None]


def _deep_list(depth: int) -> Any:
    x: Any = 0.0
    for _ in range(depth):
        x = [x]
    return x


def _workspace(c: Any) -> Any:
    from packbot.analysis import workspace

    return workspace(c.robot, samples=50)


def _obstacle_toml(n: int) -> str:
    return "".join(
        f"[[environment.obstacles]]\nname = 'b{i}'\nkind = 'box'\nsize = [0.1, 0.1, 0.1]\n"
        f"xyz = [{3 + 0.2 * (i % 50):.1f}, {i // 50}, 0.05]\n"
        for i in range(n)
    )


def _convex_toml(n: int) -> str:
    pts = ", ".join(f"[{x:.4f}, {y:.4f}, {z:.4f}]" for x, y, z in _sphere(n))
    return (
        "[[environment.obstacles]]\nname = 'ball'\nkind = 'convex'\nxyz = [2.0, 0.0, 0.5]\n"
        f"points = [{pts}]\n"
    )


def _targets_toml(n: int) -> str:
    pts = ", ".join(f"[1.0, {0.001 * i:.3f}, 0.5]" for i in range(n))
    return f"[outputs.occlusion]\ntargets = [{pts}]\n"


def _nested_arrays(depth: int) -> str:
    return "x = " + "[" * depth + "]" * depth + "\n"


def _nested_tables(depth: int) -> str:
    return "x = " + "{ a = " * depth + "1" + " }" * depth + "\n"


def _dotted(depth: int) -> str:
    return ".".join(["a"] * depth) + " = 1\n"


def _axes(n_axes: int, n_values: int) -> str:
    keys = ("config.restitution", "config.mu", "config.rest_speed", "config.zeno_speed")
    lines = ["[axes]"]
    for k in range(n_axes):
        key = keys[k] if k < len(keys) else f"config.margin{k}"  # refused before
        step = 1.0 / (n_values + 1)
        lines.append(f"'{key}' = [{', '.join(f'{(i + 1) * step:.6f}' for i in range(n_values))}]")
    return "\n".join(lines) + "\n"


def _study_axes(n_times: int) -> str:
    times = ", ".join(f"{0.1 + 0.001 * i:.3f}" for i in range(n_times))
    return f"[axes]\n'failures.0.joint' = ['elbow1', 'elbow2']\n'failures.0.t' = [{times}]\n"


def register(cat: ModuleType) -> None:
    """Add the ``sizes`` cases to the catalogue (``tests/bad_input_cases.py``)."""
    from packbot import analysis as A
    from packbot import control as C
    from packbot.matrix import Matrix
    from packbot.scenario import OcclusionCheck, Outputs, Scenario, scenario_from_dict
    from packbot.study_matrix import StudyOptions

    def api(id: str, action: Callable[[Any], Any], *words: str, **kw: Any) -> None:
        kw.setdefault("error", ConfigurationError)
        cat.add("sizes", id, action, *words, **kw)

    n1 = f"{MAX_CONFIG_SAMPLES:,}"
    # sampled configurations, scan angles, volume points, IK iterations
    api(
        "workspace-samples-above",
        lambda c: A.workspace(c.robot, samples=MAX_CONFIG_SAMPLES + 1),
        "samples",
        n1,
        guard=True,
    )
    api(
        "workspace-samples-1e9",
        lambda c: A.workspace(c.robot, samples=10**9),
        "samples",
        n1,
        guard=True,
    )
    api(
        "loose_joint_equilibria-samples-above",
        lambda c: A.loose_joint_equilibria(
            c.robot, "shoulder", c.robot.pose("stand"), samples=MAX_SCAN_SAMPLES + 1
        ),
        "samples",
        f"{MAX_SCAN_SAMPLES:,}",
        guard=True,
    )
    api(
        "loose_joint_equilibria-samples-1e8",
        lambda c: A.loose_joint_equilibria(
            c.robot, "shoulder", c.robot.pose("stand"), samples=10**8
        ),
        "samples",
        guard=True,
    )
    api(
        "monte_carlo_volume-max_points-above",
        lambda c: A.monte_carlo_volume(
            lambda p: np.ones(len(p), bool), (0, 0, 0), (1, 1, 1), max_points=MAX_VOLUME_POINTS + 1
        ),
        "max_points",
        f"{MAX_VOLUME_POINTS:,}",
        guard=True,
    )
    api(
        "monte_carlo_volume-batch-above",
        lambda c: A.monte_carlo_volume(
            lambda p: np.ones(len(p), bool),
            (0, 0, 0),
            (1, 1, 1),
            batch=MAX_VOLUME_POINTS + 1,
            max_points=MAX_VOLUME_POINTS + 1,
        ),
        "batch",
        guard=True,
    )
    api(
        "reachable_volume-max_points-above",
        lambda c: A.reachable_volume(c.robot, _workspace(c), max_points=MAX_VOLUME_POINTS + 1),
        "max_points",
        guard=True,
    )
    api(
        "reach-max_iter-above",
        lambda c: A.reach(c.robot, _workspace(c), (1.0, 0.0, 1.0), max_iter=MAX_IK_ITERATIONS + 1),
        "max_iter",
        f"{MAX_IK_ITERATIONS:,}",
        guard=True,
    )
    api(
        "reachable-max_iter-above",
        lambda c: A.reachable(
            c.robot, _workspace(c), [(1.0, 0.0, 1.0)], max_iter=MAX_IK_ITERATIONS + 1
        ),
        "max_iter",
        guard=True,
    )
    api(
        "solve_position_ik-max_iter-above",
        lambda c: C.solve_position_ik(
            c.robot.model,
            "gripper_tool",
            (9.0, 0.0, 0.0),
            c.drive(),
            max_iter=MAX_IK_ITERATIONS + 1,
        ),
        "ik.max_iter",
        guard=True,
    )
    api(
        "study-workspace_samples-above",
        lambda c: packbot.study(
            "loose_shoulder", robot=c.robot, workspace_samples=MAX_CONFIG_SAMPLES + 1
        ),
        "workspace_samples",
        n1,
        guard=True,
    )
    api(
        "StudyOptions-workspace_samples-above",
        lambda c: StudyOptions(workspace_samples=MAX_CONFIG_SAMPLES + 1),
        "study.workspace_samples",
    )
    # obstacles, convex vertices, occlusion targets, waypoints
    n_obs = f"{MAX_OBSTACLES:,}"
    api(
        "Environment-obstacles-above",
        lambda c: packbot.Environment(obstacles=(packbot.FLOOR, *_boxes(MAX_OBSTACLES))),
        "environment.obstacles",
        n_obs,
    )
    api(
        "Environment-obstacles-5000",
        lambda c: packbot.Environment(obstacles=_boxes(5000)),
        "environment.obstacles",
        n_obs,
        guard=True,
    )
    api(
        "Environment.with_obstacles-above",
        lambda c: packbot.Environment().with_obstacles(*_boxes(MAX_OBSTACLES)),
        "environment.obstacles",
    )
    api(
        "Environment-obstacles-list-above",
        lambda c: packbot.Environment(obstacles=[packbot.FLOOR] * (MAX_OBSTACLES + 1)),
        "environment.obstacles",
        n_obs,
    )
    api(
        "Obstacle-convex-points-above",
        lambda c: packbot.Obstacle(
            name="ball", kind="convex", points=_sphere(MAX_CONVEX_POINTS + 1)
        ),
        "points",
        f"{MAX_CONVEX_POINTS:,}",
        guard=True,
    )
    api(
        "Obstacle-convex-points-1e6",
        lambda c: packbot.Obstacle(name="ball", kind="convex", points=_sphere(MILLION)),
        "points",
        guard=True,
    )
    api(
        "Obstacle-convex-points-list-above",
        lambda c: packbot.Obstacle(
            name="ball", kind="convex", points=[(0.0, 0.0, 0.0)] * (MAX_CONVEX_POINTS + 1)
        ),
        "points",
        "list of 10,001 items",
    )
    api(
        "OcclusionCheck-targets-above",
        lambda c: Scenario(
            name="x",
            duration=0.05,
            outputs=Outputs(
                occlusion=OcclusionCheck(targets=((1.0, 0.0, 0.5),) * (MAX_OCCLUSION_TARGETS + 1))
            ),
        ).validate(),
        "outputs.occlusion.targets",
        f"{MAX_OCCLUSION_TARGETS:,}",
    )
    big = np.broadcast_to(np.zeros(NQ), (MAX_WAYPOINTS + 1, NQ))
    api(
        "JointTrajectory-waypoints-above",
        lambda c: C.JointTrajectory(big, np.arange(MAX_WAYPOINTS + 1.0)),
        "trajectory.waypoints",
        f"{MAX_WAYPOINTS:,}",
        guard=True,
    )
    api(
        "ComputedTorque-trajectory-waypoints-above",
        lambda c: C.ComputedTorque(
            trajectory=C.JointTrajectory(list(big[:2]) * ((MAX_WAYPOINTS + 2) // 2), [0.0, 1.0])
        ),
        "trajectory.waypoints",
        guard=True,
    )

    # workers, matrix runs, study-matrix cells (API)
    def batch(**kw: Any) -> Callable[[Any], Any]:
        def action(c: Any) -> Any:
            from packbot.batch import run_batch
            from packbot.matrix import load_matrix

            m = load_matrix("collapse-small")
            return run_batch(m, c.out(), **kw)

        return action

    api("run_batch-workers-above", batch(workers=MAX_WORKERS + 1), "workers", f"{MAX_WORKERS}")
    api("run_batch-workers-1e6", batch(workers=MILLION), "workers", f"{MAX_WORKERS}")

    def study_batch(c: Any) -> Any:
        from packbot.study_matrix import run_study_matrix

        return run_study_matrix("study-frozen-elbows", c.out(), workers=MAX_WORKERS + 1)

    api("run_study_matrix-workers-above", study_batch, "workers", guard=True)
    api(
        "regress-workers-above",
        lambda c: __import__("packbot.regress", fromlist=["x"]).run_regression(
            __import__("packbot.matrix", fromlist=["x"]).load_matrix("collapse-small"),
            c.out("golden"),
            workers=MAX_WORKERS + 1,
            update=True,
        ),
        "workers",
        guard=True,
    )
    axes_101 = {"config.restitution": [i / 200 for i in range(101)], "config.mu": [0.1] * 101}
    api(
        "Matrix-runs-above",
        lambda c: Matrix(name="m", base="collapse", axes=axes_101).validate(),
        "axes",
        f"{MAX_MATRIX_RUNS:,} runs",
    )
    api(
        "Matrix-runs-1e12",
        lambda c: Matrix(
            name="m", base="collapse", axes={f"config.x{k}": list(range(100)) for k in range(6)}
        ).validate(),
        "axes",
        "1,000,000,000,000",
        guard=True,
    )
    api(
        "Matrix-includes-above",
        lambda c: Matrix(
            name="m", base="collapse", include=[{"config.mu": 0.1}] * (MAX_MATRIX_RUNS + 1)
        ).validate(),
        "axes",
        f"{MAX_MATRIX_RUNS:,}",
    )
    # names
    api(
        "Obstacle-name-long",
        lambda c: packbot.Obstacle(name=LONG, kind="box", size=(1, 1, 1)),
        "obstacle.name",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "Failure-joint-long",
        lambda c: packbot.Failure(joint=LONG, kind="loose"),
        "failure.joint",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "Payload-frame-long",
        lambda c: packbot.Payload(mass=1.0, frame=LONG),
        "payload.frame",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "CartesianPD-frame-long",
        lambda c: C.CartesianPD(target=(1.0, 0.0, 1.0), frame=LONG),
        "controller.frame",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "Reconfig-frame-long",
        lambda c: C.ReconfigurableController(target=(0.7, 0.4, 0.2), frame=LONG),
        "controller.frame",
    )
    api(
        "Matrix-name-long",
        lambda c: Matrix(name=LONG, base="collapse", axes={"config.mu": [0.1]}).validate(),
        "name",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "scenario_from_dict-name-long",
        lambda c: scenario_from_dict({"duration": 1.0}, name=LONG),
        "name",
        f"{MAX_NAME_LENGTH}",
    )
    api(
        "Obstacle-name-1e6",
        lambda c: packbot.Obstacle(name="x" * MILLION, kind="box", size=(1, 1, 1)),
        "obstacle.name",
        "1,000,000 characters",
    )
    # huge values elsewhere: a short message (the value shortened)
    api(
        "SimConfig-gravity-1e6",
        lambda c: packbot.SimConfig(gravity=[0.0] * MILLION),
        "gravity",
        "list of 1,000,000 items",
    )
    api(
        "SimConfig-contact_mode-1e6-chars",
        lambda c: packbot.SimConfig(contact_mode="n" * MILLION),
        "contact_mode",
        "1,000,000 characters",
    )
    api(
        "SimConfig-locked_joints-1e6",
        lambda c: packbot.SimConfig(locked_joints=("camera_tilt",) * MILLION),
        "locked_joints",
        "tuple of 1,000,000 items",
    )
    api(
        "simulate-q0-1e6",
        cat.sim(q0=np.zeros(MILLION)),
        "q0",
        "(1000000,)",
    )
    api("simulate-v0-1e6-list", cat.sim(v0=[0.0] * MILLION), "v0")
    api(
        "Failure-kind-1e6-chars",
        lambda c: packbot.Failure(joint="shoulder", kind="k" * MILLION),
        "failure.kind",
        "1,000,000 characters",
    )
    api(
        "JointPD-kp-1e6",
        cat.prepared(lambda: C.JointPD(kp=[1.0] * MILLION)),
        "controller.kp",
    )
    api(
        "Robot.pose-1e6-chars",
        lambda c: c.robot.pose("p" * MILLION),
        "pose",
        "1,000,000 characters",
        error=UnknownNameError,
    )
    api(
        "Robot.q_from-1e6-joints",
        lambda c: c.robot.q_from({f"j{i}": 0.0 for i in range(MILLION)}),
        "j0",
        error=UnknownNameError,
    )
    api(
        "Obstacle-xyz-1e6",
        lambda c: packbot.Obstacle(name="b", kind="box", size=(1, 1, 1), xyz=[0.0] * MILLION),
        "xyz",
        "list of 1,000,000 items",
    )
    api(
        "Payload-inertia-1e6",
        lambda c: packbot.Payload(mass=1.0, inertia=np.ones(MILLION)),
        "payload.inertia",
    )
    # nesting through the API (no RecursionError)
    api("SimConfig-gravity-deep", lambda c: packbot.SimConfig(gravity=_deep_list(5000)), "gravity")
    api("simulate-q0-deep", cat.sim(q0=_deep_list(5000)), "q0")
    api(
        "Obstacle-points-deep",
        lambda c: packbot.Obstacle(name="c", kind="convex", points=_deep_list(5000)),
        "points",
    )
    api(
        "JointTrajectory-deep",
        lambda c: C.JointTrajectory(_deep_list(5000), [0.0, 1.0]),
        "trajectory.waypoints",
    )

    # scenario files (loaded and run) and the same through `packbot run`
    def scn(id: str, text: str, *words: str, base: bool = True, guard: bool = False) -> None:
        cat.add(
            "sizes",
            f"scenario-{id}",
            cat.scn(text, base=base),
            *words,
            error=ConfigurationError,
            guard=guard,
        )

    def run(id: str, text: str, *words: str, base: bool = True, guard: bool = False) -> None:
        def argv(c: Any) -> list[str]:
            body = (cat.BASE_SCENARIO + "\n" + text) if base else text
            return ["run", str(c.write("bad.toml", body)), "--out", c.out()]

        cat.add("sizes", f"run-{id}", argv, *words, cli=True, guard=guard)

    deep = f"{MAX_TOML_DEPTH} levels"
    size = f"{MAX_TOML_BYTES:,} bytes"
    for fn in (scn, run):
        fn(
            "obstacles-above",
            _obstacle_toml(MAX_OBSTACLES + 1),
            "environment.obstacles",
            n_obs,
            guard=True,
        )
        fn("convex-points-above", _convex_toml(MAX_CONVEX_POINTS + 1), "points", guard=True)
        fn(
            "occlusion-targets-above",
            _targets_toml(MAX_OCCLUSION_TARGETS + 1),
            "outputs.occlusion.targets",
        )
        fn("nested-arrays-5000", _nested_arrays(5000), deep)
        fn("nested-arrays-above", _nested_arrays(MAX_TOML_DEPTH), deep)
        fn("nested-inline-tables-5000", _nested_tables(5000), deep)
        fn("nested-inline-tables-above", _nested_tables(MAX_TOML_DEPTH), deep)
        fn("dotted-key-deep", _dotted(MAX_TOML_DEPTH + 1), deep)
        fn("file-above-size", "#" * (MAX_TOML_BYTES + 1) + "\n", size)
        fn(
            "initial-q-1e6",
            "duration = 1.0\n[initial]\nq = [" + "0.0, " * MILLION + "]\n",
            size,
            base=False,
        )
        fn(
            "initial-q-100000",
            "duration = 1.0\n[initial]\nq = [" + "0.0, " * 100_000 + "]\n",
            "initial.q",
            "100,000 items",
            base=False,
        )
        fn(
            "obstacle-name-long",
            f"[[environment.obstacles]]\nname = '{LONG}'\nkind = 'box'\nsize = [1, 1, 1]\n"
            "xyz = [3, 0, 0.5]\n",
            "environment.obstacles[0].name",
        )
        fn(
            "failure-joint-long",
            f"[[failures]]\njoint = '{LONG}'\nkind = 'loose'\n",
            "failures[0].joint",
        )
        fn(
            "config-key-1e6-chars",
            f"[config]\n{'k' * 100_000} = 1\n",
            "config.",
            "characters)",
        )
        fn(
            "controller-kp-1e6",
            "[controller]\nkind = 'pd'\nkp = [" + "1.0, " * 100_000 + "]\n",
            "controller.kp",
        )
        fn(
            "config-gravity-long",
            "[config]\ngravity = [" + "0.0, " * 100_000 + "]\n",
            "config.gravity",
            "100,000 items",
        )

    # matrix files, through load_matrix and `packbot batch`
    def mtx(
        id: str, text: str, *words: str, error: type = ConfigurationError, guard: bool = False
    ) -> None:
        cat.add("sizes", f"matrix-{id}", cat.mtx(text), *words, error=error, guard=guard)

        def argv(c: Any) -> list[str]:
            path = c.write("m.toml", cat.BASE_MATRIX + text)
            return ["batch", str(path), "--out", c.out(), "--workers", "0", "--no-progress"]

        cat.add("sizes", f"batch-{id}", argv, *words, cli=True, guard=guard)

    mtx("runs-two-axes-above", _axes(2, 101), "axes", f"{MAX_MATRIX_RUNS:,} runs")
    mtx("runs-one-axis-above", _axes(1, MAX_MATRIX_RUNS + 1), "axes", guard=True)
    mtx("runs-4-axes-of-100", _axes(4, 100), "axes", "100,000,000", guard=True)
    mtx(
        "includes-above",
        "[axes]\n'config.restitution' = [0.0]\n"
        + "[[include]]\n'config.mu' = 0.1\n" * MAX_MATRIX_RUNS,
        "axes",
        guard=True,
    )
    mtx("nested-5000", _nested_arrays(5000).replace("x =", "[axes]\n'config.restitution' ="), deep)
    mtx(
        "nested-tables-5000",
        "[axes]\n'config.restitution' = [" + _nested_tables(5000)[4:-1] + "]\n",
        deep,
    )
    mtx(
        "file-above-size",
        "#" * (MAX_TOML_BYTES + 1) + "\n[axes]\n'config.restitution' = [0.0]\n",
        size,
    )
    mtx(
        "dotted-deep",
        "[axes]\n" + "'" + ".".join(["a"] * (MAX_TOML_DEPTH + 1)) + "' = [1]\n",
        "a.a.a",
    )
    mtx(
        "set-deep",
        _dotted(MAX_TOML_DEPTH + 1) + "[axes]\n'config.restitution' = [0.0]\n",
        deep,
    )

    # a study matrix with too many cells; workers; sampled configurations on the command line
    def study_cells(c: Any) -> Any:
        from packbot.study_matrix import load_study_matrix

        text = 'base = "frozen_elbow_reach"\n' + _study_axes(MAX_STUDY_CELLS // 2 + 1) + "[study]\n"
        return load_study_matrix(c.write("sm.toml", text))

    api("study-matrix-cells-above", study_cells, "axes", f"{MAX_STUDY_CELLS:,} cells")

    def study_cells_cli(c: Any) -> list[str]:
        text = 'base = "frozen_elbow_reach"\n' + _study_axes(MAX_STUDY_CELLS // 2 + 1) + "[study]\n"
        return ["study", str(c.write("sm.toml", text)), "--out", c.out()]

    cat.add("sizes", "cli-study-matrix-cells-above", study_cells_cli, "cells", cli=True)
    for cmd in ("batch", "regress"):
        cat.add(
            "sizes",
            f"cli-{cmd}-workers-above",
            lambda c, cmd=cmd: [
                cmd,
                "collapse-small",
                "--out",
                c.out(),
                "--workers",
                str(MAX_WORKERS + 1),
            ],
            "workers",
            cli=True,
            guard=True,
        )

    def srdf(c: Any) -> list[str]:
        (c.tmp / "urdf").mkdir()
        return ["generate-srdf", "--samples", str(MAX_CONFIG_SAMPLES + 1), "--root", str(c.tmp)]

    cat.add("sizes", "cli-generate-srdf-samples-above", srdf, "samples", n1, cli=True, guard=True)
    cat.add(
        "sizes",
        "srdf-samples-above",
        lambda c: __import__("packbot.srdfgen", fromlist=["x"]).generate_srdf(
            c.robot, samples=MAX_CONFIG_SAMPLES + 1
        ),
        "samples",
        error=ConfigurationError,
        guard=True,
    )
