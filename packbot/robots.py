"""Arms by name: ``load_robot("ur5")``, ``load_robot("panda")``, ``load_robot("packbot")``.

``"packbot"`` is the shipped description package. The others are the URDFs and SRDFs of
`example-robot-data <https://github.com/Gepetto/example-robot-data>`_ (the optional extra
``pip install "packbot[arms]"``), whose cmeel wheel installs them under
``<site-packages>/cmeel.prefix/share/example-robot-data/robots`` with mesh URIs
``package://example-robot-data/robots/...``: the ``share`` folder is their package folder.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from packbot.errors import ResourceNotFound

__all__ = ["ROBOTS", "RobotFiles", "robot_files"]

#: Where example-robot-data's cmeel wheel puts its files, below a site-packages folder.
_SHARE = Path("cmeel.prefix") / "share"
_PACKAGE = "example-robot-data"


@dataclass(frozen=True, kw_only=True)
class RobotFiles:
    """A named arm's files.

    Attributes:
        urdf: The URDF, None for the shipped PackBot.
        srdf: Its SRDF (the link pairs not to test), None for none (or PackBot's own).
        package_dirs: The folders its ``package://`` URIs resolve in.
        tool_frame: The frame its tool point is, None for the loader's default.
    """

    urdf: Path | None
    srdf: Path | None = None
    package_dirs: tuple[Path, ...] = ()
    tool_frame: str | None = None


#: name -> (URDF, SRDF, tool frame) below example-robot-data's ``robots`` folder.
ROBOTS: dict[str, tuple[str, str, str] | None] = {
    "packbot": None,
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf", "tool0"),
    "panda": (
        "panda_description/urdf/panda.urdf",
        "panda_description/srdf/panda.srdf",
        "panda_hand_tcp",
    ),
}


def _share() -> Path | None:
    for entry in sys.path:
        share = Path(entry) / _SHARE
        if (share / _PACKAGE / "robots").is_dir():
            return share
    return None


def robot_files(name: str) -> RobotFiles:
    """The files of the arm called ``name`` (one of :data:`ROBOTS`).

    Raises:
        ResourceNotFound: The arm's files are not installed (example-robot-data).
    """
    entry = ROBOTS[name]
    if entry is None:
        return RobotFiles(urdf=None)
    share = _share()
    if share is None:
        raise ResourceNotFound(
            Path(_PACKAGE),
            f'the arm {name!r} comes with example-robot-data: pip install "packbot[arms]"',
        )
    robots = share / _PACKAGE / "robots"
    urdf, srdf, frame = entry
    return RobotFiles(
        urdf=robots / urdf, srdf=robots / srdf, package_dirs=(share,), tool_frame=frame
    )
