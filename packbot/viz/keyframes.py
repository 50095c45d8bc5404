"""Keyframes of an animation clip: when to sample a result, and the playback rate."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from packbot.errors import ConfigurationError
from packbot.result import SimResult

__all__ = ["FPS"]

#: Keyframes per second of simulated time [1/s].
FPS = 60.0
# A keyframe is dropped where interpolating its neighbours misses it by less than this [rad].
_STILL = 1e-4


def _keyframes(result: SimResult, fps: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Keyframe times [s] and q [rad] there.

    Every 1/fps s, the end and the event instants, less the keyframes that the linear
    interpolation between their kept neighbours reproduces within :data:`_STILL` (an arm at
    rest or turning steadily needs two keyframes, not one every 1/fps s).
    """
    t = np.asarray(result.t, dtype=float)
    if len(t) == 0:
        raise ConfigurationError("result.t", "empty", "a result with at least one sample")
    t0, t1 = float(t[0]), float(t[-1])
    grid = t0 + np.arange(math.floor((t1 - t0) * fps) + 1) / fps
    ev = [e.t for e in result.events if t0 <= e.t <= t1]
    t_keys = np.unique(np.concatenate([grid[grid <= t1], [t1], ev]))
    q = np.column_stack([np.interp(t_keys, t, result.q[:, j]) for j in range(result.q.shape[1])])
    # Greedy: extend the segment from the last kept key while interpolating across it
    # reproduces every key inside (the events are always kept).
    fixed = np.isin(t_keys, ev)
    keep = [0]
    for k in range(1, len(t_keys) - 1):
        a = keep[-1]
        w = (t_keys[a + 1 : k + 1] - t_keys[a]) / (t_keys[k + 1] - t_keys[a])
        err = q[a] + w[:, None] * (q[k + 1] - q[a]) - q[a + 1 : k + 1]
        if fixed[k] or np.abs(err).max() > _STILL:
            keep.append(k)
    keep.append(len(t_keys) - 1)
    return t_keys[keep], q[keep]


def _check_speed(speed: float) -> float:
    if not (isinstance(speed, (int, float)) and math.isfinite(speed) and speed > 0):
        raise ConfigurationError("speed", speed, "a finite playback rate > 0 (1 = real time)")
    return float(speed)
