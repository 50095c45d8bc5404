"""Controllers: the sampled-data interface (:mod:`packbot.control.base`) and its implementations."""

from packbot.control.base import Controller, Sensor

__all__ = ["Controller", "Sensor"]
