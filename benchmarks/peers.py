"""packbot next to its peers, each timed bare as its users run it: a collapse, a controlled run.

Table 1, the collapse (sims/collapse.toml and sims/collapse_physical.toml): zero torque from the
"drive" pose, zero velocity, ``--duration`` (5) s simulated, the joints camera_tilt, camera_pan,
gripper_roll and gripper_jaw locked (:data:`packbot.mujoco_model.WRIST_JOINTS`), the floor, the
same URDF, mu = 0.5, the same armature. Rows:

- ``packbot joint_clamp``: ``contact_mode="joint_clamp"`` (collapse.toml's config);
- ``packbot normal mu 0.5``: ``contact_mode="normal"``, mu = 0.5 (collapse_physical.toml's
  config, run for the same 5 s);
- ``MuJoCo Euler 1 ms``, ``MuJoCo Euler 2 ms``, ``MuJoCo RK4 1 ms``: the model of
  :func:`packbot.mujoco_model.build_mujoco_model` (stiff ``solref``: two steps), stepped bare
  with ``mujoco.mj_step(model, data, nstep=n)`` (one call: the binding steps n times in C, no
  Python between the steps); the model compile and ``MjData`` set-up are not timed;
- ``PyBullet 240 Hz`` and ``Drake discrete 1 ms``: run only if ``pybullet`` / ``pydrake`` is
  importable (neither is a packbot dependency), otherwise printed as "not installed". PyBullet:
  the same URDF with the locked joints welded, ``p.stepSimulation()`` in a loop, motors off,
  mu 0.5, SRDF pairs filtered (PyBullet has no armature; measured with
  pybullet 3.2.7 installed by hand); Drake: ``drake_reference.collapse`` (discrete point
  contact, lagged approximation, ``AdvanceTo`` every 2 ms).

Columns: wall time [s] (median over ``--repeats`` rounds, interleaved: round r runs every row
once, in order), real-time factor (simulated / wall), deepest penetration [m] (packbot:
max(0, -diagnostics.min_distance) of the timed run; MuJoCo: max(0, -contact dist) over every
step, read in a SEPARATE untimed run, :func:`packbot.mujoco_model.run_collapse`, so that the
timed run stays bare), the rest pose (shoulder, elbow1, elbow2 at the end [rad]), and for the
packbot rows the ratio of its median wall to MuJoCo Euler 1 ms's, with its speed target
(docs/performance.md: normal <= 1.0x, joint_clamp <= 0.5x); also the median of the rounds'
ratios (each round's packbot wall over its MuJoCo wall: steadier under a changing load).

Table 2, a controlled run: ``reconfig_elbow1`` (sims/reconfig_elbow1.toml: the reconfigurable
controller reaches from "stand", elbow1 freezes at 1 s, the controller detects it and
re-plans; joint_clamp, joint friction, gripper_jaw locked) for ``--control-duration`` (60) s.

- ``packbot``: the scenario's controller built and :func:`packbot.simulate` run with the
  scenario's start, environment, config and failures for that duration (what
  :func:`packbot.scenario.run_scenario` and ``packbot run`` do, without the checks of the file
  and the output files); the robot is loaded once, outside the timing.
- ``MuJoCo Euler 1 ms + same controller``: the scenario's own controller object
  (``scenario.build_controller(robot)``, built and reset inside the timing), called in Python
  at every tick (its ``dt``, 1 ms) with the full q, v (MuJoCo qpos/qvel mapped by joint name;
  the locked gripper_jaw at its "stand" angle, speed 0); its command, clipped to the effort
  limits as packbot's torque path does, is held in ``qfrc_applied`` while MuJoCo steps bare
  (``mj_step(..., nstep=dt / timestep)``) to the next tick. Joint friction as MuJoCo damping
  and frictionloss (``joint_dynamics=True``). The failure is applied: at its time elbow1 stops
  in an impact that keeps the other joints' generalized momentum (as packbot's frozen joint
  does), and its armature becomes 1e8 kg*m^2, which holds it (any torque on it gives
  less than 1e-6 rad/s^2; MuJoCo's soft joint limit at [q, q] lets it creep faster than the
  controller's observer calls frozen, 1e-3 rad/s, and the controller then sees a loose joint).
  MuJoCo's contacts (mu 0.5) stand in for packbot's joint-clamp law (the reach does not touch).

Ratio packbot / MuJoCo, targets: >= 20x real time and within 2x of MuJoCo. The time spent in
the controller's ``step`` (the same code in both) is measured in both rows and printed.

``--json PATH`` writes every row (medians, every repeat's wall, the columns above) and the
machine. ``--profile`` prints a cProfile of one packbot normal-mode collapse (top functions by
own time).

Run: python benchmarks/peers.py [--repeats N] [--duration S] [--control-duration S]
    [--control-repeats N] [--json PATH] [--profile] [--no-control]
"""

from __future__ import annotations

import argparse
import cProfile
import datetime
import io
import json
import os
import platform
import pstats
import statistics
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import packbot
from packbot.mujoco_model import (
    WRIST_JOINTS,
    MujocoArm,
    _rewrite_urdf,
    _srdf_pairs,
    build_mujoco_model,
    run_collapse,
)
from packbot.scenario import load_scenario, run_scenario

ARM = ("shoulder", "elbow1", "elbow2")
#: The reference row of the ratios.
REFERENCE = "MuJoCo Euler 1 ms"
#: packbot's targets against the reference: row label -> largest ratio.
TARGETS = {"packbot joint_clamp": 0.5, "packbot normal mu 0.5": 1.0}
CONTROL_RTF_TARGET = 20.0
CONTROL_RATIO_TARGET = 2.0
#: Armature [kg*m^2] that freezes a MuJoCo joint (its speed set to 0 at the failure).
FROZEN_ARMATURE = 1e8


@dataclass
class Row:
    """One row of a table; ``walls`` holds every repeat's wall time [s]."""

    label: str
    simulated: float
    status: str = "ok"  # "ok", "not installed", "error: ..."
    walls: list[float] = field(default_factory=list)
    controller_wall: float | None = None  # of the median wall, in the controller [s]
    penetration: float | None = None
    rest_pose: dict[str, float] | None = None
    note: str = ""

    @property
    def wall(self) -> float:
        return statistics.median(self.walls) if self.walls else float("nan")

    @property
    def rtf(self) -> float:
        return self.simulated / self.wall if self.walls else float("nan")

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["wall"] = self.wall if self.walls else None
        d["rtf"] = self.rtf if self.walls else None
        return d


# ------------------------------------------------------------------------------ the collapse
def _packbot_case(robot: packbot.Robot, row: Row, cfg: packbot.SimConfig) -> Callable[[], None]:
    q0, v0 = robot.pose("drive"), np.zeros(robot.nq)

    def once() -> None:
        t0 = time.perf_counter()
        res = packbot.simulate(robot, q0, v0, row.simulated, config=cfg)
        row.walls.append(time.perf_counter() - t0)
        row.penetration = max(0.0, -res.diagnostics.min_distance)
        row.rest_pose = {n: float(res.q[-1][res.joint(n)]) for n in ARM}

    return once


def _mujoco_case(robot: packbot.Robot, row: Row, arm: MujocoArm) -> Callable[[], None]:
    import mujoco

    q0 = robot.pose("drive")
    model = arm.model
    n = round(row.simulated / arm.timestep)
    # the penetration needs every step's contacts: a separate, untimed run
    ref = run_collapse(arm, q0, row.simulated)
    row.penetration = ref.max_penetration

    def once() -> None:
        data = mujoco.MjData(model)
        data.qpos[:] = arm.to_qpos(q0)
        mujoco.mj_forward(model, data)
        t0 = time.perf_counter()
        mujoco.mj_step(model, data, nstep=n)
        row.walls.append(time.perf_counter() - t0)
        q = arm.from_qpos(data.qpos)
        row.rest_pose = {name: float(q[robot.joint_names.index(name)]) for name in ARM}

    return once


def _pybullet_case(robot: packbot.Robot, row: Row) -> Callable[[], None]:
    """PyBullet at 240 Hz (its default step), if importable (not tested on this machine)."""
    import pybullet as p

    q0 = robot.pose("drive")
    urdf = Path(robot.urdf_path)
    locked = {j: float(q0[robot.joint_names.index(j)]) for j in WRIST_JOINTS}
    root = ET.fromstring(_rewrite_urdf(urdf.read_text(), urdf.parent / "meshes", locked, {}))
    for mesh in root.iter("mesh"):
        mesh.attrib["filename"] = str(urdf.parent / "meshes" / mesh.attrib["filename"])
    for ext in root.findall("mujoco"):
        root.remove(ext)
    tmp = Path(tempfile.mkdtemp()) / "packbot_pybullet.urdf"
    tmp.write_text(ET.tostring(root, encoding="unicode"))
    srdf = _srdf_pairs(urdf.parent / "packbot_eod.srdf")
    dt = 1.0 / 240.0
    n = round(row.simulated / dt)

    def once() -> None:
        cid = p.connect(p.DIRECT)
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        p.setTimeStep(dt, physicsClientId=cid)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        floor = p.createMultiBody(0, plane, physicsClientId=cid)
        body = p.loadURDF(
            str(tmp), useFixedBase=True, flags=p.URDF_USE_SELF_COLLISION, physicsClientId=cid
        )
        link = {p.getBodyInfo(body, physicsClientId=cid)[0].decode(): -1}
        names: dict[str, int] = {}
        for j in range(p.getNumJoints(body, physicsClientId=cid)):
            info = p.getJointInfo(body, j, physicsClientId=cid)
            names[info[1].decode()] = j
            link[info[12].decode()] = j
        for a, b in srdf:
            if a in link and b in link:
                p.setCollisionFilterPair(body, body, link[a], link[b], 0, physicsClientId=cid)
        for j in range(-1, p.getNumJoints(body, physicsClientId=cid)):
            p.changeDynamics(body, j, lateralFriction=0.5, physicsClientId=cid)
        p.changeDynamics(floor, -1, lateralFriction=0.5, physicsClientId=cid)
        free = [j for j in robot.joint_names if j in names]
        for j in free:
            p.resetJointState(
                body, names[j], float(q0[robot.joint_names.index(j)]), 0.0, physicsClientId=cid
            )
        p.setJointMotorControlArray(
            body,
            [names[j] for j in free],
            p.VELOCITY_CONTROL,
            forces=[0.0] * len(free),
            physicsClientId=cid,
        )
        t0 = time.perf_counter()
        for _ in range(n):
            p.stepSimulation(physicsClientId=cid)
        row.walls.append(time.perf_counter() - t0)
        pen = 0.0
        for c in p.getContactPoints(physicsClientId=cid):
            pen = max(pen, -float(c[8]))  # final state only (the timed loop stays bare)
        row.penetration = pen
        row.note = "penetration at the end only"
        row.rest_pose = {
            a: float(p.getJointState(body, names[a], physicsClientId=cid)[0]) for a in ARM
        }
        p.disconnect(physicsClientId=cid)

    return once


def _drake_case(row: Row) -> Callable[[], None]:
    """Drake discrete 1 ms via benchmarks/drake_reference.py, if pydrake is importable."""
    sys.path.insert(0, str(Path(__file__).parent))
    import drake_reference as dr

    folder = Path(tempfile.mkdtemp())
    dr.export(folder)
    side = json.loads((folder / dr.JSON_NAME).read_text())
    settings = dr.ContactSettings(
        approx="lagged", dt=1e-3, mu=0.5, stiffness=1e6, dissipation=20.0, stiction=1e-4
    )
    row.note = "AdvanceTo every 2 ms, contact results read there"

    def once() -> None:
        out = dr.collapse(folder, side, settings, row.simulated)
        row.walls.append(out.wall)
        row.penetration = out.penetration
        row.rest_pose = dict(zip(ARM, out.q_arm, strict=True))

    return once


def _importable(name: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(name) is not None


def collapse_table(robot: packbot.Robot, args: argparse.Namespace) -> list[Row]:
    """Run table 1 (interleaved repeats) and print it; returns the rows."""
    T = args.duration
    cases: list[tuple[Row, Callable[[], None]]] = []
    for label, kw in (
        ("packbot joint_clamp", {"contact_mode": "joint_clamp"}),
        ("packbot normal mu 0.5", {"contact_mode": "normal", "mu": 0.5}),
    ):
        row = Row(label, T)
        cfg = packbot.SimConfig(locked_joints=WRIST_JOINTS, **kw)  # type: ignore[arg-type]
        packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.2, config=cfg)  # warm
        cases.append((row, _packbot_case(robot, row, cfg)))
    for label, dt, integ in (
        ("MuJoCo Euler 1 ms", 1e-3, "euler"),
        ("MuJoCo Euler 2 ms", 2e-3, "euler"),
        ("MuJoCo RK4 1 ms", 1e-3, "rk4"),
    ):
        row = Row(label, T)
        arm = build_mujoco_model(robot, mu=0.5, timestep=dt, integrator=integ)  # type: ignore[arg-type]
        cases.append((row, _mujoco_case(robot, row, arm)))
    skipped: list[Row] = []
    for label, module, make in (
        ("PyBullet 240 Hz", "pybullet", lambda r: _pybullet_case(robot, r)),
        ("Drake discrete 1 ms", "pydrake", _drake_case),
    ):
        row = Row(label, T)
        if not _importable(module):
            row.status = "not installed"
            skipped.append(row)
            continue
        try:
            cases.append((row, make(row)))
        except Exception as exc:  # a peer we cannot set up is a row, not a crash
            row.status = f"error: {type(exc).__name__}: {exc}"
            skipped.append(row)
    for _ in range(args.repeats):
        for row, once in cases:
            try:
                once()
            except Exception as exc:
                row.status = f"error: {type(exc).__name__}: {exc}"
    rows = [r for r, _ in cases] + skipped
    _print_collapse(rows, T, args.repeats)
    return rows


def round_ratio(row: Row, ref: Row) -> float | None:
    """Median over the rounds of row's wall / ref's wall in the same round (None: no rounds)."""
    pairs = list(zip(row.walls, ref.walls, strict=False))
    return statistics.median(a / b for a, b in pairs) if pairs else None


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, spec)


def _print_collapse(rows: list[Row], T: float, repeats: int) -> None:
    ref = next(r for r in rows if r.label == REFERENCE)
    print(
        f"\nCollapse from 'drive', zero torque, {T:g} s simulated, wrist locked, mu 0.5; "
        f"wall: median of {repeats} interleaved rounds"
    )
    head = (
        f"{'system':<24}{'wall[s]':>9}{'RTF':>7}{'pen[m]':>10}{'shoulder':>9}{'elbow1':>8}"
        f"{'elbow2':>8}{'/MuJoCo 1ms':>12}{'target':>8}{'met':>5}"
    )
    print(head)
    print("-" * len(head))
    for r in rows:
        if r.status != "ok" or not r.walls:
            print(f"{r.label:<24}  {r.status}")
            continue
        pose = r.rest_pose or {}
        ratio = r.wall / ref.wall if ref.walls else float("nan")
        target = TARGETS.get(r.label)
        tgt = "-" if target is None else f"<={target:g}x"
        met = "-" if target is None else ("yes" if ratio <= target else "no")
        rat = f"{ratio:.2f}x" if r.label.startswith("packbot") else "-"
        print(
            f"{r.label:<24}{r.wall:9.3f}{r.rtf:7.1f}{_fmt(r.penetration, '10.2e'):>10}"
            f"{_fmt(pose.get('shoulder'), '.4f'):>9}{_fmt(pose.get('elbow1'), '.4f'):>8}"
            f"{_fmt(pose.get('elbow2'), '.4f'):>8}{rat:>12}{tgt:>8}{met:>5}"
            + (f"  ({r.note})" if r.note else "")
        )
    for r in rows:
        if r.label in TARGETS and r.walls:
            print(
                f"{r.label} / {REFERENCE}, median of the {len(r.walls)} rounds' ratios: "
                f"{round_ratio(r, ref):.2f}x"
            )
    print(
        "pen: deepest penetration over the run (packbot: max(0, -min signed distance); MuJoCo: "
        "max(0, -contact dist)\nover every step, from a separate untimed run); shoulder, elbow1, "
        "elbow2: the pose at the end [rad]."
    )


# ------------------------------------------------------------------------------ controlled run
def _freeze(mujoco: Any, model: Any, data: Any, dof: int) -> None:
    """Lock MuJoCo dof ``dof`` now: an impact that keeps the other dofs' momentum, then a
    huge armature (the joint's speed 0, the others' v_r += M_rr^-1 M_rj v_j)."""
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    rest = np.flatnonzero(np.arange(model.nv) != dof)
    v = data.qvel.copy()
    data.qvel[rest] = v[rest] + np.linalg.solve(M[np.ix_(rest, rest)], M[rest, dof] * v[dof])
    data.qvel[dof] = 0.0
    model.dof_armature[dof] = FROZEN_ARMATURE


def _timed_step(ctrl: Any) -> list[float]:
    """Wrap ``ctrl.step`` to add its wall time [s] to the returned one-item list."""
    spent = [0.0]
    step = ctrl.step
    clock = time.perf_counter

    def timed(t: float, q: Any, v: Any) -> Any:
        c0 = clock()
        try:
            return step(t, q, v)
        finally:
            spent[0] += clock() - c0

    ctrl.step = timed
    return spent


def _packbot_controlled(
    robot: packbot.Robot, scenario: Any, T: float
) -> tuple[float, float, packbot.SimResult]:
    """The scenario as :func:`packbot.scenario.run_scenario` runs it, for T [s].

    Returns:
        (wall [s], of which in the controller's ``step`` [s], the result).
    """
    t0 = time.perf_counter()
    q0, v0 = scenario.initial_state(robot)
    ctrl = scenario.build_controller(robot)
    spent = _timed_step(ctrl)
    res = packbot.simulate(
        robot,
        q0,
        v0,
        T,
        controller=ctrl,
        environment=scenario.environment,
        config=scenario.config,
        failures=list(scenario.failures),
        inform_controller=scenario.inform_controller,
    )
    return time.perf_counter() - t0, spent[0], res


def _mujoco_controlled(
    robot: packbot.Robot, scenario: Any, arm: MujocoArm, T: float
) -> tuple[float, float, dict[str, float], int]:
    """The scenario's controller on MuJoCo.

    Returns:
        (wall [s], of which in ``ctrl.step`` [s], final pose [rad] by joint, ticks).
    """
    import mujoco

    model, names = arm.model, robot.joint_names
    data = mujoco.MjData(model)
    q0, v0 = scenario.initial_state(robot)
    data.qpos[:] = arm.to_qpos(q0)
    mujoco.mj_forward(model, data)
    free = np.flatnonzero(arm.qpos_index >= 0)
    qadr = arm.qpos_index[free]
    dadr = np.array(
        [
            model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, names[i])]
            for i in free
        ]
    )
    effort = np.asarray(robot.params.effort, dtype=float)
    saturate = scenario.config.effort_saturation
    other = [f.kind for f in scenario.failures if f.kind != "frozen"]
    if other:  # only a frozen joint has a simple MuJoCo equivalent here
        raise NotImplementedError(f"failure kinds {other} on MuJoCo")
    freezes = sorted(
        (
            (f.t, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f.joint), f)
            for f in scenario.failures
        ),
        key=lambda x: x[0],
    )
    armature0 = model.dof_armature.copy()
    qf, vf = arm.q_locked.copy(), np.zeros(robot.nq)
    t0 = time.perf_counter()
    ctrl = scenario.build_controller(robot)
    ctrl.reset(robot, 0.0, q0.copy(), v0.copy())
    nstep = max(1, round(ctrl.dt / arm.timestep))
    ticks = round(T / (nstep * arm.timestep))
    in_ctrl = 0.0
    clock = time.perf_counter
    for k in range(ticks):
        t = k * nstep * arm.timestep
        while freezes and freezes[0][0] <= t + 1e-12:
            _, jid, failure = freezes.pop(0)
            _freeze(mujoco, model, data, int(model.jnt_dofadr[jid]))
            if scenario.inform_controller:
                ctrl.on_failure(failure, t)
        qf[free] = data.qpos[qadr]
        vf[free] = data.qvel[dadr]
        c0 = clock()
        tau = np.asarray(ctrl.step(t, qf, vf), dtype=float)
        in_ctrl += clock() - c0
        if saturate:
            tau = np.clip(tau, -effort, effort)
        data.qfrc_applied[dadr] = tau[free]
        mujoco.mj_step(model, data, nstep=nstep)
    wall = time.perf_counter() - t0
    model.dof_armature[:] = armature0
    q = arm.from_qpos(data.qpos)
    pose = {n: float(q[robot.joint_names.index(n)]) for n in ("turret", *ARM)}
    return wall, in_ctrl, pose, ticks


def control_table(robot: packbot.Robot, args: argparse.Namespace) -> list[Row]:
    """Run table 2 (interleaved repeats) and print it; returns the rows."""
    T = args.control_duration
    scenario = load_scenario("reconfig_elbow1")
    q0, _ = scenario.initial_state(robot)
    locked = tuple(scenario.config.locked_joints)
    arm = build_mujoco_model(
        robot,
        q_locked=q0,
        locked_joints=locked,
        timestep=1e-3,
        mu=scenario.config.mu,
        joint_dynamics=scenario.config.joint_friction,
    )
    ours = Row("packbot reconfig_elbow1", T)
    peer = Row("MuJoCo Euler 1 ms + same controller", T)
    run_scenario(scenario, robot, duration=min(T, 0.2))  # warm-up
    ctrl_walls: list[float] = []
    ours_ctrl: list[float] = []
    for _ in range(args.control_repeats):
        wall, in_ctrl, res = _packbot_controlled(robot, scenario, T)
        ours.walls.append(wall)
        ours_ctrl.append(in_ctrl)
        ours.rest_pose = {n: float(res.q[-1][res.joint(n)]) for n in ("turret", *ARM)}
        ours.note = f"{res.control_ticks} ticks, {res.diagnostics.steps} steps"
        wall, in_ctrl, pose, ticks = _mujoco_controlled(robot, scenario, arm, T)
        peer.walls.append(wall)
        ctrl_walls.append(in_ctrl)
        peer.rest_pose = pose
        peer.note = f"{ticks} ticks; elbow1 frozen at 1 s (speed 0, armature 1e8)"
    print(
        f"\nreconfig_elbow1, {T:g} s simulated (failure: elbow1 frozen at 1 s), 1 ms ticks; "
        f"wall: median of {args.control_repeats} interleaved rounds"
    )
    head = (
        f"{'system':<38}{'wall[s]':>9}{'RTF':>7}{'turret':>8}{'shoulder':>9}{'elbow1':>8}"
        f"{'elbow2':>8}"
    )
    print(head)
    print("-" * len(head))
    for r in (ours, peer):
        pose = r.rest_pose or {}
        print(
            f"{r.label:<38}{r.wall:9.3f}{r.rtf:7.1f}"
            + "".join(
                f"{pose[n]:{w}.4f}" for n, w in zip(("turret", *ARM), (8, 9, 8, 8), strict=True)
            )
            + f"  ({r.note})"
        )
    ratio = ours.wall / peer.wall
    per_round = round_ratio(ours, peer)
    for r, spent in ((ours, ours_ctrl), (peer, ctrl_walls)):
        r.controller_wall = statistics.median(spent)
        print(
            f"{r.label}: in the controller's step() {r.controller_wall:.3f} s (median; "
            f"{r.controller_wall / r.wall:.0%} of its wall, {r.controller_wall / ticks * 1e6:.0f} "
            f"us per tick): the controller alone runs at {T / r.controller_wall:.1f}x real time"
        )
    print(
        f"packbot / MuJoCo: {ratio:.2f}x (median of the rounds' ratios {per_round:.2f}x; "
        f"target <= {CONTROL_RATIO_TARGET:g}x: "
        f"{'met' if ratio <= CONTROL_RATIO_TARGET else 'not met'}); packbot real-time factor "
        f"{ours.rtf:.1f} (target >= {CONTROL_RTF_TARGET:g}: "
        f"{'met' if ours.rtf >= CONTROL_RTF_TARGET else 'not met'})"
    )
    return [ours, peer]


# ------------------------------------------------------------------------------ profile
def profile(robot: packbot.Robot, duration: float, top: int = 12) -> None:
    """Print a cProfile of one normal-mode collapse, top functions by own time."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    prof = cProfile.Profile()
    prof.enable()
    packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), duration, config=cfg)
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(top)
    print(f"\ncProfile, normal mode mu 0.5 collapse, {duration:g} s, top {top} by tottime:")
    print(buf.getvalue())


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="interleaved rounds (median wall)")
    ap.add_argument("--duration", type=float, default=5.0, help="collapse: simulated time [s]")
    ap.add_argument(
        "--control-duration", type=float, default=60.0, help="reconfig_elbow1: simulated [s]"
    )
    ap.add_argument(
        "--control-repeats", type=int, default=None, help="rounds of table 2 (default: --repeats)"
    )
    ap.add_argument("--no-control", action="store_true", help="skip the controlled run")
    ap.add_argument("--json", type=Path, default=None, help="write the rows to this JSON file")
    ap.add_argument("--profile", action="store_true", help="cProfile of the normal collapse")
    args = ap.parse_args(argv)
    if args.control_repeats is None:
        args.control_repeats = args.repeats
    for name in ("repeats", "control_repeats"):
        if getattr(args, name) < 1:
            ap.error(f"--{name.replace('_', '-')} must be >= 1")
    import mujoco

    robot = packbot.load_robot()
    machine = {
        "date": datetime.date.today().isoformat(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "packbot": packbot.__version__,
        "mujoco": mujoco.__version__,
        "load_average_start": os.getloadavg()[0],
    }
    print(
        f"{machine['date']}: {machine['processor']}, {machine['cpus']} CPUs, Python "
        f"{machine['python']}, MuJoCo {machine['mujoco']}, load average "
        f"{machine['load_average_start']:.2f}"
    )
    rows = collapse_table(robot, args)
    control = [] if args.no_control else control_table(robot, args)
    machine["load_average_end"] = os.getloadavg()[0]
    if args.json is not None:
        ref = next(r for r in rows if r.label == REFERENCE)
        out = {
            "machine": machine,
            "repeats": args.repeats,
            "collapse": [
                {
                    **r.as_dict(),
                    "ratio_to_mujoco_euler_1ms": (
                        r.wall / ref.wall if r.walls and r.label.startswith("packbot") else None
                    ),
                    "ratio_per_round_median": (
                        round_ratio(r, ref) if r.label.startswith("packbot") else None
                    ),
                    "target_ratio": TARGETS.get(r.label),
                }
                for r in rows
            ],
            "control": [r.as_dict() for r in control],
            "control_ratio": (control[0].wall / control[1].wall if control else None),
            "control_ratio_per_round_median": (
                round_ratio(control[0], control[1]) if control else None
            ),
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=2) + "\n")
        print(f"\nrows written to {args.json}")
    if args.profile:
        profile(robot, args.duration)


if __name__ == "__main__":
    main()
