"""Controllers: the sampled-data interface (:mod:`packbot.control.base`) and its implementations.

- :class:`GravityCompensation`, :class:`JointPD`, :class:`ComputedTorque` (with
  :class:`JointTrajectory`), :class:`CartesianPD`: the standard arm controllers;
- :class:`ReconfigurableController`: places the gripper and re-plans after a joint failure,
  detected by a :class:`MomentumObserver` or reported by the simulator;
- :func:`build_controller`: a controller from a scenario file's values.
"""

from packbot.control.base import Controller, Sensor
from packbot.control.cartesian import CartesianPD
from packbot.control.computed_torque import ComputedTorque
from packbot.control.detector import Detection, MomentumObserver
from packbot.control.gravity import GravityCompensation
from packbot.control.ik import IKResult, solve_position_ik
from packbot.control.model_based import ModelBasedController
from packbot.control.pd import JointPD
from packbot.control.reconfig import ReconfigEvent, ReconfigurableController
from packbot.control.registry import CONTROLLER_KINDS, CONTROLLER_PARAMS, build_controller
from packbot.control.trajectory import JointTrajectory, QuinticSegment, min_jerk_duration

__all__ = [
    "CONTROLLER_KINDS",
    "CONTROLLER_PARAMS",
    "CartesianPD",
    "ComputedTorque",
    "Controller",
    "Detection",
    "GravityCompensation",
    "IKResult",
    "JointPD",
    "JointTrajectory",
    "ModelBasedController",
    "MomentumObserver",
    "QuinticSegment",
    "ReconfigEvent",
    "ReconfigurableController",
    "Sensor",
    "build_controller",
    "min_jerk_duration",
    "solve_position_ik",
]
