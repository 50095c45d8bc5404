"""Arms drawn within the parameter table's tolerances: the model's own uncertainty.

Every geometric and inertial entry of :mod:`packbot.params` carries a
:class:`~packbot.params.Tolerance` (docs/parameters.md, "Tolerances"). :func:`sample_values`
draws ``n`` points of those boxes, quasi-random (a scrambled Sobol sequence or a Latin
hypercube of :mod:`scipy.stats.qmc`, seeded: the same seed gives the same points), each entry
uniform on ``value +- tolerance``; :func:`robot_from_values` builds one arm from such values;
:func:`sample_robots` does both.

An arm is built by the same code as the nominal model: :func:`packbot.params.design` turns the
values into parts, joints and DH chains; :func:`packbot.urdfgen.build` writes its URDF and
convex meshes (the link inertias integrated by Coal over the very solids the collision model
uses); :func:`packbot.load_robot` loads and checks it. So link lengths move the joints and the
collision pieces together, and a tube's wall, radius or length changes its inertia. Masses follow
the report: a part it weighed keeps its drawn mass whatever its drawn size (the scale read it);
every other part (tubes, boards, tracks, flippers, the chassis body, palm and fingers: masses
the report estimated or does not list) is a solid of its material, its mass the drawn value
times its volume over its nominal volume, so a thicker or longer tube is heavier as well as
wider. Masses are positive and every link inertia physically valid by construction (sums of
uniform convex solids; :func:`packbot.load_robot` checks positive definiteness and the triangle
inequality).

What does not vary: the joints' limits, actuators and friction (no tolerance), the effort limits
(the nominal model's, derived from the lift capacity: a motor's torque is not a property of our
mass estimate), gravity, the part positions that are fixed numbers of
:func:`packbot.params.design`, and the SRDF's disabled collision pairs (the shipped file's).
"""

from __future__ import annotations

import atexit
import functools
import logging
import math
import os
import shutil
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from packbot import params as P
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.geometry import part_volume
from packbot.keywords import checked_arguments
from packbot.model import Robot, load_robot
from packbot.resources import DESCRIPTION_PACKAGE, srdf_path
from packbot.validation import at_most, choice, finite_number, integer

__all__ = [
    "MAX_SAMPLED_ROBOTS",
    "METHODS",
    "ParameterSample",
    "SampledRobots",
    "robot_from_values",
    "sample_robots",
    "sample_values",
]

log = logging.getLogger(__name__)

#: Most arms one call builds: each is a model, its collision pieces and a folder of meshes
#: (about 40 ms and 140 kB of files per arm); draw more values with :func:`sample_values` and
#: build them in parts.
MAX_SAMPLED_ROBOTS = 1_000
#: The largest point count :func:`sample_values` draws (values only: 16 bytes per point and
#: entry, its values and unit-cube points; about 150 MB for 90 entries).
MAX_SAMPLED_VALUES = 100_000
#: The quasi-random designs: a scrambled Sobol sequence (its first n points; n a power of 2
#: keeps its balance), or a Latin hypercube (every entry's n strata each hit once).
METHODS = ("sobol", "lhs")
#: Largest seed: a non-negative 63-bit integer.
SEED_MAX = 2**63 - 1


def _remove_at_exit(path: str, pid: int) -> None:
    """Remove a folder of arms when the process that made it exits (not a forked child)."""
    if os.getpid() == pid:
        shutil.rmtree(path, ignore_errors=True)


@dataclass(frozen=True)
class ParameterSample:
    """``n`` draws of the toleranced entries of the parameter table.

    Attributes:
        names: The drawn entries (the columns), in table order.
        values: The drawn values, shape (n, len(names)), SI units (each entry's unit).
        points: The quasi-random points in the unit cube they map from, same shape.
        seed: The seed that drew them.
        method: ``"sobol"`` or ``"lhs"``.
    """

    names: tuple[str, ...]
    values: NDArray[np.float64]
    points: NDArray[np.float64]
    seed: int
    method: str

    def __len__(self) -> int:
        return int(self.values.shape[0])

    @property
    def bounds(self) -> NDArray[np.float64]:
        """Each drawn entry's box ``[nominal - tol, nominal + tol]``, shape (len(names), 2)."""
        return np.array([_box(n) for n in self.names])

    @checked_arguments
    def column(self, name: str) -> NDArray[np.float64]:
        """One entry's draws, shape (n,).

        Raises:
            UnknownNameError: ``name`` is not one of :attr:`names`.
        """
        if name not in self.names:
            raise UnknownNameError("sampled parameter", name, self.names)
        return self.values[:, self.names.index(name)].copy()

    @checked_arguments
    def arm(self, k: int) -> dict[str, float]:
        """Arm ``k``'s values of every table entry (the undrawn ones nominal, derived recomputed).

        Raises:
            ConfigurationError: ``k`` is not an index of the sample.
        """
        k = integer("k", k, low=0, high=len(self) - 1, what="an arm index")
        values = P.nominal_values()
        values.update(zip(self.names, (float(x) for x in self.values[k]), strict=True))
        return _with_derived(values)

    def drawn(self, k: int) -> dict[str, float]:
        """Arm ``k``'s drawn values: the sampled entries only (the others stay nominal)."""
        return {n: float(x) for n, x in zip(self.names, self.values[k], strict=True)}

    def identity(self) -> dict[str, Any]:
        """What defines the draw, JSON-ready: size, seed, method and the drawn entries."""
        return {
            "samples": len(self),
            "seed": self.seed,
            "method": self.method,
            "vary": list(self.names),
        }


@dataclass(frozen=True)
class SampledRobots:
    """Arms drawn within the tolerances (:func:`sample_robots`): a sequence of :class:`Robot`.

    Attributes:
        sample: The drawn values (:class:`ParameterSample`).
        robots: The arms, arm ``k`` built from ``sample.arm(k)``.
        part_masses: Per arm, ``"link/part"`` -> the part's mass as built [kg].
    """

    sample: ParameterSample
    robots: tuple[Robot, ...]
    part_masses: tuple[dict[str, float], ...]

    def __len__(self) -> int:
        return len(self.robots)

    def __getitem__(self, k: int) -> Robot:
        return self.robots[k]

    def __iter__(self) -> Iterator[Robot]:
        return iter(self.robots)

    @checked_arguments
    def values(self, k: int) -> dict[str, float]:
        """Arm ``k``'s parameter values by name (every table entry, SI units)."""
        return self.sample.arm(k)


def _box(name: str) -> tuple[float, float]:
    p = P.TABLE[name]
    assert p.tolerance is not None
    return p.tolerance.bounds(p.value)


def _with_derived(values: dict[str, float]) -> dict[str, float]:
    values["chassis.wheel_radius"] = values["chassis.height"] / 2
    return values


def _names(vary: Iterable[str] | None) -> tuple[str, ...]:
    valid = P.toleranced()
    if vary is None:
        return valid
    if isinstance(vary, (str, bytes)) or not isinstance(vary, Iterable):
        raise ConfigurationError("vary", vary, "a list of parameter names with a tolerance")
    given = list(vary)
    at_most("vary", vary, len(given), len(valid), "names")
    for name in given:
        if name not in valid:
            raise UnknownNameError("toleranced parameter", name, valid)
    if not given:
        raise ConfigurationError("vary", vary, "at least one parameter name, or None for all")
    chosen = set(given)
    return tuple(n for n in valid if n in chosen)


def _unit_points(n: int, d: int, seed: int, method: str) -> NDArray[np.float64]:
    from scipy.stats import qmc  # lazy: scipy.stats costs ~0.3 s of import

    engine = qmc.Sobol if method == "sobol" else qmc.LatinHypercube
    rng = np.random.default_rng(seed)
    try:
        sampler = engine(d, scramble=True, rng=rng)
    except TypeError:  # scipy < 1.15 names the generator ``seed``
        sampler = engine(d, scramble=True, seed=rng)
    if method == "sobol":
        return np.asarray(sampler.random_base2(max(0, math.ceil(math.log2(n))))[:n], dtype=float)
    return np.asarray(sampler.random(n), dtype=float)


@checked_arguments
def sample_values(
    n: int,
    seed: int = 0,
    *,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
) -> ParameterSample:
    """Draw ``n`` points of the toleranced entries' boxes, quasi-random, without building arms.

    Each entry is uniform on its box ``value +- tolerance`` (docs/parameters.md, "Tolerances").

    Args:
        n: Number of draws (1 to :data:`MAX_SAMPLED_VALUES`).
        seed: Seed of the scrambling (a non-negative integer): the same seed, ``n``, ``vary``
            and ``method`` give the same values on any machine, for the same parameter table
            and SciPy release (an entry added to the table changes the draws).
        vary: The entries to draw (names of :func:`packbot.params.toleranced`); the others stay
            nominal. None: all of them.
        method: ``"sobol"`` (scrambled Sobol; n a power of 2 keeps its balance) or ``"lhs"``
            (Latin hypercube).

    Returns:
        The draws.

    Raises:
        ConfigurationError: ``n``, ``seed``, ``vary`` or ``method`` is invalid.
        UnknownNameError: A name in ``vary`` has no tolerance (or no entry).
    """
    n = integer("n", n, low=1, high=MAX_SAMPLED_VALUES, what="a number of arms")
    seed = integer("seed", seed, low=0, high=SEED_MAX, what="a non-negative integer seed")
    chosen = choice("method", method, METHODS)
    names = _names(vary)
    points = _unit_points(n, len(names), seed, chosen)
    box = np.array([_box(name) for name in names])
    values = box[:, 0] + points * (box[:, 1] - box[:, 0])
    points.flags.writeable = False  # a sample is a record: the same seed, the same values
    values.flags.writeable = False
    return ParameterSample(names, values, points, seed, chosen)


@functools.cache
def _nominal_effort() -> dict[str, float]:
    from packbot.urdfgen import derived_efforts  # lazy: the generator stays out of `import packbot`

    return derived_efforts(P.NOMINAL)


@functools.cache
def _nominal_volumes() -> dict[tuple[str, str], float]:
    return {(link.name, p.name): part_volume(p) for link in P.LINKS for p in link.parts}


def _solid_masses(design: P.Design) -> P.Design:
    """The design with every part the report did not weigh weighing in with its volume."""
    nominal = _nominal_volumes()
    links = []
    for link in design.links:
        parts = []
        for part in link.parts:
            tol = P.TABLE[part.mass_name].tolerance if part.mass_name else None
            if tol is not None and tol.basis != "weighed":
                scale = part_volume(part) / nominal[(link.name, part.name)]
                part = replace(part, mass=part.mass * scale)
            parts.append(part)
        links.append(replace(link, parts=tuple(parts)))
    return replace(design, links=tuple(links))


def _checked_values(values: Any) -> dict[str, float]:
    if not isinstance(values, Mapping):
        raise ConfigurationError("values", values, "a {parameter name: value} table")
    valid = P.toleranced()
    out = P.nominal_values()
    for name, val in values.items():
        if name == "chassis.wheel_radius":
            continue  # derived: chassis.height / 2
        if name not in valid:
            raise UnknownNameError("toleranced parameter", name, valid)
        unit = P.TABLE[name].unit
        low = None if name == "chassis.arm_mount_x" else 0.0
        out[name] = finite_number(name, val, low=low, low_open=True, unit=unit)
    for link in ("link1", "link2", "link3"):
        if not out["link.tube_wall"] < out[f"{link}.tube_radius"]:
            raise ConfigurationError(
                "link.tube_wall", out["link.tube_wall"], f"less than {link}.tube_radius [m]"
            )
    return _with_derived(out)


def _build(values: dict[str, float], folder: Path) -> tuple[Robot, dict[str, float]]:
    from packbot.urdfgen import build, write_package  # lazy, as above

    design = _solid_masses(P.design(values))
    gen = build(design, effort=_nominal_effort(), docs=False)
    urdf = write_package(gen, folder / DESCRIPTION_PACKAGE, srdf_path())
    robot = load_robot(urdf)
    table = {n: replace(p, value=values[n]) for n, p in P.TABLE.items()}
    robot.params = replace(robot.params, table=table)
    masses = {f"{link.name}/{p.name}": p.mass for link in design.links for p in link.parts}
    return robot, masses


def _folder(directory: Any) -> Path:
    if directory is None:
        tmp = tempfile.mkdtemp(prefix="packbot-arms-")
        atexit.register(_remove_at_exit, tmp, os.getpid())
        return Path(tmp)
    if not isinstance(directory, (str, Path)):
        raise ConfigurationError(
            "directory", directory, "a folder path, or None for a temporary one"
        )
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise ConfigurationError("directory", directory, "a folder (this is a file)")
    path.mkdir(parents=True, exist_ok=True)
    return path


@checked_arguments
def robot_from_values(values: Mapping[str, float], *, directory: str | Path | None = None) -> Robot:
    """Build one arm from values of the toleranced entries (the others nominal).

    Args:
        values: Parameter name -> value (SI units), names of :func:`packbot.params.toleranced`
            (``chassis.wheel_radius``, derived, is ignored); e.g. ``sample.arm(k)``.
        directory: Folder to write the arm's description package into (``packbot/`` in it);
            None: a temporary folder removed when the interpreter exits.

    Returns:
        The arm: a :class:`Robot` like ``load_robot()``'s, its ``params.table`` holding these
        values (each entry's ``tolerance`` is still the nominal box's half-width: the box is
        around :data:`packbot.params.TABLE`'s value, not around the drawn one).

    Raises:
        ConfigurationError: ``values`` is not a table, a value is not a positive finite number
            (``chassis.arm_mount_x`` may be negative), a tube's wall is not thinner than its
            radius, or ``directory`` is not a folder path.
        UnknownNameError: A name that has no tolerance (or no entry).
    """
    checked = _checked_values(values)
    return _build(checked, _folder(directory))[0]


@checked_arguments
def sample_robots(
    n: int,
    seed: int = 0,
    *,
    vary: Iterable[str] | None = None,
    method: Literal["sobol", "lhs"] = "sobol",
    directory: str | Path | None = None,
) -> SampledRobots:
    """Draw ``n`` arms within the parameter table's tolerances.

    Example::

        arms = packbot.sample_robots(8, seed=1)
        arms[0].joint_names  # the nominal arm's joints
        arms.values(0)["link1.length"]  # arm 0's link 1 [m]

    Args:
        n: Number of arms (1 to :data:`MAX_SAMPLED_ROBOTS`).
        seed: Seed (a non-negative integer): the same seed, ``n``, ``vary`` and ``method`` give
            the same arms.
        vary: The entries to draw (see :func:`sample_values`); None: every toleranced entry.
        method: ``"sobol"`` or ``"lhs"`` (see :func:`sample_values`).
        directory: Folder for the arms' description packages (``arm_0000/packbot/`` ...);
            None: a temporary folder removed when the interpreter exits.

    Returns:
        The arms, their drawn values and their parts' masses.

    Raises:
        ConfigurationError: ``n``, ``seed``, ``vary``, ``method`` or ``directory`` is invalid.
        UnknownNameError: A name in ``vary`` has no tolerance (or no entry).
    """
    n = integer("n", n, low=1, high=MAX_SAMPLED_ROBOTS, what="a number of arms")
    sample = sample_values(n, seed, vary=vary, method=method)
    folder = _folder(directory)
    start = time.perf_counter()
    robots, masses = [], []
    for k in range(n):
        robot, m = _build(sample.arm(k), folder / f"arm_{k:04d}")
        robots.append(robot)
        masses.append(m)
    log.info(
        "sampled %d arms (%s, seed %d, %d entries) in %.2f s under %s",
        n,
        sample.method,
        sample.seed,
        len(sample.names),
        time.perf_counter() - start,
        folder,
    )
    return SampledRobots(sample, tuple(robots), tuple(masses))
