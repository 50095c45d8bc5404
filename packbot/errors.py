"""Exceptions raised by packbot.

Every error packbot raises on purpose derives from :class:`PackbotError`. Each subclass carries
the offending data as attributes, and its message says what was wrong and how to fix it (for a
bad name, the list of valid names).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "ConfigurationError",
    "ControllerError",
    "ConvexityError",
    "InertialError",
    "InitialCollisionError",
    "JointError",
    "JointMismatchError",
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

    Attributes:
        kind: What was being named ("joint", "pose", ...).
        name: The name that was given.
        valid: The valid names.
    """

    def __init__(self, kind: str, name: object, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        super().__init__(
            f"unknown {kind} {name!r}; valid {kind} names are: {', '.join(self.valid)}"
        )

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class ConfigurationError(PackbotError, ValueError):
    """A setting, argument or array has an invalid value.

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
            self.expected = "one of " + ", ".join(repr(x) for x in expected)
        super().__init__(f"invalid {field}={value!r}: expected {self.expected}")


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
