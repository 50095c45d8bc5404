"""Locate the data shipped with packbot: ``urdf/`` and ``sims/``.

In a source checkout (or an editable install) they are the repository's top-level folders; in an
installed wheel they are packaged as ``packbot/_data/urdf`` and ``packbot/_data/sims``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from packbot.errors import ResourceNotFound

__all__ = ["data_dir", "repo_root"]


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
