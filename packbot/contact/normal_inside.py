"""What passes between a step's ends: a joint past its stop and back, a pair through contact.

The contact-normal mode's event functions are read at a step's ends; a long or fast step can
carry a joint past its stop and back, or a pair into contact and apart, with nothing to see at
either end. These screens find such passes on the step's dense output and return them as
crossings located before the pass (:class:`~packbot.contact.normal_law.NormalLaw`'s
:meth:`watch <packbot.contact.normal_law.NormalLaw.watch>`; docs/contact.md, "No contact
missed between step ends").
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from packbot.collision import SweepResult
from packbot.contact.base import Crossing, Key
from packbot.contact.native import NativeRhs
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_tolerances import POINT_TOL
from packbot.ode import DenseSegment

__all__ = ["EXCURSION_TOL", "limit_excursions", "pair_dips"]

FloatArray = NDArray[np.float64]

#: How far past a stop [rad] the cubic Hermite of a step's ends must reach for the step's dense
#: output to be asked (:func:`limit_excursions`; a joint resting on its stop reads its stop to
#: rounding; the compiled stretch's screen uses the same 1e-9).
EXCURSION_TOL = 1e-9


def limit_excursions(
    seg: DenseSegment,
    native: NativeRhs,
    normal: NormalContacts,
    upper: FloatArray,
    lower: FloatArray,
) -> list[Crossing]:
    """Joints that pass a stop inside the step and are within it at both of its ends.

    A long step (35 ms with the wrists locked) can carry a joint past its stop and back with no
    event at the step's end: the candidates are the extremes of the cubic Hermite of the joint's
    (q, v) at the step's ends beyond a stop (``ContactRhs.limit_excursions``); an extreme the
    step's dense output confirms is an event, located before it: a stop's ``limit`` event, or
    for a stop in the contact set (a free row) its row's ``impact``. A held stop's row
    (engaged) is left to the modes.

    Args:
        seg: The step.
        native: The law's compiled right-hand side.
        normal: The law's contact set.
        upper: The joints' upper stops [rad].
        lower: The joints' lower stops [rad].
    """
    found = native.watch.limit_excursions(seg.y0, seg.y1, seg.h, EXCURSION_TOL)
    out: list[Crossing] = []
    for j, side, s in found:
        lim = float(upper[j] if side > 0 else lower[j])
        key: Key
        if (j, side) in normal.limits:
            if normal.limit_engaged(j, side):
                continue
            kind, key = "impact", ("mode", "nrow", normal.limit_row(j, side))
            offset = POINT_TOL
        else:
            kind, key, offset = "limit", ("limit", j, side), 0.0

        def g(t: float, j: int = j, side: int = side, lim: float = lim, c: float = offset) -> float:
            return float(side * (lim - seg(t)[j])) + c  # [rad]

        t_m = seg.t0 + s * seg.h
        g_m, g0 = g(t_m), g(seg.t0)
        if not (g_m < 0.0 < g0):
            continue  # (the dense output stays within the stop there)

        def early(t: float, g: Callable[[float], float] = g, t_m: float = t_m) -> float:
            return g(min(t, t_m))

        out.append(Crossing(kind, key, early, g0, g_m))
    return out


def pair_dips(
    seg: DenseSegment,
    sw: SweepResult,
    native: NativeRhs,
    active: NDArray[np.int64],
    start: dict[int, float],
    margin: float,
    screen: Callable[[int, FloatArray], float],
    distance: Callable[[int, FloatArray], float],
) -> list[Crossing]:
    """Pairs that touch inside the step and are apart at both of its ends.

    A fast, grazing pass (the camera head through a flipper's corner within one step) starts
    and ends the step apart: each swept pair is screened over the step by conservative
    advancement on its distance (:meth:`~packbot.contact.native.NativeWatch.pair_dips`); a query
    on the dense output that finds it touching is an ``impact`` (a pair of the contact set: its
    patch rebuilt there), one that finds a pair of the set leaving from contact below
    -:data:`~packbot.contact.normal_tolerances.PENETRATION_TOL` a ``repatch``, each located
    before that query.

    Args:
        seg: The step.
        sw: The sweep at the step's end.
        native: The law's compiled right-hand side.
        active: The pairs of the contact set (indices).
        start: The pairs' distances [m] at the step's start, where kept (else each pair is
            queried there when needed).
        margin: The sweep's query margin [m].
        screen: A pair's screening distance [m] at a state (counted as a query).
        distance: A pair's signed distance [m] at a state (the located function).
    """
    kept = (
        np.fromiter(start.keys(), np.int64, len(start)),
        np.fromiter(start.values(), float, len(start)),
    )
    found, _ = native.watch.pair_dips(seg, kept, (sw.pairs, sw.distances), active, margin, screen)
    out: list[Crossing] = []
    for p_idx, s, _, level in found:
        t_m = seg.t0 + s * seg.h

        def g(t: float, p_idx: int = p_idx, level: float = level) -> float:
            return distance(p_idx, seg(t)) - level  # [m]

        g0 = start.get(p_idx, math.nan) - level
        if not g0 > 0.0:
            g0 = g(seg.t0)
        g_m = g(t_m)  # (the located function's own value there: a bracket it agrees with)
        if not g_m <= 0.0 < g0:
            continue

        def early(t: float, g: Callable[[float], float] = g, t_m: float = t_m) -> float:
            return g(min(t, t_m))

        kind = "impact" if level == 0.0 else "repatch"
        out.append(Crossing(kind, ("pair", p_idx), early, g0, g_m))
    return out
