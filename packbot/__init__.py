"""packbot: event-driven simulation of the iRobot PackBot EOD manipulator."""

from packbot.errors import (
    ConfigurationError,
    ConvexityError,
    ModelError,
    PackbotError,
    ResourceNotFound,
    UnknownNameError,
)
from packbot.model import JointParams, Robot, load_robot

__version__ = "0.1.0"

__all__ = [
    "ConfigurationError",
    "ConvexityError",
    "JointParams",
    "ModelError",
    "PackbotError",
    "ResourceNotFound",
    "Robot",
    "UnknownNameError",
    "__version__",
    "load_robot",
]
