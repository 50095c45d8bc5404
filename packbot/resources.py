"""Locate the data shipped with packbot: ``urdf/`` and ``sims/``.

In a source checkout (or an editable install) they are the repository's top-level folders; in an
installed wheel they are packaged as ``packbot/_data/urdf`` and ``packbot/_data/sims``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from packbot.errors import ResourceNotFound

__all__ = ["PACKAGE_URI", "data_dir", "repo_root", "resolve_mesh_uri"]

#: Prefix of the mesh URIs of packbot's URDFs; it stands for the URDF file's own directory.
PACKAGE_URI = "package://packbot/"


def repo_root() -> Path | None:
    """The source checkout holding this package, or None when installed from a wheel."""
    root = Path(__file__).resolve().parent.parent
    return root if (root / "pyproject.toml").is_file() and (root / "urdf").is_dir() else None


def data_dir(name: str) -> Path:
    """Absolute path of a data folder, ``"urdf"`` or ``"sims"``.

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


def resolve_mesh_uri(uri: str, urdf_dir: Path) -> Path | None:
    """The file a mesh URI written in a URDF stands for.

    ``package://packbot/X`` is ``urdf_dir/X`` (packbot's URDFs keep their meshes beside them);
    ``file:///abs/X`` and an absolute path are themselves; a relative path is relative to
    ``urdf_dir``. The file is not required to exist.

    Args:
        uri: The ``filename`` attribute of a URDF ``<mesh>``.
        urdf_dir: The (absolute) directory of the URDF file.

    Returns:
        The path, or None for a URI packbot cannot resolve (another ROS package, a URL).
    """
    if uri.startswith(PACKAGE_URI):
        return urdf_dir / uri[len(PACKAGE_URI) :]
    if uri.startswith("file://"):
        uri = uri[len("file://") :]
    elif "://" in uri:
        return None
    path = Path(uri)
    return path if path.is_absolute() else urdf_dir / path
