"""The mode selection in one native call (``ContactRhs.select_modes``, ``src/native/modes.hpp``):
its argument checks. What the selection does on real runs (rest, no penetration, no energy
gained at an event) is checked in ``test_native_restart.py``.
"""

import numpy as np
import pytest

import packbot
from packbot.contact import native

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def test_select_modes_refuses_bad_arguments(robot):
    from packbot.system import System

    cfg = packbot.SimConfig(contact_mode="normal", locked_joints=WRIST)
    sysm = System(robot, robot.pose("drive"), cfg, None)
    rhs = native.NativeRhs(sysm.model)
    n = sysm.nv
    z, M = np.zeros(n), np.eye(n)
    args = (0.5, 1e-6, 1e-6, 1e-4, 1e-6, 1e-6, 10.0, 1e-8)
    stick, slip = np.zeros(0, dtype=np.uint8), np.zeros((0, 3))
    with pytest.raises(ValueError, match="layout first"):
        rhs._rhs.select_modes(z, z, z, M, False, np.zeros(0, dtype=np.int64), stick, slip, *args)
    with pytest.raises(ValueError, match=r"minv \(nv, nv\)"):
        rhs._rhs.select_modes(
            z, z, z, M[:1], False, np.zeros(0, dtype=np.int64), stick, slip, *args
        )
