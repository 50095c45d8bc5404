"""The absolute tolerances of a regression against golden results (:mod:`packbot.regress`).

Its own module because a matrix file carries them (``[tolerances]``, checked when the matrix
loads, :mod:`packbot.matrix`) and the regression applies them: both import it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from packbot.errors import UnknownNameError
from packbot.keywords import checked_arguments
from packbot.validation import finite_number

__all__ = ["Tolerances"]


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Tolerances:
    """Absolute tolerances of :func:`packbot.regress.compare`.

    Attributes:
        q: Final joint positions [rad].
        time: Rest time and event times [s].
        distance: Minimum signed distance [m].
        energy: Energy change [J].
        chaotic_q: The least widening of a chaotic run's final joint-position band [rad]
            (:func:`packbot.regress.compare`: after its horizon a run's final pose is
            reproducible only to about this; docs/batch.md gives the measured spread).
    """

    q: float = 1e-6
    time: float = 1e-6
    distance: float = 1e-7
    energy: float = 1e-6
    chaotic_q: float = 0.05

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad tolerance (a bool is not one)."""
        for f in fields(self):
            finite_number(f"tolerances.{f.name}", getattr(self, f.name), low=0.0)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> Tolerances:
        """From a matrix file's ``[tolerances]`` table (missing names keep their default).

        Raises:
            UnknownNameError: An unknown tolerance name.
            ConfigurationError: A bad value.
        """
        names = [f.name for f in fields(cls)]
        for key in data:
            if key not in names:
                raise UnknownNameError("tolerance", key, names)
        tol = cls(**{k: finite_number(f"tolerances.{k}", v, low=0.0) for k, v in data.items()})
        tol.validate()
        return tol
