"""The parameter table: every number of the PackBot EOD model, with its unit and source.

This module is the single source of truth. The URDF, the collision meshes, the DH tables and the
table in ``docs/model.md`` are all generated from it (``packbot generate-model``); ``load_robot()``
exposes it as ``Robot.params``.

Frames: ``base_link`` has its origin on the ground under the tracks, x forward, y left, z up. All
lengths are in metres [m], masses in kilograms [kg], angles in radians [rad], torques in newton
metres [N*m]. Part poses are given in the frame of the link that carries them (see ``docs/model.md``
for the link frames).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "ARM_JOINTS",
    "CHAINS",
    "JOINTS",
    "LINKS",
    "POSES",
    "SOURCES",
    "TABLE",
    "DHRow",
    "JointSpec",
    "LinkSpec",
    "Param",
    "Part",
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


@dataclass(frozen=True)
class Param:
    """One entry of the parameter table.

    Attributes:
        name: Dotted name, e.g. ``"link1.length"``.
        value: The number, in SI units.
        unit: Unit string, e.g. ``"m"``, ``"kg"``, ``"rad"``.
        source: A key of :data:`SOURCES`.
        note: Why this value (for estimates), or what it means.
    """

    name: str
    value: float
    unit: str
    source: str
    note: str = ""


#: The parameter table: every number of the model by name (read one with :func:`value`).
TABLE: dict[str, Param] = {}


def _p(name: str, val: float, unit: str, source: str, note: str = "") -> float:
    if source not in SOURCES:
        raise KeyError(f"unknown source {source!r} for {name}")
    if name in TABLE:
        raise KeyError(f"duplicate parameter {name}")
    TABLE[name] = Param(name, float(val), unit, source, note)
    return float(val)


def value(name: str) -> float:
    """Return the value of a table entry by its dotted name (SI units)."""
    return TABLE[name].value


# --------------------------------------------------------------------------------------------
# Chassis (base_link). Origin on the ground under the tracks, x forward, z up.
# --------------------------------------------------------------------------------------------
CH_L = _p("chassis.length", 0.68, "m", "spec", "overall length, tracks included")
CH_W = _p("chassis.width", 0.42, "m", "spec", "overall width without flippers")
CH_H = _p("chassis.height", 0.178, "m", "spec", "top deck height above ground")
WHEEL_R = _p(
    "chassis.wheel_radius", 0.089, "m", "derived", "chassis.height / 2: tracks span the full height"
)
TRACK_W = _p("chassis.track_width", 0.085, "m", "est", "each track; the body fills the rest")
BODY_CLEAR = _p("chassis.body_clearance", 0.03, "m", "est", "body underside above ground")
FLIP_W = _p("chassis.flipper_width", 0.045, "m", "est", "each flipper, outside the track")
FLIP_L = _p("chassis.flipper_length", 0.45, "m", "est", "front axle to tip, stowed backwards")
FLIP_TIP_R = _p("chassis.flipper_tip_radius", 0.04, "m", "est", "")
MOUNT_X = _p("chassis.arm_mount_x", -0.22, "m", "est", "turret axis, rear half of the deck")
MOUNT_R = _p("chassis.arm_plate_radius", 0.11, "m", "est", "arm attachment plate")
MOUNT_H = _p("chassis.arm_plate_height", 0.05, "m", "est", "arm attachment plate thickness")
M_BODY = _p(
    "mass.chassis_body", 11.0, "kg", "est", "base 19.1 kg (press510) less tracks and flippers"
)
M_TRACK = _p("mass.track", 2.5, "kg", "est", "each track with its wheels")
M_FLIPPER = _p("mass.flipper", 1.3, "kg", "est", "each flipper")
M_PLATE = _p("mass.arm_plate", 0.8, "kg", "est", "arm attachment plate")

# --------------------------------------------------------------------------------------------
# Arm kinematics (standard DH, Corke's convention). See DH_* below.
# --------------------------------------------------------------------------------------------
D_TURRET = _p("arm.turret_height", 0.10, "m", "est", "arm plate top to shoulder axis")
A_TURRET = _p("arm.shoulder_forward", 0.03, "m", "est", "shoulder axis ahead of turret axis")
L1 = _p("link1.length", 0.56, "m", "est", "shoulder to elbow1 axis; with L2, L3 fits the 2 m reach")
L2 = _p("link2.length", 0.44, "m", "est", "elbow1 to elbow2 axis; shorter than link 3 (report)")
L3 = _p(
    "link3.length",
    0.90,
    "m",
    "est",
    "elbow2 axis to gripper tool point (report: longer than link 2)",
)
OFF2 = _p("link2.lateral_offset", 0.075, "m", "est", "link 2 beside link 1 so the arm folds flat")
WRIST_X = _p("link3.wrist_start", 0.56, "m", "est", "elbow2 axis to gripper wrist along link 3")
ROLL_X = _p("link3.roll_joint", 0.68, "m", "est", "elbow2 axis to gripper roll joint along link 3")
TILT_X = _p("link3.tilt_axis_x", 0.62, "m", "est", "camera tilt axis, along link 3")
TILT_Y = _p(
    "link3.tilt_axis_up", 0.16, "m", "est", "camera tilt axis, above the link 3 centre line"
)
CAM_UP = _p(
    "camera.height", 0.10, "m", "est", "optical centre above the tilt axis, along the pan axis"
)
CAM_FWD = _p("camera.forward", 0.10, "m", "est", "optical centre ahead of the pan axis")

# --------------------------------------------------------------------------------------------
# Link parts: masses (report: known to 100 g on the real arm, never published; ours estimate
# them so that the arm totals ~11 kg, robot ~30 kg) and shapes.
# --------------------------------------------------------------------------------------------
M_TURRET = _p("mass.turret_casing", 1.0, "kg", "est", "turret bearing and yaw gearbox")
M_YOKE = _p("mass.shoulder_yoke_plate", 0.2, "kg", "est", "each of two plates")
M_SH_CASE = _p("mass.shoulder_casing", 1.1, "kg", "est", "shoulder gearbox casing, on link 1")
M_L1_TUBE = _p("mass.link1_tube", 0.45, "kg", "est", "aluminium tube, hollow")
M_L1_MOTOR = _p("mass.link1_motor", 0.6, "kg", "est", "elbow1 motor inside link 1")
M_BOARD = _p("mass.board", 0.1, "kg", "est", "electronics board in each major link")
M_E1_CASE1 = _p("mass.elbow1_casing_link1", 0.8, "kg", "est", "elbow1 gearbox, link 1 side")
M_E1_CASE2 = _p("mass.elbow1_casing_link2", 0.6, "kg", "est", "elbow1 casing, link 2 side")
M_L2_TUBE = _p("mass.link2_tube", 0.35, "kg", "est", "")
M_L2_MOTOR = _p("mass.link2_motor", 0.5, "kg", "est", "elbow2 motor inside link 2")
M_E2_CASE2 = _p("mass.elbow2_casing_link2", 0.6, "kg", "est", "elbow2 gearbox, link 2 side")
M_E2_CASE3 = _p("mass.elbow2_casing_link3", 0.5, "kg", "est", "elbow2 casing, link 3 side")
M_L3_TUBE = _p("mass.link3_tube", 0.4, "kg", "est", "")
M_GWRIST = _p("mass.gripper_wrist", 0.9, "kg", "est", "solid; holds the roll motor (report)")
M_CWRIST = _p("mass.camera_wrist", 0.6, "kg", "est", "solid; holds the tilt motor (report)")
M_PALM = _p("mass.gripper_palm", 0.45, "kg", "est", "palm with the jaw motor")
M_FINGER = _p("mass.finger", 0.15, "kg", "est", "each finger")
M_BRACKET = _p("mass.camera_bracket", 0.3, "kg", "est", "tilt bracket with the pan motor")
M_HEAD = _p("mass.camera_head", 0.7, "kg", "est", "camera head housing")
M_LENS = _p("mass.camera_lens", 0.1, "kg", "est", "")

TUBE_WALL = _p("link.tube_wall", 0.003, "m", "est", "tube wall thickness (report: from memory)")
R_SH_CASE = _p("casing.shoulder_radius", 0.075, "m", "est", "the casing the fallen link 3 props on")
R_E1_CASE = _p("casing.elbow1_radius", 0.06, "m", "est", "")
R_E2_CASE = _p("casing.elbow2_radius", 0.055, "m", "est", "")
R_TUBE1 = _p("link1.tube_radius", 0.032, "m", "est", "outer")
R_TUBE2 = _p("link2.tube_radius", 0.030, "m", "est", "outer")
R_TUBE3 = _p("link3.tube_radius", 0.030, "m", "est", "outer")

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
    """

    name: str
    shape: Literal["box", "cylinder", "tube", "stadium"]
    mass: float
    center: tuple[float, float, float]
    size: tuple[float, ...]
    axis: Literal["x", "y", "z"] = "z"
    collision: bool = True


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


def _joint(
    name: str,
    parent: str,
    child: str,
    limits: tuple[float, float],
    velocity: float,
    effort: float | None,
    ratio: float,
    rotor: float,
    viscous: float,
    coulomb: float,
    axis_shift: float = 0.0,
) -> JointSpec:
    lo = _p(f"{name}.lower", limits[0], "rad", "est", "mechanical stop")
    hi = _p(f"{name}.upper", limits[1], "rad", "est", "mechanical stop")
    vel = _p(f"{name}.velocity_limit", velocity, "rad/s", "est", "slow EOD arm")
    eff = None
    if effort is not None:
        eff = _p(f"{name}.effort_limit", effort, "N*m", "est", "not a lifting joint")
    gr = _p(
        f"{name}.gear_ratio", ratio, "-", "est", "iRobot gave the report its ratios; unpublished"
    )
    ri = _p(f"{name}.rotor_inertia", rotor, "kg*m^2", "est", "catalogue value of a motor that size")
    vi = _p(f"{name}.viscous_friction", viscous, "N*m*s/rad", "est", "at the joint output")
    co = _p(f"{name}.coulomb_friction", coulomb, "N*m", "est", "at the joint output")
    return JointSpec(name, parent, child, lo, hi, vel, eff, gr, ri, vi, co, axis_shift)


PI = math.pi
_h = math.hypot(TILT_X, TILT_Y)
_phi = math.atan2(TILT_Y, TILT_X)

# The DH chains. Both share rows 1-3; row 4 differs because standard DH attaches frame 4 to the
# axis of the *next* joint (gripper_roll along link 3, or camera_tilt parallel to elbow2).
DH_COMMON: tuple[DHRow, ...] = (
    DHRow("turret", 0.0, D_TURRET, A_TURRET, PI / 2),
    DHRow("shoulder", 0.0, 0.0, L1, 0.0),
    DHRow("elbow1", 0.0, OFF2, L2, 0.0),
)
#: The standard DH chains from the base to each tool frame: ``"gripper"`` and ``"camera"``.
CHAINS: dict[str, tuple[DHRow, ...]] = {
    "gripper": (
        *DH_COMMON,
        DHRow("elbow2", PI / 2, 0.0, 0.0, PI / 2),
        DHRow("gripper_roll", 0.0, L3, 0.0, 0.0),
    ),
    "camera": (
        *DH_COMMON,
        DHRow("elbow2", _phi, 0.0, _h, 0.0),
        DHRow("camera_tilt", -_phi, 0.0, 0.0, -PI / 2),
        DHRow("camera_pan", 0.0, CAM_UP, CAM_FWD, 0.0),
    ),
}
#: Base transform of both chains: DH frame 0 in base_link (a pure translation).
DH_BASE = (MOUNT_X, 0.0, CH_H + MOUNT_H)
#: Names of the tool frames at the end of each chain.
TOOL_FRAMES = {"gripper": "gripper_tool", "camera": "camera_optical"}

#: The arm's joints in model order: limits, actuator and friction parameters.
JOINTS: tuple[JointSpec, ...] = (
    _joint("turret", "base_link", "turret_link", (-3.05, 3.05), 1.0, 60.0, 200, 3.3e-6, 0.8, 1.5),
    _joint("shoulder", "turret_link", "link1", (-1.3, 2.1), 0.8, None, 160, 3.3e-6, 0.8, 1.5),
    _joint("elbow1", "link1", "link2", (-2.6, 3.05), 1.0, None, 160, 1.1e-6, 0.5, 1.0, OFF2),
    _joint("elbow2", "link2", "link3", (-2.9, 2.9), 1.2, None, 120, 1.1e-6, 0.4, 0.8),
    _joint("camera_tilt", "link3", "camera_tilt_link", (-2.2, 2.2), 1.5, 6.0, 100, 3e-7, 0.05, 0.2),
    _joint(
        "camera_pan", "camera_tilt_link", "camera_head", (-2.9, 2.9), 1.5, 4.0, 100, 3e-7, 0.05, 0.2
    ),
    _joint(
        "gripper_roll", "link3", "gripper_link", (-3.1, 3.1), 2.0, 10.0, 80, 3e-7, 0.05, 0.3, ROLL_X
    ),
    _joint("gripper_jaw", "gripper_link", "jaw_link", (0.0, 1.2), 1.5, 8.0, 150, 3e-7, 0.05, 0.3),
)
#: The arm's joint names in model order.
ARM_JOINTS: tuple[str, ...] = tuple(j.name for j in JOINTS)

# Jaw pivot in the gripper_link frame (z along the approach axis, x "up" at zero roll).
JAW_PIVOT = (0.03, 0.0, 0.08)


def _cyl(r: float, length: float) -> tuple[float, float]:
    return (r, length)


#: The links and their parts (geometry and mass), from the chassis to the gripper jaw.
LINKS: tuple[LinkSpec, ...] = (
    LinkSpec(
        "base_link",
        (
            Part(
                "body",
                "box",
                M_BODY,
                (0.0, 0.0, (BODY_CLEAR + CH_H) / 2),
                (CH_L - 0.06, CH_W - 2 * TRACK_W, CH_H - BODY_CLEAR),
            ),
            Part(
                "track_left",
                "stadium",
                M_TRACK,
                (0.0, CH_W / 2 - TRACK_W / 2, WHEEL_R),
                (CH_L / 2 - WHEEL_R, WHEEL_R, -(CH_L / 2 - WHEEL_R), WHEEL_R, TRACK_W),
            ),
            Part(
                "track_right",
                "stadium",
                M_TRACK,
                (0.0, -(CH_W / 2 - TRACK_W / 2), WHEEL_R),
                (CH_L / 2 - WHEEL_R, WHEEL_R, -(CH_L / 2 - WHEEL_R), WHEEL_R, TRACK_W),
            ),
            Part(
                "flipper_left",
                "stadium",
                M_FLIPPER,
                (0.0, CH_W / 2 + FLIP_W / 2, WHEEL_R),
                (CH_L / 2 - WHEEL_R, WHEEL_R, CH_L / 2 - WHEEL_R - FLIP_L, FLIP_TIP_R, FLIP_W),
            ),
            Part(
                "flipper_right",
                "stadium",
                M_FLIPPER,
                (0.0, -(CH_W / 2 + FLIP_W / 2), WHEEL_R),
                (CH_L / 2 - WHEEL_R, WHEEL_R, CH_L / 2 - WHEEL_R - FLIP_L, FLIP_TIP_R, FLIP_W),
            ),
            Part(
                "arm_plate",
                "cylinder",
                M_PLATE,
                (MOUNT_X, 0.0, CH_H + MOUNT_H / 2),
                _cyl(MOUNT_R, MOUNT_H),
                "z",
            ),
        ),
        (0.25, 0.27, 0.22, 1.0),
    ),
    LinkSpec(
        "turret_link",
        (
            Part("turret_casing", "cylinder", M_TURRET, (0.0, 0.0, 0.03), _cyl(0.09, 0.06), "z"),
            Part("yoke_left", "box", M_YOKE, (A_TURRET, 0.0725, 0.085), (0.10, 0.015, 0.05)),
            Part("yoke_right", "box", M_YOKE, (A_TURRET, -0.0725, 0.085), (0.10, 0.015, 0.05)),
        ),
        (0.55, 0.5, 0.2, 1.0),
    ),
    LinkSpec(
        "link1",
        (
            Part(
                "shoulder_casing",
                "cylinder",
                M_SH_CASE,
                (0.0, 0.0, 0.0),
                _cyl(R_SH_CASE, 0.12),
                "z",
            ),
            Part(
                "tube",
                "tube",
                M_L1_TUBE,
                ((0.07 + L1 - 0.06) / 2, 0.0, 0.0),
                (R_TUBE1, L1 - 0.06 - 0.07, TUBE_WALL),
                "x",
            ),
            Part("motor", "cylinder", M_L1_MOTOR, (0.16, 0.0, 0.0), _cyl(0.022, 0.12), "x", False),
            Part("board", "box", M_BOARD, (0.33, 0.0, 0.0), (0.14, 0.035, 0.008), collision=False),
            Part(
                "elbow1_casing", "cylinder", M_E1_CASE1, (L1, 0.0, 0.0), _cyl(R_E1_CASE, 0.07), "z"
            ),
        ),
        (0.75, 0.68, 0.3, 1.0),
    ),
    LinkSpec(
        "link2",
        (
            Part(
                "elbow1_casing", "cylinder", M_E1_CASE2, (0.0, 0.0, 0.0), _cyl(R_E1_CASE, 0.07), "z"
            ),
            Part(
                "tube",
                "tube",
                M_L2_TUBE,
                ((0.06 + L2 - 0.055) / 2, 0.0, 0.0),
                (R_TUBE2, L2 - 0.055 - 0.06, TUBE_WALL),
                "x",
            ),
            Part("motor", "cylinder", M_L2_MOTOR, (0.13, 0.0, 0.0), _cyl(0.02, 0.10), "x", False),
            Part("board", "box", M_BOARD, (0.27, 0.0, 0.0), (0.12, 0.03, 0.008), collision=False),
            Part(
                "elbow2_casing", "cylinder", M_E2_CASE2, (L2, 0.0, 0.0), _cyl(R_E2_CASE, 0.07), "z"
            ),
        ),
        (0.7, 0.62, 0.28, 1.0),
    ),
    LinkSpec(
        "link3",
        (
            Part(
                "elbow2_casing", "cylinder", M_E2_CASE3, (0.0, 0.0, 0.0), _cyl(R_E2_CASE, 0.07), "z"
            ),
            Part(
                "tube",
                "tube",
                M_L3_TUBE,
                ((0.05 + WRIST_X) / 2, 0.0, 0.0),
                (R_TUBE3, WRIST_X - 0.05, TUBE_WALL),
                "x",
            ),
            Part("board", "box", M_BOARD, (0.30, 0.0, 0.0), (0.14, 0.03, 0.008), collision=False),
            Part(
                "gripper_wrist",
                "cylinder",
                M_GWRIST,
                ((WRIST_X + ROLL_X) / 2, 0.0, 0.0),
                _cyl(0.04, ROLL_X - WRIST_X),
                "x",
            ),
            Part(
                "camera_wrist",
                "box",
                M_CWRIST,
                (TILT_X - 0.02, TILT_Y / 2 + 0.01, 0.0),
                (0.10, TILT_Y - 0.02, 0.06),
            ),
        ),
        (0.65, 0.58, 0.26, 1.0),
    ),
    LinkSpec(
        "camera_tilt_link",
        (Part("bracket", "box", M_BRACKET, (0.0, 0.0, 0.0), (0.05, 0.05, 0.08)),),
        (0.2, 0.2, 0.2, 1.0),
    ),
    LinkSpec(
        "camera_head",
        (
            Part("head", "box", M_HEAD, (0.0, 0.0, CAM_UP), (0.14, 0.16, 0.09)),
            Part("lens", "cylinder", M_LENS, (CAM_FWD - 0.015, 0.0, CAM_UP), _cyl(0.03, 0.03), "x"),
        ),
        (0.15, 0.15, 0.15, 1.0),
    ),
    LinkSpec(
        "gripper_link",
        (
            Part("palm", "box", M_PALM, (0.0, 0.0, 0.04), (0.07, 0.09, 0.08)),
            Part("fixed_finger", "box", M_FINGER, (-0.025, 0.0, 0.16), (0.02, 0.05, 0.16)),
        ),
        (0.35, 0.35, 0.38, 1.0),
    ),
    LinkSpec(
        "jaw_link",
        (Part("finger", "box", M_FINGER, (0.0, 0.0, 0.08), (0.02, 0.05, 0.16)),),
        (0.35, 0.35, 0.38, 1.0),
    ),
)

#: Named poses from the real robot's presets [rad], in ARM_JOINTS order.
#: drive: arm folded over the chassis, link 3 upright carrying the head (the report's Fig. 6).
POSES: dict[str, dict[str, float]] = {
    "drive": {"shoulder": 0.05, "elbow1": 2.85, "elbow2": -1.12, "camera_tilt": -1.6},
    "stow": {"shoulder": 0.05, "elbow1": 2.85, "elbow2": -2.8, "camera_tilt": 0.0},
    "stand": {"shoulder": 1.2, "elbow1": -0.7, "elbow2": -0.4, "camera_tilt": -0.1},
    "high": {"shoulder": 1.45, "elbow1": -0.1, "elbow2": 0.05, "camera_tilt": -1.4},
    "low": {"shoulder": 0.35, "elbow1": -0.9, "elbow2": 0.3, "camera_tilt": -0.5},
}
