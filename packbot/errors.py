"""Exceptions raised by packbot.

Every error packbot raises on purpose derives from :class:`PackbotError`. Each subclass carries
the offending data as attributes, and its message says what was wrong and how to fix it (for a
bad name, the list of valid names).
"""

from __future__ import annotations

import difflib
import reprlib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "MESSAGE_VALUE_MAX",
    "ConfigurationError",
    "ControllerError",
    "ConvexityError",
    "IKCollisionError",
    "InertialError",
    "InitialCollisionError",
    "JointError",
    "JointMismatchError",
    "KeywordError",
    "MeshError",
    "ModelError",
    "PackbotError",
    "ResourceNotFound",
    "ResultFileError",
    "ResultValueError",
    "SimulationError",
    "URDFError",
    "URDFSyntaxError",
    "UnknownNameError",
]


#: Longest repr of a value (or a name, a field) in an error message [characters]: a longer one
#: is shortened to its type, its size and its first items (``list of 1,000,000 items: [0.0,
#: 0.0, ...]``), so that a message stays one readable line (under about 300 characters with
#: the field and the expected value) whatever the input's size; the attribute keeps the value.
MESSAGE_VALUE_MAX = 120
#: Longest ``expected`` text of a :class:`ConfigurationError` message [characters] (the valid
#: choices of a table's keys, the text of a nested error).
_EXPECTED_MAX = 600
_PREVIEW = reprlib.Repr()
_PREVIEW.maxlevel = 2
_PREVIEW.maxstring = 40
_PREVIEW.maxother = 40
_PREVIEW.maxlong = 40
for _attr in ("maxtuple", "maxlist", "maxarray", "maxdict", "maxset", "maxfrozenset", "maxdeque"):
    setattr(_PREVIEW, _attr, 4)


def _is_large(value: Any, budget: int) -> bool:
    """Whether ``value`` holds more than ``budget`` items and characters (nested ones counted).

    Its repr is then longer than ``budget`` characters; it is never built.
    """
    stack, seen = [value], 0
    while stack:
        x = stack.pop()
        if isinstance(x, (str, bytes)):
            seen += len(x)
        elif isinstance(x, dict):
            seen += len(x)
            if seen <= budget:
                stack.extend(x.keys())
                stack.extend(x.values())
        elif isinstance(x, (list, tuple, set, frozenset)):
            seen += len(x)
            if seen <= budget:
                stack.extend(x)
        else:
            size = getattr(x, "size", None)  # an array: its repr is summarised by NumPy
            seen += size if isinstance(size, int) and size > 16 else 1
        if seen > budget:
            return True
    return False


def short_repr(value: Any, limit: int = MESSAGE_VALUE_MAX) -> str:
    """``repr(value)`` for an error message, shortened if longer than ``limit`` characters.

    A large string shows its start and its length, a large container its type, its length and
    its first items, an array its shape and type (the full repr of a large value is never
    built).

    Args:
        value: The value.
        limit: Longest repr kept as it is [characters].
    """
    if not _is_large(value, limit):
        text = repr(value)
        if len(text) <= limit:
            return text
    if isinstance(value, (str, bytes)):
        return f"{value[: limit // 2]!r}... ({len(value):,} characters)"
    shape = getattr(value, "shape", None)
    dtype = getattr(value, "dtype", None)
    if isinstance(shape, tuple) and dtype is not None:
        size = getattr(value, "size", 0)
        return f"array of {size:,} {getattr(dtype, 'name', dtype)} values, shape {shape}"
    preview = _PREVIEW.repr(value)
    if len(preview) > limit:
        preview = preview[: limit - 3] + "..."
    if isinstance(value, (list, tuple, dict, set, frozenset)):
        unit = "keys" if isinstance(value, dict) else "items"
        return f"{type(value).__name__} of {len(value):,} {unit}: {preview}"
    return preview


def short_name(name: object, limit: int = MESSAGE_VALUE_MAX) -> str:
    """A name or field for a message (``str``), cut to ``limit`` characters with its length."""
    text = str(name) if isinstance(name, str) else short_repr(name, limit)
    if len(text) <= limit:
        return text
    return f"{text[: limit // 2]}... ({len(text):,} characters)"


#: Closest-match cutoff of :func:`close_match`: :func:`difflib.get_close_matches`' default
#: ratio (a dropped or doubled letter scores 0.8 to 0.95; 0.5 would offer 'stand' for
#: 'sitting' and 'gravity' for 'gain').
_CLOSE_MATCH_CUTOFF = 0.6


def close_match(word: object, valid: Iterable[object]) -> str | None:
    """The valid name closest to ``word`` (a likely misspelling), or None if none is close.

    Args:
        word: The name given (not a string, or a very long one: no suggestion).
        valid: The valid names (those that are not strings are skipped).
    """
    if not isinstance(word, str) or not word or len(word) > 200:
        return None
    names = [v for v in valid if isinstance(v, str)]
    match = difflib.get_close_matches(word, names, n=1, cutoff=_CLOSE_MATCH_CUTOFF)
    if not match:  # another case ("Restitution") is a misspelling too
        lower = {v.lower(): v for v in names}
        match = [lower[word.lower()]] if word.lower() in lower else []
    return match[0] if match else None


class PackbotError(Exception):
    """Base class of every error packbot raises on purpose."""


class ModelError(PackbotError):
    """The robot description (URDF, meshes, parameter table) is missing or inconsistent."""


class ResourceNotFound(ModelError):
    """A data file shipped with packbot (URDF, mesh, scenario) could not be located.

    Attributes:
        path: The path that was looked for.
    """

    def __init__(self, path: Path | str, hint: str = "") -> None:
        self.path = Path(path)
        msg = f"packbot data file not found: {self.path}"
        if hint:
            msg += f". {hint}"
        super().__init__(msg)


class URDFError(ModelError):
    """A URDF file is malformed, or describes a model packbot cannot use.

    The message names the file, the element (link, joint, mesh) and how to fix it.

    Attributes:
        path: The URDF file.
        element: The offending element, e.g. ``"link 'link1' <mass>"`` ("" for the whole file).
        problem: What is wrong with it.
        fix: How to fix it.
        line: Line of the file, when the XML parser reports one (else None).
    """

    def __init__(
        self,
        path: Path | str,
        element: str,
        problem: str,
        fix: str = "",
        line: int | None = None,
    ) -> None:
        self.path = Path(path)
        self.element = element
        self.problem = problem
        self.fix = fix
        self.line = line
        where = f"{self.path}, line {line}" if line is not None else str(self.path)
        msg = f"invalid URDF {where}: " + (f"{element}: " if element else "") + problem
        if fix:
            msg += f"; {fix}"
        ModelError.__init__(self, msg)


class URDFSyntaxError(URDFError):
    """The URDF file is empty, is not well-formed XML, or is not a URDF (no ``<robot>``)."""


class MeshError(URDFError):
    """A mesh a link uses is missing, unreadable or corrupt.

    Attributes:
        link: Name of the link using the mesh.
        uri: The mesh file name as written in the URDF (``package://packbot/...`` or a path).
        mesh_path: The file that was tried (None if the URI could not be resolved).
    """

    def __init__(
        self,
        path: Path | str,
        link: str,
        uri: str,
        mesh_path: Path | None,
        problem: str,
        fix: str = "",
    ) -> None:
        self.link = link
        self.uri = uri
        self.mesh_path = mesh_path
        tried = f" (tried {mesh_path})" if mesh_path is not None and str(mesh_path) != uri else ""
        super().__init__(path, f"link {link!r} mesh {uri!r}{tried}", problem, fix)


class InertialError(URDFError):
    """A link's mass or inertia is not physical (non-positive, not finite, not a number).

    Attributes:
        link: Name of the link.
        value: The offending value (a mass [kg], or the inertia's six entries [kg*m^2]).
    """

    def __init__(
        self, path: Path | str, link: str, tag: str, value: Any, problem: str, fix: str
    ) -> None:
        self.link = link
        self.value = value
        super().__init__(path, f"link {link!r} <{tag}>", problem, fix)


class JointError(URDFError):
    """A joint's type, axis or limits are invalid (inverted, not finite, negative).

    Attributes:
        joint: Name of the joint.
        value: The offending value.
    """

    def __init__(
        self, path: Path | str, joint: str, tag: str, value: Any, problem: str, fix: str
    ) -> None:
        self.joint = joint
        self.value = value
        super().__init__(
            path, f"joint {joint!r} <{tag}>" if tag else f"joint {joint!r}", problem, fix
        )


class JointMismatchError(URDFError):
    """The URDF's movable joints are not the arm's joints of packbot's parameter table.

    Attributes:
        missing: Joints the parameter table expects that the file does not have.
        unexpected: Movable joints of the file that the parameter table does not know.
        found: The movable joints the file has, in file order.
    """

    def __init__(
        self,
        path: Path | str,
        missing: Sequence[str],
        unexpected: Sequence[str],
        found: Sequence[str],
        expected: Sequence[str],
    ) -> None:
        self.missing = tuple(missing)
        self.unexpected = tuple(unexpected)
        self.found = tuple(found)
        parts = []
        if self.missing:
            parts.append(f"no joint named {', '.join(map(repr, self.missing))}")
        if self.unexpected:
            parts.append(
                f"movable joint(s) {', '.join(map(repr, self.unexpected))} not in packbot's "
                "parameter table"
            )
        problem = (
            "; ".join(parts) + f" (the file's movable joints: {', '.join(self.found) or 'none'})"
        )
        fix = (
            f"packbot's model expects the revolute joints {', '.join(expected)} "
            "(packbot/params.py): rename the joints back, or make extra joints fixed"
        )
        super().__init__(path, "joints", problem, fix)


class UnknownNameError(PackbotError, KeyError):
    """A name (joint, link, pose, obstacle, ...) is not one of the valid choices.

    The message suggests the closest valid name, if one is close (a likely misspelling):
    ``unknown pose 'stnd'; did you mean 'stand'? valid pose names are: ...``.

    Attributes:
        kind: What was being named ("joint", "pose", ...).
        name: The name that was given.
        valid: The valid names.
        suggestion: The valid name closest to ``name`` (None if none is close).
    """

    def __init__(self, kind: str, name: object, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        self.suggestion = close_match(name, self.valid)
        hint = f"did you mean {self.suggestion!r}? " if self.suggestion else ""
        super().__init__(
            f"unknown {kind} {short_repr(name)}; {hint}valid {kind} names are: "
            f"{', '.join(self.valid)}"
        )

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class ConfigurationError(PackbotError, ValueError):
    """A setting, argument or array has an invalid value.

    The message shows a large value shortened (:func:`short_repr`: its type, size and first
    items), so that it stays one readable line; the attribute keeps the value as given.

    Attributes:
        field: Name of the offending field or argument.
        value: The value that was given.
        expected: What a valid value looks like (a range, the valid choices, a shape).
    """

    def __init__(self, field: str, value: Any, expected: str | Sequence[str]) -> None:
        self.field = field
        self.value = value
        if isinstance(expected, str):
            self.expected = expected
        else:
            self.expected = "one of " + ", ".join(short_repr(x) for x in expected)
        shown = " ".join(self.expected.split("\n"))
        if len(shown) > _EXPECTED_MAX:
            shown = shown[: _EXPECTED_MAX - 3] + "..."
        super().__init__(f"invalid {short_name(field)}={short_repr(value)}: expected {shown}")


class KeywordError(ConfigurationError, TypeError):
    """A call's arguments do not fit the signature: an unknown or missing keyword, too many.

    Raised by every public constructor and entry point (:mod:`packbot.keywords`) instead of
    Python's bare ``TypeError``; it is a ``TypeError`` too, so code catching one keeps working.
    The message names the keyword, the closest valid one (a likely misspelling) and the valid
    keywords: ``unknown keyword 'restitutio' of SimConfig; did you mean 'restitution'? valid
    keywords: contact_mode, restitution, ...``.

    Attributes:
        function: What was called (``"SimConfig"``, ``"simulate"``, ``"SimResult.save"``).
        keyword: The unknown keyword, or the one given twice (None for a missing keyword or too
            many positional arguments).
        missing: The required keywords that were not given (empty unless some are missing).
        valid: The valid keywords, in the signature's order.
        suggestion: The valid keyword closest to :attr:`keyword` (None if none is close).
        given: The number of positional arguments given (None unless too many were).
    """

    def __init__(
        self,
        function: str,
        valid: Sequence[str],
        *,
        keyword: str | None = None,
        value: Any = None,
        suggestion: str | None = None,
        missing: Sequence[str] = (),
        required: Sequence[str] = (),
        given: int | None = None,
        positional: Sequence[str] = (),
        twice: bool = False,
    ) -> None:
        self.function = function
        self.keyword = keyword
        self.missing = tuple(missing)
        self.valid = tuple(valid)
        self.suggestion = suggestion
        self.given = given
        names = ", ".join(self.valid) or "none"
        if self.missing:
            s = "s" if len(self.missing) > 1 else ""
            what = ", ".join(repr(m) for m in self.missing)
            msg = (
                f"missing keyword{s} {what} of {function} (required: {', '.join(required)}; "
                f"valid keywords: {names})"
            )
            field, shown, expected = self.missing[0], None, f"a value ({function} requires it)"
        elif given is not None:
            most = len(positional)
            takes = f"at most {most}" if most else "none"
            msg = (
                f"too many positional arguments to {function}: {given} given, it takes {takes}"
                + (f" ({', '.join(positional)})" if positional else "")
                + f"; pass {'the others' if most else 'them'} by keyword "
                f"(valid keywords: {names})"
            )
            field, shown, expected = "arguments", given, f"at most {most} positional arguments"
        elif twice:
            msg = (
                f"keyword {short_name(keyword)!r} of {function} given twice (by position and by "
                f"keyword); valid keywords: {names}"
            )
            field, shown, expected = str(keyword), value, "one value"
        else:
            hint = f"; did you mean {suggestion!r}? " if suggestion else "; "
            msg = (
                f"unknown keyword {short_repr(keyword)} of {function}{hint}valid keywords: {names}"
            )
            field, shown, expected = str(keyword), value, f"one of the keywords: {names}"
        PackbotError.__init__(self, msg)
        self.field, self.value, self.expected = field, shown, expected


class ConvexityError(ModelError):
    """A collision mesh is not convex, or is empty or degenerate.

    Attributes:
        name: Name of the geometry piece.
        volume: Volume enclosed by the mesh [m^3] (None if it has none).
        hull_volume: Volume of its convex hull [m^3] (None if it has none).
    """

    def __init__(
        self,
        name: str,
        reason: str,
        volume: float | None = None,
        hull_volume: float | None = None,
    ) -> None:
        self.name = name
        self.volume = volume
        self.hull_volume = hull_volume
        super().__init__(f"collision piece {name!r}: {reason}")


class InitialCollisionError(ConfigurationError):
    """The initial configuration has penetrating pairs.

    Attributes:
        pairs: ``(link1/piece1, link2/piece2, distance [m])`` of each penetrating pair.
    """

    def __init__(self, pairs: Sequence[tuple[str, str, float]]) -> None:
        self.pairs = list(pairs)
        desc = "; ".join(f"{a} - {b}: {d * 1000:.2f} mm" for a, b, d in self.pairs)
        PackbotError.__init__(
            self,
            f"invalid q0: the initial state is in collision ({desc}); start from a "
            "configuration where every signed distance is >= 0",
        )
        self.field, self.value, self.expected = "q0", desc, "a collision-free configuration"


class IKCollisionError(PackbotError):
    """Every solution the inverse kinematics found for a target collides.

    Attributes:
        frame: The frame placed.
        target: The target position [m], world frame.
        pair: The colliding pieces of the least penetrating solution, ``(piece1, piece2)``.
        distance: Their signed distance there [m] (negative: a penetration).
        seeds: How many starts were tried.
        result: That solution, an :class:`~packbot.control.IKResult`.
    """

    def __init__(
        self,
        frame: str,
        target: Any,
        pair: tuple[str, str],
        distance: float,
        seeds: int,
        result: Any = None,
    ) -> None:
        self.frame, self.target, self.pair = frame, tuple(float(x) for x in target), pair
        self.distance, self.seeds, self.result = float(distance), seeds, result
        xyz = ", ".join(f"{x:.3f}" for x in self.target)
        super().__init__(
            f"no collision-free inverse kinematics of {frame!r} at ({xyz}) m from {seeds} starts: "
            f"the least penetrating solution puts {pair[0]} into {pair[1]} "
            f"({self.distance * 1000:.1f} mm); "
            "choose another target or start, or pass collision_free=False to get the "
            "solution flagged (IKResult.colliding)"
        )


class SimulationError(PackbotError):
    """A simulation could not continue.

    Attributes:
        t: Simulated time at which it stopped [s].
        result: The result up to that time (a :class:`packbot.SimResult`), if any.
    """

    def __init__(self, message: str, t: float, result: Any = None) -> None:
        self.t = t
        self.result = result
        super().__init__(f"simulation stopped at t = {t:.9g} s: {message}")


class ControllerError(SimulationError):
    """The controller raised, or returned torques of the wrong shape or not finite.

    Attributes:
        joint: The offending joint's name, if one is to blame.
    """

    def __init__(self, message: str, t: float, joint: str | None = None) -> None:
        self.joint = joint
        super().__init__(f"controller: {message}", t)


class ResultFileError(PackbotError):
    """A file that :meth:`packbot.SimResult.load` cannot read: missing, not a result, or corrupt.

    Attributes:
        path: The file.
        reason: What is wrong with it (the value found and what was expected).
        entry: The entry of the file at fault: an array (``"q"``), the JSON metadata or one of
            its fields (``"meta_json.config"``, ``"meta_json.events[3].kind"``), a zip member
            that is not an entry; "" for the file as a whole (missing, not a zip archive).
    """

    def __init__(self, path: str | Path, reason: str, entry: str = "") -> None:
        where = f"entry {entry!r}: " if entry else ""
        # PackbotError's own initialiser: a subclass may also derive from ConfigurationError
        PackbotError.__init__(
            self, f"cannot load a packbot result from {str(path)!r}: {where}{reason}"
        )
        self.path = str(path)
        self.reason = reason
        self.entry = entry


class ResultValueError(ResultFileError, ConfigurationError):
    """A result file's stored setting, obstacle, failure or payload that its constructor refuses.

    Both a :class:`ResultFileError` (naming the file and the entry, e.g.
    ``"meta_json.payload"``) and the constructor's :class:`ConfigurationError` (its ``field``,
    ``value`` and ``expected``).
    """

    def __init__(self, path: str | Path, entry: str, error: ConfigurationError) -> None:
        ResultFileError.__init__(self, path, str(error), entry)
        self.field = getattr(error, "field", entry)
        self.value = getattr(error, "value", None)
        self.expected = getattr(error, "expected", "")
