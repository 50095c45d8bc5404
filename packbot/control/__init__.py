"""Controllers: the sampled-data interface (:mod:`packbot.control.base`) and its implementations.

- :class:`GravityCompensation`, :class:`JointPD`, :class:`ComputedTorque` (with
  :class:`JointTrajectory`), :class:`CartesianPD`: the standard arm controllers;
- :class:`ReconfigurableController`: places the gripper and re-plans after a joint failure,
  detected by a :class:`MomentumObserver` or reported by the simulator;
- :func:`build_controller`: a controller from a scenario file's values;
- :func:`exciting_trajectory`: a motion for identifying the inertial parameters
  (:func:`packbot.identify`);
- :func:`solve_position_ik` (collision-free by default) and :func:`check_path` (the first
  collision along a joint path);
- :class:`TaskRecovery`, :class:`RecoveryStrategy` (:class:`BaselineRecovery`,
  :class:`NoRecovery`), :class:`FailureReport`: the reconfigured run of a failure study and the
  strategies it hands detections to (yours or the built-in ones).
"""

from packbot.control.base import Controller, Sensor
from packbot.control.cartesian import CartesianPD
from packbot.control.computed_torque import ComputedTorque
from packbot.control.context import FailureReport, RecoveryContext, RecoveryEvent
from packbot.control.detector import Detection, MomentumObserver
from packbot.control.excitation import ExcitingTrajectory, exciting_trajectory
from packbot.control.gravity import GravityCompensation
from packbot.control.ik import IKResult, solve_position_ik
from packbot.control.model_based import ModelBasedController
from packbot.control.path_check import PathCollision, check_path, reach_bounds
from packbot.control.pd import JointPD
from packbot.control.reconfig import ReconfigEvent, ReconfigurableController
from packbot.control.recovery import TaskRecovery
from packbot.control.reduced_arm import ReducedArmTracker
from packbot.control.registry import CONTROLLER_KINDS, CONTROLLER_PARAMS, build_controller
from packbot.control.strategies import BaselineRecovery, NoRecovery, RecoveryStrategy
from packbot.control.trajectory import JointTrajectory, QuinticSegment, min_jerk_duration
from packbot.control.weak_joint import WeakJointTracker, holdable_posture

__all__ = [
    "CONTROLLER_KINDS",
    "CONTROLLER_PARAMS",
    "BaselineRecovery",
    "CartesianPD",
    "ComputedTorque",
    "Controller",
    "Detection",
    "ExcitingTrajectory",
    "FailureReport",
    "GravityCompensation",
    "IKResult",
    "JointPD",
    "JointTrajectory",
    "ModelBasedController",
    "MomentumObserver",
    "NoRecovery",
    "PathCollision",
    "QuinticSegment",
    "ReconfigEvent",
    "ReconfigurableController",
    "RecoveryContext",
    "RecoveryEvent",
    "RecoveryStrategy",
    "ReducedArmTracker",
    "Sensor",
    "TaskRecovery",
    "WeakJointTracker",
    "build_controller",
    "check_path",
    "exciting_trajectory",
    "holdable_posture",
    "min_jerk_duration",
    "reach_bounds",
    "solve_position_ik",
]
