"""The actions scheduled at given times: failures, payload pick and drop, controller ticks.

The loop cuts its integration steps at the failures and payload changes
(:meth:`Schedule.horizon`) and, once there, applies what :meth:`Schedule.due` returns, in order:
the failures due (in the order given), then the payload change, then the controller's tick. The
controller's ticks cut a step only while the command changes from tick to tick; the ticks inside
a longer step are taken on its dense output (:mod:`packbot.ticks`). Two small pieces of physics
that those actions need and that belong to no contact law are here too: the impulse that stops a
freezing joint (:func:`freeze_impulse`) and the velocities after picking up a payload
(:func:`momentum_kept`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from packbot.control.base import Controller
from packbot.failures import Failure
from packbot.payload import Payload
from packbot.system import System

__all__ = ["Schedule", "freeze_impulse", "momentum_kept"]

FloatArray = NDArray[np.float64]


class Schedule:
    """The scheduled actions of a run.

    Args:
        failures: Failures, each injected at its time.
        payload: A payload picked at ``t_pick`` (and dropped at ``t_drop``), or None.
        controller: A sampled-data controller (a tick every ``controller.dt``), or None.

    Attributes:
        ticks: The controller ticks so far.
    """

    def __init__(
        self,
        failures: Sequence[Failure],
        payload: Payload | None,
        controller: Controller | None,
    ) -> None:
        # (time, order, what): failures first, then the payload.
        self.queue: list[tuple[float, int, Failure | str]] = [(f.t, 0, f) for f in failures]
        if payload is not None:
            self.queue.append((payload.t_pick, 1, "pick"))
            if payload.t_drop is not None:
                self.queue.append((payload.t_drop, 1, "drop"))
        self.queue.sort(key=lambda x: (x[0], x[1]))
        self.controller = controller
        self.next_tick = 0.0 if controller is not None else math.inf
        self.ticks = 0

    def next_time(self) -> float:
        """Time of the next scheduled action (failure, payload, control tick) [s]."""
        t_next = self.queue[0][0] if self.queue else math.inf
        return min(t_next, self.next_tick)

    def horizon(self, ticks: bool) -> float:
        """Time [s] the next step must end at: the next failure or payload change.

        Args:
            ticks: Whether the next controller tick ends it too.
        """
        t_next = self.queue[0][0] if self.queue else math.inf
        return min(t_next, self.next_tick) if ticks else t_next

    def due(self, t: float) -> list[Failure | str]:
        """The failures and payload changes ("pick", "drop") due at t (within 1e-12 s).

        They are taken off the schedule.
        """
        out = []
        while self.queue and self.queue[0][0] <= t + 1e-12:
            out.append(self.queue.pop(0)[2])
        return out

    def tick_due(self, t: float) -> bool:
        """Whether the controller ticks at t (within 1e-12 s)."""
        return self.next_tick <= t + 1e-12

    def ticked(self) -> None:
        """Count a tick; the next one is due a period later."""
        assert self.controller is not None
        self.ticks += 1
        self.next_tick = self.ticks * self.controller.dt


def freeze_impulse(
    sys: System, q: FloatArray, v: FloatArray, j: int, still: Sequence[int]
) -> tuple[FloatArray, NDArray[np.intp]]:
    """The velocities after the impulse that stops joint j, the joints ``still`` kept still.

    The arm keeps its generalized momentum (M dv = S^T p, p the joint impulses [N*m*s]): the
    joints in ``still`` (engaged and held locks: their velocities are zero) stay at zero.

    Returns:
        The velocities after [rad/s] and the joints the impulse acted on.
    """
    idx = np.array(sorted({j, *still}), dtype=int)
    minv = sys.minv(q)
    p = np.linalg.solve(minv[np.ix_(idx, idx)], v[idx])
    v_new = v - minv[:, idx] @ p
    v_new[idx] = 0.0
    return v_new, idx


def momentum_kept(sys: System, q: FloatArray, momentum: FloatArray) -> FloatArray:
    """Velocities [rad/s] of the new system with the generalized momentum M v [N*m*s] kept."""
    return np.asarray(np.linalg.solve(sys.mass_matrix(q), momentum), dtype=np.float64)
