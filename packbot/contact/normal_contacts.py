"""The contact-normal mode's contact set: its restart and re-patch sequences."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from packbot.contact.normal_modes import ModeEvent, ModeSelection
from packbot.contact.normal_steps import RestartSteps

__all__ = ["NormalContacts"]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


class NormalContacts(RestartSteps, ModeSelection):
    """The contact set of the normal mode, its modes, and the constrained dynamics.

    The layers, one module each: the set (:class:`~packbot.contact.normal_set.ContactSet`),
    its rows (:class:`~packbot.contact.normal_rows.ContactRows`), the dynamics with the modes
    fixed (:class:`~packbot.contact.normal_dynamics.ConstrainedDynamics`), the mode selection
    (:class:`~packbot.contact.normal_modes.ModeSelection`) and the restart's steps
    (:class:`~packbot.contact.normal_steps.RestartSteps`); this class runs a restart and a
    re-patch with them. Arguments: see :class:`~packbot.contact.normal_set.ContactSet`.
    """

    def restart(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray, list[ModeEvent]]:
        """Drift correction, impulse, then modes, at a restart.

        Args:
            q: Configuration [rad].
            v: Velocity before [rad/s].
            a_free_fn: Callable (q, v) -> unconstrained accelerations [rad/s^2].
            minv: M^-1 at q.

        Returns:
            The configuration after the drift correction, the velocity after the impulse and
            the mode changes to log.
        """
        self.refresh(q)
        events: list[ModeEvent] = []
        q_in = q
        q = self.project(q, v, minv)
        if q is not q_in and not np.array_equal(q, q_in):
            v = self.neutral_velocity(q_in, q, v)
            # the impulse's energy balance is exact only with M at the q it acts on
            minv = np.array(pin.computeMinverse(self.model, self.data, q), dtype=np.float64)
            lower = self._lower  # (Pinocchio fills the upper triangle)
            minv[lower] = minv.T[lower]
        self.bounced = False
        v = self.impulse(q, v, minv)
        v = self.stop_slow(q, v, minv)
        captured = self.capture(q, v, a_free_fn, minv)
        if captured is not None:
            return q, np.zeros_like(v), events + captured
        events += self.select_modes(q, v, a_free_fn(q, v), minv)
        return q, v, events

    def repatch(
        self, q: FloatArray, v: FloatArray, a_free_fn: Any, minv: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Recompute the patches of a sliding contact, correct drift and select the modes again.

        The engaged rows before are kept when they still solve the mode problem
        (:meth:`repatch_modes`: one solve instead of the full selection); otherwise
        ``select_modes(keep=True)``.

        Returns:
            The corrected configuration [rad] and the velocity after it [rad/s]
            (:meth:`neutral_velocity`).
        """
        signature, engaged = self.row_signature(), list(self.engaged)
        self.refresh(q)
        q_in = q
        q = self.project(q, v, minv)
        if q is not q_in and not np.array_equal(q, q_in):
            v = self.neutral_velocity(q_in, q, v)
        self.repatch_modes(q, v, a_free_fn(q, v), minv, signature, engaged)
        return q, v

    def neutral_velocity(self, q0: FloatArray, q1: FloatArray, v: FloatArray) -> FloatArray:
        """The velocity after a drift projection q0 -> q1 that adds no energy [rad/s].

        The projection moves the arm out of the surfaces it drifted or was carried into (an
        event's tolerance, a stale patch's last micrometres) along the rows' normals, against
        gravity when gravity pressed it in, and keeps the velocity: the energy
        E = 1/2 v^T M(q) v + V(q) would rise by E(q1, v) - E(q0, v), energy the motion into
        the surface had turned from potential into kinetic. A positive change is taken from
        the kinetic energy by scaling v (the least change of v in the metric M(q1) that
        reaches the energy; its direction kept, so the contact set's conditions at zero still
        hold: no touching row approaching, sticking rows at rest); to zero where the kinetic
        energy is smaller (the rest of the rise stays, uncounted). A change that lowers the
        energy is left. The removed energy is added to
        :attr:`projection_energy_removed` [J]. The extension's ``ContactRhs.neutral_velocity``
        (the compiled stretch's re-patch calls it too).
        """
        v1, removed = self._rows_rhs().neutral_velocity(q0, q1, v)
        self.projection_energy_removed += removed
        return v1
