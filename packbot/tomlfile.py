"""The TOML reader of scenario and matrix files, with their size and nesting bounds.

One parser for every file packbot reads as TOML (:func:`loads`): a file larger than
:data:`~packbot.validation.MAX_TOML_BYTES`, nested deeper than
:data:`~packbot.validation.MAX_TOML_DEPTH` (tables and arrays) or not valid TOML raises one
:class:`~packbot.errors.ConfigurationError` naming the file, never a ``RecursionError``.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from packbot.errors import ConfigurationError
from packbot.validation import MAX_TOML_BYTES, MAX_TOML_DEPTH

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["check_file_size", "loads", "nesting_depth"]


def check_file_size(path: Path, field: str, value: Any) -> None:
    """Refuse a file larger than :data:`~packbot.validation.MAX_TOML_BYTES` before reading it.

    Args:
        path: The file (a missing or special file passes: its reader reports it).
        field: The field for the error (``"scenario"``, the matrix file).
        value: The value shown (the path).

    Raises:
        ConfigurationError: The file is too large.
    """
    try:
        size = path.stat().st_size
    except OSError:
        return
    if size > MAX_TOML_BYTES:
        raise ConfigurationError(field, value, _too_large(size))


def _too_large(size: int) -> str:
    return f"a TOML file of at most {MAX_TOML_BYTES:,} bytes (this one has {size:,})"


def nesting_depth(value: Any) -> int:
    """How deep tables and arrays nest in ``value`` (0 for a scalar), without recursion."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(value, 0)]
    while stack:
        x, depth = stack.pop()
        if isinstance(x, dict):
            items: Any = x.values()
        elif isinstance(x, list):
            items = x
        else:
            continue
        deepest = max(deepest, depth + 1)
        if depth + 1 > MAX_TOML_DEPTH:
            return depth + 1  # deep enough to refuse: stop walking
        stack.extend((item, depth + 1) for item in items)
    return deepest


def loads(text: str, field: str, value: Any) -> dict[str, Any]:
    """Parse a file's TOML text within the bounds.

    Args:
        text: The file's text.
        field: The field for the error (``"scenario"``, the matrix file).
        value: The value shown (the path, or ``"(file)"``).

    Raises:
        ConfigurationError: Not valid TOML (says where), larger than
            :data:`~packbot.validation.MAX_TOML_BYTES` or nested deeper than
            :data:`~packbot.validation.MAX_TOML_DEPTH`.
    """
    size = len(text.encode("utf-8", errors="replace"))
    if size > MAX_TOML_BYTES:
        raise ConfigurationError(field, value, _too_large(size))
    deep = f"TOML nested at most {MAX_TOML_DEPTH} levels deep (tables and arrays)"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigurationError(field, value, f"valid TOML: {exc}") from None
    except RecursionError:  # the parser recurses into nested arrays and inline tables
        raise ConfigurationError(field, value, deep) from None
    if nesting_depth(data) > MAX_TOML_DEPTH:
        raise ConfigurationError(field, value, deep)
    return data
