"""Scenario matrices: a base scenario expanded over lists of values into runs with stable ids.

A matrix file (TOML, shipped in ``sims/matrices/``) names a base scenario and the values to
sweep; every field of the scenario is addressed by its dotted name (``config.restitution``,
``failures.0.kind``: list items by their index)::

    name = "collapse-small"            # optional; default: the file's stem
    description = "The collapse over restitution and contact mode"
    base = "collapse"                  # a scenario name in sims/, or a path (relative to here)

    [set]                              # overrides applied to every run
    duration = 1.0

    [axes]                             # the runs are the Cartesian product of these lists
    "config.restitution" = [0.0, 0.3]
    "config.contact_mode" = ["joint_clamp", "none"]
    "failures.0.kind" = ["loose", "frozen"]

    [[include]]                        # extra runs, each a table of overrides
    "config.restitution" = 0.9

    [[exclude]]                        # drop the product's runs matching all keys of one table
    "config.contact_mode" = "none"
    "config.restitution" = 0.3

    [tolerances]                       # regression tolerances (see packbot.tolerances.Tolerances)
    q = 1e-6

    [study]                            # a study matrix: each run is a failure study
    tolerance = 0.01                   # (packbot.study_matrix.StudyOptions; docs/study.md)

Keys may be quoted dotted names or TOML's bare dotted keys (``config.restitution = [...]``, which
TOML reads as nested tables); both mean the same field. Tables are merged, never replaced: an
override sets the leaves it names. A list index may address the next item of a list
(``failures.0.joint`` on a scenario without failures), which appends a new table.

Each run's id is a readable slug of its parameters plus the first 10 hex digits of the SHA-256 of
their canonical JSON (sorted keys, no spaces). It depends on the parameters only: reordering the
axes or adding values to them keeps the ids of the existing runs. TOML's ``0`` and ``0.0`` are
different values (an integer and a float) and give different ids.

A ``[study]`` table makes it a *study matrix*: each run is a failure study of its scenario
(:mod:`packbot.study_matrix`, ``packbot study MATRIX``); this module only checks that the table's
values are JSON values (:mod:`packbot.study_matrix` checks its keys and values).

A matrix's identity is its :meth:`Matrix.canonical` form (name, base, ``[set]``, the axes in
their order, includes, excludes, a ``[study]`` table; not the description, the tolerances,
comments or layout): a
batch folder holds the runs of one matrix, and :func:`packbot.batch.run_batch` refuses another.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from packbot import tomlfile
from packbot.errors import ConfigurationError, ResourceNotFound, UnknownNameError
from packbot.keywords import checked_arguments
from packbot.tolerances import Tolerances
from packbot.validation import MAX_MATRIX_RUNS, at_most, name_str

if TYPE_CHECKING:
    from packbot.scenario import Scenario

__all__ = [
    "MATRIX_FORMAT",
    "MATRIX_KEYS",
    "Matrix",
    "Run",
    "apply_overrides",
    "canonical_json",
    "digest",
    "expand",
    "find_matrix",
    "load_matrix",
    "matrix_names",
    "parse_matrix",
    "run_id",
    "set_dotted",
]

#: The valid top-level keys of a matrix file.
MATRIX_KEYS: tuple[str, ...] = (
    "name",
    "description",
    "base",
    "set",
    "axes",
    "include",
    "exclude",
    "tolerances",
    "study",
)

#: Format tag of a matrix's canonical form (:meth:`Matrix.canonical`).
MATRIX_FORMAT = "packbot-matrix/1"

_COMPONENT = re.compile(r"^[A-Za-z0-9_\-]+$")
_SLUG_CHARS = re.compile(r"[^A-Za-z0-9.+\-]+")
_SLUG_MAX = 80
_HASH_DIGITS = 10


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Run:
    """One run of a matrix: the base scenario with its overrides applied.

    Attributes:
        id: Stable id: a slug of the parameters and a hash of their canonical JSON.
        index: Position in the matrix's expansion (product order, then includes).
        params: The run's own overrides (axis values, or an include table), dotted name ->
            value, in axis order.
        scenario: The resolved raw scenario dict (base, then ``[set]``, then ``params``), ready
            for :func:`packbot.scenario.scenario_from_dict`.
        scenario_name: The base scenario's name.
        digest: SHA-256 of the canonical JSON of ``scenario``: a stored result whose digest
            differs was made from another scenario and is stale.
        source_text: The base scenario file's text followed by the overrides as comments
            (stored with the run's trajectory).
        source_path: The base scenario file, whose folder the scenario's relative paths (its
            ``robot``'s URDF, SRDF, package folders) are taken from; None: the working
            directory. Not part of ``digest``: the same scenario read from another folder is
            the same run.
    """

    id: str
    index: int
    params: dict[str, Any]
    scenario: dict[str, Any]
    scenario_name: str
    digest: str
    source_text: str = ""
    source_path: str | None = None

    def build_scenario(self) -> Scenario:
        """The run's :class:`~packbot.scenario.Scenario` (keys and values checked).

        Raises:
            ConfigurationError: A bad key or value (names its dotted path).
        """
        from packbot.scenario import scenario_from_dict

        scenario = scenario_from_dict(self.scenario, name=self.id, source_text=self.source_text)
        if self.source_path is not None:
            scenario.source_path = Path(self.source_path)
        return scenario


@checked_arguments
@dataclass(kw_only=True)
class Matrix:
    """A matrix file: a base scenario and the values to sweep.

    Attributes:
        name: Name of the matrix (the golden results live in ``<golden>/<name>/``).
        base: The base scenario: a name in ``sims/`` or a path.
        description: One line on what the matrix studies.
        fixed: Overrides applied to every run (the file's ``[set]``), dotted name -> value.
        axes: Dotted name -> the list of its values; the runs are their Cartesian product.
        include: Extra runs, each a table of overrides (dotted name -> value).
        exclude: Tables of dotted name -> value; a product run matching every key of one of
            them is dropped.
        tolerances: Regression tolerances, name -> value (see
            :class:`packbot.tolerances.Tolerances`).
        study: The ``[study]`` table of a study matrix (its cells are failure studies: see
            :class:`packbot.study_matrix.StudyOptions`; an empty ``[study]`` table: the default
            options); None for a matrix of simulations.
        path: The file it was read from, if any (a relative ``base`` is resolved beside it).
        source_text: The file's text.
    """

    name: str
    base: str
    description: str = ""
    fixed: dict[str, Any] = field(default_factory=dict)
    axes: dict[str, list[Any]] = field(default_factory=dict)
    include: list[dict[str, Any]] = field(default_factory=list)
    exclude: list[dict[str, Any]] = field(default_factory=list)
    tolerances: dict[str, float] = field(default_factory=dict)
    study: dict[str, Any] | None = None
    path: Path | None = None
    source_text: str = ""

    def validate(self) -> None:
        """Check every field; raise :class:`ConfigurationError` naming the first bad one."""
        if not isinstance(self.name, str) or not _COMPONENT.match(self.name):
            raise ConfigurationError(
                "name", self.name, "a non-empty name of letters, digits, '_' and '-'"
            )
        name_str("name", self.name, "a name of letters, digits, '_' and '-'")
        if not isinstance(self.base, str) or not self.base:
            raise ConfigurationError("base", self.base, "a scenario name or path")
        if not isinstance(self.description, str):
            raise ConfigurationError("description", self.description, "a string")
        for key, value in self.fixed.items():
            _check_dotted(f"set.{key}", key)
            _check_json(f"set.{key}", value)
        if not self.axes and not self.include:
            raise ConfigurationError("axes", self.axes, "at least one axis or [[include]] table")
        at_most("axes", self.axes, self.run_count(), MAX_MATRIX_RUNS, "runs (the axes' product)")
        for key, values in self.axes.items():
            _check_dotted(f"axes.{key}", key)
            if not isinstance(values, list) or not values:
                raise ConfigurationError(f"axes.{key}", values, "a non-empty list of values")
            _check_json(f"axes.{key}", values)
            seen = {canonical_json(v) for v in values}
            if len(seen) != len(values):
                raise ConfigurationError(f"axes.{key}", values, "a list of distinct values")
        for i, table in enumerate(self.include):
            if not isinstance(table, dict) or not table:
                raise ConfigurationError(f"include.{i}", table, "a non-empty table of overrides")
            for key in table:
                _check_dotted(f"include.{i}.{key}", key)
        for i, table in enumerate(self.exclude):
            if not isinstance(table, dict) or not table:
                raise ConfigurationError(f"exclude.{i}", table, "a non-empty table")
            for key in table:
                if key not in self.axes:
                    raise UnknownNameError(f"axis (in exclude.{i})", key, self.axes)
        if not isinstance(self.tolerances, dict):
            raise ConfigurationError("tolerances", self.tolerances, "a table")
        Tolerances.from_mapping(self.tolerances)  # known names, finite numbers >= 0 (no bools)
        if self.study is not None:
            if not isinstance(self.study, dict):
                raise ConfigurationError("study", self.study, "a table")
            for key, value in self.study.items():
                _check_json(f"study.{key}", value)
        # Like [set] and the axes: values that the JSON of the run records can hold.
        for title, group in (("include", self.include), ("exclude", self.exclude)):
            for i, overrides in enumerate(group):
                for key, value in overrides.items():
                    _check_json(f"{title}.{i}.{key}", value)

    def run_count(self) -> int:
        """The number of runs before the excludes, computed without expanding anything.

        The product of the axes' lengths, plus one per ``[[include]]`` table; the bound
        :data:`~packbot.validation.MAX_MATRIX_RUNS` is on it.
        """
        sizes = [len(v) if isinstance(v, list) else 1 for v in self.axes.values()]
        return (math.prod(sizes) if sizes else 0) + len(self.include)

    def canonical(self) -> dict[str, Any]:
        """What defines the matrix's runs, as a JSON-ready dict.

        The name, the base, ``[set]``, the axes in their order (it sets the runs' order), the
        includes and the excludes; a study matrix's ``[study]`` table (only if it has one,
        so a matrix of simulations keeps its identity). Not the description or the tolerances
        (they change no run), nor the file's comments, layout or key quoting. Two matrices with
        the same canonical form expand into the same runs over the same base scenario.
        """
        out: dict[str, Any] = {
            "format": MATRIX_FORMAT,
            "name": self.name,
            "base": self.base,
            "set": dict(sorted(self.fixed.items())),
            "axes": [[key, list(values)] for key, values in self.axes.items()],
            "include": [dict(sorted(t.items())) for t in self.include],
            "exclude": [dict(sorted(t.items())) for t in self.exclude],
        }
        if self.study is not None:
            out["study"] = dict(sorted(self.study.items()))
        return out

    def content_digest(self) -> str:
        """SHA-256 (hex) of the canonical JSON of :meth:`canonical`."""
        return digest(self.canonical())

    def base_path(self) -> str | Path:
        """The base scenario to read.

        A path beside the matrix file if one exists, else the name (or path) as written.
        """
        if self.path is not None:
            beside = self.path.parent / self.base
            if beside.is_file():
                return beside
        return self.base

    @checked_arguments
    def runs(self, base: Mapping[str, Any] | None = None) -> list[Run]:
        """Expand into runs.

        Args:
            base: The raw base scenario dict; None reads it with
                :func:`packbot.scenario.read_scenario_dict`.

        Returns:
            The runs, in product order (first axis slowest), then the includes.
        """
        text = ""
        source = None
        if base is None:
            from packbot.scenario import read_scenario_dict, scenario_path

            where = self.base_path()
            base = read_scenario_dict(where)
            source = scenario_path(where)
            text = source.read_text(errors="replace")
        return expand(self, base, base_text=text, source_path=source)


@checked_arguments
def find_matrix(name_or_path: str | Path) -> Path:
    """The matrix file: an existing path, or a name in the shipped ``sims/matrices/``.

    Raises:
        ConfigurationError: Not a name or path (an empty string, a number).
        UnknownNameError: Neither a file nor the name of a shipped matrix.
    """
    if not isinstance(name_or_path, (str, os.PathLike)) or not str(name_or_path):
        raise ConfigurationError("matrix", name_or_path, "a matrix name or the path of a file")
    path = Path(name_or_path)
    if path.is_file():
        return path
    from packbot.resources import data_dir

    folder = data_dir("sims") / "matrices"
    stem = path.name.removesuffix(".toml")
    candidate = folder / f"{stem}.toml"
    if path.parent == Path(".") and candidate.is_file():
        return candidate
    raise UnknownNameError("matrix", str(name_or_path), matrix_names())


@checked_arguments
def matrix_names() -> list[str]:
    """Names of the matrices shipped in ``sims/matrices/``."""
    from packbot.resources import data_dir

    try:
        folder = data_dir("sims") / "matrices"
    except ResourceNotFound:
        return []
    return sorted(p.stem for p in folder.glob("*.toml"))


@checked_arguments
def load_matrix(name_or_path: str | Path) -> Matrix:
    """Read and validate a matrix file (see the module docstring for its format).

    Args:
        name_or_path: A path, or the name of a matrix in ``sims/matrices/``.

    Raises:
        UnknownNameError: No such matrix, or an unknown key in the file.
        ConfigurationError: A bad value (the message names its key) or a TOML syntax error.
    """
    path = find_matrix(name_or_path)
    tomlfile.check_file_size(path, str(path), "(file)")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigurationError(str(path), "(file)", f"a readable UTF-8 file ({exc})") from exc
    return parse_matrix(text, path=path.resolve(), default_name=path.stem)


@checked_arguments
def parse_matrix(text: str, *, path: Path | None = None, default_name: str = "") -> Matrix:
    """Parse and validate a matrix file's text.

    Args:
        text: The TOML text.
        path: The file it was read from (named in errors; a relative base is resolved beside it).
        default_name: The name if the text has no ``name`` key (:func:`load_matrix`: the stem).

    Raises:
        UnknownNameError: An unknown key.
        ConfigurationError: A bad value (the message names its key) or a TOML syntax error.
    """
    where = str(path) if path is not None else "matrix"
    data = tomlfile.loads(text, where, "(file)")
    for key in data:
        if key not in MATRIX_KEYS:
            raise UnknownNameError("matrix key", key, MATRIX_KEYS)
    for key in ("set", "axes", "tolerances", "study"):
        if key in data and not isinstance(data[key], dict):
            raise ConfigurationError(key, data[key], "a table")
    for key in ("include", "exclude"):
        if key in data and not isinstance(data[key], list):
            raise ConfigurationError(key, data[key], "an array of tables ([[...]])")
    matrix = Matrix(
        name=data.get("name", default_name),
        base=data.get("base", ""),
        description=data.get("description", ""),
        fixed=_flatten(data.get("set", {})),
        axes=_flatten(data.get("axes", {})),
        include=[_flatten(t) if isinstance(t, dict) else t for t in data.get("include", [])],
        exclude=[_flatten(t) if isinstance(t, dict) else t for t in data.get("exclude", [])],
        tolerances=data.get("tolerances", {}),
        study=data.get("study"),
        path=path,
        source_text=text,
    )
    matrix.validate()
    return matrix


@checked_arguments
def expand(
    matrix: Matrix,
    base: Mapping[str, Any],
    *,
    base_text: str = "",
    source_path: str | Path | None = None,
) -> list[Run]:
    """Expand a matrix over a base scenario dict into runs.

    Args:
        matrix: The (validated) matrix.
        base: The raw base scenario dict (as read from its TOML file).
        base_text: The base file's text (for :attr:`Run.source_text`).
        source_path: The base file (for :attr:`Run.source_path`), or None.

    Returns:
        The runs: the Cartesian product of the axes (first axis slowest) minus the excluded
        combinations, then the includes; a combination given twice is kept once.

    Raises:
        ConfigurationError: An override does not fit the scenario's structure (names it).
    """
    scenario_name = str(base.get("name", Path(str(matrix.base)).stem))
    fixed = apply_overrides(base, matrix.fixed, field_prefix="set")
    combos: list[dict[str, Any]] = []
    if matrix.axes:
        keys = list(matrix.axes)
        for values in itertools.product(*(matrix.axes[k] for k in keys)):
            params = dict(zip(keys, values, strict=True))
            if not any(_matches(params, ex) for ex in matrix.exclude):
                combos.append(params)
    combos.extend(dict(t) for t in matrix.include)
    runs: list[Run] = []
    seen: dict[str, dict[str, Any]] = {}
    for params in combos:
        rid = run_id(params)
        if rid in seen:
            if canonical_json(seen[rid]) != canonical_json(params):  # pragma: no cover
                raise ConfigurationError("axes", params, f"parameters whose id {rid} is unique")
            continue
        seen[rid] = params
        scenario = apply_overrides(fixed, params)
        runs.append(
            Run(
                id=rid,
                index=len(runs),
                params=params,
                scenario=scenario,
                scenario_name=scenario_name,
                digest=digest(scenario),
                source_text=_source_text(matrix, base_text, params),
                source_path=None if source_path is None else str(Path(source_path).resolve()),
            )
        )
    return runs


def _source_text(matrix: Matrix, base_text: str, params: Mapping[str, Any]) -> str:
    lines = [f"# packbot batch: matrix {matrix.name!r}, base scenario {matrix.base!r}, with"]
    for title, table in (("set", matrix.fixed), ("run", params)):
        lines += [f"#   [{title}] {k} = {canonical_json(v)}" for k, v in table.items()]
    return base_text.rstrip("\n") + "\n\n" + "\n".join(lines) + "\n"


@checked_arguments
def canonical_json(value: Any) -> str:
    """The canonical JSON of a value: sorted keys, no spaces, ASCII, exact floats."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)


@checked_arguments
def digest(value: Any) -> str:
    """SHA-256 (hex) of the canonical JSON of a value."""
    return hashlib.sha256(canonical_json(value).encode()).hexdigest()


@checked_arguments
def run_id(params: Mapping[str, Any]) -> str:
    """The stable id of a run: ``<slug>-<hash>``.

    The slug joins ``name-value`` for each parameter in the order of their dotted names (name:
    the last non-index component of the dotted name), cut to 80 characters; the hash is the
    first 10 hex digits of the SHA-256 of the parameters' canonical JSON. The id depends on the
    parameters' values only, not on the order of the axes.
    """
    parts = []
    for key, value in sorted(params.items()):
        comps = [c for c in key.split(".") if not c.isdigit()] or [key]
        text = value if isinstance(value, str) else canonical_json(value)
        parts.append(f"{comps[-1]}-{text}")
    slug = _SLUG_CHARS.sub("_", "_".join(parts)).strip("_.")[:_SLUG_MAX].rstrip("_.")
    h = digest(dict(params))[:_HASH_DIGITS]
    return f"{slug}-{h}" if slug else h


@checked_arguments
def apply_overrides(
    data: Mapping[str, Any], overrides: Mapping[str, Any], *, field_prefix: str = "axes"
) -> dict[str, Any]:
    """A deep copy of a raw scenario dict with dotted-name overrides set.

    Args:
        data: The raw scenario dict.
        overrides: Dotted name -> value.
        field_prefix: Prefix of the field named in errors (``"axes"``, ``"set"``).

    Raises:
        ConfigurationError: A name runs through a value that is not a table or list, or a list
            index is out of range.
    """
    out = copy.deepcopy(dict(data))
    for key, value in overrides.items():
        set_dotted(out, key, copy.deepcopy(value), field=f"{field_prefix}.{key}")
    return out


@checked_arguments
def set_dotted(data: dict[str, Any], key: str, value: Any, *, field: str = "") -> None:
    """Set ``data[a][b][...] = value`` for the dotted name ``"a.b...."``, in place.

    Missing tables are created. A component addressing a list must be an index in
    ``0..len(list)``; ``len(list)`` appends a new table.

    Raises:
        ConfigurationError: The path runs through a scalar, or an index is out of range.
    """
    field = field or key
    comps = key.split(".")
    node: Any = data
    for i, comp in enumerate(comps):
        last = i == len(comps) - 1
        if isinstance(node, dict):
            if last:
                node[comp] = value
            else:
                if comp not in node:
                    node[comp] = [] if comps[i + 1].isdigit() else {}
                node = node[comp]
        elif isinstance(node, list):
            if not comp.isdigit() or int(comp) > len(node):
                raise ConfigurationError(
                    field, value, f"a list index in 0..{len(node)} at {comp!r} of {key!r}"
                )
            k = int(comp)
            if k == len(node):
                node.append(value if last else {})
            elif last:
                node[k] = value
            node = node[k]
        else:
            where = ".".join(comps[:i])
            raise ConfigurationError(
                field, value, f"a name inside a table or list, but {where!r} is {node!r}"
            )


def _flatten(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested tables -> dotted names (leaves: anything that is not a table)."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _check_dotted(field: str, key: str) -> None:
    if not all(_COMPONENT.match(c) for c in key.split(".")):
        raise ConfigurationError(
            field, key, "a dotted name of letters, digits, '_' and '-' (e.g. config.restitution)"
        )


def _check_json(field: str, value: Any) -> None:
    """Raise :class:`ConfigurationError` if a value has no exact JSON form."""
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(
            field, value, f"a value JSON can hold: no date, no inf or nan ({exc})"
        ) from exc


def _matches(params: Mapping[str, Any], table: Mapping[str, Any]) -> bool:
    return all(canonical_json(params[k]) == canonical_json(v) for k, v in table.items())
