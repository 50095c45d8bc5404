"""A contact patch as material points: the pair record and the patch geometry.

A pair in contact is stored as its patch points on each body (in their joint frames), its
normal fixed in the body whose face it is and its friction mode (:class:`_Pair`), and the
face planes of a piece (:func:`_planes`). The patch itself is made in the extension
(``src/native/material.hpp``: ``packbot._native.patch_material``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact.normal_tolerances import SLIDE_TOL

FloatArray = NDArray[np.float64]


@dataclass
class _Pair:
    """A pair in contact: its patch as material points and its friction mode.

    The normal (from body 1 to body 2) is fixed in the body whose face it is
    (``normal_owner`` in ``src/native/material.hpp``): body 2's joint frame, or body 1's when
    ``on1``; ``normal2``, ``frame2`` and ``offset0`` are in that frame.
    """

    info: PairInfo
    local1: FloatArray  # (K, 3) points on body 1, joint1 frame [m]
    local2: FloatArray  # (K, 3) points on body 2, joint2 frame [m]
    normal2: FloatArray  # (3,) normal in the frame of the joint carrying it
    on1: bool = False  # the normal is a face normal of body 1, fixed in joint1's frame
    #: the slide [m] its patch goes stale at (``NormalContacts.stale``): SLIDE_TOL, or inf for a
    #: vertex on a face or a patch on a halfspace's face (normal_tolerances.FACE_ALIGN)
    slide_tol: float = SLIDE_TOL
    stick: bool = True
    slip_dir: FloatArray = field(default_factory=lambda: np.zeros(3))  # world, at onset
    # (2, K) tangential offsets (t1, t2 of the contact frame) of p2 - p1 when built [m]
    offset0: FloatArray = field(default_factory=lambda: np.zeros((2, 0)))
    # the patch centres (means of the points) in the joint frames [m] and the contact frame
    # (rows t1, t2, n) in the normal's joint frame: computed once, for the point layout
    centre1: FloatArray = field(init=False)
    centre2: FloatArray = field(init=False)
    frame2: FloatArray = field(init=False)
    #: the configuration (its bytes) and query margin [m] the patch was built at
    #: (``ContactSet.refresh`` does not build it again there)
    built: tuple[bytes, float] = (b"", math.nan)


def _planes(shape: Any) -> tuple[FloatArray, FloatArray] | None:
    """Face planes (unit outward normals N, offsets o: inside <=> N x + o <= 0), local frame."""
    if isinstance(shape, coal.Halfspace):
        return np.array([shape.n]), np.array([-float(shape.d)])
    if isinstance(shape, coal.Box):
        h = np.asarray(shape.halfSide)
        N = np.vstack([np.eye(3), -np.eye(3)])
        return N, -np.concatenate([h, h])
    try:
        N = np.asarray(shape.normals(), dtype=float)
        o = np.asarray(shape.offsets(), dtype=float)
    except (AttributeError, RuntimeError):
        return None
    return (N, o) if len(N) else None
