"""Identification of the arm's inertial parameters from logged motion.

:func:`identify` (and :func:`identify_csv` for a CSV log) estimates, from a log of joint angles
and joint torques (or motor currents), every body's ten inertial parameters and every joint's
armature (reflected rotor inertia), viscous and Coulomb friction, and returns an identified
:class:`~packbot.model.Robot`. The method, in five steps:

1. **Filter.** The samples must be uniformly spaced. Velocity and acceleration come from the
   joint angles by a Savitzky-Golay filter (:func:`scipy.signal.savgol_filter`: a
   least-squares polynomial of degree ``polyorder`` = 4 over a sliding window of ``window`` =
   0.5 s, an odd number of samples, zero phase; deriv 1 and 2: it passes up to 3.4 Hz at
   -3 dB, its acceleration is exact to 2.5e-5 at 0.25 Hz, 0.7 % at 1 Hz; a faster motion needs
   a shorter window), or, when the log has velocities, the acceleration from the velocities
   (deriv 1); the angles (and logged velocities) are smoothed by the same filter (deriv 0).
   The torques are not filtered: a filter would smear Coulomb friction's jump at each
   velocity reversal over its window, which no regressor row reproduces; their noise averages
   out in the least squares. The half window at each end of the log is dropped; the fit uses
   every sample (or one every ``fit_dt``).
2. **Regressor.** Pinocchio's joint-torque regressor (:func:`pinocchio.computeJointTorqueRegressor`:
   ``tau = Y(q, v, a) pi``, pi the ten parameters per body of
   ``Inertia.toDynamicParameters()``: m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz
   about the joint frame's origin) is extended with one column per joint for the armature
   (a_j), the viscous (v_j) and the Coulomb friction (sign v_j): the full parameter vector
   (:func:`parameter_names`) of ``10 nb + 3 nv`` values. The log's rows are accumulated joint by
   joint into triangular factors (a QR update per block of samples), so a long log needs no
   more memory than a short one.
3. **Weights.** An ordinary least-squares fit gives each joint's residual standard deviation
   sigma_j; its rows are weighted by 1 / sigma_j (weighted least squares: a joint with a noisy
   torque sensor counts less). sigma_j is floored at 1e-9 of the joint's RMS torque.
4. **Base parameters.** The weighted regressor's columns are scaled to unit norm and factored
   by QR with column pivoting (:func:`scipy.linalg.qr`); the leading r columns whose diagonal
   entries exceed ``rank_rtol`` (1e-6) of the first are the base parameters: each is its
   leading parameter plus a linear combination of the parameters that are not identifiable on
   their own (``base_matrix``: beta = B pi). They are estimated by least squares, with their
   standard deviations from the residual and the regressor (sigma^2 (W_b^T W_b)^-1, assuming
   independent noise on the torques: encoder noise reaches the regressor and biases the fit
   beyond them) and the condition number of the scaled base regressor.
5. **Physical consistency.** The identified parameters are the physically consistent ones
   closest, in the base parameters' metric, to that estimate: every body's parameters are
   written in the log-Cholesky parametrisation (Rucker and Wensing, 2022;
   :class:`pinocchio.LogCholeskyParameters`: the pseudo-inertia J = U U^T, U upper triangular
   with an exponential diagonal), so each body has a positive mass, a positive-definite
   inertia that obeys the triangle inequality (J positive definite implies both) for any value
   of its ten numbers; armature and friction are exponentials (positive). A nonlinear least
   squares (:func:`scipy.optimize.least_squares`, Levenberg-Marquardt, Pinocchio's Jacobian of
   the parametrisation), started from the linear fit with the same prior where that fit is
   consistent, minimises the weighted base-parameter misfit plus a weak prior
   (``prior_weight`` = 1: a standard deviation of a factor e on the mass and the Cholesky
   factor's diagonal, 0.1 m on its other terms, a factor e on the joint terms) towards the
   nominal model. The parametrisation was chosen over a projection (which would move the
   estimate after the fit, not within it) and over an LMI solve (which needs a semidefinite
   solver packbot does not depend on); the prior resolves the parameters the log cannot see,
   and, on a well-excited log, changes the base parameters by far less than their noise.

:func:`packbot.control.exciting_trajectory` gives a motion that excites every base parameter
within the limits and without collision, to record on the real arm.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from packbot.errors import ConfigurationError, ResourceNotFound
from packbot.keywords import checked_arguments
from packbot.model import Robot
from packbot.validation import MAX_SAMPLES, boolean, finite_number, integer, real_array

__all__ = [
    "BODY_PARAMETERS",
    "JOINT_PARAMETERS",
    "Identification",
    "MotionLog",
    "identifiable_columns",
    "identify",
    "identify_csv",
    "load_log",
    "parameter_names",
    "parameters",
    "predict_torques",
    "regressor",
    "with_parameters",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: The ten inertial parameters of a body, in Pinocchio's order (``toDynamicParameters``): mass
#: [kg], first moments [kg*m], inertia about the joint frame's origin [kg*m^2].
BODY_PARAMETERS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: The three parameters of a joint: armature [kg*m^2], viscous [N*m*s/rad], Coulomb [N*m].
JOINT_PARAMETERS = ("armature", "viscous", "coulomb")
#: Rows of the regressor accumulated at once.
_BLOCK = 512
#: Lengths [m] that scale the log-Cholesky numbers s_ij and t_i in the prior.
_PRIOR_LENGTH = 0.1
#: Floor of a joint's residual standard deviation, relative to its RMS torque.
_SIGMA_FLOOR = 1e-9


def _bodies(robot: Robot) -> list[str]:
    """The name of each joint's body (the first link on it), joint order."""
    model = robot.model
    out = []
    for j in range(1, model.njoints):
        name = next(
            (str(f.name) for f in model.frames if f.type == pin.BODY and f.parentJoint == j),
            str(model.names[j]),
        )
        out.append(name)
    return out


@checked_arguments
def parameter_names(robot: Robot) -> tuple[str, ...]:
    """Names of the full parameter vector: ``link.m``, ... then ``joint.armature``, ...

    The bodies' ten parameters each (:data:`BODY_PARAMETERS`), in joint order, then each
    joint's :data:`JOINT_PARAMETERS`.
    """
    names = [f"{b}.{p}" for b in _bodies(robot) for p in BODY_PARAMETERS]
    names += [f"{j}.{p}" for p in JOINT_PARAMETERS for j in robot.joint_names]
    return tuple(names)


@checked_arguments
def parameters(robot: Robot) -> FloatArray:
    """The robot's full parameter vector (order of :func:`parameter_names`), SI units."""
    model = robot.model
    body = [np.asarray(model.inertias[j].toDynamicParameters()) for j in range(1, model.njoints)]
    p = robot.params
    return np.concatenate([*body, p.armature, p.viscous, p.coulomb])


@checked_arguments
def regressor(robot: Robot, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> FloatArray:
    """The stacked regressor W with ``tau = W pi`` (pi from :func:`parameters`).

    Rows: sample-major, joint-minor (row ``k nv + j`` is joint j at sample k). Pinocchio's
    joint-torque regressor, then diag(a), diag(v), diag(sign v) for the joint terms.

    Args:
        robot: The robot (its kinematics).
        q: Joint angles [rad], shape (m, nq) or (nq,).
        v: Joint velocities [rad/s], same shape.
        a: Joint accelerations [rad/s^2], same shape.
    """
    Q, V, A = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, v, a))
    model = robot.model
    data = model.createData()
    nv = model.nv
    nb = 10 * (model.njoints - 1)
    W = np.zeros((len(Q) * nv, nb + 3 * nv))
    idx = np.arange(nv)
    for k, (qk, vk, ak) in enumerate(zip(Q, V, A, strict=True)):
        rows = slice(k * nv, (k + 1) * nv)
        W[rows, :nb] = pin.computeJointTorqueRegressor(model, data, qk, vk, ak)
        block = W[rows]
        block[idx, nb + idx] = ak
        block[idx, nb + nv + idx] = vk
        block[idx, nb + 2 * nv + idx] = np.sign(vk)
    return W


_IDENTIFIABLE: dict[tuple[int, bytes], NDArray[np.intp]] = {}


@checked_arguments
def identifiable_columns(robot: Robot, rtol: float = 1e-8) -> NDArray[np.intp]:
    """Indices of a set of columns that spans the regressor's structural column space.

    From the regressor at 64 random states (fixed seed) scaled to unit columns, QR with
    column pivoting: the pivots whose diagonal entries exceed ``rtol`` of the first. Cached
    per model (its joint placements).
    """
    model = robot.model
    key = (id(model), b"".join(p.homogeneous.tobytes() for p in model.jointPlacements))
    if key not in _IDENTIFIABLE:
        rng = np.random.default_rng(0)
        p = robot.params
        m = 64
        q = rng.uniform(*p.sampling_bounds(), (m, robot.nq))
        v = rng.uniform(-1.0, 1.0, (m, robot.nq)) * p.velocity
        a = rng.uniform(-1.0, 1.0, (m, robot.nq)) * 5.0
        W = regressor(robot, q, v, a)
        norms = np.linalg.norm(W, axis=0)
        live = np.flatnonzero(norms > 0)
        _, R, piv = scipy.linalg.qr(W[:, live] / norms[live], mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        r = int(np.count_nonzero(d > rtol * d[0]))
        _IDENTIFIABLE.clear()
        _IDENTIFIABLE[key] = np.sort(live[piv[:r]])
    return _IDENTIFIABLE[key].copy()


@checked_arguments
def predict_torques(robot: Robot, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> FloatArray:
    """Joint torques [N*m] the robot's model needs for a motion: inverse dynamics plus friction.

    ``rnea(q, v, a)`` (armature included) ``+ viscous v + coulomb sign(v)``: the motor torque
    the simulator applies (before the joints' friction takes its share).

    Args:
        robot: The robot.
        q: Joint angles [rad], shape (m, nq).
        v: Joint velocities [rad/s], shape (m, nq).
        a: Joint accelerations [rad/s^2], shape (m, nq).

    Returns:
        Torques [N*m], shape (m, nq).
    """
    Q, V, A = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, v, a))
    model = robot.model
    data = model.createData()
    p = robot.params
    out = np.array([pin.rnea(model, data, qk, vk, ak) for qk, vk, ak in zip(Q, V, A, strict=True)])
    return out + p.viscous * V + p.coulomb * np.sign(V)


@checked_arguments
def with_parameters(robot: Robot, values: ArrayLike) -> Robot:
    """A copy of the robot with other parameters (order of :func:`parameter_names`).

    The bodies' inertias of its Pinocchio model, the armature (``model.armature`` and
    ``params.armature``, ``params.rotor_inertia`` = armature / gear_ratio^2), the viscous and
    Coulomb friction; the kinematics, collision model, poses and limits are shared.

    Raises:
        ConfigurationError: Not one finite value per parameter, or a body's parameters that
            are not physically consistent (a non-positive mass, an inertia that is not positive
            definite).
    """
    names = parameter_names(robot)
    x = real_array("values", values, shape=(len(names),), expected=f"{len(names)} finite values")
    model = pin.Model(robot.model)
    nb = model.njoints - 1
    for j in range(nb):
        pj = x[10 * j : 10 * j + 10]
        eig = np.linalg.eigvalsh(pin.PseudoInertia.FromDynamicParameters(pj).toMatrix())
        if pj[0] <= 0.0 or eig[0] < -1e-12 * abs(eig[-1]):
            raise ConfigurationError(
                f"values[{names[10 * j]}...]",
                pj.tolist(),
                "a physically consistent body: positive mass, positive-definite pseudo-inertia",
            )
        model.inertias[j + 1] = pin.Inertia.FromDynamicParameters(pj)
    nv = model.nv
    arm, visc, coul = (x[10 * nb + k * nv : 10 * nb + (k + 1) * nv] for k in range(3))
    for name, arr in (("armature", arm), ("viscous", visc), ("coulomb", coul)):
        if np.any(arr < 0.0):
            j = int(np.flatnonzero(arr < 0.0)[0])
            raise ConfigurationError(
                f"values[{robot.joint_names[j]}.{name}]", float(arr[j]), "a value >= 0"
            )
    p = robot.params
    params = dataclasses.replace(
        p,
        armature=arm.copy(),
        rotor_inertia=arm / p.gear_ratio**2,
        viscous=visc.copy(),
        coulomb=coul.copy(),
    )
    model.armature = arm.copy()
    return dataclasses.replace(
        robot, model=model, poses={k: v.copy() for k, v in robot.poses.items()}, params=params
    )


# --------------------------------------------------------------------------- log-Cholesky


def _log_cholesky(pi: FloatArray) -> FloatArray:
    """The log-Cholesky numbers of a body's ten parameters (inverse of Pinocchio's map)."""
    J = pin.PseudoInertia.FromDynamicParameters(pi).toMatrix()
    flip = J[::-1, ::-1]
    L = np.linalg.cholesky(flip)  # flip = L L^T, so J = U U^T with U = flip(L), upper
    U = L[::-1, ::-1]
    U = U / U[3, 3]
    alpha = 0.5 * math.log(J[3, 3])
    d = np.log(np.diag(U)[:3])
    return np.array([alpha, *d, U[0, 1], U[1, 2], U[0, 2], U[0, 3], U[1, 3], U[2, 3]])


def _from_log_cholesky(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A body's ten parameters and their Jacobian (10, 10) from its log-Cholesky numbers."""
    lc = pin.LogCholeskyParameters(theta)
    return np.asarray(lc.toDynamicParameters()), np.asarray(lc.calculateJacobian())


# --------------------------------------------------------------------------- the log


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class MotionLog:
    """A log of joint motion: what :func:`load_log` reads, what :func:`identify` takes.

    Attributes:
        t: Times [s], shape (N,), uniformly spaced.
        q: Joint angles [rad], shape (N, nq).
        v: Joint velocities [rad/s], shape (N, nq), or None (from q by the filter).
        tau: Joint torques [N*m], shape (N, nq), or None (then ``currents``).
        currents: Motor currents [A], shape (N, nq), or None.
    """

    t: FloatArray
    q: FloatArray
    v: FloatArray | None = None
    tau: FloatArray | None = None
    currents: FloatArray | None = None


def _column_names(robot: Robot) -> dict[str, list[str]]:
    names = robot.joint_names
    return {kind: [f"{kind}_{j}" for j in names] for kind in ("q", "v", "tau", "current")}


@checked_arguments
def load_log(robot: Robot, path: str | Path) -> MotionLog:
    """Read a CSV log: a header row, then one row per sample, comma separated.

    Columns (any order): ``time`` [s]; ``q_<joint>`` [rad] for every joint; optionally
    ``v_<joint>`` [rad/s] for every joint; ``tau_<joint>`` [N*m] or ``current_<joint>`` [A] for
    every joint (one of the two). Joint names as in ``robot.joint_names``.

    Raises:
        ResourceNotFound: No such file.
        ConfigurationError: An unknown or repeated column (the valid names are listed), a
            missing one, a cell that is not a finite number (row and column named), a row of
            another length, too few or too many rows.
    """
    p = Path(path)
    if not p.is_file():
        raise ResourceNotFound(p, "a CSV log of time, q_<joint>, tau_<joint> or current_<joint>")
    groups = _column_names(robot)
    valid = ["time"] + [c for cols in groups.values() for c in cols]
    with p.open(newline="") as f:
        reader = csv.reader(f)
        header = [h.strip() for h in next(reader, [])]
        if not header:
            raise ConfigurationError(f"{p}: header", header, "a header row naming the columns")
        for h in header:
            if h not in valid:
                raise ConfigurationError(f"{p}: column", h, valid)
            if header.count(h) > 1:
                raise ConfigurationError(f"{p}: column", h, "each column once")
        rows: list[list[float]] = []
        for line, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise ConfigurationError(
                    f"{p}: line {line}", len(row), f"{len(header)} cells, one per column"
                )
            vals = []
            for name, cell in zip(header, row, strict=True):
                try:
                    x = float(cell)
                except ValueError:
                    x = math.nan
                if not math.isfinite(x):
                    raise ConfigurationError(
                        f"{p}: line {line}, column {name}", cell, "a finite number"
                    )
                vals.append(x)
            rows.append(vals)
            if len(rows) > MAX_SAMPLES:
                raise ConfigurationError(
                    f"{p}: rows", f"> {MAX_SAMPLES}", f"at most {MAX_SAMPLES} samples"
                )
    data = np.array(rows, dtype=float).reshape(len(rows), len(header))
    col = {h: data[:, k] for k, h in enumerate(header)}
    if "time" not in col:
        raise ConfigurationError(f"{p}: columns", header, "a 'time' column [s]")

    def group(kind: str, required: bool) -> FloatArray | None:
        names = groups[kind]
        present = [c for c in names if c in col]
        if not present and not required:
            return None
        missing = [c for c in names if c not in col]
        if missing:
            raise ConfigurationError(
                f"{p}: columns", missing, f"every {kind}_<joint> column: {names}"
            )
        return np.stack([col[c] for c in names], axis=1)

    tau, cur = group("tau", False), group("current", False)
    if tau is not None and cur is not None:
        raise ConfigurationError(f"{p}: columns", "tau_* and current_*", "one of the two")
    if tau is None and cur is None:
        raise ConfigurationError(
            f"{p}: columns", header, "tau_<joint> [N*m] or current_<joint> [A] for every joint"
        )
    q = group("q", True)
    assert q is not None
    return MotionLog(t=col["time"], q=q, v=group("v", False), tau=tau, currents=cur)


# --------------------------------------------------------------------------- the fit


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Identification:
    """What :func:`identify` found: the identified robot, its parameters and the fit's quality.

    Attributes:
        robot: The identified robot (same API as :func:`packbot.load_robot`'s).
        names: Names of the full parameter vector (:func:`parameter_names`).
        values: The identified full parameters (SI units), physically consistent.
        nominal: The starting robot's full parameters.
        base_names: Each base parameter's leading parameter (a base parameter is it plus a
            combination of parameters not identifiable on their own: ``base_matrix``).
        base_matrix: B, shape (r, len(names)): base parameters = B @ full parameters; each row
            has a 1 at its leading parameter.
        base_values: The identified robot's base parameters (B @ values), leading units.
        base_estimate: The unconstrained weighted least-squares estimate of the base parameters.
        base_std: Standard deviations of ``base_estimate`` (from the residual and the regressor).
        condition_number: Condition number of the base regressor, columns scaled to unit norm.
        rank: Number of base parameters r.
        residual_rms: RMS torque residual of the identified model per joint [N*m], shape (nv,).
        relative_residual: ||tau - W values|| / ||tau|| over the fit's samples [-].
        noise_std: Each joint's torque residual standard deviation of the unweighted fit
            [N*m] (the weights are its inverse).
        samples: Samples in the fit (after trimming the ends and thinning to ``fit_dt``).
        window_samples: The Savitzky-Golay window [samples] (odd).
        dt: The log's sample spacing [s].
    """

    robot: Robot = field(repr=False)
    names: tuple[str, ...] = field(repr=False)
    values: FloatArray = field(repr=False)
    nominal: FloatArray = field(repr=False)
    base_names: tuple[str, ...] = field(repr=False)
    base_matrix: FloatArray = field(repr=False)
    base_values: FloatArray = field(repr=False)
    base_estimate: FloatArray = field(repr=False)
    base_std: FloatArray = field(repr=False)
    condition_number: float
    rank: int
    residual_rms: FloatArray
    relative_residual: float
    noise_std: FloatArray = field(repr=False)
    samples: int
    window_samples: int
    dt: float

    def parameter(self, name: str) -> float:
        """One identified parameter by name (``"link1.m"``, ``"shoulder.viscous"``).

        Raises:
            UnknownNameError: No parameter of that name.
        """
        from packbot.errors import UnknownNameError

        if name not in self.names:
            raise UnknownNameError("parameter", name, self.names)
        return float(self.values[self.names.index(name)])


def _series(field_name: str, x: ArrayLike | None, n: int, nq: int, unit: str) -> FloatArray:
    expected = f"an array of shape ({n}, {nq}) of finite values [{unit}], one row per time"
    arr = real_array(field_name, x, ndim=2, expected=expected)
    if arr.shape != (n, nq):
        raise ConfigurationError(field_name, arr.shape, expected)
    return arr


def _torque_constants(robot: Robot, kt: object) -> FloatArray:
    n = robot.nq
    expected = f"motor torque constants [N*m/A]: a positive number, {n} of them or {{joint: k_t}}"
    if isinstance(kt, Mapping):
        out = np.full(n, np.nan)
        for name, val in kt.items():
            out[robot.params.index(str(name))] = finite_number(
                f"torque_constant[{name}]", val, low=0.0, low_open=True, unit="N*m/A"
            )
        if np.any(np.isnan(out)):
            missing = [j for j, x in zip(robot.joint_names, out, strict=True) if np.isnan(x)]
            raise ConfigurationError("torque_constant", dict(kt), f"{expected}; missing {missing}")
        return out
    if kt is None:
        raise ConfigurationError("torque_constant", None, expected + " (needed with currents)")
    arr = np.atleast_1d(real_array("torque_constant", kt, expected=expected))
    arr = np.broadcast_to(arr, (n,)).copy() if arr.shape == (1,) else arr
    if arr.shape != (n,) or np.any(arr <= 0):
        raise ConfigurationError("torque_constant", kt, expected)
    return arr


def _base_fit(
    G: FloatArray, rank_rtol: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, float, float]:
    """Base parameters of the stacked factor G = [A | b].

    Returns:
        (B (r, p), beta_hat (r,), R1 (r, r) of the scaled columns, lead scales (r,),
        cov of the scaled base estimate / sigma^2 (r, r), residual^2, condition number).
    """
    p = G.shape[1] - 1
    A, b = G[:, :p], G[:, p]
    norms = np.linalg.norm(A, axis=0)
    live = np.flatnonzero(norms > 1e-300)
    Qm, R, piv = scipy.linalg.qr(A[:, live] / norms[live], mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.count_nonzero(d > rank_rtol * d[0]))
    R1, R2 = R[:r, :r], R[:r, r:]
    K = scipy.linalg.solve_triangular(R1, R2)
    qb = Qm.T @ b
    beta_s = scipy.linalg.solve_triangular(R1, qb[:r])
    lead, dep = live[piv[:r]], live[piv[r:]]
    B = np.zeros((r, p))
    B[np.arange(r), lead] = 1.0
    B[:, dep] = K * norms[dep][None, :] / norms[lead][:, None]
    res2 = max(float(b @ b - qb[:r] @ qb[:r]), 0.0)
    R1inv = scipy.linalg.solve_triangular(R1, np.eye(r))
    cond = float(np.linalg.cond(R1))
    return B, beta_s / norms[lead], R1, norms[lead], R1inv @ R1inv.T, res2, cond


def _consistent_fit(
    robot: Robot,
    Gd: FloatArray,
    hd: FloatArray,
    x0: FloatArray,
    prior_weight: float,
) -> FloatArray:
    """The physically consistent parameters minimising ||Gd pi - hd||^2 + prior (module doc).

    Unknowns: each body's log-Cholesky numbers, each joint term's logarithm (so armature and
    friction stay positive). Started from the linear fit with the same prior (a ridge
    regression) where it is consistent, and solved by Levenberg-Marquardt.
    """
    nb = robot.model.njoints - 1
    nj = 3 * robot.nq
    n_theta = 10 * nb
    theta0 = np.concatenate([_log_cholesky(x0[10 * j : 10 * j + 10]) for j in range(nb)])
    joint0 = np.maximum(x0[n_theta:], 1e-9 * max(float(np.max(x0[n_theta:])), 1e-300))
    z0 = np.concatenate([theta0, np.log(joint0)])
    prior = prior_weight * np.concatenate(
        [np.tile([1.0] * 4 + [1.0 / _PRIOR_LENGTH] * 6, nb), np.ones(nj)]
    )
    # warm start: the linear fit with a prior of the same strength on the parameters
    masses = np.repeat(x0[0:n_theta:10], 10)
    per_body = np.tile([1.0] + [_PRIOR_LENGTH] * 3 + [_PRIOR_LENGTH**2] * 6, nb)
    lin_scale = prior_weight / np.concatenate([masses * per_body, joint0])
    A = np.vstack([Gd, np.diag(lin_scale)])
    rhs = np.concatenate([hd, lin_scale * x0])
    lin = np.asarray(np.linalg.lstsq(A, rhs, rcond=None)[0], dtype=float)
    start = z0.copy()
    for j in range(nb):
        s = slice(10 * j, 10 * j + 10)
        with contextlib.suppress(np.linalg.LinAlgError, ValueError):  # else: from the nominal
            start[s] = _log_cholesky(lin[s])
    start[n_theta:] = np.log(np.maximum(lin[n_theta:], 1e-3 * joint0))

    def unpack(z: FloatArray) -> tuple[FloatArray, FloatArray]:
        pi = np.empty(n_theta + nj)
        jac = np.zeros((n_theta + nj, n_theta + nj))
        for j in range(nb):
            s = slice(10 * j, 10 * j + 10)
            pi[s], jac[s, s] = _from_log_cholesky(z[s])
        pi[n_theta:] = np.exp(z[n_theta:])
        jac[n_theta:, n_theta:] = np.diag(pi[n_theta:])
        return pi, jac

    def fun(z: FloatArray) -> FloatArray:
        pi, _ = unpack(z)
        return np.concatenate([Gd @ pi - hd, prior * (z - z0)])

    def jac(z: FloatArray) -> FloatArray:
        _, dpi = unpack(z)
        return np.vstack([Gd @ dpi, np.diag(prior)])

    import scipy.optimize  # here: ``import packbot`` leaves it unloaded (tests/test_startup.py)

    with np.errstate(over="ignore", invalid="ignore"):
        sol = scipy.optimize.least_squares(
            fun,
            start,
            jac=jac,
            method="lm",
            x_scale="jac",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=500,
        )
    log.debug("consistent fit: %s after %d evaluations, cost %.3g", sol.message, sol.nfev, sol.cost)
    return unpack(sol.x)[0]


@checked_arguments
def identify(
    robot: Robot,
    t: ArrayLike,
    q: ArrayLike,
    v: ArrayLike | None = None,
    tau: ArrayLike | None = None,
    *,
    currents: ArrayLike | None = None,
    torque_constant: ArrayLike | Mapping[str, float] | float | None = None,
    window: float = 0.5,
    polyorder: int = 4,
    fit_dt: float | None = None,
    rank_rtol: float = 1e-6,
    prior_weight: float = 1.0,
    weighted: bool = True,
) -> Identification:
    """Identify the inertial, armature and friction parameters from a log (module docstring).

    Args:
        robot: The nominal robot: its kinematics, and the prior of what the log cannot see.
        t: Times [s], shape (N,), uniformly spaced (within 1 %).
        q: Joint angles [rad], shape (N, nq).
        v: Joint velocities [rad/s], shape (N, nq), or None: from q by the filter.
        tau: Joint torques [N*m] (motor torque at the joint output), shape (N, nq); or None
            and ``currents``.
        currents: Motor currents [A], shape (N, nq): tau = gear_ratio * torque_constant * i.
        torque_constant: The motors' torque constants [N*m/A] (a number, nq numbers or
            {joint: k_t}); needed with ``currents``.
        window: Savitzky-Golay window [s] (rounded to an odd number of samples).
        polyorder: Savitzky-Golay polynomial degree (2 to 6, below the window's samples).
        fit_dt: Spacing of the samples in the fit [s]; None: every sample.
        rank_rtol: Relative threshold of the base parameters' QR diagonal.
        prior_weight: Inverse standard deviation of the prior towards the nominal model
            (log-Cholesky numbers: log mass and log diagonal, the other terms per 0.1 m; log
            joint terms), against the weighted base-parameter misfit.
        weighted: Weight each joint's rows by its inverse residual standard deviation.

    Returns:
        The identified robot, its parameters, base parameters with their standard deviations,
        the condition number and the residual.

    Raises:
        ConfigurationError: Shapes that disagree (names the field, its shape and the one
            expected), non-finite values, times that are not increasing and uniform, too few
            samples for the window or the parameters, both or neither of ``tau`` and
            ``currents``, a bad filter setting.
        UnknownNameError: A joint of ``torque_constant`` that the robot does not have.
    """
    ts = real_array("t", t, ndim=1, expected="times [s], shape (N,), increasing, uniform")
    n, nq = len(ts), robot.nq
    if n < 3:
        raise ConfigurationError("t", n, "at least 3 samples [s]")
    Q = _series("q", q, n, nq, "rad")
    V = None if v is None else _series("v", v, n, nq, "rad/s")
    if (tau is None) == (currents is None):
        raise ConfigurationError(
            "tau",
            "given with currents" if tau is not None else None,
            "joint torques [N*m] or motor currents [A] (with torque_constant): one of the two",
        )
    if tau is not None:
        TAU = _series("tau", tau, n, nq, "N*m")
        if torque_constant is not None:
            raise ConfigurationError(
                "torque_constant", torque_constant, "None with torques (it converts currents)"
            )
    else:
        kt = _torque_constants(robot, torque_constant)
        TAU = _series("currents", currents, n, nq, "A") * kt * robot.params.gear_ratio
    steps = np.diff(ts)
    dt = float(np.median(steps))
    if not dt > 0 or np.any(np.abs(steps - dt) > 0.01 * dt):
        raise ConfigurationError(
            "t",
            f"spacing {steps.min():.6g} to {steps.max():.6g} s",
            "increasing times, uniformly spaced (within 1 %): resample the log",
        )
    order = integer("polyorder", polyorder, low=2, high=6)
    win_s = finite_number("window", window, low=0.0, low_open=True, high=60.0, unit="s")
    w = round(win_s / dt) | 1
    if w < order + 3:
        raise ConfigurationError(
            "window", win_s, f"at least {(order + 3) * dt:.4g} s ({order + 3} samples of {dt:g} s)"
        )
    spacing = (
        dt if fit_dt is None else finite_number("fit_dt", fit_dt, low=0.0, low_open=True, unit="s")
    )
    rtol = finite_number("rank_rtol", rank_rtol, low=1e-14, high=0.1)
    prior_w = finite_number("prior_weight", prior_weight, low=0.0, low_open=True, high=1e6)
    use_weights = boolean("weighted", weighted)
    names = parameter_names(robot)
    p = len(names)
    step = max(1, round(spacing / dt))
    idx = np.arange(w // 2, n - w // 2, step)
    need = math.ceil(2 * p / nq)
    if len(idx) < need:
        raise ConfigurationError(
            "t",
            n,
            f"at least {need} samples after dropping {w // 2} at each end and thinning to "
            f"fit_dt = {spacing:g} s (about {need * step + w} samples)",
        )

    import scipy.signal  # here: it loads scipy.optimize

    def sg(x: FloatArray, deriv: int) -> FloatArray:
        return np.asarray(scipy.signal.savgol_filter(x, w, order, deriv=deriv, delta=dt, axis=0))

    qf = sg(Q, 0)
    vf, af = (sg(Q, 1), sg(Q, 2)) if V is None else (sg(V, 0), sg(V, 1))
    tf = TAU  # not filtered: a filter would smear Coulomb friction's jump at a reversal
    # per-joint triangular factors of [W_j | tau_j]
    R_aug = [np.zeros((0, p + 1)) for _ in range(nq)]
    for start in range(0, len(idx), _BLOCK):
        blk = idx[start : start + _BLOCK]
        W = regressor(robot, qf[blk], vf[blk], af[blk])
        for j in range(nq):
            aug = np.hstack([W[j::nq], tf[blk, j : j + 1]])
            R_aug[j] = np.asarray(np.linalg.qr(np.vstack([R_aug[j], aug]), mode="r"), dtype=float)
    tau_norm = np.array([np.linalg.norm(R[:, p]) for R in R_aug])

    def joint_residuals(x: FloatArray) -> FloatArray:
        xe = np.append(x, -1.0)
        return np.array([float(np.linalg.norm(R @ xe)) for R in R_aug])

    B, beta, _, _, _, _, _ = _base_fit(np.vstack(R_aug), rtol)
    res0 = joint_residuals(np.asarray(np.linalg.lstsq(B, beta, rcond=None)[0], dtype=float))
    noise = res0 / math.sqrt(len(idx))
    floor = _SIGMA_FLOOR * np.maximum(tau_norm / math.sqrt(len(idx)), 1e-300)
    weights = 1.0 / np.maximum(noise, floor) if use_weights else np.ones(nq)
    G = np.vstack([R * wj for R, wj in zip(R_aug, weights, strict=True)])
    B, beta, R1, lead_norm, cov_s, res2, cond = _base_fit(G, rtol)
    r = len(beta)
    dof = max(len(idx) * nq - r, 1)
    sigma2 = res2 / dof
    std = np.sqrt(np.maximum(np.diag(cov_s), 0.0) * sigma2) / lead_norm
    nominal = parameters(robot)
    Gd = R1 @ (B * lead_norm[:, None])
    values = _consistent_fit(
        robot, Gd, Gd @ np.zeros(p) + R1 @ (beta * lead_norm), nominal, prior_w
    )
    ident = with_parameters(robot, values)
    res = joint_residuals(values)
    lead = [names[int(np.flatnonzero(row == 1.0)[0])] for row in B]
    out = Identification(
        robot=ident,
        names=names,
        values=values,
        nominal=nominal,
        base_names=tuple(lead),
        base_matrix=B,
        base_values=B @ values,
        base_estimate=beta,
        base_std=std,
        condition_number=cond,
        rank=r,
        residual_rms=res / math.sqrt(len(idx)),
        relative_residual=float(np.linalg.norm(res) / max(np.linalg.norm(tau_norm), 1e-300)),
        noise_std=noise,
        samples=len(idx),
        window_samples=w,
        dt=dt,
    )
    log.info(
        "identified %d base parameters from %d samples: condition number %.3g, relative "
        "residual %.3g",
        r,
        len(idx),
        cond,
        out.relative_residual,
    )
    return out


@checked_arguments
def identify_csv(
    robot: Robot,
    path: str | Path,
    *,
    torque_constant: ArrayLike | Mapping[str, float] | float | None = None,
    window: float = 0.5,
    polyorder: int = 4,
    fit_dt: float | None = None,
    rank_rtol: float = 1e-6,
    prior_weight: float = 1.0,
    weighted: bool = True,
) -> Identification:
    """:func:`identify` on a CSV log (:func:`load_log` describes the columns).

    Args:
        robot: The nominal robot.
        path: The CSV file.
        torque_constant: The motors' torque constants [N*m/A], for a log of currents.
        window: Savitzky-Golay window [s].
        polyorder: Savitzky-Golay polynomial degree.
        fit_dt: Spacing of the samples in the fit [s]; None: every sample.
        rank_rtol: Relative threshold of the base parameters' QR diagonal.
        prior_weight: Inverse standard deviation of the prior towards the nominal model.
        weighted: Weight each joint's rows by its inverse residual standard deviation.

    Raises:
        ResourceNotFound: No such file.
        ConfigurationError: A bad column, cell or row (:func:`load_log`), or a bad log or
            option (:func:`identify`).
    """
    data = load_log(robot, path)
    return identify(
        robot,
        data.t,
        data.q,
        data.v,
        data.tau,
        currents=data.currents,
        torque_constant=torque_constant,
        window=window,
        polyorder=polyorder,
        fit_dt=fit_dt,
        rank_rtol=rank_rtol,
        prior_weight=prior_weight,
        weighted=weighted,
    )
