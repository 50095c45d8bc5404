"""A contact patch as material points: the pair record and the patch geometry.

A pair in contact is stored as its patch points on each body (in their joint frames), its
normal fixed in the body whose face it is and its friction mode (:class:`_Pair`). The helpers
are the face planes of a piece and the numpy reference of the patch construction
(``kernels.patch_material``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.collision import PairInfo
from packbot.contact.normal_tolerances import PATCH_TOL, SLIDE_TOL

FloatArray = NDArray[np.float64]


@dataclass
class _Pair:
    """A pair in contact: its patch as material points and its friction mode.

    The normal (from body 1 to body 2) is fixed in the body whose face it is
    (:func:`packbot.contact.kernels.normal_owner`): body 2's joint frame, or body 1's when
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


# The patch construction in numpy (the reference of kernels.patch_material: tests).
def _consistent(pts1: FloatArray, pts2: FloatArray, patch: Any) -> bool:
    """Whether a patch's points have gaps (along its normal) within PATCH_TOL of its distance.

    The smallest gap is the pair's distance; the others may exceed it (points on a tilted
    face) but not fall below it.
    """
    gaps = (pts2 - pts1) @ patch.normal
    d = float(patch.distance)
    return bool(abs(float(gaps.min()) - d) <= PATCH_TOL and float(gaps.max()) <= d + 1e-3)


def _lift(
    planes: tuple[FloatArray, FloatArray] | None,
    oMg: pin.SE3,
    mid: FloatArray,
    n: FloatArray,
    sign: float,
) -> FloatArray | None:
    """Patch points moved along n onto the shape's face most aligned with sign * n.

    Coal puts every patch point at the patch's one depth; on two faces meeting at a small angle
    the points' true gaps differ (by up to Coal's patch tolerance, 1 mm). The face whose
    outward normal is closest to sign * n carries them. ``planes``: the shape's face planes
    (:func:`_planes`), None if it has none.
    """
    if planes is None:
        return None
    N, o = planes
    R, t = oMg.rotation, oMg.translation
    nl = R.T @ n
    f = int(np.argmax(sign * (N @ nl)))
    den = float(N[f] @ nl)
    if abs(den) < 0.5:
        return None
    pl = (mid - t) @ R  # local
    s = -(pl @ N[f] + o[f]) / den
    return np.asarray(mid + s[:, None] * n, dtype=np.float64)


def _tangents(n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit tangents (t1, t2) with (t1, t2, n) right-handed."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = _cross(a, n)
    t1 /= np.linalg.norm(t1)
    return t1, _cross(n, t1)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of 3-vectors along the last axis, broadcast.

    np.cross is slow on the small arrays of the contact rows.
    """
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out
