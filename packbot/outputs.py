"""The outputs of a scenario (its ``[outputs]`` table): plots, image formats, occlusion check.

What a run writes besides its trajectory and event log (:func:`packbot.scenario.write_outputs`
writes it): :class:`Outputs`, the plot kinds it may ask for (:data:`PLOT_KINDS`), the image
formats (:data:`IMAGE_FORMATS`) and the camera-occlusion check (:class:`OcclusionCheck`).
:mod:`packbot.scenario` loads a scenario file's table into them (and re-exports them);
:mod:`packbot.scenario_schema` describes them to editors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments
from packbot.validation import MAX_OCCLUSION_TARGETS, at_most

__all__ = ["IMAGE_FORMATS", "PLOT_KINDS", "OcclusionCheck", "Outputs"]

#: The plots a scenario can ask for (``[outputs] plots``).
PLOT_KINDS: tuple[str, ...] = (
    "joints",
    "distance",
    "energy",
    "tracking",
    "torques",
    "tool_path",
    "occlusion",
    "contacts",
)
#: The image formats of the plots (``[outputs] formats``).
IMAGE_FORMATS: tuple[str, ...] = ("png", "svg")
_PLANAR_JOINTS = ("shoulder", "elbow1", "elbow2")


def _finite(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class OcclusionCheck:
    """Is the camera's view of target points blocked (by the arm, the chassis, obstacles)?

    Evaluated at every sample with :meth:`packbot.CollisionWorld.line_of_sight`.

    Attributes:
        targets: World points looked at [m], each (x, y, z) in the ``base_link`` frame.
        frame: The eye: a Pinocchio frame (default the camera's optical frame).
        radius: Radius of the clear corridor asked for [m] (0: the line itself).
        ignore: Links not tested (default the camera head, on which the line starts).
    """

    targets: tuple[tuple[float, float, float], ...]
    frame: str = "camera_optical"
    radius: float = 0.0
    ignore: tuple[str, ...] = ("camera_head",)

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field."""
        if not self.targets:
            raise ConfigurationError(
                "outputs.occlusion.targets", self.targets, "at least one (x, y, z) point [m]"
            )
        if isinstance(self.targets, (list, tuple)):
            at_most(
                "outputs.occlusion.targets",
                self.targets,
                len(self.targets),
                MAX_OCCLUSION_TARGETS,
                "targets",
            )
        for k, p in enumerate(self.targets):
            if len(p) != 3 or not all(_finite(x) for x in p):
                raise ConfigurationError(
                    f"outputs.occlusion.targets[{k}]", p, "3 finite coordinates [m]"
                )
        if not (_finite(self.radius) and self.radius >= 0):
            raise ConfigurationError(
                "outputs.occlusion.radius", self.radius, "a finite radius >= 0 [m]"
            )


@checked_arguments
@dataclass(frozen=True, kw_only=True)
class Outputs:
    """What a run writes besides its trajectory and event log.

    Attributes:
        plots: Plot kinds (:data:`PLOT_KINDS`); None: automatic (joints, distance, energy; plus
            tracking, torques and tool_path with a controller, occlusion with an occlusion
            check).
        joints: Joints shown in the joint, tracking and torque plots (the default: PackBot's
            planar joints; on another arm, all its joints: :meth:`joints_of`).
        formats: Image formats of the plots ("png", "svg").
        html: Whether ``packbot run`` also writes the browser animation.
        occlusion: A camera-occlusion check, or None.
    """

    plots: tuple[str, ...] | None = None
    joints: tuple[str, ...] = _PLANAR_JOINTS
    formats: tuple[str, ...] = IMAGE_FORMATS
    html: bool = False
    occlusion: OcclusionCheck | None = None

    def joints_of(self, joint_names: tuple[str, ...], is_packbot: bool) -> tuple[str, ...]:
        """The joints to plot on an arm: :attr:`joints`, or all of another arm's by default."""
        if not is_packbot and self.joints == _PLANAR_JOINTS:
            return joint_names
        return self.joints

    def validate(self) -> None:
        """Raise :class:`ConfigurationError` naming the first bad field."""
        for name, items in (
            ("plots", self.plots),
            ("joints", self.joints),
            ("formats", self.formats),
        ):
            if name == "plots" and items is None:
                continue
            if not isinstance(items, (tuple, list)) or not all(isinstance(x, str) for x in items):
                raise ConfigurationError(f"outputs.{name}", items, "a list of names (strings)")
        if not isinstance(self.html, bool):
            raise ConfigurationError("outputs.html", self.html, "true or false")
        if self.occlusion is not None and not isinstance(self.occlusion, OcclusionCheck):
            raise ConfigurationError("outputs.occlusion", self.occlusion, "an OcclusionCheck")
        for k, kind in enumerate(self.plots or ()):
            if kind not in PLOT_KINDS:
                raise ConfigurationError(f"outputs.plots[{k}]", kind, PLOT_KINDS)
        if "occlusion" in (self.plots or ()) and self.occlusion is None:
            raise ConfigurationError(
                "outputs.plots",
                list(self.plots or ()),
                "no 'occlusion' without [outputs.occlusion]",
            )
        for k, fmt in enumerate(self.formats):
            if fmt not in IMAGE_FORMATS:
                raise ConfigurationError(f"outputs.formats[{k}]", fmt, IMAGE_FORMATS)
        for name, items in (
            ("plots", self.plots or ()),
            ("joints", self.joints),
            ("formats", self.formats),
        ):
            if len(set(items)) != len(items):
                raise ConfigurationError(f"outputs.{name}", list(items), "each name at most once")
        if not self.formats:
            raise ConfigurationError(
                "outputs.formats", [], f"at least one image format, of {', '.join(IMAGE_FORMATS)}"
            )
        if not self.joints:
            raise ConfigurationError(
                "outputs.joints", [], "at least one joint to plot (omit it for the default)"
            )
        if self.occlusion is not None:
            self.occlusion.validate()
