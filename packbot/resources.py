"""Locate the data shipped with packbot: ``urdf/`` and ``sims/``.

In a source checkout (or an editable install) they are the repository's top-level folders; in an
installed wheel they are packaged as ``packbot/_data/urdf`` and ``packbot/_data/sims``.

``urdf/`` holds one ROS-style description package, ``urdf/packbot/`` (``package.xml`` names it
``packbot``, as the URDF's ``package://packbot/meshes/...`` URIs do). A loader resolves
``package://packbot/X`` by searching its package directories for ``<dir>/packbot/X``, so
:func:`package_dirs` is ``[urdf/]`` and :func:`urdf_path` is ``urdf/packbot/packbot_eod.urdf``::

    pinocchio.buildModelsFromUrdf(str(packbot.urdf_path()), package_dirs=packbot.package_dirs())
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from importlib.resources import files
from pathlib import Path

from packbot.errors import ConfigurationError, ResourceNotFound
from packbot.keywords import checked_arguments

__all__ = [
    "DESCRIPTION_PACKAGE",
    "MJCF_NAME",
    "PACKAGE_URI",
    "SRDF_NAME",
    "URDF_NAME",
    "data_dir",
    "description_dir",
    "mjcf_path",
    "package_dirs",
    "repo_root",
    "resolve_mesh_uri",
    "search_package_dirs",
    "srdf_path",
    "urdf_path",
]

#: Name of the ROS-style description package (its ``package.xml`` and its folder's name).
DESCRIPTION_PACKAGE = "packbot"
#: Prefix of the mesh URIs of packbot's URDFs; it stands for the URDF file's own directory.
PACKAGE_URI = f"package://{DESCRIPTION_PACKAGE}/"
#: File name of the URDF inside the description package.
URDF_NAME = "packbot_eod.urdf"
#: File name of the SRDF (groups, named poses, disabled collision pairs) beside the URDF.
SRDF_NAME = "packbot_eod.srdf"
#: File name of the MuJoCo MJCF model beside the URDF.
MJCF_NAME = "packbot_eod.xml"


@checked_arguments
def repo_root() -> Path | None:
    """The source checkout holding this package, or None when installed from a wheel."""
    root = Path(__file__).resolve().parent.parent
    return root if (root / "pyproject.toml").is_file() and (root / "urdf").is_dir() else None


@functools.cache
def _data_root(name: str) -> Path:
    """Absolute path of the top-level data folder ``urdf/`` or ``sims/`` (found once).

    Raises:
        ResourceNotFound: Neither the wheel's nor the checkout's folder exists.
    """
    packaged = Path(str(files("packbot"))) / "_data" / name
    if packaged.is_dir():
        return packaged
    root = repo_root()
    if root is not None and (root / name).is_dir():
        return root / name
    raise ResourceNotFound(packaged, "reinstall packbot (pip install .) or run from a checkout")


@checked_arguments
def data_dir(name: str) -> Path:
    """Absolute path of a data folder: ``"urdf"`` (the description package) or ``"sims"``.

    ``data_dir("urdf")`` is the package folder ``urdf/packbot`` holding the URDF, the SRDF, the
    MJCF and ``meshes/``; ``data_dir("sims")`` is ``sims/``.

    Raises:
        ResourceNotFound: Neither the wheel's nor the checkout's folder exists.
    """
    if name == "urdf":
        return description_dir()
    return _data_root(name)


@checked_arguments
@functools.cache
def description_dir() -> Path:
    """Absolute path of the description package folder ``urdf/packbot`` (holds ``package.xml``).

    Found once (every collision world reads the SRDF beside it).

    Raises:
        ResourceNotFound: The folder is missing (a broken install).
    """
    path = _data_root("urdf") / DESCRIPTION_PACKAGE
    if not path.is_dir():
        raise ResourceNotFound(path, "reinstall packbot (pip install .) or run from a checkout")
    return path


@checked_arguments
def package_dirs() -> list[str]:
    """The package directories under which ``package://packbot/...`` mesh URIs resolve.

    Pass them to a loader's package path, e.g. ``pinocchio.buildModelsFromUrdf(...,
    package_dirs=packbot.package_dirs())`` or ``ROS_PACKAGE_PATH``.
    """
    return [str(description_dir().parent)]


@checked_arguments
def urdf_path() -> Path:
    """Absolute path of the shipped URDF, ``urdf/packbot/packbot_eod.urdf``."""
    return description_dir() / URDF_NAME


@checked_arguments
def srdf_path() -> Path:
    """Absolute path of the shipped SRDF (collision pairs, groups, named poses)."""
    return description_dir() / SRDF_NAME


@checked_arguments
def mjcf_path() -> Path:
    """Absolute path of the shipped MuJoCo model (MJCF) generated from the same parameters."""
    return description_dir() / MJCF_NAME


@checked_arguments
def resolve_mesh_uri(uri: str, urdf_dir: Path, package_dirs: Sequence[Path] = ()) -> Path | None:
    """The file a mesh URI written in a URDF stands for.

    ``package://packbot/X`` is ``urdf_dir/X`` (packbot's URDFs keep their meshes beside them);
    ``package://pkg/X`` of another package is ``d/pkg/X`` for the first of ``package_dirs``
    where that file exists, or ``d/X`` where ``d`` is itself the package's folder (named
    ``pkg``), as ROS resolves it; ``file:///abs/X`` and an absolute path are themselves; a
    relative path is relative to ``urdf_dir``. Only another package's file must exist.

    Args:
        uri: The ``filename`` attribute of a URDF ``<mesh>``.
        urdf_dir: The (absolute) directory of the URDF file.
        package_dirs: Folders that hold ROS packages (or are one), searched in order.

    Returns:
        The path, or None for a URI packbot cannot resolve (a package found in none of
        ``package_dirs``, a URL).
    """
    if uri.startswith(PACKAGE_URI):
        return urdf_dir / uri[len(PACKAGE_URI) :]
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://") :].partition("/")
        for d in package_dirs:
            for candidate in (d / package / rest, d / rest if d.name == package else None):
                if candidate is not None and candidate.is_file():
                    return candidate
        return None
    if uri.startswith("file://"):
        uri = uri[len("file://") :]
    elif "://" in uri:
        return None
    path = Path(uri)
    return path if path.is_absolute() else urdf_dir / path


def search_package_dirs(package_dirs: Sequence[str | Path] | str | Path | None) -> tuple[Path, ...]:
    """The folders searched for ``package://`` meshes: those given, then ``ROS_PACKAGE_PATH``'s.

    Raises:
        ConfigurationError: ``package_dirs`` is not a folder path or a list of them, or names
            a folder that does not exist.
    """
    if package_dirs is None:
        given: list[str | Path] = []
    elif isinstance(package_dirs, (str, os.PathLike)):
        given = [package_dirs]
    elif isinstance(package_dirs, Sequence) and all(
        isinstance(d, (str, os.PathLike)) for d in package_dirs
    ):
        given = list(package_dirs)
    else:
        raise ConfigurationError(
            "package_dirs", package_dirs, "a folder path, a list of folder paths, or None"
        )
    dirs = [Path(d).expanduser().resolve() for d in given]
    for d in dirs:
        if not d.is_dir():
            raise ConfigurationError("package_dirs", str(d), "folders that exist")
    ros = os.environ.get("ROS_PACKAGE_PATH", "")
    dirs += [Path(d) for d in ros.split(os.pathsep) if d and Path(d).is_dir()]
    return tuple(dirs)
