"""One evaluation of the contact-normal mode's constrained dynamics with the modes fixed.

What :meth:`ConstrainedDynamics.evaluate
<packbot.contact.normal_dynamics.ConstrainedDynamics.evaluate>` and the extension's evaluations
(:class:`packbot.contact.native.NativeRhs`) return.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass
class _Eval:
    """The constrained dynamics at one state with the modes fixed."""

    a: FloatArray
    lam: FloatArray  # forces of the engaged normal rows then the stick rows
    gap: FloatArray  # every row
    vn: FloatArray  # every row
    vt: FloatArray  # (pairs, 3): relative tangential velocity at each patch centre (world)
    rest: tuple[FloatArray, FloatArray, FloatArray] | None = None  # (q, a_free, M^-1) at rest
    # the rows' generalized force C^T lambda [N*m] (None: not asked for, see evaluate's forces)
    qc: FloatArray | None = None
    cond: float | None = None  # the smallest mode condition (compiled path; see violated)
    slide2: FloatArray | None = None  # (pairs,) largest squared slide (compiled; see stale)
