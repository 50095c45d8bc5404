"""The parameter table: every number of the PackBot EOD model, with its unit, source and tolerance.

This module is the single source of truth. The URDF, the collision meshes, the DH tables and the
table in ``docs/parameters.md`` are all generated from it (``packbot generate-model``);
``load_robot()`` exposes it as ``Robot.params``.

Every geometric and inertial entry (unit ``m`` or ``kg``, but for the lift-capacity figures)
carries a :class:`Tolerance`: a half-width in the entry's unit and its basis, after the 2010
report's Appendix A (``REPORT``): dimensions the report measured by hand to 5 mm, masses it
weighed to 100 g, numbers it took "from estimates and memory" (a wider bound, with the reason),
and numbers the report does not list (our own guess, with its bound).
:func:`packbot.sample_robots` draws arms within these boxes through :func:`design`, the one
function that turns a table of values into the model's bodies, joints and DH chains (the
nominal model is ``design(nominal_values())``).

Frames: ``base_link`` has its origin on the ground under the tracks, x forward, y left, z up. All
lengths are in metres [m], masses in kilograms [kg], angles in radians [rad], torques in newton
metres [N*m]. Part poses are given in the frame of the link that carries them (see ``docs/model.md``
for the link frames).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "ARM_JOINTS",
    "BASES",
    "CHAINS",
    "JOINTS",
    "LINKS",
    "NOMINAL",
    "POSES",
    "REPORT",
    "SOURCES",
    "TABLE",
    "DHRow",
    "Design",
    "JointSpec",
    "LinkSpec",
    "Param",
    "Part",
    "Tolerance",
    "design",
    "nominal_values",
    "toleranced",
    "value",
]

#: The sources of the numbers: key (as cited by :attr:`Param.source`) -> reference.
SOURCES: dict[str, str] = {
    "press510": "PackBot 510 press figures (strategypage.com, 2007-12-19): base robot 42 lb "
    "(19.1 kg), 28 x 16 x 8 in (0.71 x 0.41 x 0.20 m).",
    "press-eod": "PackBot EOD press figures (Boston Magazine, 2007-04-27): 68 lb (30.8 kg) with "
    "the arm, arm reach more than 6 ft (1.83 m), the claw lifts 30 lb (13.6 kg).",
    "spec": "GVR-Bot / PackBot 510 public spec-sheet figures as collected in the project brief: "
    "chassis about 0.68 x 0.42 x 0.178 m, robot about 30 kg, reach about 2 m from the turret, arm "
    "plus payload kit about 12 kg (low confidence), lift about 13.6 kg close in.",
    "report": "Hall 2010, GRRC TR 2010-02: link construction (tube + motor + board, capped by "
    "joint casings), link 3 longer than link 2, drive pose arm folded over the chassis.",
    "est": "Estimate: engineering judgement, chosen to fit the sourced totals; see the note.",
    "derived": "Derived in code from other entries (packbot/urdfgen.py).",
}

#: The report whose Appendix A gives the tolerances; :attr:`Tolerance.line` is a line of it.
REPORT = "Hall 2010, GRRC TR 2010-02, Appendix A; lines of its text, packbot-report-2010.txt"

#: The bases of a tolerance: how the report knew the number on the real arm.
BASES: dict[str, str] = {
    "measured": "measured by hand on the real arm, known to within 5 mm (report, Appendix A)",
    "weighed": "weighed on the real arm, known to within 100 g (report, Appendix A)",
    "estimated": "based on estimates and memory (report, Appendix A): a wider bound, +-30 %",
    "unlisted": "a part the report's Appendix A does not list: our guess, +-20 %",
    "derived": "computed from other entries; its bound follows theirs",
}

#: Half-widths of the report's classes: lengths measured to 5 mm [m], masses weighed to 100 g [kg].
MEASURED_M = 0.005
WEIGHED_KG = 0.1
#: Relative half-widths of the wider classes: the report's estimates, and parts it does not list.
ESTIMATED_REL = 0.30
UNLISTED_REL = 0.20


@dataclass(frozen=True)
class Tolerance:
    """How well a number of the table is known: the box ``value +- plus_minus``.

    Attributes:
        plus_minus: Half-width of the box, in the entry's unit (> 0).
        basis: A key of :data:`BASES`: ``"measured"``, ``"weighed"``, ``"estimated"``,
            ``"unlisted"`` or ``"derived"``.
        reason: Why this bound (what the report says, or why ours is wider).
        line: The line of the report's text (:data:`REPORT`) that states it, or None.
    """

    plus_minus: float
    basis: Literal["measured", "weighed", "estimated", "unlisted", "derived"]
    reason: str
    line: int | None = None

    def bounds(self, nominal: float) -> tuple[float, float]:
        """The box ``(nominal - plus_minus, nominal + plus_minus)`` in the entry's unit."""
        return (nominal - self.plus_minus, nominal + self.plus_minus)


#: A tolerance, or a rule that makes one from the entry's value (for relative bounds).
_TolSpec = Tolerance | Callable[[float], Tolerance] | None


def _measured(line: int, what: str) -> Tolerance:
    return Tolerance(MEASURED_M, "measured", f"{what}: measured to 5 mm", line)


def _weighed(line: int, what: str) -> Callable[[float], Tolerance]:
    def rule(val: float) -> Tolerance:
        if 0.5 * val > WEIGHED_KG:
            return Tolerance(WEIGHED_KG, "weighed", f"{what}: weighed to 100 g", line)
        return Tolerance(
            0.5 * val,
            "weighed",
            f"{what}: weighed to 100 g, this part's share bounded to +-50 % to stay positive",
            line,
        )

    return rule


def _estimated(line: int, what: str) -> Callable[[float], Tolerance]:
    return lambda val: Tolerance(
        ESTIMATED_REL * abs(val), "estimated", f"{what}: from estimates and memory, +-30 %", line
    )


def _unlisted(why: str) -> Callable[[float], Tolerance]:
    return lambda val: Tolerance(UNLISTED_REL * abs(val), "unlisted", f"{why}: our guess, +-20 %")


@dataclass(frozen=True)
class Param:
    """One entry of the parameter table.

    Attributes:
        name: Dotted name, e.g. ``"link1.length"``.
        value: The number, in SI units.
        unit: Unit string, e.g. ``"m"``, ``"kg"``, ``"rad"``.
        source: A key of :data:`SOURCES`.
        note: Why this value (for estimates), or what it means.
        tolerance: How well the number is known (every geometric and inertial entry has one;
            the joints' limits, actuators and friction, gravity and the lift capacity do not).
    """

    name: str
    value: float
    unit: str
    source: str
    note: str = ""
    tolerance: Tolerance | None = None


#: The parameter table: every number of the model by name (read one with :func:`value`).
TABLE: dict[str, Param] = {}


def _p(
    name: str, val: float, unit: str, source: str, note: str = "", tol: _TolSpec = None
) -> float:
    if source not in SOURCES:
        raise KeyError(f"unknown source {source!r} for {name}")
    if name in TABLE:
        raise KeyError(f"duplicate parameter {name}")
    tolerance = tol if tol is None or isinstance(tol, Tolerance) else tol(float(val))
    if tolerance is not None and not tolerance.plus_minus > 0.0:
        raise ValueError(f"tolerance of {name} must be positive, got {tolerance.plus_minus}")
    TABLE[name] = Param(name, float(val), unit, source, note, tolerance)
    return float(val)


def value(name: str) -> float:
    """Return the value of a table entry by its dotted name (SI units)."""
    return TABLE[name].value


def nominal_values() -> dict[str, float]:
    """The table's values by name (SI units): the nominal model is ``design(nominal_values())``."""
    return {name: p.value for name, p in TABLE.items()}


def toleranced() -> tuple[str, ...]:
    """Names of the entries that carry a tolerance and are drawn independently (not derived)."""
    return tuple(
        n for n, p in TABLE.items() if p.tolerance is not None and p.tolerance.basis != "derived"
    )


# Lines of the report's Appendix A (REPORT) that state each class.
_L_CHASSIS, _L_WHEEL, _L_ARM_AT, _L_CAMERA, _L_LINKS, _L_CASING, _L_WRIST, _L_PLATE = range(
    315, 323
)
_L_MOTOR_LEN, _L_CHIP_DIM, _L_TUBE_WALL, _L_WRIST_THICK = range(324, 328)
_L_M_MOTOR, _L_M_CASING, _L_M_ARM, _L_M_CAMERA, _L_M_CWRIST, _L_M_GWRIST, _L_M_PLATE = range(
    329, 336
)
_L_M_CHIP, _L_M_TUBE, _L_M_WHEEL, _L_M_CHASSIS = range(338, 342)

# --------------------------------------------------------------------------------------------
# Chassis (base_link). Origin on the ground under the tracks, x forward, z up.
# --------------------------------------------------------------------------------------------
_chassis_dim = _measured(_L_CHASSIS, "full length definition of the chassis")
CH_L = _p("chassis.length", 0.68, "m", "spec", "overall length, tracks included", _chassis_dim)
CH_W = _p("chassis.width", 0.42, "m", "spec", "overall width without flippers", _chassis_dim)
CH_H = _p("chassis.height", 0.178, "m", "spec", "top deck height above ground", _chassis_dim)
WHEEL_R = _p(
    "chassis.wheel_radius",
    0.089,
    "m",
    "derived",
    "chassis.height / 2: tracks span the full height",
    Tolerance(MEASURED_M / 2, "derived", "chassis.height / 2: half the height's bound"),
)
_wheel = _measured(_L_WHEEL, "wheel width, radius and location")
TRACK_W = _p(
    "chassis.track_width", 0.085, "m", "est", "each track; the body fills the rest", _wheel
)
BODY_CLEAR = _p(
    "chassis.body_clearance",
    0.03,
    "m",
    "est",
    "body underside above ground",
    _unlisted("clearance"),
)
_flipper = _unlisted("flipper shape (the report models no flippers)")
FLIP_W = _p("chassis.flipper_width", 0.045, "m", "est", "each flipper, outside the track", _flipper)
FLIP_L = _p(
    "chassis.flipper_length", 0.45, "m", "est", "front axle to tip, stowed backwards", _flipper
)
FLIP_TIP_R = _p("chassis.flipper_tip_radius", 0.04, "m", "est", "", _flipper)
_arm_at = _measured(_L_ARM_AT, "location of the arm with respect to the chassis")
MOUNT_X = _p(
    "chassis.arm_mount_x", -0.22, "m", "est", "turret axis, rear half of the deck", _arm_at
)
_plate = _measured(_L_PLATE, "full length dimension of the arm attachment plate")
MOUNT_R = _p("chassis.arm_plate_radius", 0.11, "m", "est", "arm attachment plate", _plate)
MOUNT_H = _p(
    "chassis.arm_plate_height",
    0.05,
    "m",
    "est",
    "arm attachment plate thickness",
    _unlisted("plate thickness (only its length is listed)"),
)
M_BODY = _p(
    "mass.chassis_body",
    11.0,
    "kg",
    "est",
    "base 19.1 kg (press510) less tracks and flippers",
    _estimated(_L_M_CHASSIS, "chassis mass"),
)
M_TRACK = _p(
    "mass.track", 2.5, "kg", "est", "each track with its wheels", _estimated(_L_M_WHEEL, "wheels")
)
M_FLIPPER = _p("mass.flipper", 1.3, "kg", "est", "each flipper", _unlisted("flipper mass"))
M_PLATE = _p(
    "mass.arm_plate", 0.8, "kg", "est", "arm attachment plate", _weighed(_L_M_PLATE, "arm plate")
)

# --------------------------------------------------------------------------------------------
# Arm kinematics (standard DH, Corke's convention). See DH_* below.
# --------------------------------------------------------------------------------------------
_links = _measured(_L_LINKS, "manipulator link lengths, offsets and diameters")
D_TURRET = _p("arm.turret_height", 0.10, "m", "est", "arm plate top to shoulder axis", _arm_at)
A_TURRET = _p(
    "arm.shoulder_forward", 0.03, "m", "est", "shoulder axis ahead of turret axis", _arm_at
)
L1 = _p(
    "link1.length",
    0.56,
    "m",
    "est",
    "shoulder to elbow1 axis; with L2, L3 fits the 2 m reach",
    _links,
)
L2 = _p(
    "link2.length", 0.44, "m", "est", "elbow1 to elbow2 axis; shorter than link 3 (report)", _links
)
L3 = _p(
    "link3.length",
    0.90,
    "m",
    "est",
    "elbow2 axis to gripper tool point (report: longer than link 2)",
    _links,
)
OFF2 = _p(
    "link2.lateral_offset", 0.075, "m", "est", "link 2 beside link 1 so the arm folds flat", _links
)
_wrist = _measured(_L_WRIST, "wrist lengths and widths")
WRIST_X = _p(
    "link3.wrist_start", 0.56, "m", "est", "elbow2 axis to gripper wrist along link 3", _wrist
)
ROLL_X = _p(
    "link3.roll_joint", 0.68, "m", "est", "elbow2 axis to gripper roll joint along link 3", _wrist
)
TILT_X = _p("link3.tilt_axis_x", 0.62, "m", "est", "camera tilt axis, along link 3", _links)
TILT_Y = _p(
    "link3.tilt_axis_up", 0.16, "m", "est", "camera tilt axis, above the link 3 centre line", _links
)
_camera = _measured(_L_CAMERA, "camera dimensions")
CAM_UP = _p(
    "camera.height",
    0.10,
    "m",
    "est",
    "optical centre above the tilt axis, along the pan axis",
    _camera,
)
CAM_FWD = _p("camera.forward", 0.10, "m", "est", "optical centre ahead of the pan axis", _camera)

# --------------------------------------------------------------------------------------------
# Link parts: masses (report: known to 100 g on the real arm, never published; ours estimate
# them so that the arm totals ~11 kg, robot ~30 kg) and shapes.
# --------------------------------------------------------------------------------------------
_casing_m = _weighed(_L_M_CASING, "joint casing/gearing")
_motor_m = _weighed(_L_M_MOTOR, "motor")
_tube_m = _estimated(_L_M_TUBE, "hollow tube mass")
_camera_m = _weighed(_L_M_CAMERA, "camera")
_effector_m = _unlisted("end-effector part (only its wrist is weighed)")
M_TURRET = _p("mass.turret_casing", 1.0, "kg", "est", "turret bearing and yaw gearbox", _casing_m)
M_YOKE = _p(
    "mass.shoulder_yoke_plate",
    0.2,
    "kg",
    "est",
    "each of two plates",
    _unlisted("shoulder yoke plate (the report lists no yoke)"),
)
M_SH_CASE = _p(
    "mass.shoulder_casing", 1.1, "kg", "est", "shoulder gearbox casing, on link 1", _casing_m
)
M_L1_TUBE = _p("mass.link1_tube", 0.45, "kg", "est", "aluminium tube, hollow", _tube_m)
M_L1_MOTOR = _p("mass.link1_motor", 0.6, "kg", "est", "elbow1 motor inside link 1", _motor_m)
M_BOARD = _p(
    "mass.board",
    0.1,
    "kg",
    "est",
    "electronics board in each major link",
    _estimated(_L_M_CHIP, "computer chip mass"),
)
M_E1_CASE1 = _p(
    "mass.elbow1_casing_link1", 0.8, "kg", "est", "elbow1 gearbox, link 1 side", _casing_m
)
M_E1_CASE2 = _p(
    "mass.elbow1_casing_link2", 0.6, "kg", "est", "elbow1 casing, link 2 side", _casing_m
)
M_L2_TUBE = _p("mass.link2_tube", 0.35, "kg", "est", "", _tube_m)
M_L2_MOTOR = _p("mass.link2_motor", 0.5, "kg", "est", "elbow2 motor inside link 2", _motor_m)
M_E2_CASE2 = _p(
    "mass.elbow2_casing_link2", 0.6, "kg", "est", "elbow2 gearbox, link 2 side", _casing_m
)
M_E2_CASE3 = _p(
    "mass.elbow2_casing_link3", 0.5, "kg", "est", "elbow2 casing, link 3 side", _casing_m
)
M_L3_TUBE = _p("mass.link3_tube", 0.4, "kg", "est", "", _tube_m)
M_GWRIST = _p(
    "mass.gripper_wrist",
    0.9,
    "kg",
    "est",
    "solid; holds the roll motor (report)",
    _weighed(_L_M_GWRIST, "end effector wrist"),
)
M_CWRIST = _p(
    "mass.camera_wrist",
    0.6,
    "kg",
    "est",
    "solid; holds the tilt motor (report)",
    _weighed(_L_M_CWRIST, "camera wrist"),
)
M_PALM = _p("mass.gripper_palm", 0.45, "kg", "est", "palm with the jaw motor", _effector_m)
M_FINGER = _p("mass.finger", 0.15, "kg", "est", "each finger", _effector_m)
M_BRACKET = _p(
    "mass.camera_bracket", 0.3, "kg", "est", "tilt bracket with the pan motor", _camera_m
)
M_HEAD = _p("mass.camera_head", 0.7, "kg", "est", "camera head housing", _camera_m)
M_LENS = _p("mass.camera_lens", 0.1, "kg", "est", "", _camera_m)

TUBE_WALL = _p(
    "link.tube_wall",
    0.003,
    "m",
    "est",
    "tube wall thickness (report: from memory)",
    _estimated(_L_TUBE_WALL, "hollow tube thickness"),
)
_casing = _measured(_L_CASING, "joint casing diameters")
_casing_w = _unlisted("casing width along its axis (only its diameter is listed)")
R_SH_CASE = _p(
    "casing.shoulder_radius", 0.075, "m", "est", "the casing the fallen link 3 props on", _casing
)
R_E1_CASE = _p("casing.elbow1_radius", 0.06, "m", "est", "", _casing)
R_E2_CASE = _p("casing.elbow2_radius", 0.055, "m", "est", "", _casing)
W_SH_CASE = _p("casing.shoulder_width", 0.12, "m", "est", "along the shoulder axis", _casing_w)
W_E1_CASE = _p("casing.elbow1_width", 0.07, "m", "est", "each side, along the axis", _casing_w)
W_E2_CASE = _p("casing.elbow2_width", 0.07, "m", "est", "each side, along the axis", _casing_w)
R_TUBE1 = _p("link1.tube_radius", 0.032, "m", "est", "outer", _links)
R_TUBE2 = _p("link2.tube_radius", 0.030, "m", "est", "outer", _links)
R_TUBE3 = _p("link3.tube_radius", 0.030, "m", "est", "outer", _links)
_motor_len = _estimated(_L_MOTOR_LEN, "motor length")
_motor_r = _unlisted("motor diameter")
R_MOTOR1 = _p("link1.motor_radius", 0.022, "m", "est", "elbow1 motor", _motor_r)
L_MOTOR1 = _p("link1.motor_length", 0.12, "m", "est", "elbow1 motor", _motor_len)
R_MOTOR2 = _p("link2.motor_radius", 0.02, "m", "est", "elbow2 motor", _motor_r)
L_MOTOR2 = _p("link2.motor_length", 0.10, "m", "est", "elbow2 motor", _motor_len)
_chip = _estimated(_L_CHIP_DIM, "computer chip width and thickness")
_chip_len = _unlisted("computer chip length")
T_BOARD = _p("board.thickness", 0.008, "m", "est", "every link's board", _chip)
L_BOARD1 = _p("link1.board_length", 0.14, "m", "est", "", _chip_len)
W_BOARD1 = _p("link1.board_width", 0.035, "m", "est", "", _chip)
L_BOARD2 = _p("link2.board_length", 0.12, "m", "est", "", _chip_len)
W_BOARD2 = _p("link2.board_width", 0.03, "m", "est", "", _chip)
L_BOARD3 = _p("link3.board_length", 0.14, "m", "est", "", _chip_len)
W_BOARD3 = _p("link3.board_width", 0.03, "m", "est", "", _chip)
R_GWRIST = _p("link3.gripper_wrist_radius", 0.04, "m", "est", "", _wrist)
L_CWRIST = _p("link3.camera_wrist_length", 0.10, "m", "est", "along link 3", _wrist)
T_CWRIST = _p(
    "link3.camera_wrist_thickness",
    0.06,
    "m",
    "est",
    "across link 3's plane",
    _estimated(_L_WRIST_THICK, "wrist thickness"),
)
HEAD_X = _p("camera.head_length", 0.14, "m", "est", "camera head housing", _camera)
HEAD_Y = _p("camera.head_width", 0.16, "m", "est", "", _camera)
HEAD_Z = _p("camera.head_height", 0.09, "m", "est", "", _camera)
R_LENS = _p("camera.lens_radius", 0.03, "m", "est", "", _camera)
L_LENS = _p("camera.lens_length", 0.03, "m", "est", "ahead of the head, along its axis", _camera)
_bracket = "tilt bracket with the pan motor"
BRK_X = _p("camera.bracket_length", 0.05, "m", "est", _bracket, _camera)
BRK_Y = _p("camera.bracket_width", 0.05, "m", "est", _bracket, _camera)
BRK_Z = _p("camera.bracket_height", 0.08, "m", "est", _bracket + ", along the pan axis", _camera)
R_TURRET = _p("casing.turret_radius", 0.09, "m", "est", "turret bearing and yaw gearbox", _casing)
H_TURRET = _p(
    "casing.turret_height", 0.06, "m", "est", "above the arm plate", _unlisted("casing height")
)
_yoke = _unlisted("shoulder yoke plate (the report lists no yoke)")
YOKE_X = _p("yoke.length", 0.10, "m", "est", "each plate, along x", _yoke)
YOKE_Y = _p("yoke.thickness", 0.015, "m", "est", "each plate, along the shoulder axis", _yoke)
YOKE_Z = _p("yoke.height", 0.05, "m", "est", "each plate, along z", _yoke)
_effector = _unlisted("end effector (only its wrist is listed)")
PALM_X = _p("gripper.palm_length", 0.07, "m", "est", "x at zero roll", _effector)
PALM_Y = _p("gripper.palm_width", 0.09, "m", "est", "", _effector)
PALM_Z = _p("gripper.palm_height", 0.08, "m", "est", "along the approach axis", _effector)
FING_X = _p("gripper.finger_thickness", 0.02, "m", "est", "each finger", _effector)
FING_Y = _p("gripper.finger_width", 0.05, "m", "est", "each finger", _effector)
FING_Z = _p("gripper.finger_length", 0.16, "m", "est", "each finger, from the palm", _effector)

# --------------------------------------------------------------------------------------------
# Lift capacity and actuators.
# --------------------------------------------------------------------------------------------
LIFT_MASS = _p("lift.mass", 13.6, "kg", "press-eod", "30 lb, close in")
LIFT_LEVER = _p(
    "lift.lever", 0.5, "m", "est", "'close in': payload within 0.5 m of each pitch joint"
)
GRAVITY = _p("gravity", 9.81, "m/s^2", "est", "standard gravity, rounded")


@dataclass(frozen=True)
class Part:
    """One solid part of a link, with uniform density.

    Attributes:
        name: Part name, unique within its link.
        shape: ``"box"`` (``size`` = full extents x, y, z), ``"cylinder"`` (``size`` = radius,
            length; axis along ``axis``), ``"tube"`` (hollow cylinder: ``size`` = outer radius,
            length, wall thickness; its collision piece is the solid outer cylinder),
            ``"stadium"`` (hull of two cylinders with axes along y: ``size`` = (x1, r1, x2, r2,
            width), centre z at ``center[2]``).
        mass: Part mass [kg].
        center: Centre of the part in the link frame [m].
        axis: Axis of a cylinder or tube, ``"x"``, ``"y"`` or ``"z"`` (link frame).
        size: Shape dimensions [m], see ``shape``.
        collision: Whether the part is a convex collision piece (internal parts are not).
        mass_name: The table entry that gives ``mass`` (``""`` for a part built by hand).
    """

    name: str
    shape: Literal["box", "cylinder", "tube", "stadium"]
    mass: float
    center: tuple[float, float, float]
    size: tuple[float, ...]
    axis: Literal["x", "y", "z"] = "z"
    collision: bool = True
    mass_name: str = ""


@dataclass(frozen=True)
class LinkSpec:
    """A rigid body of the robot: its parts and its display colour (RGBA)."""

    name: str
    parts: tuple[Part, ...]
    color: tuple[float, float, float, float] = (0.3, 0.3, 0.3, 1.0)


@dataclass(frozen=True)
class DHRow:
    """One row of a standard DH table (Corke's convention).

    ``T_{i-1,i} = Rz(q_i + offset) Tz(d) Tx(a) Rx(alpha)``.

    Attributes:
        joint: Name of the joint whose variable is ``q_i``.
        offset: Joint angle offset [rad].
        d: Offset along the previous z axis [m].
        a: Length along the new x axis [m].
        alpha: Twist about the new x axis [rad].
    """

    joint: str
    offset: float
    d: float
    a: float
    alpha: float


@dataclass(frozen=True)
class JointSpec:
    """A revolute joint: its parent and child, limits and actuator.

    Attributes:
        name: Joint name (iRobot's control-library names).
        parent: Parent link name.
        child: Child link name.
        lower: Lower position limit [rad].
        upper: Upper position limit [rad].
        velocity: Velocity limit [rad/s].
        effort: Effort limit [N*m]; ``None`` means derived from the lift capacity.
        gear_ratio: Motor turns per joint turn [-].
        rotor_inertia: Motor rotor inertia [kg*m^2]; armature = gear_ratio^2 * rotor_inertia.
        viscous: Viscous friction at the joint [N*m*s/rad].
        coulomb: Coulomb friction at the joint [N*m].
        axis_shift: Where the URDF joint frame sits along the joint axis, from the DH frame [m].
    """

    name: str
    parent: str
    child: str
    lower: float
    upper: float
    velocity: float
    effort: float | None
    gear_ratio: float
    rotor_inertia: float
    viscous: float
    coulomb: float
    axis_shift: float = 0.0


#: The arm's joints in model order: name, parent, child, whether an effort limit is given, and
#: the table entry of the axis shift ("" for none).
_JOINT_TREE: tuple[tuple[str, str, str, bool, str], ...] = (
    ("turret", "base_link", "turret_link", True, ""),
    ("shoulder", "turret_link", "link1", False, ""),
    ("elbow1", "link1", "link2", False, "link2.lateral_offset"),
    ("elbow2", "link2", "link3", False, ""),
    ("camera_tilt", "link3", "camera_tilt_link", True, ""),
    ("camera_pan", "camera_tilt_link", "camera_head", True, ""),
    ("gripper_roll", "link3", "gripper_link", True, "link3.roll_joint"),
    ("gripper_jaw", "gripper_link", "jaw_link", True, ""),
)


def _register_joint(
    name: str,
    limits: tuple[float, float],
    velocity: float,
    effort: float | None,
    ratio: float,
    rotor: float,
    viscous: float,
    coulomb: float,
) -> None:
    _p(f"{name}.lower", limits[0], "rad", "est", "mechanical stop")
    _p(f"{name}.upper", limits[1], "rad", "est", "mechanical stop")
    _p(f"{name}.velocity_limit", velocity, "rad/s", "est", "slow EOD arm")
    if effort is not None:
        _p(f"{name}.effort_limit", effort, "N*m", "est", "not a lifting joint")
    _p(f"{name}.gear_ratio", ratio, "-", "est", "iRobot gave the report its ratios; unpublished")
    _p(f"{name}.rotor_inertia", rotor, "kg*m^2", "est", "catalogue value of a motor that size")
    _p(f"{name}.viscous_friction", viscous, "N*m*s/rad", "est", "at the joint output")
    _p(f"{name}.coulomb_friction", coulomb, "N*m", "est", "at the joint output")


_register_joint("turret", (-3.05, 3.05), 1.0, 60.0, 200, 3.3e-6, 0.8, 1.5)
_register_joint("shoulder", (-1.3, 2.1), 0.8, None, 160, 3.3e-6, 0.8, 1.5)
_register_joint("elbow1", (-2.6, 3.05), 1.0, None, 160, 1.1e-6, 0.5, 1.0)
_register_joint("elbow2", (-2.9, 2.9), 1.2, None, 120, 1.1e-6, 0.4, 0.8)
_register_joint("camera_tilt", (-2.2, 2.2), 1.5, 6.0, 100, 3e-7, 0.05, 0.2)
_register_joint("camera_pan", (-2.9, 2.9), 1.5, 4.0, 100, 3e-7, 0.05, 0.2)
_register_joint("gripper_roll", (-3.1, 3.1), 2.0, 10.0, 80, 3e-7, 0.05, 0.3)
_register_joint("gripper_jaw", (0.0, 1.2), 1.5, 8.0, 150, 3e-7, 0.05, 0.3)

PI = math.pi
#: Names of the tool frames at the end of each chain.
TOOL_FRAMES = {"gripper": "gripper_tool", "camera": "camera_optical"}


@dataclass(frozen=True)
class Design:
    """The model's bodies, joints and DH chains, built by :func:`design` from table values.

    Attributes:
        links: The links and their parts, from the chassis to the gripper jaw.
        joints: The arm's joints in model order.
        chains: The standard DH chains from the base to each tool frame (``"gripper"``,
            ``"camera"``).
        dh_base: Base transform of both chains: DH frame 0 in base_link, a translation [m].
        jaw_pivot: The jaw pivot in the gripper_link frame [m].
        gravity: Standard gravity [m/s^2].
        lift_mass: The rated payload "close in" [kg].
        lift_lever: Its lever from each pitch joint [m].
    """

    links: tuple[LinkSpec, ...]
    joints: tuple[JointSpec, ...]
    chains: dict[str, tuple[DHRow, ...]]
    dh_base: tuple[float, float, float]
    jaw_pivot: tuple[float, float, float]
    gravity: float
    lift_mass: float
    lift_lever: float


def _cyl(r: float, length: float) -> tuple[float, float]:
    return (r, length)


def _joints(v: Mapping[str, float]) -> tuple[JointSpec, ...]:
    out = []
    for name, parent, child, has_effort, shift in _JOINT_TREE:
        out.append(
            JointSpec(
                name,
                parent,
                child,
                v[f"{name}.lower"],
                v[f"{name}.upper"],
                v[f"{name}.velocity_limit"],
                v[f"{name}.effort_limit"] if has_effort else None,
                v[f"{name}.gear_ratio"],
                v[f"{name}.rotor_inertia"],
                v[f"{name}.viscous_friction"],
                v[f"{name}.coulomb_friction"],
                v[shift] if shift else 0.0,
            )
        )
    return tuple(out)


def _chains(v: Mapping[str, float]) -> dict[str, tuple[DHRow, ...]]:
    tilt_x, tilt_y = v["link3.tilt_axis_x"], v["link3.tilt_axis_up"]
    h = math.hypot(tilt_x, tilt_y)
    phi = math.atan2(tilt_y, tilt_x)
    # Both chains share rows 1-3; row 4 differs because standard DH attaches frame 4 to the
    # axis of the *next* joint (gripper_roll along link 3, or camera_tilt parallel to elbow2).
    common = (
        DHRow("turret", 0.0, v["arm.turret_height"], v["arm.shoulder_forward"], PI / 2),
        DHRow("shoulder", 0.0, 0.0, v["link1.length"], 0.0),
        DHRow("elbow1", 0.0, v["link2.lateral_offset"], v["link2.length"], 0.0),
    )
    return {
        "gripper": (
            *common,
            DHRow("elbow2", PI / 2, 0.0, 0.0, PI / 2),
            DHRow("gripper_roll", 0.0, v["link3.length"], 0.0, 0.0),
        ),
        "camera": (
            *common,
            DHRow("elbow2", phi, 0.0, h, 0.0),
            DHRow("camera_tilt", -phi, 0.0, 0.0, -PI / 2),
            DHRow("camera_pan", 0.0, v["camera.height"], v["camera.forward"], 0.0),
        ),
    }


_Shape = Literal["box", "cylinder", "tube", "stadium"]
_Vec = tuple[float, float, float]


class _Parts:
    """Builds parts whose mass is a table entry (so each part knows which one)."""

    def __init__(self, v: Mapping[str, float]) -> None:
        self.v = v

    def __call__(
        self,
        name: str,
        shape: _Shape,
        mass: str,
        center: _Vec,
        size: tuple[float, ...],
        axis: Literal["x", "y", "z"] = "z",
        collision: bool = True,
    ) -> Part:
        return Part(name, shape, self.v[mass], center, size, axis, collision, mass)


def _chassis(v: Mapping[str, float]) -> LinkSpec:
    part = _Parts(v)
    ch_l, ch_w, ch_h = v["chassis.length"], v["chassis.width"], v["chassis.height"]
    wheel_r = ch_h / 2  # chassis.wheel_radius: derived
    track_w, clear = v["chassis.track_width"], v["chassis.body_clearance"]
    flip_w, flip_l = v["chassis.flipper_width"], v["chassis.flipper_length"]
    mount_h = v["chassis.arm_plate_height"]
    track = (ch_l / 2 - wheel_r, wheel_r, -(ch_l / 2 - wheel_r), wheel_r, track_w)
    tip = v["chassis.flipper_tip_radius"]
    flipper = (ch_l / 2 - wheel_r, wheel_r, ch_l / 2 - wheel_r - flip_l, tip, flip_w)
    track_y = ch_w / 2 - track_w / 2
    flip_y = ch_w / 2 + flip_w / 2
    return LinkSpec(
        "base_link",
        (
            part(
                "body",
                "box",
                "mass.chassis_body",
                (0.0, 0.0, (clear + ch_h) / 2),
                (ch_l - 0.06, ch_w - 2 * track_w, ch_h - clear),
            ),
            part("track_left", "stadium", "mass.track", (0.0, track_y, wheel_r), track),
            part("track_right", "stadium", "mass.track", (0.0, -track_y, wheel_r), track),
            part("flipper_left", "stadium", "mass.flipper", (0.0, flip_y, wheel_r), flipper),
            part("flipper_right", "stadium", "mass.flipper", (0.0, -flip_y, wheel_r), flipper),
            part(
                "arm_plate",
                "cylinder",
                "mass.arm_plate",
                (v["chassis.arm_mount_x"], 0.0, ch_h + mount_h / 2),
                _cyl(v["chassis.arm_plate_radius"], mount_h),
                "z",
            ),
        ),
        (0.25, 0.27, 0.22, 1.0),
    )


def _arm_links(v: Mapping[str, float]) -> tuple[LinkSpec, ...]:
    part = _Parts(v)
    a_turret, wall = v["arm.shoulder_forward"], v["link.tube_wall"]
    l1, l2 = v["link1.length"], v["link2.length"]
    wrist_x, roll_x = v["link3.wrist_start"], v["link3.roll_joint"]
    tilt_x, tilt_y = v["link3.tilt_axis_x"], v["link3.tilt_axis_up"]
    cam_up, cam_fwd = v["camera.height"], v["camera.forward"]
    r_e1, r_e2 = v["casing.elbow1_radius"], v["casing.elbow2_radius"]
    w_e1, w_e2 = v["casing.elbow1_width"], v["casing.elbow2_width"]
    t_board = v["board.thickness"]
    yoke = (v["yoke.length"], v["yoke.thickness"], v["yoke.height"])
    bracket = (v["camera.bracket_length"], v["camera.bracket_width"], v["camera.bracket_height"])
    palm = (v["gripper.palm_length"], v["gripper.palm_width"], v["gripper.palm_height"])
    finger = (v["gripper.finger_thickness"], v["gripper.finger_width"], v["gripper.finger_length"])
    lens_l, palm_h, finger_l = v["camera.lens_length"], palm[2], finger[2]
    turret = LinkSpec(
        "turret_link",
        (
            part(
                "turret_casing",
                "cylinder",
                "mass.turret_casing",
                (0.0, 0.0, v["casing.turret_height"] / 2),
                _cyl(v["casing.turret_radius"], v["casing.turret_height"]),
            ),
            part(
                "yoke_left",
                "box",
                "mass.shoulder_yoke_plate",
                (a_turret, 0.0725, 0.085),
                yoke,
            ),
            part(
                "yoke_right",
                "box",
                "mass.shoulder_yoke_plate",
                (a_turret, -0.0725, 0.085),
                yoke,
            ),
        ),
        (0.55, 0.5, 0.2, 1.0),
    )
    link1 = LinkSpec(
        "link1",
        (
            part(
                "shoulder_casing",
                "cylinder",
                "mass.shoulder_casing",
                (0.0, 0.0, 0.0),
                _cyl(v["casing.shoulder_radius"], v["casing.shoulder_width"]),
            ),
            part(
                "tube",
                "tube",
                "mass.link1_tube",
                ((0.07 + l1 - 0.06) / 2, 0.0, 0.0),
                (v["link1.tube_radius"], l1 - 0.06 - 0.07, wall),
                "x",
            ),
            part(
                "motor",
                "cylinder",
                "mass.link1_motor",
                (0.16, 0.0, 0.0),
                _cyl(v["link1.motor_radius"], v["link1.motor_length"]),
                "x",
                False,
            ),
            part(
                "board",
                "box",
                "mass.board",
                (0.33, 0.0, 0.0),
                (v["link1.board_length"], v["link1.board_width"], t_board),
                collision=False,
            ),
            part(
                "elbow1_casing",
                "cylinder",
                "mass.elbow1_casing_link1",
                (l1, 0.0, 0.0),
                _cyl(r_e1, w_e1),
            ),
        ),
        (0.75, 0.68, 0.3, 1.0),
    )
    link2 = LinkSpec(
        "link2",
        (
            part(
                "elbow1_casing",
                "cylinder",
                "mass.elbow1_casing_link2",
                (0.0, 0.0, 0.0),
                _cyl(r_e1, w_e1),
            ),
            part(
                "tube",
                "tube",
                "mass.link2_tube",
                ((0.06 + l2 - 0.055) / 2, 0.0, 0.0),
                (v["link2.tube_radius"], l2 - 0.055 - 0.06, wall),
                "x",
            ),
            part(
                "motor",
                "cylinder",
                "mass.link2_motor",
                (0.13, 0.0, 0.0),
                _cyl(v["link2.motor_radius"], v["link2.motor_length"]),
                "x",
                False,
            ),
            part(
                "board",
                "box",
                "mass.board",
                (0.27, 0.0, 0.0),
                (v["link2.board_length"], v["link2.board_width"], t_board),
                collision=False,
            ),
            part(
                "elbow2_casing",
                "cylinder",
                "mass.elbow2_casing_link2",
                (l2, 0.0, 0.0),
                _cyl(r_e2, w_e2),
            ),
        ),
        (0.7, 0.62, 0.28, 1.0),
    )
    link3 = LinkSpec(
        "link3",
        (
            part(
                "elbow2_casing",
                "cylinder",
                "mass.elbow2_casing_link3",
                (0.0, 0.0, 0.0),
                _cyl(r_e2, w_e2),
            ),
            part(
                "tube",
                "tube",
                "mass.link3_tube",
                ((0.05 + wrist_x) / 2, 0.0, 0.0),
                (v["link3.tube_radius"], wrist_x - 0.05, wall),
                "x",
            ),
            part(
                "board",
                "box",
                "mass.board",
                (0.30, 0.0, 0.0),
                (v["link3.board_length"], v["link3.board_width"], t_board),
                collision=False,
            ),
            part(
                "gripper_wrist",
                "cylinder",
                "mass.gripper_wrist",
                ((wrist_x + roll_x) / 2, 0.0, 0.0),
                _cyl(v["link3.gripper_wrist_radius"], roll_x - wrist_x),
                "x",
            ),
            part(
                "camera_wrist",
                "box",
                "mass.camera_wrist",
                (tilt_x - 0.02, tilt_y / 2 + 0.01, 0.0),
                (v["link3.camera_wrist_length"], tilt_y - 0.02, v["link3.camera_wrist_thickness"]),
            ),
        ),
        (0.65, 0.58, 0.26, 1.0),
    )
    head_size = (v["camera.head_length"], v["camera.head_width"], v["camera.head_height"])
    camera = (
        LinkSpec(
            "camera_tilt_link",
            (part("bracket", "box", "mass.camera_bracket", (0.0, 0.0, 0.0), bracket),),
            (0.2, 0.2, 0.2, 1.0),
        ),
        LinkSpec(
            "camera_head",
            (
                part("head", "box", "mass.camera_head", (0.0, 0.0, cam_up), head_size),
                part(
                    "lens",
                    "cylinder",
                    "mass.camera_lens",
                    (cam_fwd - lens_l / 2, 0.0, cam_up),
                    _cyl(v["camera.lens_radius"], lens_l),
                    "x",
                ),
            ),
            (0.15, 0.15, 0.15, 1.0),
        ),
    )
    gripper = (
        LinkSpec(
            "gripper_link",
            (
                part("palm", "box", "mass.gripper_palm", (0.0, 0.0, palm_h / 2), palm),
                part(
                    "fixed_finger",
                    "box",
                    "mass.finger",
                    (-0.025, 0.0, palm_h + finger_l / 2),
                    finger,
                ),
            ),
            (0.35, 0.35, 0.38, 1.0),
        ),
        LinkSpec(
            "jaw_link",
            (part("finger", "box", "mass.finger", (0.0, 0.0, finger_l / 2), finger),),
            (0.35, 0.35, 0.38, 1.0),
        ),
    )
    return (turret, link1, link2, link3, *camera, *gripper)


def design(values: Mapping[str, float]) -> Design:
    """Build the model's bodies, joints and DH chains from table values.

    The one place that turns numbers into geometry: the nominal model is
    ``design(nominal_values())`` (:data:`NOMINAL`), and :func:`packbot.sample_robots` calls it
    with sampled values. Every part dimension is a table entry; a few part positions are fixed
    numbers of this function, not table entries: where the motors and boards sit along their
    links, where each tube ends short of its casings, the yoke plates' place, the camera wrist's
    offsets from the tilt axis, the fixed finger's and the jaw pivot's offset across the palm,
    and the body's 6 cm short of the chassis length.

    Args:
        values: Table entry name -> value (SI units), every entry of :data:`TABLE`
            (``chassis.wheel_radius`` is ignored: it is ``chassis.height / 2``).

    Returns:
        The design.

    Raises:
        KeyError: An entry is missing from ``values``.
    """
    v = values
    return Design(
        links=(_chassis(v), *_arm_links(v)),
        joints=_joints(v),
        chains=_chains(v),
        dh_base=(
            v["chassis.arm_mount_x"],
            0.0,
            v["chassis.height"] + v["chassis.arm_plate_height"],
        ),
        jaw_pivot=(0.03, 0.0, v["gripper.palm_height"]),
        gravity=v["gravity"],
        lift_mass=v["lift.mass"],
        lift_lever=v["lift.lever"],
    )


#: The nominal model: ``design(nominal_values())``.
NOMINAL: Design = design(nominal_values())
#: The links and their parts (geometry and mass), from the chassis to the gripper jaw.
LINKS: tuple[LinkSpec, ...] = NOMINAL.links
#: The arm's joints in model order: limits, actuator and friction parameters.
JOINTS: tuple[JointSpec, ...] = NOMINAL.joints
#: The arm's joint names in model order.
ARM_JOINTS: tuple[str, ...] = tuple(j.name for j in JOINTS)
#: The standard DH chains from the base to each tool frame: ``"gripper"`` and ``"camera"``.
CHAINS: dict[str, tuple[DHRow, ...]] = NOMINAL.chains
DH_COMMON: tuple[DHRow, ...] = CHAINS["gripper"][:3]
#: Base transform of both chains: DH frame 0 in base_link (a pure translation).
DH_BASE = NOMINAL.dh_base
# Jaw pivot in the gripper_link frame (z along the approach axis, x "up" at zero roll).
JAW_PIVOT = NOMINAL.jaw_pivot

#: Named poses from the real robot's presets [rad], in ARM_JOINTS order.
#: drive: arm folded over the chassis, link 3 upright carrying the head (the report's Fig. 6).
POSES: dict[str, dict[str, float]] = {
    "drive": {"shoulder": 0.05, "elbow1": 2.85, "elbow2": -1.12, "camera_tilt": -1.6},
    "stow": {"shoulder": 0.05, "elbow1": 2.85, "elbow2": -2.8, "camera_tilt": 0.0},
    "stand": {"shoulder": 1.2, "elbow1": -0.7, "elbow2": -0.4, "camera_tilt": -0.1},
    "high": {"shoulder": 1.45, "elbow1": -0.1, "elbow2": 0.05, "camera_tilt": -1.4},
    "low": {"shoulder": 0.35, "elbow1": -0.9, "elbow2": 0.3, "camera_tilt": -0.5},
}
