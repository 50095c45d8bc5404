"""What the contact-normal mode watches at a step's end: the screen's code and its checks.

After a native step (:meth:`NormalLaw.step_kernel
<packbot.contact.normal_law.NormalLaw.step_kernel>`), one call on its last stage's evaluation
and the end's sweep (:meth:`~packbot.contact.native.NativeWatch.end_check`: :func:`end_code`)
says which of the checks of :meth:`NormalLaw.watch <packbot.contact.normal_law.NormalLaw.watch>`
and ``after_step`` can find something: the limits' (bit 8), the pairs' (an impact, a release,
a re-patch: 1), the modes' (a negative condition: 2) and the refresh's (a sliding contact's
stale patch: 4); -1: not a native step's end (every check runs). :func:`screened_crossings`
runs the checks the code asks for; a step end it finds clear (the common case) is marked on
the law (``NormalLaw._clear``: nothing to re-patch there, its evaluation handed to the contact
set only if events or a window read it, :func:`keep_end_eval`). What passes between the step's
ends (a joint past its stop and back, a pair through contact and apart) is
:mod:`packbot.contact.normal_inside`'s, read here on the law's state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from packbot.collision import SweepResult
from packbot.contact.base import Crossing
from packbot.contact.normal_inside import limit_excursions, pair_dips
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.ode import DenseSegment

if TYPE_CHECKING:
    from packbot.contact.normal_law import NormalLaw

__all__ = [
    "dip_crossings",
    "end_code",
    "excursion_crossings",
    "keep_end_eval",
    "mode_crossings",
    "screened_crossings",
]

FloatArray = NDArray[np.float64]


def end_code(law: NormalLaw, y1: FloatArray, sw: SweepResult) -> int:
    """The step end's screen (:meth:`~packbot.contact.native.NativeWatch.end_check`); -1: none.

    Args:
        law: The law (its contact set, its native right-hand side, its active pairs).
        y1: The step's end.
        sw: The sweep there.
    """
    if law.normal.empty:
        return -1
    active = np.array([k[1] for k in law.active if k[0] == "pair"], dtype=np.int64)
    return law._native.watch.end_check(
        y1,
        sw.pairs,
        sw.distances,
        active,
        law.cfg.proximity_tolerance,
        PENETRATION_TOL,
    )


def screened_crossings(
    law: NormalLaw, seg: DenseSegment, y1: FloatArray, sw: SweepResult, code: int
) -> list[Crossing]:
    """The pairs' and modes' events over the step: the checks the screen's code asks for.

    As without the screen; a step end it finds clear of pair, mode and refresh checks (the
    common case) is marked for the law's refresh (nothing to re-patch there).
    """
    if code < 0:  # not a native step's end: every check
        out = law._swept_crossings(seg, sw)
        out.extend(mode_crossings(law, seg, y1))
        return out
    out = law._swept_crossings(seg, sw) if code & 1 else []
    if code & 2:
        out.extend(mode_crossings(law, seg, y1))
    elif code & 4:  # the evaluation the refresh reads (end_eval's, as without the screen)
        law._native.end_eval(law.normal, y1)
    else:
        law._clear = y1
    return out


def mode_crossings(law: NormalLaw, seg: DenseSegment, y1: FloatArray) -> list[Crossing]:
    """The contact set's mode conditions that changed sign over the step."""
    nc = law.normal
    if nc.empty:
        return []
    rhs = law._native
    ev = rhs.end_eval(nc, y1)  # a native step's end: its last stage evaluated the conditions
    if ev is not None and ev.cond is not None and ev.cond >= 0.0:
        return []
    # (ev None: not a native step, its modes are not the loaded ones)
    return law._problem_crossings(nc, seg, y1, None if ev is None else rhs)


def keep_end_eval(law: NormalLaw) -> None:
    """The last step end's evaluation kept by the contact set, as without the screen.

    A step end the screen found clear (:func:`screened_crossings`) did not hand its
    evaluation to the contact set; before events or a window, which may read it, it does.
    """
    if law._clear is not None:
        law._native.end_eval(law.normal, law._clear)


def excursion_crossings(law: NormalLaw, seg: DenseSegment) -> list[Crossing]:
    """Joints past a stop inside the step and within it at its ends (:func:`limit_excursions`)."""
    if not law.cfg.joint_limits or law.normal.resting:
        return []
    return limit_excursions(seg, law._native, law.normal, law.sys.upper, law.sys.lower)


def dip_crossings(law: NormalLaw, seg: DenseSegment, sw: SweepResult) -> list[Crossing]:
    """Pairs that touch inside the step and are apart at its ends (:func:`pair_dips`)."""
    active = np.array([k[1] for k in law.active if k[0] == "pair"], dtype=np.int64)
    # the kept distances are the step start's, unless a re-patch's projection moved it
    # since they were swept (then each pair is queried at the start when needed)
    last = law.last_d if law._start_swept else {}
    law._start_swept = True
    n = law.n

    def screen(pair: int, y: FloatArray) -> float:
        law.diag.distance_queries += 1
        return law.world.screen_distance(y[:n], pair)

    return pair_dips(seg, sw, law._native, active, last, law.cfg.margin, screen, law.distance)
