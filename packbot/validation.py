"""Small checks shared by the constructors: numbers, flags, choices, names and vectors.

Each check returns the value normalised (a Python ``float``, ``int``, ``bool``, ``str``, tuple or
float array) or raises :class:`~packbot.errors.ConfigurationError` naming the field, the value
and what a valid value looks like. The rules are the same everywhere:

- a number is an ``int`` or a ``float``, or a NumPy integer or floating scalar (``np.float64``,
  ``np.int64``); an int is accepted where a float is expected;
- a ``bool`` is not a number (``True`` is not 1), and ``complex``, ``str`` and ``None`` are not
  numbers either;
- a string is not a list of names (``"camera_tilt"`` is not ``("camera_tilt",)``);
- a vector is a list, tuple or array of numbers of the right shape (no bools, no strings).

The limits that protect the machine (samples, control ticks, forced steps, events per run, and
every other size a user can ask for: sampled configurations, obstacles, convex vertices, matrix
runs, workers, TOML nesting, file sizes, name lengths) are here too, each derived from what one
unit costs; docs/simulator.md ("Limits") lists them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError, UnknownNameError

__all__ = [
    "CONTROL_DT_MIN",
    "GRAVITY_MAX",
    "MAX_CONFIG_SAMPLES",
    "MAX_CONVEX_POINTS",
    "MAX_EVENTS_LIMIT",
    "MAX_IK_ITERATIONS",
    "MAX_MATRIX_RUNS",
    "MAX_NAME_LENGTH",
    "MAX_OBSTACLES",
    "MAX_OCCLUSION_TARGETS",
    "MAX_SAMPLES",
    "MAX_SCAN_SAMPLES",
    "MAX_STEPS",
    "MAX_STEP_MIN",
    "MAX_STUDY_CELLS",
    "MAX_TOML_BYTES",
    "MAX_TOML_DEPTH",
    "MAX_VOLUME_POINTS",
    "MAX_WAYPOINTS",
    "MAX_WORKERS",
    "RTOL_MAX",
    "RTOL_MIN",
    "SAMPLE_DT_MIN",
    "V0_MAX",
    "at_most",
    "boolean",
    "choice",
    "expected_number",
    "finite_number",
    "integer",
    "is_number",
    "joint_names",
    "name_str",
    "real_array",
    "vector",
]

FloatArray = NDArray[np.float64]

#: Most samples a run may keep: ``duration / sample_dt`` above this is refused before the run
#: starts. A sample takes about 1.7 kB while the run lasts (its arrays, before the result packs
#: them into 0.4 kB) and about 80 us to record, so the cap is under 1 GB and a minute.
MAX_SAMPLES = 500_000
#: Most control ticks (``duration / controller.dt``) or forced steps (``duration / max_step``)
#: a run may need: each costs at least one integration step (a tick about 0.2 ms with
#: collisions on, a free step about 0.05 ms), so the cap is a few minutes of computation.
MAX_STEPS = 1_000_000
#: Largest accepted ``SimConfig.max_events``: each event keeps two samples and its record
#: (about 4 kB), so the cap is under 0.5 GB.
MAX_EVENTS_LIMIT = 100_000
#: Most configurations a sampling analysis may draw (``analysis.workspace(samples=...)``, a
#: study's ``workspace_samples``, ``packbot generate-srdf --samples``): each is a collision test
#: of every pair (about 0.26 ms) and a kept sample takes about 230 B, so the cap is about four
#: minutes and 230 MB (10**9 samples used to grow past 2.5 GB).
MAX_CONFIG_SAMPLES = 1_000_000
#: Most angles of a loose joint's scan (``analysis.loose_joint_equilibria(samples=...)``): each
#: is a gravity-torque evaluation (about 10 us) and about 50 B, and the roots are refined by
#: Brent's method to 1e-12 rad anyway, so a finer scan finds nothing more: 10 s and 50 MB.
MAX_SCAN_SAMPLES = 1_000_000
#: Most points of a Monte Carlo volume estimate (``max_points`` and ``batch`` of
#: ``analysis.monte_carlo_volume`` and ``reachable_volume``): a point of ``reachable_volume`` is
#: an IK test (about 10 ms), so the cap is about 15 minutes; a batch holds 24 B per point.
MAX_VOLUME_POINTS = 100_000
#: Most iterations of a position IK solve (``max_iter``): an iteration is a Jacobian and a
#: damped solve (about 0.3 ms), so a solve stops within 3 s; it converges in tens.
MAX_IK_ITERATIONS = 10_000
#: Most obstacles of an environment: each adds about 20 collision pairs (one per link piece),
#: about 4 ms to build the collision world and about 3 ms per simulated second of a collapse
#: (the broad phase sweeps every pair at each step), so 1,000 obstacles cost about 4 s and 3 s
#: per simulated second (5,000 used to run for minutes).
MAX_OBSTACLES = 1_000
#: Most vertices of a convex obstacle: building its hull and the collision world takes about
#: 0.15 ms per vertex (1.7 s at the cap; 100,000 vertices took 15 s).
MAX_CONVEX_POINTS = 10_000
#: Most occlusion targets (``[outputs.occlusion] targets``): each is a line-of-sight query per
#: sample (about 1.7 ms), so 100 targets over a 5 s run sampled at 100 Hz take about 90 s.
MAX_OCCLUSION_TARGETS = 100
#: Most waypoints of a joint trajectory: one per control tick of the longest run a controller
#: may take (:data:`MAX_STEPS`); more could not be followed.
MAX_WAYPOINTS = MAX_STEPS
#: Most runs of a matrix (the product of its axes' lengths, plus its ``[[include]]`` tables),
#: checked before it is expanded: a run is a simulation (about 0.3 s with its process and
#: files, at least) and about 20 kB of files and 5 kB of expanded scenario, so the cap is about
#: an hour of one core and 200 MB (a product of six axes of 100 values used to expand forever).
MAX_MATRIX_RUNS = 10_000
#: Most cells of a study matrix: a cell is a study (healthy, failed and reconfigured runs and a
#: workspace: about 10 s, the shipped ``study-frozen-elbows`` takes 40 s for 4), so the cap is
#: about three hours of one core.
MAX_STUDY_CELLS = 1_000
#: Most worker processes of a batch: each holds the robot and its collision world (about
#: 100 MB), so 64 workers take about 6.4 GB; more than the machine's cores only wait.
MAX_WORKERS = 64
#: Deepest nesting of a scenario or matrix file (tables and arrays): the deepest a file needs
#: is 5 (``outputs.occlusion.targets``, a list of points); deeper input used to exhaust the
#: parser's recursion (a RecursionError and 3,000 lines of traceback). 32 is also NumPy's
#: dimension limit.
MAX_TOML_DEPTH = 32
#: Largest scenario or matrix file [bytes]: the TOML parser reads about 0.35 MB/s of obstacle
#: tables, so 1 MB is about 3 s; it holds 1,000 box obstacles (100 kB) or a convex obstacle of
#: 10,000 vertices (300 kB). The shipped files are under 5 kB.
MAX_TOML_BYTES = 1_000_000
#: Longest name (an obstacle, a frame, a joint, a scenario or matrix) [characters]: names become
#: parts of file names (at most 255 bytes on ext4, APFS and NTFS, with suffixes such as
#: ``_occlusion.svg``) and of one-line messages.
MAX_NAME_LENGTH = 100
#: Smallest sampling interval [s]: sample times are matched to 1e-12 s, and the state just before
#: and after every event is sampled anyway.
SAMPLE_DT_MIN = 1e-6
#: Smallest control period [s] (1 MHz; an arm's joint loops run at about 1 kHz).
CONTROL_DT_MIN = 1e-6
#: Smallest ``max_step`` [s]: 1000 times the stepper's smallest step ``h_min`` = 1e-12 s, so that
#: its error control has room.
MAX_STEP_MIN = 1e-9
#: Relative tolerance range of the integrator [-]: below 1e-13 (about 500 machine epsilons) the
#: local error estimate is rounding noise; above 0.1 it controls nothing.
RTOL_MIN, RTOL_MAX = 1e-13, 0.1
#: Largest gravity [m/s^2] (about 10 g): more is a unit mistake (cm/s^2), not a slope or a planet.
GRAVITY_MAX = 100.0
#: Largest initial joint speed [rad/s]: 50 times the fastest joint's velocity limit (2 rad/s); an
#: arm falling from its highest pose reaches a few rad/s, so more is a unit mistake (deg/s, rpm).
V0_MAX = 100.0


def is_number(x: object) -> bool:
    """Whether x is a real number: int, float or a NumPy integer/floating scalar, not a bool."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(
        x, (bool, np.bool_)
    )


def _fmt(x: float) -> str:
    if isinstance(x, int):
        return f"{x:,}"
    return f"{x:.6g}"


def _range_text(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    if low is not None and high is not None:
        return f"in {'(' if low_open else '['}{_fmt(low)}, {_fmt(high)}{')' if high_open else ']'}"
    if low is not None:
        return f"{'>' if low_open else '>='} {_fmt(low)}"
    if high is not None:
        return f"{'<' if high_open else '<='} {_fmt(high)}"
    return ""


def expected_number(
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
    what: str = "a finite number",
) -> str:
    """The description of a valid number used in error messages ("a finite number > 0 [s]")."""
    text = " ".join(p for p in (what, _range_text(low, high, low_open, high_open)) if p)
    return f"{text} [{unit}]" if unit else text


def finite_number(
    field: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
    what: str = "a finite number",
) -> float:
    """A finite real number within a range, as a float.

    Args:
        field: Name of the field, for the error message.
        value: The value given.
        low: Lower bound (None: none).
        high: Upper bound (None: none).
        low_open: Whether the lower bound is excluded.
        high_open: Whether the upper bound is excluded.
        unit: Unit of the value, for the message ("s", "m", "rad").
        what: What a valid value is, for the message ("a finite time").

    Raises:
        ConfigurationError: Not a number (bool, str, complex, None...), not finite, or out of
            the range.
    """
    expected = expected_number(
        low=low, high=high, low_open=low_open, high_open=high_open, unit=unit, what=what
    )
    if not is_number(value):
        raise ConfigurationError(field, value, expected)
    try:
        x = float(value)
    except OverflowError:  # an int beyond the float range
        raise ConfigurationError(field, value, expected) from None
    if not math.isfinite(x):
        raise ConfigurationError(field, value, expected)
    if low is not None and (x < low or (low_open and x == low)):
        raise ConfigurationError(field, value, expected)
    if high is not None and (x > high or (high_open and x == high)):
        raise ConfigurationError(field, value, expected)
    return x


def integer(
    field: str,
    value: Any,
    *,
    low: int | None = None,
    high: int | None = None,
    what: str = "an integer",
) -> int:
    """An integer (int or NumPy integer, not a bool nor a float) within [low, high].

    Raises:
        ConfigurationError: Not an integer or out of the range.
    """
    expected = " ".join(p for p in (what, _range_text(low, high, False, False)) if p)
    if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)):
        raise ConfigurationError(field, value, expected)
    n = int(value)
    if (low is not None and n < low) or (high is not None and n > high):
        raise ConfigurationError(field, value, expected)
    return n


def boolean(field: str, value: Any) -> bool:
    """A flag: ``True`` or ``False`` (or a NumPy bool); 0, 1, "yes" are refused.

    Raises:
        ConfigurationError: Not a bool.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigurationError(field, value, "true or false")
    return bool(value)


def choice(field: str, value: Any, valid: Sequence[str]) -> str:
    """One of the valid strings.

    Raises:
        ConfigurationError: Not one of ``valid`` (they are listed).
    """
    if not isinstance(value, str) or value not in valid:
        raise ConfigurationError(field, value, valid)
    return str(value)


def name_str(field: str, value: Any, what: str = "a non-empty name (a string)") -> str:
    """A non-empty string of at most :data:`MAX_NAME_LENGTH` characters.

    Raises:
        ConfigurationError: Not a string, empty, or too long.
    """
    if not isinstance(value, str) or not value:
        raise ConfigurationError(field, value, what)
    if len(value) > MAX_NAME_LENGTH:
        raise ConfigurationError(field, value, f"{what}, at most {MAX_NAME_LENGTH} characters")
    return str(value)


def at_most(field: str, value: Any, n: int, high: int, what: str) -> None:
    """Refuse a collection of ``n`` items when ``n > high`` (``what``: the items, plural).

    Raises:
        ConfigurationError: More than ``high`` items; the value is shown shortened.
    """
    if n > high:
        raise ConfigurationError(field, value, f"at most {high:,} {what} (got {n:,})")


def joint_names(field: str, value: Any, valid: Iterable[str] | None = None) -> tuple[str, ...]:
    """A tuple of distinct joint names (a list is accepted; a single string is not).

    Args:
        field: Name of the field.
        value: The names given.
        valid: The valid joint names, or None (only the form is checked).

    Raises:
        ConfigurationError: A string, not a list, a name that is not a string, or a name given
            twice.
        UnknownNameError: A name not in ``valid`` (they are listed).
    """
    if isinstance(value, str):
        raise ConfigurationError(
            field,
            value,
            f"a tuple of joint names, not a string: write ({value!r},) for one joint",
        )
    if not isinstance(value, (list, tuple)):
        raise ConfigurationError(field, value, "a tuple of joint names (strings)")
    out: list[str] = []
    for k, x in enumerate(value):
        if not isinstance(x, str) or not x:
            raise ConfigurationError(f"{field}[{k}]", x, "a joint name (a non-empty string)")
        if x in out:
            raise ConfigurationError(
                field, tuple(value), f"each joint at most once ({x!r} is given twice)"
            )
        out.append(str(x))
    if valid is not None:
        names = list(valid)
        for x in out:
            if x not in names:
                raise UnknownNameError("joint", x, names)
    return tuple(out)


def _has_non_number_leaf(value: Any, depth: int = 0) -> bool:
    """Whether a nested list/tuple holds a bool, a complex, a string or None.

    Nesting deeper than :data:`MAX_TOML_DEPTH` (NumPy's dimension limit) counts as such a leaf.
    """
    if isinstance(value, (list, tuple)):
        if depth >= MAX_TOML_DEPTH:
            return True
        return any(_has_non_number_leaf(x, depth + 1) for x in value)
    return not (is_number(value) or isinstance(value, np.ndarray))


def real_array(
    field: str,
    value: Any,
    *,
    shape: tuple[int, ...] | None = None,
    ndim: int | None = None,
    expected: str = "an array of finite numbers",
    shape_error_value: bool = False,
) -> FloatArray:
    """A float array of finite real numbers (ints accepted; bools, complex, strings refused).

    Args:
        field: Name of the field.
        value: A list, tuple or array.
        shape: The required shape, or None.
        ndim: The required number of dimensions, or None.
        expected: What a valid value is, for the message.
        shape_error_value: Report a wrong shape with the shape as the value (``q0=(7,)``).

    Raises:
        ConfigurationError: Not numbers, ragged, the wrong shape, or not finite.
    """
    if value is None or isinstance(value, (str, bytes, Mapping)) or is_number(value):
        if shape_error_value and is_number(value):
            raise ConfigurationError(field, (), expected)
        raise ConfigurationError(field, value, expected)
    if isinstance(value, (list, tuple)) and _has_non_number_leaf(value):
        raise ConfigurationError(field, value, expected)
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting, or an object numpy cannot take
        raise ConfigurationError(field, value, expected) from None
    if arr.dtype.kind == "O":
        if not all(is_number(x) for x in arr.flat):
            raise ConfigurationError(field, value, expected)
        try:
            arr = arr.astype(float)
        except (OverflowError, TypeError, ValueError):
            raise ConfigurationError(field, value, expected) from None
    elif arr.dtype.kind not in "iuf":  # bool, complex, strings, dates...
        raise ConfigurationError(field, value, expected)
    arr = np.array(arr, dtype=float)
    if (shape is not None and arr.shape != shape) or (ndim is not None and arr.ndim != ndim):
        raise ConfigurationError(field, arr.shape if shape_error_value else value, expected)
    if not np.all(np.isfinite(arr)):
        raise ConfigurationError(
            field, arr.tolist() if shape_error_value else value, f"{expected} (finite values)"
        )
    return arr


def vector(
    field: str, value: Any, n: int, *, bound: float | None = None, unit: str = ""
) -> tuple[float, ...]:
    """A tuple of n finite numbers, each within +/- bound if given.

    Raises:
        ConfigurationError: Not n finite numbers, or one beyond the bound.
    """
    expected = f"{n} finite numbers"
    if bound is not None:
        expected += f", each within +/-{_fmt(bound)}"
    if unit:
        expected += f" [{unit}]"
    arr = real_array(field, value, shape=(n,), expected=expected)
    if bound is not None and np.any(np.abs(arr) > bound):
        raise ConfigurationError(field, value, expected)
    return tuple(float(x) for x in arr)
