"""CSV cells a spreadsheet will not run as formulas.

A spreadsheet reads a cell beginning with ``=``, ``+``, ``-`` or ``@`` (and, in some, a tab or a
carriage return) as a formula: an obstacle named ``=HYPERLINK("http://...")`` in an event log
would run when the CSV is opened. :func:`spreadsheet_safe` prefixes such a cell with a single
quote (``'=HYPERLINK(...)``), as OWASP advises ("CSV injection"), unless the cell is a number
(``-0.5``, ``+1e-3`` and ``-inf`` stay numbers). Every CSV packbot writes (the event logs, the
occlusion tables, a batch's and a regression's ``summary.csv``) passes its cells through it.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

__all__ = ["FORMULA_STARTS", "spreadsheet_row", "spreadsheet_safe"]

#: The first characters that make a spreadsheet read a cell as a formula.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _is_number(text: str) -> bool:
    if text != text.strip() or "_" in text:  # float() accepts " 1" and "1_0"; a sheet does not
        return False
    try:
        float(text)
    except ValueError:
        return False
    return True


def spreadsheet_safe(cell: Any) -> Any:
    """A CSV cell that a spreadsheet shows as text instead of running it.

    Args:
        cell: The cell's value; only strings are changed.

    Returns:
        ``cell`` as it is, or ``"'" + cell`` for a string beginning with one of
        :data:`FORMULA_STARTS` that is not a number.
    """
    if isinstance(cell, str) and cell.startswith(FORMULA_STARTS) and not _is_number(cell):
        return "'" + cell
    return cell


def spreadsheet_row(cells: Iterable[Any]) -> list[Any]:
    """:func:`spreadsheet_safe` of each cell of a row."""
    return [spreadsheet_safe(c) for c in cells]
