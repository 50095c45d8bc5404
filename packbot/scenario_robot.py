"""The arm a scenario runs on: the scenario file's ``robot`` key.

::

    robot = "ur5"                        # a name of packbot.robots.ROBOTS ("packbot": the default)

    [robot]                              # or a URDF, as load_robot takes it
    urdf = "arms/my_arm.urdf"            # relative paths: to the scenario file's folder
    package_dirs = ["ros_ws/src"]
    srdf = "arms/my_arm.srdf"
    tool_frame = "tool0"

No ``robot`` key: PackBot.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from packbot.errors import ConfigurationError
from packbot.robots import ROBOTS

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = ["ROBOT_KEYS", "RobotSpec", "load_spec_robot", "robot_spec"]

#: The keys of a ``[robot]`` table.
ROBOT_KEYS: tuple[str, ...] = ("urdf", "package_dirs", "srdf", "tool_frame", "armature")


@dataclass(frozen=True, kw_only=True)
class RobotSpec:
    """The arm of a scenario, as written in its file.

    Attributes:
        urdf: A name of :data:`packbot.robots.ROBOTS`, or a URDF file (relative: to the
            scenario file's folder, or the working directory for a scenario built in code).
        package_dirs: Folders of the URDF's ``package://`` meshes (relative as ``urdf``).
        srdf: An SRDF of the link pairs not to test, or None (the loader's default).
        tool_frame: The tool frame, or None (the loader's default).
        armature: The joints' armature: joint -> [kg*m^2] (a ``[robot.armature]`` table), a
            sidecar TOML file (relative as ``urdf``), or None (the loader's default).
    """

    urdf: str = "packbot"
    package_dirs: tuple[str, ...] = ()
    srdf: str | None = None
    tool_frame: str | None = None
    armature: str | tuple[tuple[str, float], ...] | None = None


def _text(path: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigurationError(path, value, "a non-empty string")
    return value


def robot_spec(value: Any) -> RobotSpec:
    """The :class:`RobotSpec` of a scenario file's ``robot`` value (a string or a table).

    Raises:
        ConfigurationError: Not a name, a path or a ``[robot]`` table of :data:`ROBOT_KEYS`;
            the message names ``robot.<key>``.
    """
    if isinstance(value, str):
        return RobotSpec(urdf=_text("robot", value))
    if not isinstance(value, Mapping):
        raise ConfigurationError(
            "robot", value, f"an arm's name ({', '.join(ROBOTS)}), a URDF path or a [robot] table"
        )
    unknown = [k for k in value if k not in ROBOT_KEYS]
    if unknown:
        raise ConfigurationError(f"robot.{unknown[0]}", value[unknown[0]], f"one of {ROBOT_KEYS}")
    if "urdf" not in value:
        raise ConfigurationError("robot.urdf", None, "an arm's name or a URDF path (required)")
    dirs = value.get("package_dirs", [])
    if isinstance(dirs, str) or not isinstance(dirs, list):
        raise ConfigurationError("robot.package_dirs", dirs, "an array of folder paths")
    arm = value.get("armature")
    if isinstance(arm, Mapping):
        armature: str | tuple[tuple[str, float], ...] | None = tuple(
            (str(k), v) for k, v in arm.items()
        )
    else:
        armature = None if arm is None else _text("robot.armature", arm)
    return RobotSpec(
        armature=armature,
        urdf=_text("robot.urdf", value["urdf"]),
        package_dirs=tuple(_text(f"robot.package_dirs[{k}]", d) for k, d in enumerate(dirs)),
        srdf=_text("robot.srdf", value["srdf"]) if "srdf" in value else None,
        tool_frame=_text("robot.tool_frame", value["tool_frame"])
        if "tool_frame" in value
        else None,
    )


def load_spec_robot(spec: RobotSpec | None, source: Path | None = None) -> Robot:
    """Load a scenario's arm (PackBot for None).

    Relative paths are taken from ``source``'s folder (the scenario file) or the working
    directory.

    Raises:
        ModelError: The arm cannot be loaded (:func:`packbot.load_robot`'s errors).
    """
    from packbot.model import load_robot

    if spec is None:
        return load_robot()
    base = source.resolve().parent if source is not None else Path.cwd()

    def here(p: str) -> Path:
        return Path(p) if Path(p).is_absolute() else base / p

    named = spec.urdf in ROBOTS and not here(spec.urdf).is_file()
    return load_robot(
        spec.urdf if named else here(spec.urdf),
        package_dirs=[here(d) for d in spec.package_dirs] or None,
        srdf=here(spec.srdf) if spec.srdf is not None else None,
        tool_frame=spec.tool_frame,
        armature=(
            here(spec.armature)
            if isinstance(spec.armature, str)
            else None
            if spec.armature is None
            else dict(spec.armature)
        ),
    )
