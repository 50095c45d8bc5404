"""Failure analysis: where a loose joint settles, and what a frozen joint leaves reachable.

- :func:`loose_joint_equilibria`: with one joint loose (no motor torque) and the others held at
  ``q_hold``, the loose joint is at rest where its gravity torque is zero. g(q) = dV/dq (the
  torque that holds the arm, Pinocchio's generalized gravity) is scanned over the joint's range,
  its sign changes refined by Brent's method; an equilibrium is stable where dg_j/dq_j > 0 (a
  minimum of the potential energy V along the joint). A joint limit where gravity pushes the joint
  into its stop is a rest position too (kind ``"limit"``). Each one is checked for collisions.
- :func:`workspace`: gripper positions sampled uniformly over the joint limits of the joints that
  move the frame, collision-free samples only, for the healthy arm or with one joint frozen;
  :func:`plot_workspace` draws two of them side by side (top and side views).
- :func:`reach` / :func:`reachable`: is a position reachable (collision free, within the
  limits, the frozen joint kept)? Damped-least-squares IK from the configurations of the nearest
  workspace samples; a "yes" carries its witness configuration, a "no" the closest approach.
- :func:`reachable_volume`: the reachable volume [m^3] with its standard error, by Monte Carlo
  over the samples' bounding box: uniform points, each tested by :func:`reachable`, drawn until
  the binomial standard error is below ``rel_tol`` of the estimate. Unlike the voxel count of the
  samples (:meth:`Workspace.volume`, which grows with the sample count as ever more voxels get
  hit), its expectation does not depend on how many points are drawn.
  :func:`monte_carlo_volume` is the estimator for any membership test.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq
from scipy.spatial import cKDTree

from packbot.collision import CollisionWorld
from packbot.control.ik import solve_position_ik
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.validation import (
    MAX_CONFIG_SAMPLES,
    MAX_IK_ITERATIONS,
    MAX_SCAN_SAMPLES,
    MAX_VOLUME_POINTS,
    integer,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from packbot.environment import Environment
    from packbot.model import Robot

__all__ = [
    "Equilibrium",
    "ReachAnswer",
    "VolumeEstimate",
    "Workspace",
    "gravity_torque_on",
    "loose_joint_equilibria",
    "monte_carlo_volume",
    "plot_workspace",
    "reach",
    "reachable",
    "reachable_volume",
    "workspace",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Default gravity [m/s^2] (SimConfig's).
GRAVITY: tuple[float, float, float] = (0.0, 0.0, -9.81)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Equilibrium:
    """A rest position of a loose joint, the other joints held.

    Attributes:
        joint: The loose joint's name.
        angle: Its angle [rad].
        q: The full configuration [rad], shape (nq,).
        kind: ``"root"`` (zero gravity torque) or ``"limit"`` (pressed into a joint stop).
        stiffness: dg_j/dq_j at the equilibrium [N*m/rad] (> 0: stable).
        stable: Whether a small displacement returns (root: stiffness > 0; limit: always).
        gravity_torque: g_j at the rest position [N*m] (zero for a root; the stop's load for a
            limit).
        min_distance: Smallest signed distance of the arm there [m].
        in_collision: Whether some pair penetrates there (min_distance < 0): the equilibrium is
            then not reachable, a contact stops the link first.
        closest_pair: The closest pair, ``"link/piece - link/piece"``.
    """

    joint: str
    angle: float
    q: FloatArray
    kind: str
    stiffness: float
    stable: bool
    gravity_torque: float
    min_distance: float
    in_collision: bool
    closest_pair: str


def _gravity_model(robot: Robot, gravity: ArrayLike) -> tuple[pin.Model, pin.Data]:
    g = np.asarray(gravity, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ConfigurationError("gravity", gravity, "3 finite numbers [m/s^2]")
    model = robot.model.copy()
    model.gravity.linear = g
    return model, model.createData()


@checked_arguments
def gravity_torque_on(
    robot: Robot, joint: str, q_hold: ArrayLike, angles: ArrayLike, gravity: ArrayLike = GRAVITY
) -> FloatArray:
    """Gravity torque g_j [N*m] on one joint at each of ``angles`` [rad], the others at q_hold."""
    j = robot.params.index(joint)
    model, data = _gravity_model(robot, gravity)
    q = np.array(q_hold, dtype=float)
    out = []
    for a in np.atleast_1d(np.asarray(angles, dtype=float)):
        q[j] = a
        out.append(pin.computeGeneralizedGravity(model, data, q)[j])
    return np.array(out)


@checked_arguments
def loose_joint_equilibria(
    robot: Robot,
    joint: str,
    q_hold: ArrayLike,
    *,
    gravity: ArrayLike = GRAVITY,
    environment: Environment | None = None,
    samples: int = 721,
) -> list[Equilibrium]:
    """Rest positions of a loose joint with the other joints held at ``q_hold``.

    Args:
        robot: The robot.
        joint: The loose joint.
        q_hold: Configuration of the held joints [rad], shape (nq,) (the loose joint's entry is
            ignored).
        gravity: Gravity [m/s^2], world frame.
        environment: Obstacles for the collision check (None: the floor).
        samples: Scan resolution over the joint's range (a continuous joint's: the turn centred
            on its angle in q_hold).

    Returns:
        The equilibria in increasing angle: zero-torque roots and loaded joint stops. Empty if
        gravity exerts no torque on the joint anywhere (a vertical axis: neutral everywhere).

    Raises:
        UnknownNameError: Unknown joint.
        ConfigurationError: Bad q_hold shape or gravity.
    """
    j = robot.params.index(joint)
    q0 = np.array(q_hold, dtype=float)
    if q0.shape != (robot.nq,) or not np.all(np.isfinite(q0)):
        raise ConfigurationError("q_hold", q_hold, f"{robot.nq} finite angles [rad]")
    integer("samples", samples, low=3, high=MAX_SCAN_SAMPLES)
    model, data = _gravity_model(robot, gravity)
    bounded = bool(robot.params.bounded[j])  # (a continuous joint: one turn about q_hold's)
    lo, hi = (float(b[j]) for b in robot.params.sampling_bounds(q0))

    def g(a: float) -> float:
        q = q0.copy()
        q[j] = a
        return float(pin.computeGeneralizedGravity(model, data, q)[j])

    grid = np.linspace(lo, hi, samples)
    vals = np.array([g(a) for a in grid])
    scale = float(np.max(np.abs(vals)))
    if scale < 1e-9:
        log.info("joint %s: no gravity torque at any angle (neutral)", joint)
        return []
    world = CollisionWorld(robot, environment)
    out: list[Equilibrium] = []

    def make(a: float, kind: str) -> Equilibrium:
        q = q0.copy()
        q[j] = a
        h = 1e-6 * (hi - lo)
        k = (g(min(a + h, hi)) - g(max(a - h, lo))) / (min(a + h, hi) - max(a - h, lo))
        c = world.closest(q)
        pair = f"{c.pair.piece1} - {c.pair.piece2}"
        return Equilibrium(
            joint=joint,
            angle=float(a),
            q=q,
            kind=kind,
            stiffness=float(k),
            stable=bool(k > 0) if kind == "root" else True,
            gravity_torque=0.0 if kind == "root" else g(a),
            min_distance=float(c.distance),
            in_collision=bool(c.distance < 0),
            closest_pair=pair,
        )

    tiny = 1e-9 * scale
    if bounded and vals[0] > tiny:  # gravity (-g) pushes toward the lower stop
        out.append(make(lo, "limit"))
    for k in range(samples - 1):
        a, b = vals[k], vals[k + 1]
        if abs(a) <= tiny and k > 0:
            continue  # counted as the previous interval's root
        if a * b < 0 or abs(b) <= tiny:
            root = grid[k + 1] if abs(b) <= tiny else brentq(g, grid[k], grid[k + 1], xtol=1e-12)
            out.append(make(float(root), "root"))
    if bounded and vals[-1] < -tiny:  # pushed toward the upper stop
        out.append(make(hi, "limit"))
    return out


def _attr_names(model: pin.Model, frame: str) -> list[int]:
    if not model.existFrame(frame):
        raise UnknownNameError("frame", frame, [f.name for f in model.frames])
    parent = model.frames[model.getFrameId(frame)].parentJoint
    return sorted(model.joints[i].idx_q for i in model.supports[parent] if i > 0)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Workspace:
    """Sampled reachable positions of a frame.

    Attributes:
        points: Collision-free frame positions [m], world frame, shape (N, 3).
        q: Their configurations [rad], shape (N, nq).
        n_samples: Configurations sampled (collision-free or not).
        frozen: ``(joint, angle [rad])`` of the frozen joint, or None (healthy).
        frame: The frame.
        joints: Names of the sampled joints.
    """

    points: FloatArray
    q: FloatArray
    n_samples: int
    frozen: tuple[str, float] | None
    frame: str
    joints: tuple[str, ...]

    @property
    def free_fraction(self) -> float:
        """Fraction of the samples that were collision free."""
        return len(self.points) / max(self.n_samples, 1)

    @checked_arguments
    def volume(self, voxel: float = 0.05) -> float:
        """Volume of the voxels [m^3] (edge ``voxel`` [m]) holding at least one point.

        Deprecated: this count grows with the number of samples (every new sample may hit a new
        voxel: 0.29 m^3 at 5,000 samples, 1.09 m^3 at 20,000 for the healthy arm) and is no
        estimate of the reachable volume. Use :func:`reachable_volume`.
        """
        warnings.warn(
            "Workspace.volume() counts the voxels its samples hit and grows with the sample "
            "count; use packbot.analysis.reachable_volume() for a converged estimate",
            DeprecationWarning,
            stacklevel=2,
        )
        if not (isinstance(voxel, (int, float)) and math.isfinite(voxel) and voxel > 0):
            raise ConfigurationError("voxel", voxel, "a positive voxel edge [m]")
        if len(self.points) == 0:
            return 0.0
        cells = np.unique(np.floor(self.points / voxel).astype(np.int64), axis=0)
        return float(len(cells) * voxel**3)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class VolumeEstimate:
    """A Monte Carlo volume with its uncertainty.

    Attributes:
        volume_m3: The estimate [m^3]: box volume times the fraction of points inside.
        stderr_m3: Its binomial standard error [m^3], box * sqrt(f (1 - f) / n).
        samples: Points drawn (n).
        hits: Points found inside.
        box_m3: Volume of the box the points were drawn in [m^3].
        converged: Whether stderr_m3 <= rel_tol * volume_m3 was reached before max_points.
        rel_tol: The relative standard error asked for.
    """

    volume_m3: float
    stderr_m3: float
    samples: int
    hits: int
    box_m3: float
    converged: bool
    rel_tol: float

    def __str__(self) -> str:
        flag = "" if self.converged else " (not converged)"
        return f"{self.volume_m3:.3f} +- {self.stderr_m3:.3f} m^3 ({self.samples} points){flag}"


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class ReachAnswer:
    """Whether a position is reachable, with the evidence.

    Attributes:
        reachable: True if a collision-free configuration within the limits (the frozen joint
            kept) places the frame within ``tol`` of the target. False means the IK from every
            seed failed: the target is out of reach unless all seeds missed a solution.
        error_m: Distance from the target of the best configuration found [m] (<= tol if
            reachable; the closest approach otherwise).
        q: That configuration [rad], shape (nq,) (the witness if reachable).
        tol_m: The tolerance used [m].
    """

    reachable: bool
    error_m: float
    q: FloatArray
    tol_m: float


@checked_arguments
def workspace(
    robot: Robot,
    frozen: tuple[str, float] | str | None = None,
    *,
    samples: int = 4000,
    seed: int = 0,
    frame: str | None = None,
    q_ref: ArrayLike | None = None,
    environment: Environment | None = None,
) -> Workspace:
    """Sample the reachable positions of a frame, collision-free configurations only.

    The joints that move the frame are sampled uniformly within their limits (the frozen one
    excepted); the other joints stay at ``q_ref``.

    Args:
        robot: The robot.
        frozen: None (healthy), ``(joint, angle [rad])``, or a joint name (frozen at its
            ``q_ref`` angle).
        samples: Configurations to sample.
        seed: Seed of the sampler.
        frame: The frame whose positions are collected; None: the robot's tool frame
            (:attr:`packbot.Robot.tool_frame`, PackBot's ``gripper_tool``).
        q_ref: Configuration of the joints not sampled [rad] (default: the ``stand`` pose).
        environment: Obstacles (None: the floor).

    Raises:
        UnknownNameError: Unknown joint or frame.
        ConfigurationError: Bad frozen angle, samples or q_ref.
    """
    base = robot.pose("stand") if q_ref is None else np.array(q_ref, dtype=float)
    if base.shape != (robot.nq,):
        raise ConfigurationError("q_ref", q_ref, f"{robot.nq} angles [rad]")
    integer("samples", samples, low=1, high=MAX_CONFIG_SAMPLES, what="a positive integer")
    fz: tuple[str, float] | None = None
    if isinstance(frozen, str):
        fz = (frozen, float(base[robot.params.index(frozen)]))
    elif frozen is not None:
        name, angle = frozen
        j = robot.params.index(name)
        if not robot.params.lower[j] <= float(angle) <= robot.params.upper[j]:
            raise ConfigurationError(
                "frozen",
                angle,
                f"an angle of {name} within [{robot.params.lower[j]}, {robot.params.upper[j]}]",
            )
        fz = (name, float(angle))
    model = robot.model
    data = model.createData()
    frame = robot.tool_frame if frame is None else frame
    idx = _attr_names(model, frame)
    if fz is not None:
        jf = robot.params.index(fz[0])
        base[jf] = fz[1]
        idx = [i for i in idx if i != jf]
    fid = model.getFrameId(frame)
    rng = np.random.default_rng(seed)
    lo, hi = (b[idx] for b in robot.params.sampling_bounds(base))
    world = CollisionWorld(robot, environment)
    pts, qs = [], []
    for _ in range(samples):
        q = base.copy()
        q[idx] = rng.uniform(lo, hi)
        if world.in_collision(q):
            continue
        pin.framesForwardKinematics(model, data, q)
        pts.append(data.oMf[fid].translation.copy())
        qs.append(q)
    return Workspace(
        points=np.array(pts).reshape(-1, 3),
        q=np.array(qs).reshape(-1, robot.nq),
        n_samples=samples,
        frozen=fz,
        frame=frame,
        joints=tuple(robot.params.names[i] for i in idx),
    )


@checked_arguments
def monte_carlo_volume(
    inside: Callable[[FloatArray], NDArray[np.bool_]],
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    rel_tol: float = 0.03,
    batch: int = 500,
    max_points: int = 20000,
    seed: int = 0,
) -> VolumeEstimate:
    """Volume of a set [m^3] from a membership test, sampled until its standard error converges.

    Points are drawn uniformly in the box [lower, upper] in batches; the estimate is the box
    volume times the fraction inside, its standard error the binomial one. Drawing stops once
    the standard error is at most ``rel_tol`` of the estimate (with at least one point inside
    and one outside), or at ``max_points`` (then ``converged`` is False and a warning is
    logged). The expectation does not depend on the number of points; the set must lie in the
    box (what lies outside is not counted).

    Args:
        inside: Membership test of an (n, 3) array of points [m], returning n booleans.
        lower: Lower corner of the box [m], shape (3,).
        upper: Upper corner [m], shape (3,), above lower on every axis.
        rel_tol: Relative standard error to reach, in (0, 1).
        batch: Points per batch.
        max_points: Most points to draw.
        seed: Seed of the sampler.

    Raises:
        ConfigurationError: Bad box, tolerance or counts, or a membership test that returns the
            wrong shape.
    """
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo) & np.isfinite(hi)):
        raise ConfigurationError("box", (lower, upper), "two corners of 3 finite numbers [m]")
    if not np.all(hi > lo):
        raise ConfigurationError("box", (lower, upper), "upper > lower on every axis")
    if not (isinstance(rel_tol, (int, float)) and 0 < rel_tol < 1):
        raise ConfigurationError("rel_tol", rel_tol, "a number in (0, 1)")
    integer("batch", batch, low=1, high=MAX_VOLUME_POINTS, what="a positive integer")
    integer("max_points", max_points, low=batch, high=MAX_VOLUME_POINTS, what="an integer >= batch")
    box = float(np.prod(hi - lo))
    rng = np.random.default_rng(seed)
    n = hits = 0
    converged = False
    se = vol = 0.0
    while n < max_points:
        m = min(batch, max_points - n)
        pts = rng.uniform(lo, hi, size=(m, 3))
        ins = np.asarray(inside(pts), dtype=bool)
        if ins.shape != (m,):
            raise ConfigurationError("inside", ins.shape, f"{m} booleans, one per point")
        n += m
        hits += int(ins.sum())
        f = hits / n
        vol = box * f
        se = box * math.sqrt(f * (1.0 - f) / n)
        if 0 < hits < n and se <= rel_tol * vol:
            converged = True
            break
    if not converged:
        log.warning(
            "volume not converged: %.4g +- %.4g m^3 after %d points (%d inside)", vol, se, n, hits
        )
    return VolumeEstimate(
        volume_m3=vol,
        stderr_m3=se,
        samples=n,
        hits=hits,
        box_m3=box,
        converged=converged,
        rel_tol=float(rel_tol),
    )


def _reach_setup(
    robot: Robot, ws: Workspace, environment: Environment | None
) -> tuple[cKDTree, list[int], CollisionWorld]:
    if len(ws.points) == 0:
        raise ConfigurationError("workspace", "no collision-free samples", "a sampled workspace")
    if ws.q.shape[1] != robot.nq:
        raise ConfigurationError("workspace.q", ws.q.shape, f"(N, {robot.nq}) for this robot")
    active = [robot.params.index(name) for name in ws.joints]
    return cKDTree(ws.points), active, CollisionWorld(robot, environment)


def _reach_one(
    robot: Robot,
    ws: Workspace,
    tree: cKDTree,
    active: list[int],
    world: CollisionWorld,
    target: FloatArray,
    *,
    seeds: int,
    tol: float,
    max_iter: int,
) -> ReachAnswer:
    k = min(seeds, len(ws.points))
    _, nearest = tree.query(target, k=k)
    best: ReachAnswer | None = None
    for i in np.atleast_1d(nearest):
        res = solve_position_ik(
            robot.model,
            ws.frame,
            target,
            ws.q[int(i)],
            robot=robot,
            active=active,
            tol=tol,
            max_iter=max_iter,
            accept=lambda q: not world.in_collision(q),  # the workspace's own world
            collision_free=False,
        )
        if res.success:
            return ReachAnswer(reachable=True, error_m=res.error, q=res.q, tol_m=tol)
        if best is None or res.error < best.error_m:
            best = ReachAnswer(reachable=False, error_m=res.error, q=res.q, tol_m=tol)
    assert best is not None
    return best


def _check_reach_args(seeds: int, tol: float, max_iter: int) -> None:
    if not isinstance(seeds, int) or isinstance(seeds, bool) or seeds < 1:
        raise ConfigurationError("seeds", seeds, "a positive integer")
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ConfigurationError("tol", tol, "a positive distance [m]")
    integer("max_iter", max_iter, low=1, high=MAX_IK_ITERATIONS, what="a positive integer")


@checked_arguments
def reach(
    robot: Robot,
    ws: Workspace,
    point: ArrayLike,
    *,
    seeds: int = 4,
    tol: float = 2e-3,
    max_iter: int = 60,
    environment: Environment | None = None,
) -> ReachAnswer:
    """Is ``point`` [m] reachable by the workspace's frame, with its joints and frozen joint?

    Damped-least-squares IK (:func:`packbot.control.ik.solve_position_ik`) on the workspace's
    sampled joints, from the configurations of the ``seeds`` samples nearest the point; a
    solution counts if it is collision free. The other joints (the frozen one included) keep
    the samples' values.

    Args:
        robot: The robot the workspace was sampled on.
        ws: The workspace (its samples seed the IK).
        point: The position [m], world frame, shape (3,).
        seeds: Nearest samples to start from.
        tol: Position tolerance [m].
        max_iter: IK iterations per seed.
        environment: Obstacles (None: the floor); the workspace's own.

    Returns:
        The answer, with the witness configuration or the closest approach.

    Raises:
        ConfigurationError: Bad point, seeds, tol or max_iter, or an empty workspace.
    """
    _check_reach_args(seeds, tol, max_iter)
    p = np.asarray(point, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigurationError("point", point, "3 finite coordinates [m]")
    tree, active, world = _reach_setup(robot, ws, environment)
    return _reach_one(robot, ws, tree, active, world, p, seeds=seeds, tol=tol, max_iter=max_iter)


@checked_arguments
def reachable(
    robot: Robot,
    ws: Workspace,
    points: ArrayLike,
    *,
    seeds: int = 4,
    tol: float = 2e-3,
    max_iter: int = 60,
    environment: Environment | None = None,
) -> NDArray[np.bool_]:
    """Which of ``points`` [m], shape (n, 3), are reachable (see :func:`reach`)."""
    _check_reach_args(seeds, tol, max_iter)
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise ConfigurationError("points", pts.shape, "(n, 3) finite coordinates [m]")
    tree, active, world = _reach_setup(robot, ws, environment)
    return np.array(
        [
            _reach_one(
                robot, ws, tree, active, world, p, seeds=seeds, tol=tol, max_iter=max_iter
            ).reachable
            for p in pts
        ],
        dtype=bool,
    )


@checked_arguments
def reachable_volume(
    robot: Robot,
    ws: Workspace,
    *,
    rel_tol: float = 0.03,
    pad: float = 0.05,
    seeds: int = 4,
    tol: float = 2e-3,
    max_points: int = 20000,
    seed: int = 0,
    environment: Environment | None = None,
) -> VolumeEstimate:
    """Reachable volume of the workspace's frame [m^3], with its standard error.

    :func:`monte_carlo_volume` over the samples' bounding box grown by ``pad``, each point
    tested by :func:`reachable`. The samples only seed the IK and bound the box: the estimate
    does not grow with their number. It is biased low only by IK failures (a reachable point
    whose every seed fails), which the tests bound on points known reachable.

    Args:
        robot: The robot the workspace was sampled on.
        ws: The workspace.
        rel_tol: Relative standard error to reach.
        pad: Margin added to the samples' bounding box on every side [m].
        seeds: Nearest samples the IK starts from.
        tol: Position tolerance of the IK [m].
        max_points: Most points to test.
        seed: Seed of the point sampler.
        environment: Obstacles (None: the floor); the workspace's own.

    Raises:
        ConfigurationError: Bad arguments or an empty workspace.
    """
    _check_reach_args(seeds, tol, 1)
    integer("max_points", max_points, low=250, high=MAX_VOLUME_POINTS, what="an integer >= 250")
    if not (isinstance(pad, (int, float)) and math.isfinite(pad) and pad >= 0):
        raise ConfigurationError("pad", pad, "a distance >= 0 [m]")
    tree, active, world = _reach_setup(robot, ws, environment)

    def inside(pts: FloatArray) -> NDArray[np.bool_]:
        return np.array(
            [
                _reach_one(
                    robot, ws, tree, active, world, p, seeds=seeds, tol=tol, max_iter=60
                ).reachable
                for p in pts
            ],
            dtype=bool,
        )

    lo = ws.points.min(axis=0) - pad
    hi = ws.points.max(axis=0) + pad
    return monte_carlo_volume(
        inside, lo, hi, rel_tol=rel_tol, batch=250, max_points=max_points, seed=seed
    )


@checked_arguments
def plot_workspace(
    spaces: Sequence[Workspace],
    path: str | Path | None = None,
    *,
    labels: Sequence[str] | None = None,
    formats: Sequence[str] = ("png", "svg"),
    dpi: int = 120,
) -> Figure:
    """Top (x-y) and side (x-z) views of sampled workspaces, overlaid.

    Args:
        spaces: The workspaces (e.g. healthy, then frozen).
        path: Output path without suffix (one file per format), or None to only return it.
        labels: Legend labels, as given (default: "healthy" / "<joint> frozen at <angle> rad",
            with the number of points).
        formats: File formats.
        dpi: Raster resolution.

    Returns:
        The figure.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.5), layout="constrained")
    ax_top, ax_side = fig.subplots(1, 2)
    colors = ["0.6", "tab:red", "tab:blue", "tab:green"]
    for k, ws in enumerate(spaces):
        if labels is not None:
            label = labels[k]
        else:
            name = (
                "healthy"
                if ws.frozen is None
                else f"{ws.frozen[0]} frozen at {ws.frozen[1]:.2f} rad"
            )
            label = f"{name} ({len(ws.points)} pts)"
        p = ws.points
        c = colors[k % len(colors)]
        size = 2 if k == 0 else 1.5
        ax_top.scatter(p[:, 0], p[:, 1], s=size, c=c, alpha=0.5, lw=0, label=label)
        ax_side.scatter(p[:, 0], p[:, 2], s=size, c=c, alpha=0.5, lw=0, label=label)
    ax_top.set(xlabel="x [m]", ylabel="y [m]", title="top view", aspect="equal")
    ax_side.set(xlabel="x [m]", ylabel="z [m]", title="side view", aspect="equal")
    ax_side.axhline(0.0, color="k", lw=0.8)
    ax_top.legend(loc="lower left", fontsize=8, markerscale=5)
    frame = spaces[0].frame if spaces else "gripper_tool"
    fig.suptitle(f"reachable positions of {frame} (collision-free samples)")
    if path is not None:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        for fmt in formats:
            fig.savefig(out.with_suffix(f".{fmt}"), dpi=dpi)
    return fig
