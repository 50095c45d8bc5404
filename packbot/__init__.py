"""packbot: event-driven simulation of the iRobot PackBot EOD manipulator."""

from packbot.collision import CollisionWorld, Contact, ContactPatch, PairInfo
from packbot.config import SimConfig
from packbot.contact_forces import ContactForce, ContactTable
from packbot.contact_impulses import ContactImpulse, ImpactTable
from packbot.environment import FLOOR, Environment, Obstacle
from packbot.errors import (
    ConfigurationError,
    ControllerError,
    ConvexityError,
    InitialCollisionError,
    ModelError,
    PackbotError,
    ResourceNotFound,
    SimulationError,
    UnknownNameError,
)
from packbot.failures import FAILURE_KINDS, Failure
from packbot.identification import Identification, identify, identify_csv
from packbot.integrator import simulate
from packbot.model import JointParams, Robot, load_robot
from packbot.payload import Payload
from packbot.resources import package_dirs, urdf_path
from packbot.result import Diagnostics, Event, SimResult
from packbot.study import StudyResult, study
from packbot.uncertain_run import UncertainRun, uncertain_run
from packbot.uncertain_study import UncertainStudy, uncertain_study
from packbot.uncertainty import ParameterSample, SampledRobots, sample_robots, sample_values

#: The package version (PEP 440), as in pyproject.toml.
__version__ = "0.1.0"

__all__ = [
    "FAILURE_KINDS",
    "FLOOR",
    "CollisionWorld",
    "ConfigurationError",
    "Contact",
    "ContactForce",
    "ContactImpulse",
    "ContactPatch",
    "ContactTable",
    "ControllerError",
    "ConvexityError",
    "Diagnostics",
    "Environment",
    "Event",
    "Failure",
    "Identification",
    "ImpactTable",
    "InitialCollisionError",
    "JointParams",
    "ModelError",
    "Obstacle",
    "PackbotError",
    "PairInfo",
    "ParameterSample",
    "Payload",
    "ResourceNotFound",
    "Robot",
    "SampledRobots",
    "SimConfig",
    "SimResult",
    "SimulationError",
    "StudyResult",
    "UncertainRun",
    "UncertainStudy",
    "UnknownNameError",
    "__version__",
    "identify",
    "identify_csv",
    "load_robot",
    "package_dirs",
    "sample_robots",
    "sample_values",
    "simulate",
    "study",
    "uncertain_run",
    "uncertain_study",
    "urdf_path",
]
