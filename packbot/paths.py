"""File names that stay inside their folder: the checks of every name packbot writes under.

A run's files are named after its scenario (``<stem>.npz``, ``<stem>_events.csv``, ...), a batch's
after its run ids (``runs/<id>.json``): a name with a separator, ``..`` or an absolute path
would write outside the output folder. :func:`check_stem` refuses such a name with a
:class:`~packbot.errors.ConfigurationError` naming the field and the value, before anything is
written; :func:`inside` checks a path, once resolved (symbolic links followed), against its
folder.

A stem (:func:`is_plain_name`) is one path component: a non-empty string of at most
:data:`MAX_STEM_BYTES` bytes (UTF-8), not ``.`` or ``..``, without ``/``, a backslash, ``:``
(a Windows drive or stream), NUL or another control character (a line break in a file name
would split the one-line messages that quote it). Anything else is allowed: a scenario named
``a&b <i>`` writes ``a&b <i>.npz`` (the pages escape the names they show).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from packbot.errors import ConfigurationError

__all__ = [
    "MAX_STEM_BYTES",
    "STEM_RULE",
    "atomic_write",
    "check_stem",
    "inside",
    "is_plain_name",
]

#: Longest stem [bytes of UTF-8]: file systems allow 255 per name, the suffixes packbot adds
#: (``_partial_events.csv``, ``.bad-<n>``, a temporary file's ``.<name>.<random>.tmp``) need the
#: rest.
MAX_STEM_BYTES = 200
#: What a stem must be, as the error messages say it.
STEM_RULE = (
    f"a single file name (one path component of at most {MAX_STEM_BYTES} bytes: no '/', '\\', "
    "':', NUL or control characters, not '.' or '..')"
)
_FORBIDDEN = frozenset("/\\:") | frozenset(os.sep + (os.altsep or ""))


def is_plain_name(name: object) -> bool:
    """Whether ``name`` is a file name of one component (see the module's rule)."""
    return (
        isinstance(name, str)
        and name not in ("", ".", "..")
        and len(name.encode("utf-8", "surrogatepass")) <= MAX_STEM_BYTES
        and not any(c in _FORBIDDEN or ord(c) < 32 or ord(c) == 127 for c in name)
    )


def check_stem(field: str, value: Any) -> str:
    """A file-name stem, checked (see :func:`is_plain_name`).

    Args:
        field: What the value is, for the message (``"stem"``, ``"scenario.name"``, ...).
        value: The stem.

    Returns:
        The stem.

    Raises:
        ConfigurationError: Not a string, or not a single file name (names ``field``).
    """
    if not is_plain_name(value):
        raise ConfigurationError(field, value, STEM_RULE)
    return str(value)


def inside(field: str, folder: str | os.PathLike[str], path: str | os.PathLike[str]) -> Path:
    """``path``, checked to resolve (symbolic links followed) to a place inside ``folder``.

    Args:
        field: What the path is, for the message.
        folder: The output folder.
        path: A path in it (relative paths are taken from the current folder, as ``open`` does).

    Returns:
        ``path`` as a :class:`~pathlib.Path` (unresolved).

    Raises:
        ConfigurationError: ``path`` resolves outside ``folder`` (names ``field`` and the path).
    """
    root = Path(folder).resolve()
    target = Path(path).resolve()
    if target != root and root not in target.parents:
        raise ConfigurationError(field, str(path), f"a path inside the folder {folder}")
    return Path(path)


def atomic_write(path: Path, write: Callable[[Any], None], binary: bool) -> None:
    """Write a file whole or not at all: into a temporary file of its folder, then renamed.

    A run stopped while writing leaves the old file (or none), never half of one. The file
    gets the usual mode (0o666 less the umask; ``mkstemp`` makes it private).

    Args:
        path: The file (its folder is made if missing).
        write: Called with the open file (bytes if ``binary``, else text with newline="").
        binary: Whether the file is written as bytes.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        fh: IO[Any]
        with os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="") as fh:
            write(fh)
        umask = os.umask(0o022)  # mkstemp makes the file private: give it the usual mode
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
