"""The format tag of a study matrix's summary (``study-matrix.json``).

:func:`packbot.study_matrix.study_matrix_summary` writes it into the summary and
:func:`packbot.viz.study_matrix_report.write_matrix_report` checks it before rendering one (a
summary read back from the file is data): both read it here.
"""

from __future__ import annotations

__all__ = ["SUMMARY_FORMAT"]

#: Format tag of ``study-matrix.json``.
SUMMARY_FORMAT = "packbot-study-matrix/1"
