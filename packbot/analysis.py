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
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from packbot.collision import CollisionWorld
from packbot.errors import ConfigurationError, UnknownNameError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from packbot.environment import Environment
    from packbot.model import Robot

__all__ = [
    "Equilibrium",
    "Workspace",
    "gravity_torque_on",
    "loose_joint_equilibria",
    "plot_workspace",
    "workspace",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Default gravity [m/s^2] (SimConfig's).
GRAVITY: tuple[float, float, float] = (0.0, 0.0, -9.81)


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
        samples: Scan resolution over the joint's range.

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
    if not isinstance(samples, int) or samples < 3:
        raise ConfigurationError("samples", samples, "an integer >= 3")
    model, data = _gravity_model(robot, gravity)
    lo, hi = float(robot.params.lower[j]), float(robot.params.upper[j])

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
    if vals[0] > tiny:  # gravity (-g) pushes toward the lower stop
        out.append(make(lo, "limit"))
    for k in range(samples - 1):
        a, b = vals[k], vals[k + 1]
        if abs(a) <= tiny and k > 0:
            continue  # counted as the previous interval's root
        if a * b < 0 or abs(b) <= tiny:
            root = grid[k + 1] if abs(b) <= tiny else brentq(g, grid[k], grid[k + 1], xtol=1e-12)
            out.append(make(float(root), "root"))
    if vals[-1] < -tiny:  # pushed toward the upper stop
        out.append(make(hi, "limit"))
    return out


def _attr_names(model: pin.Model, frame: str) -> list[int]:
    if not model.existFrame(frame):
        raise UnknownNameError("frame", frame, [f.name for f in model.frames])
    parent = model.frames[model.getFrameId(frame)].parentJoint
    return sorted(model.joints[i].idx_q for i in model.supports[parent] if i > 0)


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

    def volume(self, voxel: float = 0.05) -> float:
        """Volume of the voxels [m^3] (edge ``voxel`` [m]) holding at least one point."""
        if len(self.points) == 0:
            return 0.0
        cells = np.unique(np.floor(self.points / voxel).astype(np.int64), axis=0)
        return float(len(cells) * voxel**3)


def workspace(
    robot: Robot,
    frozen: tuple[str, float] | str | None = None,
    *,
    samples: int = 4000,
    seed: int = 0,
    frame: str = "gripper_tool",
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
        frame: The frame whose positions are collected.
        q_ref: Configuration of the joints not sampled [rad] (default: the ``stand`` pose).
        environment: Obstacles (None: the floor).

    Raises:
        UnknownNameError: Unknown joint or frame.
        ConfigurationError: Bad frozen angle, samples or q_ref.
    """
    base = robot.pose("stand") if q_ref is None else np.array(q_ref, dtype=float)
    if base.shape != (robot.nq,):
        raise ConfigurationError("q_ref", q_ref, f"{robot.nq} angles [rad]")
    if not isinstance(samples, int) or samples < 1:
        raise ConfigurationError("samples", samples, "a positive integer")
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
    idx = _attr_names(model, frame)
    if fz is not None:
        jf = robot.params.index(fz[0])
        base[jf] = fz[1]
        idx = [i for i in idx if i != jf]
    fid = model.getFrameId(frame)
    rng = np.random.default_rng(seed)
    lo, hi = robot.params.lower[idx], robot.params.upper[idx]
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
        labels: Legend labels (default: "healthy" / "<joint> frozen at <angle> rad").
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
        elif ws.frozen is None:
            label = "healthy"
        else:
            label = f"{ws.frozen[0]} frozen at {ws.frozen[1]:.2f} rad"
        label += f" ({len(ws.points)} pts, {ws.volume():.2f} m$^3$)"
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
