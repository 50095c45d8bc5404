"""A catalogue of bad inputs: every one must give a clean error, never a traceback or a hang.

Used by ``tests/test_bad_inputs.py`` (one pytest case each) and ``benchmarks/bad_inputs.py``
(a table of outcomes, each case in a worker process with a timeout, so that a hang is counted
instead of stopping the run). Its categories (:data:`CATEGORIES`):

- ``api``: the Python API (settings, failures, payloads, obstacles, environments, controllers,
  ``simulate()`` arguments, ``load_robot``, ``Robot`` and result helpers);
- ``scenario``: scenario files (TOML written to a temporary folder), loaded with
  ``packbot.scenario.load_scenario`` and checked against the robot, some run through
  ``packbot run``;
- ``cli``: every subcommand with bad options, values and paths (``packbot.cli.main`` in process);
- ``matrix``: matrix files, loaded with ``packbot.matrix.load_matrix`` and expanded over their
  base scenario, some run through ``packbot batch`` and ``packbot regress``;
- ``urdf``: broken copies of ``urdf/packbot_eod.urdf`` given to ``load_robot`` and ``packbot info``;
- ``keywords``, ``result_file``, ``sizes``, ``content``, ``paths``, ``signals``: in their own
  modules (:data:`EXTENSIONS`, ``tests/bad_inputs_*.py``), each registering its cases through
  ``register(catalogue)``.

A case's outcome (:func:`run_case`) is one of:

- ``clean``: the expected :class:`~packbot.errors.PackbotError` subclass, whose message names the
  field (or element); for the command line, the expected exit code and exactly one line on
  stderr without a traceback;
- ``unclear``: a PackbotError, but of another class or not naming the field (or, on the command
  line, another exit code or more than one line);
- ``traceback``: any other exception escaped (or a traceback was printed);
- ``accepted``: no error at all (silently accepted nonsense);
- ``hang``: (worker mode only) the case did not finish within the timeout.

A case may instead hold input that is legal but hostile (an obstacle named ``<img onerror=...>``
must be escaped on the pages, not refused; a run stopped by SIGTERM must save its partial
result): its ``check`` is called with what the action returned and says whether the outcome is
right. None: ``clean`` (the input was handled as it must be); a string: ``accepted``, with that
string (the problem) as the detail. An action that raises is classified as any other (a
PackbotError is then ``clean`` or ``unclear``); a check that raises is a ``traceback``.

Run as a script, this module is the worker: ``python tests/bad_input_cases.py --worker`` reads
case ids on stdin and answers one JSON line per case; ``--case ID`` runs one case.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import os
import shutil
import sys
import tempfile
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # run as a script or imported from benchmarks/
    sys.path.insert(0, str(HERE))

from test_model_validation import SHOULDER_LIMIT, TUBE, broken_copy  # noqa: E402

import packbot  # noqa: E402
from packbot import (  # noqa: E402
    Environment,
    Failure,
    Obstacle,
    Payload,
    SimConfig,
    simulate,
)
from packbot.cli import main as cli_main  # noqa: E402
from packbot.control import (  # noqa: E402
    CartesianPD,
    ComputedTorque,
    GravityCompensation,
    JointPD,
    JointTrajectory,
    MomentumObserver,
    QuinticSegment,
    ReconfigurableController,
    Sensor,
    build_controller,
)
from packbot.errors import (  # noqa: E402
    ConfigurationError,
    InertialError,
    InitialCollisionError,
    JointError,
    JointMismatchError,
    MeshError,
    ModelError,
    PackbotError,
    ResourceNotFound,
    UnknownNameError,
    URDFError,
    URDFSyntaxError,
)
from packbot.matrix import load_matrix, parse_matrix  # noqa: E402
from packbot.scenario import (  # noqa: E402
    OcclusionCheck,
    Outputs,
    Scenario,
    load_scenario,
    run_scenario,
    save_run,
    scenario_from_dict,
)

CATEGORIES = (
    "api",
    "scenario",
    "cli",
    "matrix",
    "urdf",
    "keywords",  # unknown, misspelt and missing keywords of every public entry point
    "result_file",  # damaged, hand-made and inconsistent result files for SimResult.load
    "sizes",  # sizes past their documented bounds (samples, obstacles, cells, depth, lengths)
    "content",  # hostile strings reaching HTML pages and CSV cells
    "paths",  # stems, names and manifests that would write or delete outside the folder
    "signals",  # runs interrupted by signals; a batch's main process killed
)
#: The modules holding the newer categories' cases, each with ``register(catalogue)``
#: (this module), which adds its cases with :func:`add`, :func:`api`, :func:`cli`, ...
EXTENSIONS = (
    "bad_inputs_keywords",
    "bad_inputs_result_files",
    "bad_inputs_sizes",
    "bad_inputs_content",
    "bad_inputs_paths",
    "bad_inputs_signals",
)
OUTCOMES = ("clean", "unclear", "traceback", "hang", "accepted")

NQ = 8
JOINTS = (
    "turret",
    "shoulder",
    "elbow1",
    "elbow2",
    "camera_tilt",
    "camera_pan",
    "gripper_roll",
    "gripper_jaw",
)


# ------------------------------------------------------------------------ the harness
class Ctx:
    """What a case may use: the robot, a fresh folder, helpers to write files in it."""

    _robot: packbot.Robot | None = None
    _result: packbot.SimResult | None = None

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp

    @property
    def robot(self) -> packbot.Robot:
        """The shipped robot, loaded once per process."""
        if Ctx._robot is None:
            Ctx._robot = packbot.load_robot()
        return Ctx._robot

    @property
    def result(self) -> packbot.SimResult:
        """A short valid run (0.02 s of collapse), made once per process."""
        if Ctx._result is None:
            r = self.robot
            Ctx._result = simulate(r, r.pose("drive"), np.zeros(NQ), 0.02)
        return Ctx._result

    def drive(self) -> np.ndarray:
        return self.robot.pose("drive")

    def write(self, name: str, text: str | bytes) -> Path:
        path = self.tmp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text)
        return path

    def out(self, name: str = "out") -> str:
        return str(self.tmp / name)


@dataclass(frozen=True)
class Case:
    """One bad input.

    Attributes:
        category: One of :data:`CATEGORIES`.
        id: A readable id, unique in the catalogue.
        action: Does the bad thing (API) or returns the command line's arguments (``cli``).
        words: Substrings the error message (or the stderr line) must hold: the field, element
            or option.
        error: The PackbotError subclass expected (API).
        cli: Whether ``action`` returns argv for ``packbot.cli.main``.
        code: The exit code expected (command line).
        guard: The input used to hang: pytest runs it in a worker process with a timeout
            (tests/bad_input_worker.py; a signals case in a process of its own).
        check: For legal but hostile input: called with the action's return value, returns
            None when the outcome is right (``clean``) or the problem (``accepted``).
    """

    category: str
    id: str
    action: Callable[[Ctx], Any]
    words: tuple[str, ...] = ()
    error: type[PackbotError] = PackbotError
    cli: bool = False
    code: int = 2
    guard: bool = False
    check: Callable[[Any], str | None] | None = None

    @property
    def key(self) -> str:
        return f"{self.category}/{self.id}"


@dataclass
class Outcome:
    """The outcome of a case: one of :data:`OUTCOMES`, and what happened."""

    status: str
    detail: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


class _StderrLog(logging.Handler):
    """Log records of WARNING and above go to the current sys.stderr (they count as lines)."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(self.format(record) + "\n")


def _run_cli(argv: Sequence[str]) -> tuple[int | None, str, str, BaseException | None]:
    out, err = io.StringIO(), io.StringIO()
    handler = _StderrLog(logging.WARNING)
    root = logging.getLogger()
    root.addHandler(handler)
    code: int | None = None
    exc: BaseException | None = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli_main(list(argv))
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
            except Exception as e:  # an escaped exception: a traceback for the user
                exc = e
                traceback.print_exc()
    finally:
        root.removeHandler(handler)
    return code, out.getvalue(), err.getvalue(), exc


def run_case(case: Case, tmp: Path) -> Outcome:
    """Run one case in ``tmp`` (an empty folder) and classify what happened."""
    ctx = Ctx(tmp)
    if case.cli:
        try:
            argv = case.action(ctx)
        except Exception as e:  # the case's own setup failed
            return Outcome("traceback", f"setup: {type(e).__name__}: {e}")
        cwd = os.getcwd()
        os.chdir(tmp)  # a relative or empty path lands in the case's folder, never in the repo
        try:
            code, _, err, exc = _run_cli(argv)
        finally:
            os.chdir(cwd)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        extra = {"code": code, "stderr": err}
        if exc is not None or "Traceback" in err:
            name = type(exc).__name__ if exc is not None else "printed"
            return Outcome("traceback", f"{name}: {exc}", extra)
        if code == 0:
            return Outcome("accepted", f"exit 0: {err.strip()!r}", extra)
        if code != case.code or len(lines) != 1:
            return Outcome("unclear", f"exit {code}, {len(lines)} stderr lines: {err!r}", extra)
        missing = [w for w in case.words if w not in err]
        if missing:
            return Outcome("unclear", f"stderr does not name {missing}: {err.strip()!r}", extra)
        return Outcome("clean", err.strip(), extra)
    try:
        value = case.action(ctx)
    except PackbotError as e:
        msg = str(e)
        if not isinstance(e, case.error):
            return Outcome("unclear", f"{type(e).__name__} (not {case.error.__name__}): {msg}")
        missing = [w for w in case.words if w not in msg]
        if missing:
            return Outcome("unclear", f"does not name {missing}: {type(e).__name__}: {msg}")
        return Outcome("clean", f"{type(e).__name__}: {msg}")
    except Exception as e:
        tb = traceback.format_exc(limit=-3)
        return Outcome("traceback", f"{type(e).__name__}: {e}", {"traceback": tb})
    if case.check is not None:
        try:
            problem = case.check(value)
        except Exception as e:
            tb = traceback.format_exc(limit=-3)
            return Outcome("traceback", f"check: {type(e).__name__}: {e}", {"traceback": tb})
        if problem is None:
            return Outcome("clean", f"checked: {value!r:.200}")
        return Outcome("accepted", problem)
    return Outcome("accepted", f"returned {value!r:.200}")


# ------------------------------------------------------------------------ helpers
CASES: list[Case] = []


def add(category: str, id: str, action: Callable[[Ctx], Any], *words: str, **kw: Any) -> None:
    CASES.append(Case(category, id, action, tuple(words), **kw))


def api(id: str, action: Callable[[Ctx], Any], *words: str, **kw: Any) -> None:
    add("api", id, action, *words, **kw)


def cfg(**kw: Any) -> Callable[[Ctx], Any]:
    return lambda c: SimConfig(**kw)


def sim(**kw: Any) -> Callable[[Ctx], Any]:
    """simulate() from the drive pose at rest for 0.05 s, with arguments replaced by ``kw``.

    A value that is a function of the Ctx is called first (for arguments needing the robot).
    """

    def action(c: Ctx) -> Any:
        args = {"q0": c.drive(), "v0": np.zeros(NQ), "duration": 0.05}
        args.update({k: (v(c) if callable(v) and k.startswith("_") else v) for k, v in kw.items()})
        args = {k.lstrip("_"): v for k, v in args.items()}
        robot = args.pop("robot", c.robot)
        q0, v0, duration = args.pop("q0"), args.pop("v0"), args.pop("duration")
        return simulate(robot, q0, v0, duration, **args)

    return action


def mutated_config(**kw: Any) -> SimConfig:
    """A valid SimConfig whose fields are then changed (simulate() checks it again)."""
    c = SimConfig()
    for k, v in kw.items():
        setattr(c, k, v)
    return c


def mutated_dt(ctrl: Any, dt: Any) -> Any:
    ctrl.dt = dt
    return ctrl


def prepared(ctrl_factory: Callable[[], Any]) -> Callable[[Ctx], Any]:
    """Build a controller and prepare it for the robot (names and lengths are checked there)."""

    def action(c: Ctx) -> Any:
        ctrl = ctrl_factory()
        ctrl.prepare(c.robot)
        return ctrl

    return action


def _traj_bad_shape(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.zeros(3), np.zeros(3), np.zeros(3)


def _traj_raises(t: float) -> Any:
    raise RuntimeError("no reference")


def _traj_not_tuple(t: float) -> Any:
    return 42


NAN, INF = math.nan, math.inf

# ------------------------------------------------------------------------ API: SimConfig
_cfg_cases: list[tuple[str, dict[str, Any], str]] = [
    ("restitution-str", {"restitution": "0.5"}, "restitution"),
    ("restitution-none", {"restitution": None}, "restitution"),
    ("restitution-bool", {"restitution": True}, "restitution"),
    ("restitution-above-1", {"restitution": 1.5}, "restitution"),
    ("restitution-negative", {"restitution": -0.1}, "restitution"),
    ("restitution-nan", {"restitution": NAN}, "restitution"),
    ("restitution-complex", {"restitution": 0.5 + 0j}, "restitution"),
    ("restitution-list", {"restitution": [0.5]}, "restitution"),
    ("restitution-ndarray", {"restitution": np.array([0.5])}, "restitution"),
    ("contact_mode-unknown", {"contact_mode": "bogus"}, "contact_mode"),
    ("contact_mode-none", {"contact_mode": None}, "contact_mode"),
    ("contact_mode-int", {"contact_mode": 1}, "contact_mode"),
    ("contact_mode-uppercase", {"contact_mode": "NONE"}, "contact_mode"),
    ("clamp_rule-unknown", {"clamp_rule": "normal"}, "clamp_rule"),
    ("reset_rule-int", {"reset_rule": 3}, "reset_rule"),
    ("contact_tolerance-zero", {"contact_tolerance": 0.0}, "contact_tolerance"),
    ("contact_tolerance-negative", {"contact_tolerance": -1e-3}, "contact_tolerance"),
    ("contact_tolerance-inf", {"contact_tolerance": INF}, "contact_tolerance"),
    ("contact_tolerance-1m", {"contact_tolerance": 1.0}, "contact_tolerance"),
    ("proximity-below-contact", {"proximity_tolerance": 1e-4}, "proximity_tolerance"),
    ("margin-below-proximity", {"margin": 1e-3}, "margin"),
    ("rtol-bool", {"rtol": True}, "rtol"),
    ("rtol-1000", {"rtol": 1000}, "rtol"),
    ("rtol-zero", {"rtol": 0.0}, "rtol"),
    ("rtol-1e-20", {"rtol": 1e-20}, "rtol"),
    ("rtol-str", {"rtol": "1e-6"}, "rtol"),
    ("atol-zero", {"atol": 0.0}, "atol"),
    ("atol-10", {"atol": 10.0}, "atol"),
    ("sample_dt-1e-9", {"sample_dt": 1e-9}, "sample_dt"),
    ("sample_dt-zero", {"sample_dt": 0}, "sample_dt"),
    ("sample_dt-negative", {"sample_dt": -0.01}, "sample_dt"),
    ("sample_dt-none", {"sample_dt": None}, "sample_dt"),
    ("sample_dt-inf", {"sample_dt": INF}, "sample_dt"),
    ("gravity-none", {"gravity": None}, "gravity"),
    ("gravity-scalar", {"gravity": 9.81}, "gravity"),
    ("gravity-two", {"gravity": (0.0, -9.81)}, "gravity"),
    ("gravity-cm-per-s2", {"gravity": (0.0, 0.0, -981.0)}, "gravity"),
    ("gravity-str-item", {"gravity": ("0", 0.0, -9.81)}, "gravity"),
    ("gravity-nan", {"gravity": (0.0, 0.0, NAN)}, "gravity"),
    ("gravity-complex", {"gravity": (0j, 0.0, -9.81)}, "gravity"),
    ("gravity-str", {"gravity": "0 0 -9.81"}, "gravity"),
    ("gravity-dict", {"gravity": {"z": -9.81}}, "gravity"),
    ("gravity-bools", {"gravity": np.array([True, False, True])}, "gravity"),
    ("relevant_threshold-2", {"relevant_threshold": 2}, "relevant_threshold"),
    ("relevant_threshold-1", {"relevant_threshold": 1.0}, "relevant_threshold"),
    ("relevant_threshold-negative", {"relevant_threshold": -0.1}, "relevant_threshold"),
    ("joint_limits-int", {"joint_limits": 1}, "joint_limits"),
    ("joint_limits-str", {"joint_limits": "yes"}, "joint_limits"),
    ("joint_friction-none", {"joint_friction": None}, "joint_friction"),
    ("effort_saturation-str", {"effort_saturation": "true"}, "effort_saturation"),
    ("locked_joints-none", {"locked_joints": None}, "locked_joints"),
    ("locked_joints-str", {"locked_joints": "camera_tilt"}, "locked_joints"),
    ("locked_joints-twice", {"locked_joints": ("camera_tilt", "camera_tilt")}, "locked_joints"),
    ("locked_joints-int-item", {"locked_joints": (1,)}, "locked_joints"),
    ("locked_joints-empty-name", {"locked_joints": ("",)}, "locked_joints"),
    ("locked_joints-set", {"locked_joints": {"camera_tilt"}}, "locked_joints"),
    ("max_step-1e-12", {"max_step": 1e-12}, "max_step"),
    ("max_step-zero", {"max_step": 0.0}, "max_step"),
    ("rest_speed-zero", {"rest_speed": 0.0}, "rest_speed"),
    ("max_events-zero", {"max_events": 0}, "max_events"),
    ("max_events-float", {"max_events": 1.5}, "max_events"),
    ("max_events-1e9", {"max_events": 10**9}, "max_events"),
    ("max_events-bool", {"max_events": True}, "max_events"),
    ("max_events-str", {"max_events": "100"}, "max_events"),
    ("motor_lag-negative", {"motor_lag": -1.0}, "motor_lag"),
    ("motor_lag-1e-9", {"motor_lag": 1e-9}, "motor_lag"),
    ("motor_lag-nan", {"motor_lag": NAN}, "motor_lag"),
    ("mu-negative", {"mu": -0.1}, "mu"),
    ("mu-100", {"mu": 100.0}, "mu"),
    ("zeno_speed-negative", {"zeno_speed": -1.0}, "zeno_speed"),
    ("handoff-with-mode-none", {"contact_mode": "none", "handoff": True}, "handoff"),
    ("handoff-with-the-default-mode", {"handoff": True}, "handoff"),
    ("handoff-int", {"handoff": 1}, "handoff"),
]
for _id, _kw, _word in _cfg_cases:
    api(f"SimConfig-{_id}", cfg(**_kw), _word, error=ConfigurationError)

# ------------------------------------------------------------------------ API: Failure
_failure_cases: list[tuple[str, dict[str, Any], str]] = [
    ("kind-unknown", {"joint": "shoulder", "kind": "broken"}, "failure.kind"),
    ("kind-none", {"joint": "shoulder", "kind": None}, "failure.kind"),
    ("joint-empty", {"joint": "", "kind": "loose"}, "failure.joint"),
    ("joint-int", {"joint": 1, "kind": "loose"}, "failure.joint"),
    ("joint-list", {"joint": ["shoulder"], "kind": "loose"}, "failure.joint"),
    ("t-negative", {"joint": "shoulder", "kind": "loose", "t": -0.5}, "failure.t"),
    ("t-nan", {"joint": "shoulder", "kind": "loose", "t": NAN}, "failure.t"),
    ("t-bool", {"joint": "shoulder", "kind": "loose", "t": True}, "failure.t"),
    ("t-str", {"joint": "shoulder", "kind": "loose", "t": "0.5"}, "failure.t"),
    ("scale-zero", {"joint": "shoulder", "kind": "weak", "scale": 0.0}, "failure.scale"),
    ("scale-above-1", {"joint": "shoulder", "kind": "weak", "scale": 1.5}, "failure.scale"),
    ("torque-inf", {"joint": "shoulder", "kind": "stuck", "torque": INF}, "failure.torque"),
    ("threshold-negative", {"joint": "shoulder", "kind": "brake", "threshold": -1}, "threshold"),
    ("threshold-str", {"joint": "shoulder", "kind": "brake", "threshold": "20"}, "threshold"),
]
for _id, _kw, _word in _failure_cases:
    api(f"Failure-{_id}", lambda c, kw=_kw: Failure(**kw), _word, error=ConfigurationError)

# ------------------------------------------------------------------------ API: Payload
_payload_cases: list[tuple[str, dict[str, Any], str]] = [
    ("mass-zero", {"mass": 0.0}, "payload.mass"),
    ("mass-negative", {"mass": -1.0}, "payload.mass"),
    ("mass-str", {"mass": "1"}, "payload.mass"),
    ("mass-bool", {"mass": True}, "payload.mass"),
    ("mass-1e6", {"mass": 1e6}, "payload.mass"),
    ("com-two", {"mass": 1.0, "com": (0.0, 0.0)}, "payload.com"),
    ("com-100m", {"mass": 1.0, "com": (0.0, 0.0, 100.0)}, "payload.com"),
    ("inertia-negative", {"mass": 1.0, "inertia": (-1, 1, 1, 0, 0, 0)}, "payload.inertia"),
    ("inertia-triangle", {"mass": 1.0, "inertia": (1, 1, 5, 0, 0, 0)}, "payload.inertia"),
    ("inertia-five", {"mass": 1.0, "inertia": (1, 1, 1, 0, 0)}, "payload.inertia"),
    ("frame-empty", {"mass": 1.0, "frame": ""}, "payload.frame"),
    ("frame-int", {"mass": 1.0, "frame": 5}, "payload.frame"),
    ("t_pick-negative", {"mass": 1.0, "t_pick": -1.0}, "payload.t_pick"),
    ("t_drop-before-pick", {"mass": 1.0, "t_pick": 1.0, "t_drop": 0.5}, "payload.t_drop"),
    ("t_drop-nan", {"mass": 1.0, "t_drop": NAN}, "payload.t_drop"),
]
for _id, _kw, _word in _payload_cases:
    api(f"Payload-{_id}", lambda c, kw=_kw: Payload(**kw), _word, error=ConfigurationError)

# ------------------------------------------------------------------------ API: Obstacle
_TETRA = ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1))
_obstacle_cases: list[tuple[str, dict[str, Any], str, type[PackbotError]]] = [
    ("name-empty", {"name": "", "kind": "box", "size": (1, 1, 1)}, "name", ConfigurationError),
    ("name-none", {"name": None, "kind": "box", "size": (1, 1, 1)}, "name", ConfigurationError),
    ("kind-sphere", {"name": "b", "kind": "sphere"}, "kind", ConfigurationError),
    ("box-size-zero", {"name": "b", "kind": "box", "size": (0, 1, 1)}, "size", ConfigurationError),
    ("box-size-negative", {"name": "b", "kind": "box", "size": (-1, 1, 1)}, "size", PackbotError),
    ("box-size-two", {"name": "b", "kind": "box", "size": (1, 1)}, "size", ConfigurationError),
    ("box-default-size", {"name": "b", "kind": "box"}, "size", ConfigurationError),
    (
        "xyz-nan",
        {"name": "b", "kind": "box", "size": (1, 1, 1), "xyz": (NAN, 0, 0)},
        "xyz",
        ConfigurationError,
    ),
    (
        "xyz-1e6",
        {"name": "b", "kind": "box", "size": (1, 1, 1), "xyz": (1e6, 0, 0)},
        "xyz",
        ConfigurationError,
    ),
    (
        "rpy-str",
        {"name": "b", "kind": "box", "size": (1, 1, 1), "rpy": ("a", 0, 0)},
        "rpy",
        ConfigurationError,
    ),
    (
        "halfspace-zero-normal",
        {"name": "h", "kind": "halfspace", "normal": (0, 0, 0)},
        "normal",
        ConfigurationError,
    ),
    (
        "halfspace-offset-inf",
        {"name": "h", "kind": "halfspace", "offset": INF},
        "offset",
        ConfigurationError,
    ),
    (
        "convex-three-points",
        {"name": "c", "kind": "convex", "points": _TETRA[:3]},
        "'c'",
        PackbotError,
    ),
    (
        "convex-flat",
        {"name": "c", "kind": "convex", "points": ((0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0))},
        "'c'",
        PackbotError,
    ),
    ("convex-no-points", {"name": "c", "kind": "convex"}, "'c'", PackbotError),
    (
        "convex-ragged",
        {"name": "c", "kind": "convex", "points": ((0, 0, 0), (1, 0), (0, 1, 0), (0, 0, 1))},
        "points",
        ConfigurationError,
    ),
    (
        "convex-str-points",
        {"name": "c", "kind": "convex", "points": "0 0 0"},
        "points",
        PackbotError,
    ),
    (
        "box-with-points",
        {"name": "b", "kind": "box", "size": (1, 1, 1), "points": _TETRA},
        "points",
        ConfigurationError,
    ),
]
for _id, _kw, _word, _err in _obstacle_cases:
    api(f"Obstacle-{_id}", lambda c, kw=_kw: Obstacle(**kw), _word, error=_err)

_BOX = {"name": "crate", "kind": "box", "size": (1, 1, 1), "xyz": (3, 0, 0.5)}
api(
    "Environment-single-obstacle",
    lambda c: Environment(obstacles=packbot.FLOOR),
    "obstacles",
    error=ConfigurationError,
)
api(
    "Environment-str",
    lambda c: Environment(obstacles="floor"),
    "obstacles",
    error=ConfigurationError,
)
api(
    "Environment-int-item",
    lambda c: Environment(obstacles=(1,)),
    "obstacles[0]",
    error=ConfigurationError,
)
api(
    "Environment-none", lambda c: Environment(obstacles=None), "obstacles", error=ConfigurationError
)
api(
    "Environment-duplicate-names",
    lambda c: Environment(obstacles=(Obstacle(**_BOX), Obstacle(**_BOX))),
    "crate",
    error=ConfigurationError,
)
api(
    "Environment-with_obstacles-dict",
    lambda c: Environment().with_obstacles(_BOX),
    "obstacles[1]",
    error=ConfigurationError,
)

# ------------------------------------------------------------------------ API: controllers
_ctrl_cases: list[tuple[str, Callable[[], Any], str]] = [
    ("JointPD-dt-1e-9", lambda: JointPD(dt=1e-9), "controller.dt"),
    ("JointPD-dt-zero", lambda: JointPD(dt=0.0), "controller.dt"),
    ("JointPD-dt-str", lambda: JointPD(dt="0.001"), "controller.dt"),
    ("JointPD-dt-bool", lambda: JointPD(dt=True), "controller.dt"),
    ("JointPD-target-empty", lambda: JointPD(target=""), "controller.target"),
    ("JointPD-target-nan", lambda: JointPD(target=[NAN] * NQ), "controller.target"),
    ("JointPD-target-int", lambda: JointPD(target=5), "controller.target"),
    ("JointPD-kp-negative", lambda: JointPD(kp=-1.0), "controller.kp"),
    ("JointPD-kp-str", lambda: JointPD(kp="high"), "controller.kp"),
    ("JointPD-kd-str-item", lambda: JointPD(kd=[1.0, 2.0, "a"]), "controller.kd"),
    ("JointPD-kp-table-nan", lambda: JointPD(kp={"shoulder": NAN}), "controller.kp.shoulder"),
    ("JointPD-omega-zero", lambda: JointPD(omega=0.0), "controller.omega"),
    ("JointPD-omega-above-nyquist", lambda: JointPD(omega=1e5), "controller.omega"),
    ("JointPD-zeta-zero", lambda: JointPD(zeta=0.0), "controller.zeta"),
    (
        "JointPD-gravity_compensation-int",
        lambda: JointPD(gravity_compensation=1),
        "gravity_compensation",
    ),
    ("JointPD-sensor-str", lambda: JointPD(sensor="exact"), "controller.sensor"),
    ("JointPD-gravity-none", lambda: JointPD(gravity=None), "controller.gravity"),
    ("GravityCompensation-dt-negative", lambda: GravityCompensation(dt=-1e-3), "controller.dt"),
    (
        "GravityCompensation-gravity-cm",
        lambda: GravityCompensation(gravity=(0, 0, -981)),
        "controller.gravity",
    ),
    ("Sensor-resolution-negative", lambda: Sensor(resolution=-1e-3), "sensor.resolution"),
    ("Sensor-seed-float", lambda: Sensor(seed=1.5), "sensor.seed"),
    ("Sensor-noise_v-1000", lambda: Sensor(noise_v=1e3), "sensor.noise_v"),
    ("ComputedTorque-trajectory-int", lambda: ComputedTorque(trajectory=5), "trajectory"),
    (
        "ComputedTorque-omega-negative",
        lambda: ComputedTorque(trajectory=_traj_bad_shape, omega=-1.0),
        "controller.omega",
    ),
    ("JointTrajectory-one-waypoint", lambda: JointTrajectory([[0.0] * NQ], [0.0]), "waypoints"),
    (
        "JointTrajectory-times-decreasing",
        lambda: JointTrajectory([[0.0] * NQ, [0.1] * NQ], [1.0, 0.0]),
        "trajectory.times",
    ),
    (
        "JointTrajectory-times-length",
        lambda: JointTrajectory([[0.0] * NQ, [0.1] * NQ], [0.0, 1.0, 2.0]),
        "trajectory.times",
    ),
    (
        "JointTrajectory-nan-waypoint",
        lambda: JointTrajectory([[0.0] * NQ, [NAN] * NQ], [0.0, 1.0]),
        "trajectory.waypoints",
    ),
    (
        "JointTrajectory-beyond-limit",
        lambda: JointTrajectory([[0.0] * 2, [5.0] * 2], [0.0, 1.0], upper=[1.0, 1.0]),
        "trajectory.waypoints[1][0]",
    ),
    (
        "JointTrajectory-too-fast",
        lambda: JointTrajectory([[0.0] * 2, [2.0] * 2], [0.0, 0.1], v_max=[1.0, 1.0]),
        "trajectory.times[1]",
    ),
    (
        "QuinticSegment-duration-zero",
        lambda: QuinticSegment(q0=[0.0], q1=[1.0], duration=0.0),
        "trajectory.duration",
    ),
    ("QuinticSegment-q1-length", lambda: QuinticSegment(q0=[0.0], q1=[1.0, 2.0]), "trajectory.q1"),
    ("CartesianPD-target-empty", lambda: CartesianPD(target=""), "controller.target"),
    ("CartesianPD-target-two", lambda: CartesianPD(target=(1.0, 2.0)), "controller.target"),
    (
        "CartesianPD-frame-empty",
        lambda: CartesianPD(target=(1, 0, 1), frame=""),
        "controller.frame",
    ),
    (
        "CartesianPD-orientation-not-rotation",
        lambda: CartesianPD(target=(1, 0, 1), orientation=np.ones((3, 3))),
        "controller.orientation",
    ),
    ("CartesianPD-kp-negative", lambda: CartesianPD(target=(1, 0, 1), kp=-1.0), "controller.kp"),
    (
        "CartesianPD-pinv_damping-zero",
        lambda: CartesianPD(target=(1, 0, 1), pinv_damping=0.0),
        "controller.pinv_damping",
    ),
    (
        "Reconfig-speed_fraction-zero",
        lambda: ReconfigurableController(target=(0.7, 0.4, 0.2), speed_fraction=0.0),
        "controller.speed_fraction",
    ),
    (
        "Reconfig-observer_gain-unstable",
        lambda: ReconfigurableController(target=(0.7, 0.4, 0.2), observer_gain=1e4),
        "controller.observer_gain",
    ),
    (
        "Reconfig-ik_seeds-negative",
        lambda: ReconfigurableController(target=(0.7, 0.4, 0.2), ik_seeds=-1),
        "controller.ik_seeds",
    ),
    (
        "Reconfig-environment-str",
        lambda: ReconfigurableController(target=(0.7, 0.4, 0.2), environment="floor"),
        "controller.environment",
    ),
    (
        "Reconfig-threshold-zero",
        lambda: ReconfigurableController(target=(0.7, 0.4, 0.2), threshold=0.0),
        "controller.threshold",
    ),
    (
        "Reconfig-detect-str",
        lambda: ReconfigurableController(target="stand", detect="yes"),
        "controller.detect",
    ),
    (
        "MomentumObserver-model-none",
        lambda: MomentumObserver(None, np.ones(NQ), threshold=np.ones(NQ)),
        "observer.model",
    ),
]
for _id, _factory, _word in _ctrl_cases:
    api(_id, lambda c, f=_factory: f(), _word, error=ConfigurationError)

# Checked against the robot by prepare() (build_controller and simulate call it).
api(
    "JointPD-target-unknown-pose",
    prepared(lambda: JointPD(target="bogus_pose")),
    "bogus_pose",
    error=UnknownNameError,
)
api(
    "JointPD-target-unknown-joint",
    prepared(lambda: JointPD(target={"wrist": 0.1})),
    "wrist",
    error=UnknownNameError,
)
api(
    "JointPD-target-beyond-limits",
    prepared(lambda: JointPD(target={"shoulder": 3.0})),
    "shoulder",
    error=ConfigurationError,
)
api(
    "JointPD-kp-wrong-length",
    prepared(lambda: JointPD(kp=[1.0, 2.0])),
    "controller.kp",
    error=ConfigurationError,
)
api(
    "CartesianPD-frame-unknown",
    prepared(lambda: CartesianPD(target=(1, 0, 1), frame="hand")),
    "hand",
    error=UnknownNameError,
)
api(
    "ComputedTorque-trajectory-wrong-shape",
    prepared(lambda: ComputedTorque(trajectory=_traj_bad_shape)),
    "controller.trajectory",
    error=ConfigurationError,
)
api(
    "ComputedTorque-trajectory-raises",
    prepared(lambda: ComputedTorque(trajectory=_traj_raises)),
    "controller.trajectory",
    error=ConfigurationError,
)
api(
    "ComputedTorque-trajectory-not-tuple",
    prepared(lambda: ComputedTorque(trajectory=_traj_not_tuple)),
    "controller.trajectory",
    error=ConfigurationError,
)
api(
    "build_controller-unknown-kind",
    lambda c: build_controller("pid", c.robot, {}),
    "controller.kind",
    error=ConfigurationError,
)
api(
    "build_controller-unknown-param",
    lambda c: build_controller("pd", c.robot, {"gain": 1}),
    "controller.gain",
    error=ConfigurationError,
)
api(
    "build_controller-params-list",
    lambda c: build_controller("pd", c.robot, [1, 2]),
    "controller",
    error=ConfigurationError,
)
api(
    "build_controller-sensor-list",
    lambda c: build_controller("pd", c.robot, {"sensor": [1]}),
    "controller.sensor",
    error=ConfigurationError,
)

# ------------------------------------------------------------------------ API: simulate
_sim_cases: list[tuple[str, dict[str, Any], str, type[PackbotError]]] = [
    ("q0-short", {"q0": np.zeros(7)}, "q0", ConfigurationError),
    ("q0-2d", {"q0": np.zeros((2, NQ))}, "q0", ConfigurationError),
    ("q0-str-items", {"q0": ["a"] * NQ}, "q0", ConfigurationError),
    ("q0-complex", {"q0": np.zeros(NQ, dtype=complex)}, "q0", ConfigurationError),
    ("q0-nan", {"q0": [NAN] * NQ}, "q0", ConfigurationError),
    ("q0-none", {"q0": None}, "q0", ConfigurationError),
    ("q0-pose-name", {"q0": "drive"}, "q0", ConfigurationError),
    ("q0-dict", {"q0": {"shoulder": 0.1}}, "q0", ConfigurationError),
    ("q0-bools", {"q0": [False] * NQ}, "q0", ConfigurationError),
    ("q0-scalar", {"q0": 0.0}, "q0", ConfigurationError),
    ("q0-outside-limits", {"q0": [0.0, 3.0, 0, 0, 0, 0, 0, 0]}, "shoulder", ConfigurationError),
    ("q0-object-array", {"q0": np.array([None] * NQ)}, "q0", ConfigurationError),
    ("v0-nan", {"v0": [NAN] * NQ}, "v0", ConfigurationError),
    ("v0-long", {"v0": np.zeros(9)}, "v0", ConfigurationError),
    ("v0-str", {"v0": "0"}, "v0", ConfigurationError),
    ("duration-zero", {"duration": 0.0}, "duration", ConfigurationError),
    ("duration-negative", {"duration": -1.0}, "duration", ConfigurationError),
    ("duration-nan", {"duration": NAN}, "duration", ConfigurationError),
    ("duration-inf", {"duration": INF}, "duration", ConfigurationError),
    ("duration-bool", {"duration": True}, "duration", ConfigurationError),
    ("duration-str", {"duration": "1"}, "duration", ConfigurationError),
    ("duration-none", {"duration": None}, "duration", ConfigurationError),
    ("duration-1e9-samples", {"duration": 1e9}, "sample_dt", ConfigurationError),
    (
        "failures-single",
        {"failures": Failure(joint="shoulder", kind="loose")},
        "failures",
        ConfigurationError,
    ),
    ("failures-str", {"failures": "loose"}, "failures", ConfigurationError),
    ("failures-none-item", {"failures": [None]}, "failures", ConfigurationError),
    (
        "failures-dict-item",
        {"failures": [{"joint": "shoulder", "kind": "loose"}]},
        "failures",
        ConfigurationError,
    ),
    (
        "failures-unknown-joint",
        {"failures": [Failure(joint="wrist", kind="loose")]},
        "wrist",
        UnknownNameError,
    ),
    (
        "failures-one-joint-twice-at-once",
        {
            "failures": [
                Failure(joint="elbow1", kind="loose"),
                Failure(joint="elbow1", kind="frozen"),
            ]
        },
        "failures[1].t",
        ConfigurationError,
    ),
    (
        "failures-loose-then-weak",
        {
            "failures": [
                Failure(joint="elbow1", kind="loose", t=0.1),
                Failure(joint="elbow1", kind="weak", t=0.2),
            ]
        },
        "failures[1].kind",
        ConfigurationError,
    ),
    ("failures-none", {"failures": None}, "failures", ConfigurationError),
    ("locked-unknown", {"config": SimConfig(locked_joints=("wrist",))}, "wrist", UnknownNameError),
    (
        "locked-all-joints",
        {"config": SimConfig(locked_joints=JOINTS)},
        "locked_joints",
        ConfigurationError,
    ),
    (
        "locked-and-frozen-cover-all",
        {
            "config": SimConfig(locked_joints=JOINTS[1:]),
            "failures": [Failure(joint="turret", kind="frozen")],
        },
        "locked_joints",
        ConfigurationError,
    ),
    (
        "failure-on-locked-joint",
        {
            "config": SimConfig(locked_joints=("camera_tilt",)),
            "failures": [Failure(joint="camera_tilt", kind="loose")],
        },
        "camera_tilt",
        ConfigurationError,
    ),
    (
        "v0-on-locked-joint",
        {"config": SimConfig(locked_joints=("camera_tilt",)), "v0": [0, 0, 0, 0, 1.0, 0, 0, 0]},
        "v0",
        ConfigurationError,
    ),
    (
        "relevant_threshold-above-1-over-sqrt-n",
        {"config": SimConfig(relevant_threshold=0.5)},
        "relevant_threshold",
        ConfigurationError,
    ),
    ("controller-int", {"controller": 5}, "controller", ConfigurationError),
    ("controller-class", {"controller": JointPD}, "controller", ConfigurationError),
    ("controller-str", {"controller": "pd"}, "controller", ConfigurationError),
    ("environment-list", {"environment": []}, "environment", ConfigurationError),
    (
        "environment-obstacle",
        {"environment": Obstacle(name="b", kind="box", size=(1, 1, 1))},
        "environment",
        ConfigurationError,
    ),
    ("config-dict", {"config": {"restitution": 0.5}}, "config", ConfigurationError),
    ("payload-int", {"payload": 5}, "payload", ConfigurationError),
    (
        "payload-unknown-frame",
        {"payload": Payload(mass=1.0, frame="hand")},
        "hand",
        UnknownNameError,
    ),
    ("inform_controller-int", {"inform_controller": 1}, "inform_controller", ConfigurationError),
    ("progress-int", {"progress": 5}, "progress", ConfigurationError),
    ("robot-none", {"robot": None}, "robot", ConfigurationError),
    ("robot-path", {"robot": "urdf/packbot_eod.urdf"}, "robot", ConfigurationError),
    (
        "config-mutated-sample_dt",
        {"_config": lambda c: mutated_config(sample_dt=1e-9)},
        "sample_dt",
        ConfigurationError,
    ),
    (
        "config-mutated-rtol-bool",
        {"_config": lambda c: mutated_config(rtol=True)},
        "rtol",
        ConfigurationError,
    ),
    (
        "controller-dt-mutated",
        {"_controller": lambda c: mutated_dt(GravityCompensation(), 1e-9)},
        "controller.dt",
        ConfigurationError,
    ),
    (
        "controller-ticks-beyond-limit",
        {"controller": GravityCompensation(dt=1e-3), "duration": 2000.0},
        "controller.dt",
        ConfigurationError,
    ),
    (
        "max_step-beyond-step-limit",
        {"config": SimConfig(max_step=1e-6), "duration": 10.0},
        "max_step",
        ConfigurationError,
    ),
    (
        "q0-in-collision-with-box",
        {
            "environment": Environment().with_obstacles(
                Obstacle(name="crate", kind="box", size=(4.0, 4.0, 4.0), xyz=(0.0, 0.0, 0.5))
            )
        },
        "q0",
        InitialCollisionError,
    ),
    (
        "controller-unknown-target-pose",
        {"controller": JointPD(target="bogus_pose")},
        "bogus_pose",
        UnknownNameError,
    ),
]
_GUARD = {
    "config-mutated-sample_dt",
    "controller-dt-mutated",
    "relevant_threshold-above-1-over-sqrt-n",
    "duration-1e9-samples",
    "controller-ticks-beyond-limit",
    "max_step-beyond-step-limit",
}
for _id, _kw, _word, _err in _sim_cases:
    api(f"simulate-{_id}", sim(**_kw), _word, error=_err, guard=_id in _GUARD)


# ------------------------------------------------------------------------ API: identification
def _log(n: int = 200, **change: Any) -> dict[str, Any]:
    """A short log at rest at q = 0 (t, q, tau), with entries replaced by ``change``."""
    t = np.arange(n) * 0.01
    q = np.zeros((n, NQ))
    out: dict[str, Any] = {"t": t, "q": q, "tau": np.zeros((n, NQ))}
    out.update(change)
    return out


def _ident(**change: Any) -> Callable[[Ctx], Any]:
    def action(c: Ctx) -> Any:
        args = _log(**change)
        return packbot.identify(c.robot, args.pop("t"), args.pop("q"), **args)

    return action


_CSV_HEAD = ",".join(
    ["time"]
    + [f"q_{j}" for j in packbot.params.ARM_JOINTS]
    + [f"tau_{j}" for j in packbot.params.ARM_JOINTS]
)
api("identify-q-rows", _ident(q=np.zeros((199, NQ))), "q", "(199, 8)", error=ConfigurationError)
api("identify-tau-columns", _ident(tau=np.zeros((200, 7))), "tau", error=ConfigurationError)
api("identify-tau-nan", _ident(tau=np.full((200, NQ), np.nan)), "tau", error=ConfigurationError)
api("identify-few-samples", _ident(n=20), "t", "at least", error=ConfigurationError)
api(
    "identify-t-uneven",
    _ident(t=np.arange(200) ** 1.1 * 0.01),
    "t",
    "uniform",
    error=ConfigurationError,
)
api("identify-no-torques", _ident(tau=None), "tau", "currents", error=ConfigurationError)
api(
    "identify-currents-no-kt",
    _ident(tau=None, currents=np.zeros((200, NQ))),
    "torque_constant",
    error=ConfigurationError,
)
api("identify-window-short", _ident(window=0.02), "window", error=ConfigurationError)
api(
    "load_log-unknown-column",
    lambda c: packbot.identification.load_log(
        c.robot, c.write("log.csv", _CSV_HEAD.replace("tau_gripper_jaw", "tau_gripper_jw") + "\n")
    ),
    "tau_gripper_jw",
    "tau_gripper_jaw",
    error=ConfigurationError,
)
api(
    "load_log-bad-cell",
    lambda c: packbot.identification.load_log(
        c.robot, c.write("log.csv", _CSV_HEAD + "\n" + ",".join(["x"] * (1 + 2 * NQ)) + "\n")
    ),
    "line 2",
    "time",
    error=ConfigurationError,
)
api(
    "exciting_trajectory-harmonics",
    lambda c: packbot.control.exciting_trajectory(c.robot, 10.0, harmonics=1),
    "harmonics",
    error=ConfigurationError,
)
api(
    "exciting_trajectory-duration",
    lambda c: packbot.control.exciting_trajectory(c.robot, -1.0),
    "duration",
    error=ConfigurationError,
)

# ------------------------------------------------------------------------ API: model, results
api("load_robot-int", lambda c: packbot.load_robot(42), "urdf", error=ConfigurationError)
api(
    "load_robot-bytes",
    lambda c: packbot.load_robot(b"urdf/packbot_eod.urdf"),
    "urdf",
    error=ConfigurationError,
)
api(
    "load_robot-missing-file",
    lambda c: packbot.load_robot(c.tmp / "none.urdf"),
    "none.urdf",
    error=ResourceNotFound,
)
api(
    "load_robot-directory", lambda c: packbot.load_robot(c.tmp), "directory", error=ResourceNotFound
)
api("load_robot-empty-str", lambda c: packbot.load_robot(""), "", error=ResourceNotFound)
api("Robot.pose-unknown", lambda c: c.robot.pose("crouch"), "crouch", error=UnknownNameError)
api("Robot.pose-int", lambda c: c.robot.pose(5), "pose", error=UnknownNameError)
api("Robot.pose-list", lambda c: c.robot.pose(["drive"]), "pose", error=PackbotError)
api(
    "Robot.q_from-unknown-joint",
    lambda c: c.robot.q_from({"wrist": 0.1}),
    "wrist",
    error=UnknownNameError,
)
api(
    "Robot.q_from-str-value",
    lambda c: c.robot.q_from({"shoulder": "high"}),
    "shoulder",
    error=ConfigurationError,
)
api(
    "Robot.q_from-nan",
    lambda c: c.robot.q_from({"shoulder": NAN}),
    "shoulder",
    error=ConfigurationError,
)
api(
    "Robot.q_from-bool",
    lambda c: c.robot.q_from({"shoulder": True}),
    "shoulder",
    error=ConfigurationError,
)
api(
    "Robot.q_from-not-a-table",
    lambda c: c.robot.q_from([0.1] * NQ),
    "values",
    error=ConfigurationError,
)
api(
    "Robot.q_from-unknown-base",
    lambda c: c.robot.q_from({}, base="crouch"),
    "crouch",
    error=UnknownNameError,
)
api(
    "Robot.check_within_limits-shape",
    lambda c: c.robot.check_within_limits(np.zeros(3), "q"),
    "q",
    error=ConfigurationError,
)
api("SimResult.joint-unknown", lambda c: c.result.joint("wrist"), "wrist", error=UnknownNameError)
api(
    "SimResult.events_of-unknown-kind",
    lambda c: c.result.events_of("impakt"),
    "impakt",
    error=UnknownNameError,
)
for _key, _t in (
    ("none", None),
    ("text", "0.1"),
    ("bool", True),
    ("list", [0.0]),
    ("nan", float("nan")),
    ("not-a-sample", 0.0123),
):
    api(
        f"SimResult.contacts_at-{_key}",
        lambda c, t=_t: c.result.contacts_at(t),
        "t",
        error=ConfigurationError,
    )
    api(
        f"SimResult.sample_index-{_key}",
        lambda c, t=_t: c.result.sample_index(t),
        "t",
        error=ConfigurationError,
    )

# ------------------------------------------------------------------------ scenario files
BASE_SCENARIO = 'duration = 0.05\n\n[initial]\npose = "drive"\n'


def scn(text: str, *, base: bool = True) -> Callable[[Ctx], Any]:
    """Write a scenario (the base plus ``text``), load it and run it (it checks it first)."""

    def action(c: Ctx) -> Any:
        body = BASE_SCENARIO + "\n" + text if base else text
        path = c.write("bad.toml", body)
        return run_scenario(load_scenario(path), c.robot)  # checks, then runs (0.05 s)

    return action


def scenario(id: str, text: str, *words: str, base: bool = True, **kw: Any) -> None:
    add("scenario", id, scn(text, base=base), *words, **kw)


def scenario_cli(id: str, text: str | bytes, *words: str, base: bool = True) -> None:
    """The same through ``packbot run FILE --out DIR``: exit 2, one line."""

    def argv(c: Ctx) -> list[str]:
        if isinstance(text, bytes):
            path = c.write("bad.toml", text)
        else:
            path = c.write("bad.toml", BASE_SCENARIO + "\n" + text if base else text)
        return ["run", str(path), "--out", c.out()]

    add("scenario", f"run-{id}", argv, *words, cli=True)


# the file itself
scenario("empty-file", "", "duration", base=False)
scenario("syntax-error", "duration = = 1\n", "TOML", base=False)
scenario("unclosed-table", "duration = 1\n[initial\npose = 'drive'\n", "TOML", base=False)
scenario("duplicate-key", "duration = 1\nduration = 2\n", "TOML", base=False)
scenario("unknown-top-level-key", "durations = 1.0\n", "durations")
scenario("unknown-section", "[simulation]\nrtol = 1e-6\n", "simulation")
add(
    "scenario",
    "binary-file",
    lambda c: load_scenario(c.write("bad.toml", bytes(range(256)))),
    "TOML",
)
add("scenario", "directory", lambda c: load_scenario(c.tmp), "scenario", error=ConfigurationError)
add(
    "scenario",
    "missing-file",
    lambda c: load_scenario(c.tmp / "none.toml"),
    "none.toml",
    error=ConfigurationError,
)
add(
    "scenario",
    "unknown-name",
    lambda c: load_scenario("colapse"),
    "colapse",
    error=UnknownNameError,
)
# top level
scenario("no-duration", '[initial]\npose = "drive"\n', "duration", base=False)
scenario("duration-str", 'duration = "5"\n', "duration", base=False)
scenario("duration-zero", "duration = 0\n", "duration", base=False)
scenario("duration-negative", "duration = -1.0\n", "duration", base=False)
scenario("duration-nan", "duration = nan\n", "duration", base=False)
scenario("duration-inf", "duration = inf\n", "duration", base=False)
scenario("duration-bool", "duration = true\n", "duration", base=False)
scenario("duration-absurd", "duration = 1e12\n", "duration", base=False)
scenario("duration-table", "[duration]\nt = 1\n", "duration", base=False)
scenario("description-number", "description = 5\nduration = 1.0\n", "description", base=False)
# [initial]
scenario("initial-not-table", 'duration = 1.0\ninitial = "drive"\n', "initial", base=False)
scenario(
    "initial-unknown-key",
    "duration = 1.0\n[initial]\nposture = 'drive'\n",
    "initial.posture",
    base=False,
)
scenario(
    "initial-unknown-pose", "duration = 1.0\n[initial]\npose = 'crouch'\n", "crouch", base=False
)
scenario("initial-pose-number", "duration = 1.0\n[initial]\npose = 3\n", "initial.pose", base=False)
scenario(
    "initial-q-unknown-joint",
    "duration = 1.0\n[initial]\nq = { wrist = 0.1 }\n",
    "initial.q.wrist",
    base=False,
)
scenario(
    "initial-q-str-value",
    "duration = 1.0\n[initial]\nq = { shoulder = 'up' }\n",
    "initial.q.shoulder",
    base=False,
)
scenario(
    "initial-q-short-list", "duration = 1.0\n[initial]\nq = [0.0, 0.1]\n", "initial.q", base=False
)
scenario(
    "initial-q-beyond-limits",
    "duration = 1.0\n[initial]\nq = { shoulder = 3.0 }\n",
    "shoulder",
    base=False,
)
scenario(
    "initial-q-list-with-pose",
    "duration = 1.0\n[initial]\npose = 'drive'\nq = [0, 0, 0, 0, 0, 0, 0, 0]\n",
    "initial.q",
    base=False,
)
scenario(
    "initial-v-nan", "duration = 1.0\n[initial]\nv = { shoulder = nan }\n", "initial.v", base=False
)
scenario("initial-v-str", "duration = 1.0\n[initial]\nv = 'fast'\n", "initial.v", base=False)
scenario(
    "initial-v-bool-item",
    "duration = 1.0\n[initial]\nv = [true, 0, 0, 0, 0, 0, 0, 0]\n",
    "initial.v",
    base=False,
)
scenario(
    "initial-q-nested-list",
    "duration = 1.0\n[initial]\nq = [[0.0], 0, 0, 0, 0, 0, 0, 0]\n",
    "initial.q",
    base=False,
)
scenario("initial-v-beyond-limit", "[initial.v]\nshoulder = 1e6\n", "initial.v")
# [config]
scenario("config-not-table", 'duration = 1.0\nconfig = "fast"\n', "config", base=False)
scenario("config-unknown-key", "[config]\nrestitutio = 0.5\n", "config.restitutio")
scenario("config-restitution-str", "[config]\nrestitution = '0.5'\n", "config.restitution")
scenario("config-restitution-range", "[config]\nrestitution = 1.5\n", "config.restitution")
scenario("config-contact_mode-unknown", "[config]\ncontact_mode = 'soft'\n", "config.contact_mode")
scenario("config-gravity-scalar", "[config]\ngravity = -9.81\n", "config.gravity")
scenario("config-gravity-two", "[config]\ngravity = [0.0, -9.81]\n", "config.gravity")
scenario("config-locked-str", "[config]\nlocked_joints = 'camera_tilt'\n", "config.locked_joints")
scenario("config-locked-unknown", "[config]\nlocked_joints = ['wrist']\n", "wrist")
scenario(
    "config-locked-twice",
    "[config]\nlocked_joints = ['camera_tilt', 'camera_tilt']\n",
    "config.locked_joints",
)
scenario("config-sample_dt-tiny", "[config]\nsample_dt = 1e-9\n", "config.sample_dt")
scenario("config-sample_dt-zero", "[config]\nsample_dt = 0\n", "config.sample_dt")
scenario("config-max_events-float", "[config]\nmax_events = 100.5\n", "config.max_events")
scenario("config-joint_limits-str", "[config]\njoint_limits = 'yes'\n", "config.joint_limits")
scenario("config-rtol-bool", "[config]\nrtol = true\n", "config.rtol")
scenario(
    "config-relevant_threshold-2",
    "[config]\nrelevant_threshold = 2.0\n",
    "config.relevant_threshold",
)
scenario(
    "config-relevant_threshold-0.5", "[config]\nrelevant_threshold = 0.5\n", "relevant_threshold"
)
scenario(
    "config-handoff-with-none",
    "[config]\ncontact_mode = 'none'\nhandoff = true\n",
    "config.handoff",
)
scenario(
    "config-sample_dt-vs-duration",
    "duration = 1e4\n[config]\nsample_dt = 1e-5\n",
    "sample_dt",
    base=False,
)
# [[failures]]
scenario("failures-table", "[failures]\njoint = 'shoulder'\nkind = 'loose'\n", "failures")
scenario(
    "failure-kind-unknown",
    "[[failures]]\njoint = 'shoulder'\nkind = 'broken'\n",
    "failures[0].kind",
)
scenario("failure-no-kind", "[[failures]]\njoint = 'shoulder'\n", "failures[0].kind")
scenario("failure-no-joint", "[[failures]]\nkind = 'loose'\n", "failures[0].joint")
scenario(
    "failure-joint-unknown", "[[failures]]\njoint = 'wrist'\nkind = 'loose'\n", "failures[0].joint"
)
scenario(
    "failure-t-negative",
    "[[failures]]\njoint = 'shoulder'\nkind = 'loose'\nt = -1.0\n",
    "failures[0].t",
)
scenario(
    "failure-t-str",
    "[[failures]]\njoint = 'shoulder'\nkind = 'loose'\nt = '0.5'\n",
    "failures[0].t",
)
scenario(
    "failure-unknown-key",
    "[[failures]]\njoint = 'shoulder'\nkind = 'loose'\nwhen = 0.5\n",
    "failures[0].when",
)
scenario(
    "failure-one-joint-twice-at-once",
    "[[failures]]\njoint = 'elbow1'\nkind = 'loose'\n"
    "[[failures]]\njoint = 'elbow1'\nkind = 'frozen'\n",
    "failures[1].t",
)
scenario(
    "failure-after-frozen",
    "[[failures]]\njoint = 'elbow1'\nkind = 'frozen'\nt = 0.1\n"
    "[[failures]]\njoint = 'elbow1'\nkind = 'weak'\nt = 0.2\n",
    "failures[1].kind",
)
scenario(
    "failure-weak-recovering",
    "[[failures]]\njoint = 'elbow1'\nkind = 'weak'\nscale = 0.3\nt = 0.1\n"
    "[[failures]]\njoint = 'elbow1'\nkind = 'weak'\nscale = 0.6\nt = 0.2\n",
    "failures[1].scale",
)
scenario(
    "failure-scale-range",
    "[[failures]]\njoint = 'shoulder'\nkind = 'weak'\nscale = 2.0\n",
    "failures[0].scale",
)
scenario(
    "failure-on-locked-joint",
    "[config]\nlocked_joints = ['camera_tilt']\n"
    "[[failures]]\njoint = 'camera_tilt'\nkind = 'loose'\n",
    "camera_tilt",
)
# [payload]
scenario("payload-no-mass", "[payload]\nframe = 'gripper_tool'\n", "payload.mass")
scenario("payload-mass-negative", "[payload]\nmass = -2.0\n", "payload.mass")
scenario("payload-frame-unknown", "[payload]\nmass = 1.0\nframe = 'hand'\n", "payload.frame")
scenario("payload-com-two", "[payload]\nmass = 1.0\ncom = [0.0, 0.1]\n", "payload.com")
scenario(
    "payload-t_drop-before-pick",
    "[payload]\nmass = 1.0\nt_pick = 1.0\nt_drop = 0.5\n",
    "payload.t_drop",
)
scenario("payload-unknown-key", "[payload]\nmass = 1.0\nvolume = 2.0\n", "payload.volume")
# [controller]
scenario("controller-kind-unknown", "[controller]\nkind = 'pid'\n", "controller.kind")
scenario("controller-kind-number", "[controller]\nkind = 1\n", "controller.kind")
scenario("controller-unknown-param", "[controller]\nkind = 'pd'\ngain = 5.0\n", "controller.gain")
scenario("controller-param-for-zero", "[controller]\nomega = 5.0\n", "controller.omega")
scenario("controller-dt-tiny", "[controller]\nkind = 'pd'\ndt = 1e-9\n", "controller.dt")
scenario("controller-omega-nyquist", "[controller]\nkind = 'pd'\nomega = 1e5\n", "controller.omega")
scenario(
    "controller-target-pose-unknown", "[controller]\nkind = 'pd'\ntarget = 'crouch'\n", "crouch"
)
scenario(
    "controller-target-joint-unknown",
    "[controller]\nkind = 'pd'\ntarget = { wrist = 1 }\n",
    "wrist",
)
scenario("controller-kp-negative", "[controller]\nkind = 'pd'\nkp = -5.0\n", "controller.kp")
scenario(
    "controller-inform-str", "[controller]\nkind = 'pd'\ninform = 'yes'\n", "controller.inform"
)
scenario(
    "controller-sensor-unknown-key",
    "[controller]\nkind = 'pd'\nsensor = { noise = 0.1 }\n",
    "controller.sensor.noise",
)
scenario(
    "controller-waypoints-one",
    "[controller]\nkind = 'computed_torque'\nwaypoints = ['drive']\n",
    "controller.waypoints",
)
scenario(
    "controller-times-decreasing",
    "[controller]\nkind = 'computed_torque'\nwaypoints = ['drive', 'stand']\ntimes = [1.0, 0.0]\n",
    "controller.times",
)
scenario(
    "controller-cartesian-no-target", "[controller]\nkind = 'cartesian'\n", "controller.target"
)
scenario(
    "controller-reconfig-frame-unknown",
    "[controller]\nkind = 'reconfig'\ntarget = [0.7, 0.4, 0.2]\nframe = 'hand'\n",
    "hand",
)
scenario(
    "controller-gravity-cm",
    "[controller]\nkind = 'gravity'\ngravity = [0, 0, -981]\n",
    "controller.gravity",
)
# [environment]
scenario("environment-unknown-key", "[environment]\nwalls = true\n", "environment.walls")
scenario("environment-floor-str", "[environment]\nfloor = 'yes'\n", "environment.floor")
scenario(
    "obstacles-table-not-array",
    "[environment.obstacles]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n",
    "environment.obstacles",
)
scenario(
    "obstacle-kind-unknown",
    "[[environment.obstacles]]\nname = 'ball'\nkind = 'sphere'\n",
    "environment.obstacles[0].kind",
)
scenario(
    "obstacle-size-zero",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [0, 1, 1]\n"
    "xyz = [3, 0, 0.5]\n",
    "environment.obstacles[0].size",
)
scenario(
    "obstacle-size-str",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = 'big'\n",
    "environment.obstacles[0].size",
)
scenario(
    "obstacle-no-name",
    "[[environment.obstacles]]\nkind = 'box'\nsize = [1, 1, 1]\n",
    "environment.obstacles[0].name",
)
scenario(
    "obstacle-duplicate-name",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n"
    "xyz = [3, 0, 0.5]\n"
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n"
    "xyz = [-3, 0, 0.5]\n",
    "environment.obstacles[1].name",
)
scenario(
    "obstacle-named-floor",
    "[[environment.obstacles]]\nname = 'floor'\nkind = 'box'\nsize = [1, 1, 1]\n"
    "xyz = [3, 0, 0.5]\n",
    "environment.obstacles[0].name",
)
scenario(
    "obstacle-convex-flat",
    "[[environment.obstacles]]\nname = 'plate'\nkind = 'convex'\n"
    "points = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]\n",
    "environment.obstacles[0].points",
)
scenario(
    "obstacle-unknown-key",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\ncolor = 1\n",
    "environment.obstacles[0].color",
)
scenario(
    "obstacle-robot-inside",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [4, 4, 4]\n"
    "xyz = [0, 0, 0.5]\n",
    "q0",
)
# [outputs]
scenario(
    "outputs-plot-kind-unknown", "[outputs]\nplots = ['joints', 'speed']\n", "outputs.plots[1]"
)
scenario("outputs-plots-str", "[outputs]\nplots = 'joints'\n", "outputs.plots")
scenario("outputs-format-unknown", "[outputs]\nformats = ['jpg']\n", "outputs.formats[0]")
scenario("outputs-formats-empty", "[outputs]\nformats = []\n", "outputs.formats")
scenario("outputs-joint-unknown", "[outputs]\njoints = ['wrist']\n", "outputs.joints[0]")
scenario("outputs-joints-twice", "[outputs]\njoints = ['shoulder', 'shoulder']\n", "outputs.joints")
scenario("outputs-html-str", "[outputs]\nhtml = 'yes'\n", "outputs.html")
scenario("outputs-unknown-key", "[outputs]\nvideo = true\n", "outputs.video")
scenario(
    "outputs-occlusion-plot-without-check", "[outputs]\nplots = ['occlusion']\n", "outputs.plots"
)
scenario("occlusion-no-targets", "[outputs.occlusion]\ntargets = []\n", "outputs.occlusion.targets")
scenario(
    "occlusion-target-two",
    "[outputs.occlusion]\ntargets = [[1.0, 0.0]]\n",
    "outputs.occlusion.targets",
)
scenario(
    "occlusion-radius-negative",
    "[outputs.occlusion]\ntargets = [[1.0, 0.0, 0.0]]\nradius = -0.1\n",
    "outputs.occlusion.radius",
)
scenario(
    "occlusion-frame-unknown",
    "[outputs.occlusion]\ntargets = [[1.0, 0.0, 0.0]]\nframe = 'eye'\n",
    "outputs.occlusion.frame",
)
scenario(
    "occlusion-ignore-unknown",
    "[outputs.occlusion]\ntargets = [[1.0, 0.0, 0.0]]\nignore = ['hat']\n",
    "outputs.occlusion.ignore[0]",
)
# the same problems through `packbot run FILE`
scenario_cli("empty-file", "", "duration", base=False)
scenario_cli("syntax-error", "duration = = 1\n", "TOML", base=False)
scenario_cli("binary-file", bytes(range(256)), "TOML")
scenario_cli("unknown-section", "[simulation]\nrtol = 1e-6\n", "simulation")
scenario_cli("config-restitution-range", "[config]\nrestitution = 1.5\n", "config.restitution")
scenario_cli("config-sample_dt-tiny", "[config]\nsample_dt = 1e-9\n", "config.sample_dt")
scenario_cli("config-locked-str", "[config]\nlocked_joints = 'camera_tilt'\n", "locked_joints")
scenario_cli(
    "initial-unknown-pose", "duration = 1.0\n[initial]\npose = 'crouch'\n", "crouch", base=False
)
scenario_cli(
    "failure-kind-unknown",
    "[[failures]]\njoint = 'shoulder'\nkind = 'broken'\n",
    "failures[0].kind",
)
scenario_cli(
    "failure-joint-unknown", "[[failures]]\njoint = 'wrist'\nkind = 'loose'\n", "failures[0].joint"
)
scenario_cli("controller-kind-unknown", "[controller]\nkind = 'pid'\n", "controller.kind")
scenario_cli("controller-dt-tiny", "[controller]\nkind = 'pd'\ndt = 1e-9\n", "controller.dt")
scenario_cli(
    "obstacle-duplicate-name",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n"
    "xyz = [3, 0, 0.5]\n"
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n"
    "xyz = [-3, 0, 0.5]\n",
    "environment.obstacles[1].name",
)
scenario_cli(
    "obstacle-robot-inside",
    "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsize = [4, 4, 4]\n"
    "xyz = [0, 0, 0.5]\n",
    "collision",
)
scenario_cli("outputs-formats-empty", "[outputs]\nformats = []\n", "outputs.formats")
scenario_cli("outputs-plot-kind-unknown", "[outputs]\nplots = ['speed']\n", "outputs.plots")
scenario_cli("duration-absurd", "duration = 1e12\n", "duration", base=False)
scenario_cli("relevant_threshold-0.5", "[config]\nrelevant_threshold = 0.5\n", "relevant_threshold")
scenario_cli("initial-v-beyond-limit", "[initial.v]\nshoulder = 1e6\n", "initial.v")


# ------------------------------------------------------------------------ CLI
def cli(id: str, argv: Callable[[Ctx], list[str]] | list[str], *words: str, code: int = 2) -> None:
    action = argv if callable(argv) else (lambda c, a=list(argv): a)
    add("cli", id, action, *words, cli=True, code=code)


def _file(c: Ctx) -> str:
    return str(c.write("afile", "not a folder\n"))


def _foreign_out(c: Ctx) -> str:
    c.write("out/notes.txt", "mine\n")
    return c.out()


# top level
cli("no-command", [], "no command")
cli("run-dev-null", lambda c: ["run", "/dev/null", "--out", c.out()], "/dev/null")
cli("info-urdf-dev-zero", ["info", "--urdf", "/dev/zero"], "/dev/zero")
cli("batch-dev-null", lambda c: ["batch", "/dev/null", "--out", c.out()], "/dev/null")
cli("only-verbose", ["-vv"], "no command")
cli("unknown-command", ["fly"], "fly")
cli("unknown-global-option", ["--colour", "run", "collapse"], "--colour")
cli("verbose-with-value", ["-v=3", "info"], "-v")
# info
cli("info-urdf-missing", lambda c: ["info", "--urdf", str(c.tmp / "none.urdf")], "none.urdf")
cli("info-urdf-directory", lambda c: ["info", "--urdf", str(c.tmp)], "directory")
cli("info-urdf-empty", lambda c: ["info", "--urdf", str(c.write("e.urdf", ""))], "empty")
cli(
    "info-urdf-binary",
    lambda c: ["info", "--urdf", str(c.write("b.urdf", bytes(range(256))))],
    "b.urdf",
)
cli(
    "info-urdf-not-xml",
    lambda c: ["info", "--urdf", str(c.write("t.urdf", "robot: yes\n"))],
    "t.urdf",
)
cli("info-urdf-no-value", ["info", "--urdf"], "--urdf")
cli("info-extra-argument", ["info", "extra"], "extra")
# list, show
cli("list-extra-argument", ["list", "all"], "all")
cli("show-unknown-pose", ["show", "crouch"], "crouch")
cli("show-port-zero", ["show", "--port", "0"], "--port")
cli("show-port-99999", ["show", "--port", "99999"], "99999")
cli("show-port-str", ["show", "--port", "http"], "http")
cli("show-port-negative", ["show", "--port", "-1"], "--port")
# run
cli("run-no-scenario", ["run"], "SCENARIO")
cli("run-unknown-scenario", lambda c: ["run", "colapse", "--out", c.out()], "colapse")
cli("run-missing-path", lambda c: ["run", str(c.tmp / "none.toml"), "--out", c.out()], "none.toml")
cli("run-directory", lambda c: ["run", str(c.tmp), "--out", c.out()], "scenario")
cli(
    "run-duration-zero",
    lambda c: ["run", "collapse", "--duration", "0", "--out", c.out()],
    "--duration",
)
cli(
    "run-duration-negative",
    lambda c: ["run", "collapse", "--duration", "-1", "--out", c.out()],
    "--duration",
)
cli(
    "run-duration-nan",
    lambda c: ["run", "collapse", "--duration", "nan", "--out", c.out()],
    "--duration",
)
cli(
    "run-duration-inf",
    lambda c: ["run", "collapse", "--duration", "inf", "--out", c.out()],
    "--duration",
)
cli(
    "run-duration-str",
    lambda c: ["run", "collapse", "--duration", "long", "--out", c.out()],
    "--duration",
)
cli(
    "run-duration-absurd",
    lambda c: ["run", "collapse", "--duration", "1e12", "--out", c.out()],
    "sample_dt",
)
cli("run-duration-no-value", ["run", "collapse", "--duration"], "--duration")
cli(
    "run-out-is-file",
    lambda c: ["run", "collapse", "--duration", "0.01", "--out", _file(c)],
    "--out",
)
cli(
    "run-out-under-file",
    lambda c: ["run", "collapse", "--duration", "0.01", "--out", _file(c) + "/sub"],
    "--out",
)
cli("run-out-proc", ["run", "collapse", "--duration", "0.01", "--out", "/proc/packbot-x"], "--out")
cli(
    "run-out-foreign-files",
    lambda c: ["run", "collapse", "--duration", "0.01", "--out", _foreign_out(c)],
    "--overwrite",
)
cli("run-out-empty-str", ["run", "collapse", "--duration", "0.01", "--out", ""], "--out")
cli("run-unknown-option", lambda c: ["run", "collapse", "--plots", "--out", c.out()], "--plots")
cli(
    "run-two-scenarios",
    lambda c: ["run", "collapse", "loose_shoulder", "--out", c.out()],
    "loose_shoulder",
)
cli("run-overwrite-with-value", lambda c: ["run", "collapse", "--overwrite=yes"], "--overwrite")
# a run or a study on sampled arms (--uncertain N)
cli(
    "run-uncertain-one",
    lambda c: ["run", "collapse", "--uncertain", "1", "--out", c.out()],
    "samples",
)
cli("run-uncertain-not-int", ["run", "collapse", "--uncertain", "x"], "--uncertain")
cli("run-seed-alone", lambda c: ["run", "collapse", "--seed", "1", "--out", c.out()], "--seed")
cli(
    "run-uncertain-plot",
    lambda c: ["run", "collapse", "--uncertain", "2", "--plot", "--out", c.out()],
    "--plot",
)
cli(
    "run-uncertain-workers-negative",
    lambda c: ["run", "collapse", "--uncertain", "2", "--workers", "-1", "--out", c.out()],
    "workers",
)
cli(
    "run-uncertain-seed-negative",
    lambda c: ["run", "collapse", "--uncertain", "2", "--seed", "-4", "--out", c.out()],
    "seed",
)
cli(
    "study-uncertain-overwrite",
    lambda c: ["study", "reconfig_elbow1", "--uncertain", "2", "--overwrite", "--out", c.out()],
    "--overwrite",
)
cli(
    "study-uncertain-timeout-zero",
    lambda c: ["study", "reconfig_elbow1", "--uncertain", "2", "--timeout", "0", "--out", c.out()],
    "timeout",
)
# collapse
cli("collapse-mode-unknown", lambda c: ["collapse", "--mode", "soft", "--out", c.out()], "soft")
cli(
    "collapse-duration-negative",
    lambda c: ["collapse", "--duration", "-5", "--out", c.out()],
    "--duration",
)
cli(
    "collapse-out-is-file", lambda c: ["collapse", "--duration", "0.01", "--out", _file(c)], "--out"
)
cli(
    "collapse-out-foreign",
    lambda c: ["collapse", "--duration", "0.01", "--out", _foreign_out(c)],
    "--overwrite",
)
# generate-model, generate-srdf
cli(
    "generate-model-root-missing",
    lambda c: ["generate-model", "--root", str(c.tmp / "none")],
    "--root",
)
cli("generate-model-root-file", lambda c: ["generate-model", "--root", _file(c)], "--root")
cli("generate-model-check-with-value", ["generate-model", "--check=1"], "--check")
cli("generate-srdf-samples-zero", ["generate-srdf", "--samples", "0"], "--samples")
cli("generate-srdf-samples-str", ["generate-srdf", "--samples", "many"], "many")
cli("generate-srdf-samples-float", ["generate-srdf", "--samples", "1.5"], "1.5")
cli("generate-srdf-clearance-negative", ["generate-srdf", "--clearance", "-0.1"], "--clearance")
cli("generate-srdf-clearance-nan", ["generate-srdf", "--clearance", "nan"], "--clearance")
cli("generate-srdf-urdf-without-out", ["generate-srdf", "--urdf", "panda"], "--out")
cli(
    "generate-srdf-out-and-root",
    lambda c: ["generate-srdf", "--out", str(c.tmp / "a.srdf"), "--root", str(c.tmp)],
    "--root",
)
cli("generate-srdf-out-a-folder", lambda c: ["generate-srdf", "--out", str(c.tmp)], "--out")
cli(
    "generate-srdf-urdf-missing",
    lambda c: ["generate-srdf", "--urdf", str(c.tmp / "none.urdf"), "--out", str(c.tmp / "a")],
    "none.urdf",
)
cli(
    "generate-srdf-root-without-urdf",
    lambda c: ["generate-srdf", "--samples", "1", "--root", str(c.tmp)],
    "urdf",
)
# batch
cli("batch-no-out", ["batch", "collapse-small"], "--out")
cli("batch-no-matrix", lambda c: ["batch", "--out", c.out()], "MATRIX")
cli("batch-unknown-matrix", lambda c: ["batch", "collapse-big", "--out", c.out()], "collapse-big")
cli(
    "batch-matrix-missing-path",
    lambda c: ["batch", str(c.tmp / "none.toml"), "--out", c.out()],
    "none.toml",
)
cli("batch-matrix-directory", lambda c: ["batch", str(c.tmp), "--out", c.out()], "matrix")
cli(
    "batch-workers-negative",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--workers", "-1"],
    "workers",
)
cli(
    "batch-workers-str",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--workers", "all"],
    "--workers",
)
cli(
    "batch-timeout-zero",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--timeout", "0"],
    "timeout",
)
cli(
    "batch-timeout-nan",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--timeout", "nan"],
    "timeout",
)
cli(
    "batch-timeout-negative",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--timeout", "-1"],
    "timeout",
)
cli(
    "batch-scheduler-bogus",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--scheduler", "bogus://x"],
    "bogus://x",
)
cli(
    "batch-scheduler-port-99999",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--scheduler", "tcp://h:99999"],
    "--scheduler",
)
cli(
    "batch-scheduler-no-port",
    lambda c: ["batch", "collapse-small", "--out", c.out(), "--scheduler", "tcp://host"],
    "--scheduler",
)
cli("batch-out-is-file", lambda c: ["batch", "collapse-small", "--out", _file(c)], "afile")
cli(
    "batch-out-under-file",
    lambda c: ["batch", "collapse-small", "--out", _file(c) + "/sub"],
    "afile",
)
cli("batch-out-proc", ["batch", "collapse-small", "--out", "/proc/packbot-x"], "/proc/packbot-x")
# regress
cli("regress-unknown-matrix", ["regress", "collapse-big"], "collapse-big")
cli(
    "regress-golden-missing",
    lambda c: ["regress", "collapse-small", "--golden", c.out("none")],
    "collapse-small",
)
cli("regress-golden-empty", lambda c: ["regress", "--golden", str(c.tmp)], "golden")
cli(
    "regress-golden-is-file", lambda c: ["regress", "collapse-small", "--golden", _file(c)], "afile"
)
cli("regress-workers-negative", ["regress", "collapse-small", "--workers", "-2"], "workers")
cli(
    "regress-scheduler-bogus",
    ["regress", "collapse-small", "--scheduler", "udp://x:1"],
    "udp://x:1",
)
cli("regress-update-with-value", ["regress", "--update=yes"], "--update")
cli("regress-out-is-file", lambda c: ["regress", "collapse-small", "--out", _file(c)], "afile")


# ------------------------------------------------------------------------ matrices
BASE_MATRIX = 'base = "collapse"\n\n[set]\nduration = 0.02\n'


def mtx(text: str, *, base: bool = True, expand: bool = True) -> Callable[[Ctx], Any]:
    """Write a matrix file, load it and expand it over its base scenario."""

    def action(c: Ctx) -> Any:
        path = c.write("m.toml", (BASE_MATRIX + text) if base else text)
        m = load_matrix(path)
        if expand:
            from packbot.batch import check_runs

            check_runs(m.runs())
        return m

    return action


def matrix(id: str, text: str, *words: str, base: bool = True, **kw: Any) -> None:
    add("matrix", id, mtx(text, base=base), *words, **kw)


def matrix_cli(id: str, text: str, *words: str, command: str = "batch", base: bool = True) -> None:
    def argv(c: Ctx) -> list[str]:
        path = c.write("m.toml", (BASE_MATRIX + text) if base else text)
        if command == "batch":
            return ["batch", str(path), "--out", c.out(), "--workers", "0", "--no-progress"]
        return [
            "regress",
            str(path),
            "--update",
            "--golden",
            c.out("golden"),
            "--out",
            c.out(),
            "--workers",
            "0",
            "--no-progress",
        ]

    add("matrix", f"{command}-{id}", argv, *words, cli=True)


matrix("empty-file", "", "base", base=False)
matrix("syntax-error", "[axes\n", "TOML", base=False)
matrix("unknown-top-level-key", "[axis]\n'config.restitution' = [0.0]\n", "axis")
matrix("no-axes", "", "axes")
matrix("axes-not-table", "axes = [1, 2]\n", "axes", base=False)
matrix("axis-empty", "[axes]\n'config.restitution' = []\n", "axes.config.restitution")
matrix("axis-scalar", "[axes]\n'config.restitution' = 0.5\n", "axes.config.restitution")
matrix(
    "axis-repeated-values", "[axes]\n'config.restitution' = [0.5, 0.5]\n", "axes.config.restitution"
)
matrix("axis-bad-dotted-name", "[axes]\n'config..restitution' = [0.5]\n", "config..restitution")
matrix("axis-name-with-space", "[axes]\n'config.rest itution' = [0.5]\n", "rest itution")
matrix("axis-unknown-field", "[axes]\n'config.restitutio' = [0.0, 0.5]\n", "config.restitutio")
matrix("axis-unknown-section", "[axes]\n'simulation.rtol' = [1e-6]\n", "simulation")
matrix(
    "axis-value-wrong-type",
    "[axes]\n'config.restitution' = ['high', 'low']\n",
    "config.restitution",
)
matrix(
    "axis-value-out-of-range", "[axes]\n'config.restitution' = [0.5, 1.5]\n", "config.restitution"
)
matrix(
    "axis-value-mixed-types", "[axes]\n'config.contact_mode' = ['none', 5]\n", "config.contact_mode"
)
matrix("axis-through-scalar", "[axes]\n'duration.x' = [1.0]\n", "duration")
matrix("axis-index-out-of-range", "[axes]\n'failures.3.kind' = ['loose']\n", "failures.3.kind")
matrix(
    "axis-unknown-failure-kind",
    "[axes]\n'failures.0.kind' = ['loose', 'broken']\n'failures.0.joint' = ['elbow1']\n",
    "failures",
)
matrix("axis-unknown-pose", "[axes]\n'initial.pose' = ['drive', 'crouch']\n", "crouch")
matrix(
    "axis-datetime-value",
    "[axes]\n'config.restitution' = [1979-05-27]\n",
    "axes.config.restitution",
)
matrix("set-not-table", 'base = "collapse"\nset = 5\n[axes]\nx = [1]\n', "set", base=False)
matrix(
    "set-unknown-field", "config.bogus = 1\n[axes]\n'config.restitution' = [0.0]\n", "config.bogus"
)
matrix(
    "set-bad-value", "config.sample_dt = 1e-9\n[axes]\n'config.restitution' = [0.0]\n", "sample_dt"
)
matrix(
    "base-missing",
    'base = "no_such_scenario"\n[axes]\n"config.restitution" = [0.0]\n',
    "no_such_scenario",
    base=False,
)
matrix(
    "base-missing-path",
    'base = "../none.toml"\n[axes]\n"config.restitution" = [0.0]\n',
    "none.toml",
    base=False,
)
matrix("base-empty", '[axes]\n"config.restitution" = [0.0]\n', "base", base=False)
matrix(
    "name-with-slash",
    'name = "a/b"\nbase = "collapse"\n[axes]\n"config.restitution" = [0.0]\n',
    "name",
    base=False,
)
matrix("set-top-level-name", 'name = "a"\n[axes]\n"config.restitution" = [0.0]\n', "name")
matrix("include-empty-table", "[axes]\n'config.restitution' = [0.0]\n[[include]]\n", "include")
matrix(
    "exclude-unknown-axis",
    "[axes]\n'config.restitution' = [0.0]\n[[exclude]]\n'config.mu' = 0.5\n",
    "config.mu",
)
matrix(
    "tolerance-negative",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nq = -1e-6\n",
    "tolerances.q",
)
matrix(
    "tolerance-str",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nq = 'tight'\n",
    "tolerances.q",
)
matrix(
    "tolerance-bool",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nq = true\n",
    "tolerances.q",
)
matrix(
    "tolerance-unknown-name",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nangle = 1e-6\n",
    "angle",
)
matrix(
    "tolerance-nan", "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nq = nan\n", "tolerances.q"
)
add(
    "matrix", "parse-not-toml", lambda c: parse_matrix("\x00\x01"), "TOML", error=ConfigurationError
)
add(
    "matrix",
    "load-unknown-name",
    lambda c: load_matrix("collapse-big"),
    "collapse-big",
    error=UnknownNameError,
)
add(
    "matrix",
    "load-binary-file",
    lambda c: load_matrix(c.write("m.toml", bytes(range(256)))),
    "m.toml",
    error=ConfigurationError,
)
matrix_cli("axis-unknown-field", "[axes]\n'config.restitutio' = [0.0, 0.5]\n", "config.restitutio")
matrix_cli(
    "axis-value-out-of-range", "[axes]\n'config.restitution' = [0.5, 1.5]\n", "config.restitution"
)
matrix_cli(
    "base-missing",
    'base = "no_such_scenario"\n[axes]\n"config.restitution" = [0.0]\n',
    "no_such_scenario",
    base=False,
)
matrix_cli(
    "tolerance-unknown-name",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nangle = 1e-6\n",
    "angle",
)
matrix_cli(
    "tolerance-bool",
    "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nq = true\n",
    "tolerances.q",
    command="regress",
)
matrix_cli(
    "axis-unknown-pose",
    "[axes]\n'initial.pose' = ['drive', 'crouch']\n",
    "crouch",
    command="regress",
)


# ------------------------------------------------------------------------ URDFs
def urdf(
    id: str,
    edit: Callable[[str], str] | None,
    *words: str,
    error: type[PackbotError] = ModelError,
    meshes: Callable[[Path], None] | None = None,
    guard: bool = False,
) -> None:
    def action(c: Ctx) -> Any:
        return packbot.load_robot(broken_copy(c.tmp, edit, meshes))

    add("urdf", id, action, *words, error=error, guard=guard)


def urdf_cli(id: str, edit: Callable[[str], str], *words: str) -> None:
    add(
        "urdf",
        f"info-{id}",
        lambda c: ["info", "--urdf", str(broken_copy(c.tmp, edit))],
        *words,
        cli=True,
    )


def sub(old: str, new: str, count: int = 1) -> Callable[[str], str]:
    def edit(t: str) -> str:
        assert old in t, old
        return t.replace(old, new, count)

    return edit


def _unlink(name: str) -> Callable[[Path], None]:
    return lambda d: (d / name).unlink()


def _write_mesh(name: str, data: bytes) -> Callable[[Path], None]:
    return lambda d: (d / name).write_bytes(data)


MASS = '<mass value="3.05"/>'
IXX = 'ixx="0.00441725822407"'
urdf("empty", lambda t: "", "empty", error=URDFSyntaxError)
urdf("whitespace", lambda t: "\n \n", "empty", error=URDFSyntaxError)
urdf("truncated", lambda t: t[: len(t) // 2], "truncated", error=URDFSyntaxError)
urdf(
    "binary",
    lambda t: bytes(range(256)).decode("latin-1"),
    "packbot_eod.urdf",
    error=URDFSyntaxError,
)
urdf(
    "unclosed-tag", sub('<link name="link1">', '<link name="link1"'), "line", error=URDFSyntaxError
)
urdf(
    "not-a-urdf",
    lambda t: t.replace('<robot name="packbot_eod">', "<sdf>").replace("</robot>", "</sdf>"),
    "sdf",
    error=URDFSyntaxError,
)
urdf("no-links", lambda t: '<robot name="x"></robot>', "packbot_eod.urdf", error=URDFError)
urdf(
    "mass-negative", sub(MASS, '<mass value="-3.05"/>'), "link 'link1' <mass>", error=InertialError
)
urdf("mass-zero", sub(MASS, '<mass value="0"/>'), "link 'link1' <mass>", error=InertialError)
urdf("mass-nan", sub(MASS, '<mass value="nan"/>'), "link 'link1' <mass>", error=InertialError)
urdf("mass-text", sub(MASS, '<mass value="heavy"/>'), "link 'link1' <mass>", error=InertialError)
urdf("mass-missing-value", sub(MASS, "<mass/>"), "link 'link1'", error=URDFError)
urdf("inertia-negative", sub(IXX, 'ixx="-1"'), "link 'link1' <inertia>", error=InertialError)
urdf("inertia-triangle", sub(IXX, 'ixx="0.5"'), "link 'link1' <inertia>", error=InertialError)
urdf("inertia-inf", sub(IXX, 'ixx="inf"'), "link 'link1' <inertia>", error=InertialError)
urdf(
    "inertia-indefinite",
    sub('ixy="-4.66502003005e-19"', 'ixy="0.1"'),
    "link 'link1' <inertia>",
    error=InertialError,
)
urdf(
    "limits-inverted",
    sub(SHOULDER_LIMIT, '<limit lower="2.1" upper="-1.3" effort="156" velocity="0.8"/>'),
    "joint 'shoulder'",
    error=JointError,
)
urdf(
    "limits-empty-range",
    sub(SHOULDER_LIMIT, '<limit lower="0.5" upper="0.5" effort="156" velocity="0.8"/>'),
    "joint 'shoulder'",
    error=JointError,
)
urdf(
    "limit-effort-negative",
    sub(SHOULDER_LIMIT, '<limit lower="-1.3" upper="2.1" effort="-156" velocity="0.8"/>'),
    "joint 'shoulder'",
    error=JointError,
)
urdf(
    "limit-velocity-zero",
    sub(SHOULDER_LIMIT, '<limit lower="-1.3" upper="2.1" effort="156" velocity="0"/>'),
    "joint 'shoulder'",
    error=JointError,
)
urdf("limit-missing", sub(SHOULDER_LIMIT, ""), "joint 'shoulder'", error=JointError)
urdf(
    "limit-nan",
    sub(SHOULDER_LIMIT, '<limit lower="-1.3" upper="nan" effort="156" velocity="0.8"/>'),
    "joint 'shoulder'",
    error=JointError,
)
urdf(
    "joint-renamed",
    sub('<joint name="elbow1"', '<joint name="elbow_one"'),
    "elbow1",
    error=JointMismatchError,
)
urdf(
    "joint-fixed",
    sub('<joint name="elbow2" type="revolute">', '<joint name="elbow2" type="fixed">'),
    "joint 'elbow2'",
    error=JointError,
)
urdf(
    "joint-type-unknown",
    sub('<joint name="elbow2" type="revolute">', '<joint name="elbow2" type="hinge">'),
    "elbow2",
    error=URDFError,
)
urdf(
    "joint-parent-undefined",
    sub('<parent link="link1"/>', '<parent link="link_one"/>'),
    "link_one",
    error=JointError,
)
urdf(
    "joint-axis-zero",
    sub('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'),
    "gripper_jaw",
    error=JointError,
)
urdf(
    "joint-defined-twice",
    sub('name="elbow2" type', 'name="elbow1" type'),
    "defined twice",
    error=URDFError,
)
urdf(
    "link-defined-twice",
    sub('<link name="link3">', '<link name="link2">'),
    "defined twice",
    error=URDFError,
)
urdf(
    "origin-two-numbers",
    sub('<origin xyz="0.44 0 0" rpy="0 0 0"/>', '<origin xyz="0.44 0"/>'),
    "elbow2",
    error=URDFError,
)
urdf("loop", sub('<child link="link1"/>', '<child link="link2"/>'), "link2", error=URDFError)
urdf("mesh-missing", None, "link1__tube.stl", error=MeshError, meshes=_unlink("link1__tube.stl"))
urdf(
    "mesh-empty",
    None,
    "link1__tube.stl",
    error=MeshError,
    meshes=_write_mesh("link1__tube.stl", b""),
)
urdf(
    "mesh-garbage",
    None,
    "link1__tube.stl",
    error=MeshError,
    meshes=_write_mesh("link1__tube.stl", b"solid x\n facet garbage\nendsolid x\n"),
)
urdf(
    "mesh-unknown-package",
    sub(TUBE, "package://other/meshes/tube.stl", 2),
    "other",
    error=MeshError,
)
urdf_cli("truncated", lambda t: t[: len(t) // 2], "truncated")
urdf_cli("mass-negative", sub(MASS, '<mass value="-3.05"/>'), "link1")
urdf_cli(
    "limits-inverted",
    sub(SHOULDER_LIMIT, '<limit lower="2.1" upper="-1.3" effort="156" velocity="0.8"/>'),
    "shoulder",
)
urdf_cli("joint-renamed", sub('<joint name="elbow1"', '<joint name="elbow_one"'), "elbow1")


# more URDF problems: the file's structure, shapes, meshes
def _stl(triangles: Sequence[Sequence[Sequence[float]]]) -> bytes:
    """A binary STL file of the given triangles (3 vertices each) [m]."""
    import struct

    data = bytearray(b"packbot bad-input test".ljust(80, b" "))
    data += struct.pack("<I", len(triangles))
    for tri in triangles:
        data += struct.pack("<3f", 0.0, 0.0, 0.0)
        for v in tri:
            data += struct.pack("<3f", *v)
        data += b"\0\0"
    return bytes(data)


def _tetra(o: Sequence[float], size: float = 0.05, nan: bool = False) -> list[list[list[float]]]:
    a = [o[0], o[1], o[2]]
    b = [o[0] + size, o[1], o[2]]
    c = [o[0], o[1] + size, o[2]]
    d = [o[0], o[1], o[2] + size]
    if nan:
        d = [math.nan, o[1], o[2]]
    return [[a, c, b], [a, b, d], [a, d, c], [b, c, d]]


_FLAT = [[[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], [[0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]]]
_BOMB = (
    '<?xml version="1.0"?>\n<!DOCTYPE r [\n<!ENTITY a "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa">\n'
    + "".join(f'<!ENTITY {chr(98 + k)} "{("&" + chr(97 + k) + ";") * 10}">\n' for k in range(9))
    + ']>\n<robot name="x"><link name="&j;"/></robot>\n'
)
urdf("entity-expansion-bomb", lambda t: _BOMB, "packbot_eod.urdf", error=URDFError, guard=True)
urdf(
    "external-entity",
    lambda t: t.replace(
        '<?xml version="1.0"?>',
        '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/hostname">]>',
    ).replace('<robot name="packbot_eod">', '<robot name="&x;">'),
    "packbot_eod.urdf",
    error=URDFError,
)
urdf("mass-missing", sub(MASS, ""), "link 'link1' <mass>", error=InertialError)
urdf(
    "inertia-missing",
    lambda t: t.replace(
        t[t.index("<inertia ", t.index(MASS)) : t.index("/>", t.index(MASS) + 40) + 2], "", 1
    ),
    "link 'link1' <inertia>",
    error=InertialError,
)
urdf(
    "inertial-origin-nan",
    sub(
        '<origin xyz="0.231229508197 4.43245595149e-19 1.6285512355e-18" rpy="0 0 0"/>',
        '<origin xyz="nan 0 0" rpy="0 0 0"/>',
    ),
    "link 'link1' <inertial> <origin>",
    error=URDFError,
)
urdf("link-no-name", sub('<link name="link3">', "<link>"), "<link>", error=URDFError)
urdf(
    "joint-no-name",
    sub('<joint name="elbow2" type="revolute">', '<joint type="revolute">'),
    "<joint>",
    error=URDFError,
)
urdf(
    "joint-no-child", sub('<child link="link1"/>', ""), "joint 'shoulder' <child>", error=JointError
)
urdf(
    "joint-removed-two-roots",
    lambda t: t.replace(
        t[
            t.index('<joint name="gripper_tool_joint"') : t.index(
                "</joint>", t.index('<joint name="gripper_tool_joint"')
            )
            + 8
        ],
        "",
        1,
    ),
    "gripper_tool",
    error=URDFError,
)
urdf(
    "joint-rpy-text",
    sub('<origin xyz="0.44 0 0" rpy="0 0 0"/>', '<origin xyz="0.44 0 0" rpy="up"/>'),
    "joint 'elbow2' <origin> rpy='up'",
    error=URDFError,
)
urdf(
    "joint-axis-two-numbers",
    sub('<axis xyz="0 1 0"/>', '<axis xyz="0 1"/>'),
    "joint 'gripper_jaw' <axis>",
    error=JointError,
)
urdf(
    "arm-joint-continuous",
    sub('<joint name="elbow2" type="revolute">', '<joint name="elbow2" type="continuous">'),
    "joint 'elbow2'",
    error=JointError,
)
urdf(
    "arm-joint-prismatic",
    sub('<joint name="elbow2" type="revolute">', '<joint name="elbow2" type="prismatic">'),
    "joint 'elbow2'",
    error=JointError,
)
urdf(
    "limit-no-effort",
    sub(SHOULDER_LIMIT, '<limit lower="-1.3" upper="2.1" velocity="0.8"/>'),
    "joint 'shoulder' <limit>",
    error=JointError,
)
urdf(
    "dynamics-damping-negative",
    sub('<dynamics damping="0.8" friction="1.5"/>', '<dynamics damping="-0.8" friction="1.5"/>'),
    "joint 'turret' <dynamics>",
    error=JointError,
)
urdf(
    "geometry-empty",
    sub(f'<geometry><mesh filename="{TUBE}"/></geometry>', "<geometry/>"),
    "link 'link1'",
    error=URDFError,
)
urdf(
    "geometry-unknown-shape",
    sub(f'<mesh filename="{TUBE}"/>', '<capsule radius="1"/>'),
    "<capsule>",
    error=URDFError,
)
urdf(
    "box-negative",
    sub(f'<mesh filename="{TUBE}"/>', '<box size="-1 1 1"/>'),
    "<box>",
    error=URDFError,
)
urdf(
    "cylinder-zero-radius",
    sub(f'<mesh filename="{TUBE}"/>', '<cylinder radius="0" length="1"/>'),
    "<cylinder> radius",
    error=URDFError,
)
urdf(
    "sphere-no-radius", sub(f'<mesh filename="{TUBE}"/>', "<sphere/>"), "<sphere>", error=URDFError
)
urdf(
    "mesh-scale-zero",
    sub(f'<mesh filename="{TUBE}"/>', f'<mesh filename="{TUBE}" scale="0 1 1"/>'),
    "scale",
    error=MeshError,
)
urdf(
    "mesh-no-filename",
    sub(f'<mesh filename="{TUBE}"/>', "<mesh/>"),
    "link 'link1'",
    error=MeshError,
)
urdf(
    "mesh-file-uri-missing",
    sub(TUBE, "file:///nonexistent/tube.stl"),
    "/nonexistent/tube.stl",
    error=MeshError,
)
urdf(
    "mesh-one-triangle",
    None,
    "link1",
    error=ModelError,
    meshes=_write_mesh("link1__tube.stl", _stl(_FLAT[:1])),
)
urdf(
    "mesh-flat", None, "link1", error=ModelError, meshes=_write_mesh("link1__tube.stl", _stl(_FLAT))
)
urdf(
    "mesh-nan-vertex",
    None,
    "link1",
    error=ModelError,
    meshes=_write_mesh("link1__tube.stl", _stl(_tetra((0, 0, 0), nan=True))),
    guard=True,
)
urdf(
    "mesh-not-convex",
    None,
    "link1",
    error=ModelError,
    meshes=_write_mesh("link1__tube.stl", _stl(_tetra((0, 0, 0)) + _tetra((0.5, 0, 0)))),
)
urdf(
    "mesh-huge-count",
    None,
    "link1__tube.stl",
    error=MeshError,
    meshes=_write_mesh("link1__tube.stl", b"x" * 80 + (10**9).to_bytes(4, "little")),
)
urdf_cli("empty", lambda t: "", "empty")
urdf_cli("mesh-unknown-package", sub(TUBE, "package://other/meshes/tube.stl", 2), "other")

# more command lines: empty paths, and the same option twice
cli("run-out-empty", ["run", "collapse", "--out", ""], "--out")
cli("collapse-out-empty", ["collapse", "--out", ""], "--out")
cli("batch-out-empty", ["batch", "collapse-small", "--out", ""], "--out")
cli("regress-out-empty", ["regress", "collapse-small", "--out", ""], "--out")
cli("regress-golden-empty-str", ["regress", "collapse-small", "--golden", ""], "--golden")
cli("generate-model-root-empty", ["generate-model", "--root", ""], "--root")
cli("generate-srdf-root-empty", ["generate-srdf", "--root", " "], "--root")
cli("info-urdf-empty-str", ["info", "--urdf", ""], "directory")
cli("run-scenario-empty-str", lambda c: ["run", "", "--out", c.out()], "scenario")
cli("batch-matrix-empty-str", lambda c: ["batch", "", "--out", c.out()], "matrix")
cli(
    "run-matrix-as-scenario",
    lambda c: [
        "run",
        str(HERE.parent / "sims" / "matrices" / "collapse-small.toml"),
        "--out",
        c.out(),
    ],
    "name",
)
cli(
    "batch-scenario-as-matrix",
    lambda c: ["batch", str(HERE.parent / "sims" / "collapse.toml"), "--out", c.out()],
    "duration",
)
cli(
    "run-urdf-as-scenario",
    lambda c: ["run", str(HERE.parent / "urdf" / "packbot" / "packbot_eod.urdf"), "--out", c.out()],
    "TOML",
)

# more of the API: simulate's initial speeds, scenario objects built in code
api(
    "simulate-v0-1e6-rad-per-s",
    sim(v0=[0.0, 1e6, 0, 0, 0, 0, 0, 0]),
    "v0",
    error=ConfigurationError,
)
api(
    "simulate-v0-rpm-mistake",
    sim(v0=[0.0, 0.0, 300.0, 0, 0, 0, 0, 0]),
    "elbow1",
    error=ConfigurationError,
)


# controllers that misbehave at run time, and callbacks
class _ComplexController(packbot.control.Controller):
    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros(NQ) + 1j


class _NoInitController(packbot.control.Controller):
    def __init__(self) -> None:  # forgets Controller.__init__ (no dt, no sensor)
        pass

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros(NQ)


def _progress_raises(t: float) -> None:
    raise ValueError("disk full")


_SIM_ERR = packbot.SimulationError
api(
    "simulate-controller-fn-wrong-shape",
    sim(controller=lambda t, q, v: np.zeros(3)),
    "shape (3,)",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-fn-nan",
    sim(controller=lambda t, q, v: np.full(NQ, NAN)),
    "turret",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-fn-raises",
    sim(controller=lambda t, q, v: 1 / 0),
    "ZeroDivisionError",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-fn-none",
    sim(controller=lambda t, q, v: None),
    "controller",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-fn-str",
    sim(controller=lambda t, q, v: "x"),
    "controller",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-fn-complex",
    sim(controller=lambda t, q, v: np.zeros(NQ) + 0j),
    "complex",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-complex",
    sim(_controller=lambda c: _ComplexController()),
    "complex",
    error=packbot.ControllerError,
)
api(
    "simulate-controller-without-init",
    sim(_controller=lambda c: _NoInitController()),
    "controller.dt",
    error=ConfigurationError,
)
api("simulate-progress-raises", sim(progress=_progress_raises), "progress", error=_SIM_ERR)

# Scenario objects built in code, and the scenario functions' arguments


def _run_built(**kw: Any) -> Callable[[Ctx], Any]:
    def action(c: Ctx) -> Any:
        return run_scenario(Scenario(name="built", duration=0.05, pose="drive", **kw), c.robot)

    return action


def built(id: str, kw: dict[str, Any], *words: str) -> None:
    add("scenario", f"built-{id}", _run_built(**kw), *words, error=ConfigurationError)


add(
    "scenario",
    "built-duration-str",
    lambda c: run_scenario(Scenario(name="x", duration="1"), c.robot),
    "duration",
    error=ConfigurationError,
)
built("config-dict", {"config": {"restitution": 0.5}}, "config")
built("failures-dict-item", {"failures": ({"joint": "shoulder", "kind": "loose"},)}, "failures[0]")
built("environment-list", {"environment": []}, "environment")
built("outputs-none", {"outputs": None}, "outputs")
built("q0-str", {"q0": "drive"}, "initial.q")
built("controller-int", {"controller": 5}, "controller.kind")
built("controller_params-list", {"controller": "pd", "controller_params": [1]}, "controller")
built("inform-int", {"inform_controller": 1}, "controller.inform")
built("payload-dict", {"payload": {"mass": 1.0}}, "payload")
built("outputs-joints-str", {"outputs": Outputs(joints="shoulder")}, "outputs.joints")
built("outputs-plots-str", {"outputs": Outputs(plots="joints")}, "outputs.plots")
built(
    "occlusion-radius-str",
    {"outputs": Outputs(occlusion=OcclusionCheck(targets=((1.0, 0.0, 0.0),), radius="1"))},
    "outputs.occlusion.radius",
)
built("v0-beyond-limit", {"v0": {"elbow2": 500.0}}, "initial.v")
built("q0-str-angle", {"q0": {"shoulder": "high"}}, "initial.q.shoulder")
built("v0-list-of-str", {"v0": ["fast"] * NQ}, "initial.v")
built("q0-list-with-pose", {"q0": [0.0] * NQ}, "initial.q")
built("v0-int", {"v0": 0}, "initial.v")
add(
    "scenario",
    "run_scenario-name",
    lambda c: run_scenario("collapse"),
    "scenario",
    error=ConfigurationError,
)
add(
    "scenario",
    "run_scenario-robot-str",
    lambda c: run_scenario(load_scenario("collapse"), "robot", duration=0.02),
    "robot",
    error=ConfigurationError,
)
add(
    "scenario",
    "run_scenario-duration-bool",
    lambda c: run_scenario(load_scenario("collapse"), c.robot, duration=True),
    "duration",
    error=ConfigurationError,
)
add(
    "scenario",
    "scenario_from_dict-list",
    lambda c: scenario_from_dict([1, 2], name="x"),
    "scenario",
    error=ConfigurationError,
)
add(
    "scenario",
    "scenario_from_dict-name-int",
    lambda c: scenario_from_dict({"duration": 1.0}, name=5),
    "name",
    error=ConfigurationError,
)
add(
    "scenario",
    "save_run-into-a-file",
    lambda c: save_run(c.result, load_scenario("collapse"), c.write("afile", "x")),
    "out_dir",
    error=ConfigurationError,
)
add("matrix", "load-int", lambda c: load_matrix(5), "matrix", error=ConfigurationError)
add("matrix", "load-none", lambda c: load_matrix(None), "matrix", error=ConfigurationError)
add("matrix", "load-empty-str", lambda c: load_matrix(""), "matrix", error=ConfigurationError)


def _batch(**kw: Any) -> Callable[[Ctx], Any]:
    def action(c: Ctx) -> Any:
        from packbot.batch import run_batch

        m = load_matrix(c.write("m.toml", BASE_MATRIX + "[axes]\n'config.restitution' = [0.0]\n"))
        args: dict[str, Any] = {"out_dir": c.out(), "workers": 0}
        args.update(kw)
        return run_batch(m, **args)

    return action


add("matrix", "run_batch-workers-bool", _batch(workers=True), "workers", error=ConfigurationError)
add("matrix", "run_batch-timeout-bool", _batch(timeout=True), "timeout", error=ConfigurationError)
add("matrix", "run_batch-timeout-str", _batch(timeout="10"), "timeout", error=ConfigurationError)
add("matrix", "run_batch-out-none", _batch(out_dir=None), "out_dir", error=ConfigurationError)
add("matrix", "run_batch-out-empty", _batch(out_dir=""), "out_dir", error=ConfigurationError)


# ------------------------------------------------------------------------ the catalogue
def _register_extensions() -> None:
    """Add the cases of the extension modules (:data:`EXTENSIONS`) that exist."""
    import importlib

    me = sys.modules[__name__]
    for name in EXTENSIONS:
        if (HERE / f"{name}.py").is_file():
            importlib.import_module(name).register(me)


_register_extensions()


def _check_unique() -> None:
    seen: set[str] = set()
    for case in CASES:
        assert case.category in CATEGORIES, case
        assert case.key not in seen, f"duplicate case id {case.key}"
        seen.add(case.key)


_check_unique()
BY_KEY: dict[str, Case] = {c.key: c for c in CASES}


def counts() -> dict[str, int]:
    """Number of cases per category."""
    return {cat: sum(c.category == cat for c in CASES) for cat in CATEGORIES}


# ------------------------------------------------------------------------ worker
def run_in_tmp(case: Case) -> Outcome:
    """Run a case in a fresh temporary folder (removed afterwards)."""
    tmp = Path(tempfile.mkdtemp(prefix="packbot-bad-"))
    try:
        return run_case(case, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _answer(key: str) -> str:
    o = run_in_tmp(BY_KEY[key])
    return json.dumps({"key": key, "status": o.status, "detail": o.detail})


def worker_main(argv: Sequence[str]) -> int:
    """``--worker``: case keys on stdin, one JSON line each on stdout; ``--case KEY``: one."""
    logging.basicConfig(handlers=[logging.NullHandler()])  # main() adds none of its own
    # The answers go to the original stdout; file descriptor 1 then points to stderr, so that
    # nothing a case prints (Python's print or a C++ library's own writes) mixes with them.
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    if argv[:1] == ["--case"]:
        out.write(_answer(argv[1]) + "\n")
        out.flush()
        return 0
    for line in sys.stdin:
        key = line.strip()
        if key:
            out.write(_answer(key) + "\n")
            out.flush()
    return 0


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.exit(worker_main(sys.argv[1:]))
