"""Bad-input catalogue, category ``keywords``: unknown, misspelt and missing keywords.

Every public constructor and entry point (``packbot.__all__``, ``packbot.control.__all__``, the
scenario, matrix, batch, study, analysis, regression, plotting and viewer functions, the result
and robot methods) is called with an unknown keyword, a misspelt one (the message must suggest
the valid one), a required argument left out and one positional argument too many; each must
raise :class:`~packbot.errors.KeywordError` naming the keyword and the callable. Keywords also
come from files: scenario and matrix files with a misspelt key (the message names its dotted
path and suggests the valid key), through the API and ``packbot run`` / ``packbot batch``; and
the command line's own options, misspelt.

The calls fail at binding, before the callable runs, so heavy arguments (a workspace, a
matrix, a result) are given as ``None`` where the body would need them.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

import packbot
from packbot.errors import ConfigurationError, KeywordError, UnknownNameError


class Entry(NamedTuple):
    """A callable and a valid call of it: ``get(c)(*args(c), **kwargs(c))``."""

    name: str  # as the message names it
    get: Callable[[Any], Callable[..., Any]]
    args: Callable[[Any], tuple[Any, ...]]
    kwargs: Callable[[Any], dict[str, Any]]
    misspelt: tuple[tuple[str, str], ...] = ()  # (given, suggested)


def _none(c: Any) -> tuple[Any, ...]:
    return ()


def _nokw(c: Any) -> dict[str, Any]:
    return {}


def ep(
    name: str,
    get: Callable[[Any], Callable[..., Any]],
    args: Callable[[Any], tuple[Any, ...]] = _none,
    kwargs: Callable[[Any], dict[str, Any]] = _nokw,
    *misspelt: tuple[str, str],
) -> Entry:
    return Entry(name, get, args, kwargs, tuple(misspelt))


class _UserController(packbot.control.Controller):
    """A user's controller: a keyword of its own, the others passed to Controller."""

    def __init__(self, gain: float = 1.0, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.gain = gain

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return -self.gain * v


class _UserControllerNoInit(packbot.control.Controller):
    """A user's controller using Controller's constructor."""

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros_like(v)


def _nones(get: Callable[[Any], Callable[..., Any]]) -> Callable[[Any], tuple[Any, ...]]:
    """``None`` for each required positional parameter (the call fails before they are used)."""

    def args(c: Any) -> tuple[Any, ...]:
        kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
        params = inspect.signature(get(c)).parameters.values()
        return tuple(None for p in params if p.kind in kinds and p.default is p.empty)

    return args


def _mod(name: str) -> ModuleType:
    import importlib

    return importlib.import_module(name)


NQ = 8
Z = np.zeros(NQ)
_SPAN = _mod("packbot.viz.contacts").ContactSpan


def entries() -> list[Entry]:
    import packbot.control as C

    A = _mod("packbot.analysis")
    S = _mod("packbot.scenario")
    M = _mod("packbot.matrix")
    B = _mod("packbot.batch")
    SM = _mod("packbot.study_matrix")
    R = _mod("packbot.regress")
    PL = _mod("packbot.plots")
    RS = _mod("packbot.resources")
    ST = _mod("packbot.study")
    V = _mod("packbot.viz")
    UB = _mod("packbot.uncertain_batch")
    traj = C.JointTrajectory([Z, Z + 0.1], [0.0, 1.0])
    return [
        # packbot
        ep(
            "SimConfig",
            lambda c: packbot.SimConfig,
            _none,
            _nokw,
            ("restitutio", "restitution"),
            ("Restitution", "restitution"),
            ("contact_mod", "contact_mode"),
            ("sampl_dt", "sample_dt"),
            ("max_event", "max_events"),
            ("locked_joint", "locked_joints"),
            ("gravty", "gravity"),
            ("motorlag", "motor_lag"),
            ("joint_limit", "joint_limits"),
            ("zeno_sped", "zeno_speed"),
        ),
        ep(
            "Failure",
            lambda c: packbot.Failure,
            _none,
            lambda c: {"joint": "shoulder", "kind": "loose"},
            ("joints", "joint"),
            ("knd", "kind"),
            ("threshhold", "threshold"),
            ("scal", "scale"),
            ("torq", "torque"),
        ),
        ep(
            "Payload",
            lambda c: packbot.Payload,
            _none,
            lambda c: {"mass": 1.0},
            ("mas", "mass"),
            ("frme", "frame"),
            ("t_pik", "t_pick"),
            ("inerta", "inertia"),
        ),
        ep(
            "Obstacle",
            lambda c: packbot.Obstacle,
            _none,
            lambda c: {"name": "crate", "kind": "box", "size": (1, 1, 1)},
            ("nme", "name"),
            ("sise", "size"),
            ("xzy", "xyz"),
            ("offest", "offset"),
            ("point", "points"),
        ),
        ep("Environment", lambda c: packbot.Environment, _none, _nokw, ("obstacle", "obstacles")),
        ep("Environment.with_obstacles", lambda c: packbot.Environment().with_obstacles),
        ep("Environment.empty", lambda c: packbot.Environment.empty),
        ep(
            "Scenario.validate",
            lambda c: _scenario().validate,
            _none,
            _nokw,
            ("robots", "robot"),
        ),
        ep("Scenario.initial_state", lambda c: _scenario().initial_state, lambda c: (None,)),
        ep("Failure.validate", lambda c: _failure().validate, lambda c: ((),)),
        ep(
            "check_sequence",
            lambda c: _mod("packbot.failures").check_sequence,
            lambda c: ((),),
            _nokw,
            ("feild", "field"),
        ),
        ep(
            "simulate",
            lambda c: packbot.simulate,
            lambda c: (None, None, None, 0.05),
            _nokw,
            ("controler", "controller"),
            ("enviroment", "environment"),
            ("confg", "config"),
            ("failure", "failures"),
            ("payloads", "payload"),
            ("progres", "progress"),
            ("durations", "duration"),
        ),
        ep(
            "study",
            lambda c: packbot.study,
            lambda c: ("collapse",),
            _nokw,
            ("tolerence", "tolerance"),
            ("workspace_sample", "workspace_samples"),
            ("robots", "robot"),
            ("contact_mod", "contact_mode"),
        ),
        ep(
            "uncertain_study",
            lambda c: packbot.uncertain_study,
            lambda c: ("reconfig_elbow1",),
            _nokw,
            ("sample", "samples"),
            ("sed", "seed"),
            ("recoverey", "recovery"),
        ),
        ep(
            "uncertain_run",
            lambda c: packbot.uncertain_run,
            lambda c: ("collapse",),
            _nokw,
            ("sampels", "samples"),
            ("controler", "controller"),
        ),
        ep(
            "run_uncertain_study",
            lambda c: UB.run_uncertain_study,
            lambda c: ("reconfig_elbow1", "out"),
            _nokw,
            ("worker", "workers"),
            ("schedular", "scheduler"),
        ),
        ep(
            "run_uncertain_runs",
            lambda c: UB.run_uncertain_runs,
            lambda c: ("collapse", "out"),
            _nokw,
            ("timout", "timeout"),
        ),
        ep("load_robot", lambda c: packbot.load_robot, _none, _nokw, ("urdf_file", "urdf")),
        ep(
            "identify",
            lambda c: packbot.identify,
            lambda c: (c.robot, None, None),
            _nokw,
            ("windw", "window"),
            ("torque_constants", "torque_constant"),
        ),
        ep(
            "identify_csv",
            lambda c: packbot.identify_csv,
            lambda c: (c.robot, "log.csv"),
            _nokw,
            ("prior_weigth", "prior_weight"),
        ),
        ep(
            "exciting_trajectory",
            lambda c: packbot.control.exciting_trajectory,
            lambda c: (c.robot, None),
            _nokw,
            ("harmonic", "harmonics"),
        ),
        ep("package_dirs", lambda c: packbot.package_dirs),
        ep("urdf_path", lambda c: packbot.urdf_path),
        ep("srdf_path", lambda c: RS.srdf_path),
        ep("data_dir", lambda c: RS.data_dir, lambda c: ("sims",), _nokw, ("nam", "name")),
        ep("Robot.pose", lambda c: c.robot.pose, lambda c: ("drive",), _nokw, ("nme", "name")),
        ep(
            "Robot.q_from",
            lambda c: c.robot.q_from,
            lambda c: ({},),
            _nokw,
            ("bse", "base"),
            ("value", "values"),
        ),
        ep(
            "Robot.check_within_limits",
            lambda c: c.robot.check_within_limits,
            lambda c: (c.drive(),),
            _nokw,
            ("field", "field_name"),
        ),
        ep(
            "Robot",
            lambda c: packbot.Robot,
            _nones(lambda c: packbot.Robot),
            _nokw,
            ("modl", "model"),
        ),
        ep("JointParams", lambda c: packbot.JointParams, _nones(lambda c: packbot.JointParams)),
        ep(
            "SimResult.save",
            lambda c: c.result.save,
            lambda c: (c.tmp / "r.npz",),
            _nokw,
            ("extr", "extra"),
        ),
        ep(
            "SimResult.load",
            lambda c: packbot.SimResult.load,
            lambda c: (c.tmp / "r.npz",),
            _nokw,
            ("pth", "path"),
        ),
        ep("SimResult.events_of", lambda c: c.result.events_of),
        ep("SimResult.joint", lambda c: c.result.joint, lambda c: ("shoulder",), _nokw),
        ep(
            "SimResult.frame_positions",
            lambda c: c.result.frame_positions,
            _none,
            _nokw,
            ("fram", "frame"),
            ("robott", "robot"),
        ),
        ep("SimResult.to_dataframe", lambda c: c.result.to_dataframe),
        ep("SimResult", lambda c: packbot.SimResult, _nones(lambda c: packbot.SimResult)),
        ep(
            "Event",
            lambda c: packbot.Event,
            lambda c: (0.0, "impact"),
            _nokw,
            ("distanse", "distance"),
            ("energy_befor", "energy_before"),
        ),
        ep("Diagnostics", lambda c: packbot.Diagnostics, _none, _nokw, ("step", "steps")),
        ep(
            "CollisionWorld",
            lambda c: packbot.CollisionWorld,
            lambda c: (None,),
            _nokw,
            ("margn", "margin"),
            ("environmnt", "environment"),
        ),
        ep("Contact", lambda c: packbot.Contact, lambda c: (None, 0.0, Z, Z, Z)),
        ep("ContactPatch", lambda c: packbot.ContactPatch, _nones(lambda c: packbot.ContactPatch)),
        ep("PairInfo", lambda c: packbot.PairInfo, _nones(lambda c: packbot.PairInfo)),
        ep("StudyResult", lambda c: packbot.StudyResult, _none, lambda c: _study_result_kw()),
        # packbot.control
        ep(
            "GravityCompensation",
            lambda c: C.GravityCompensation,
            _none,
            _nokw,
            ("dtt", "dt"),
            ("sensr", "sensor"),
            ("gravty", "gravity"),
        ),
        ep(
            "JointPD",
            lambda c: C.JointPD,
            _none,
            _nokw,
            ("kpp", "kp"),
            ("trget", "target"),
            ("omga", "omega"),
            ("gravity_compensate", "gravity_compensation"),
        ),
        ep(
            "ComputedTorque",
            lambda c: C.ComputedTorque,
            _none,
            lambda c: {"trajectory": traj},
            ("trajectry", "trajectory"),
            ("zetta", "zeta"),
        ),
        ep(
            "JointTrajectory",
            lambda c: C.JointTrajectory,
            lambda c: ([Z, Z + 0.1], [0.0, 1.0]),
            _nokw,
            ("vmax", "v_max"),
            ("lowr", "lower"),
        ),
        ep(
            "QuinticSegment",
            lambda c: C.QuinticSegment,
            _none,
            lambda c: {"q0": [0.0], "q1": [1.0]},
            ("duraton", "duration"),
            ("t_0", "t0"),
        ),
        ep(
            "CartesianPD",
            lambda c: C.CartesianPD,
            _none,
            lambda c: {"target": (1.0, 0.0, 1.0)},
            ("trget", "target"),
            ("fram", "frame"),
            ("orientaton", "orientation"),
        ),
        ep(
            "ReconfigurableController",
            lambda c: C.ReconfigurableController,
            _none,
            lambda c: {"target": (0.7, 0.4, 0.2)},
            ("speed_fractio", "speed_fraction"),
            ("ik_seed", "ik_seeds"),
            ("environmnt", "environment"),
        ),
        ep(
            "MomentumObserver",
            lambda c: C.MomentumObserver,
            lambda c: (None, Z),
            lambda c: {"threshold": Z + 1.0},
            ("gian", "gain"),
            ("persistance", "persistence"),
        ),
        ep(
            "Sensor",
            lambda c: C.Sensor,
            _none,
            _nokw,
            ("seeds", "seed"),
            ("noise_qq", "noise_q"),
            ("resolutoin", "resolution"),
        ),
        ep("_UserController", lambda c: _UserController, _none, _nokw),
        ep("_UserControllerNoInit", lambda c: _UserControllerNoInit, _none, _nokw, ("dtt", "dt")),
        ep(
            "build_controller",
            lambda c: C.build_controller,
            lambda c: ("pd", c.robot, {}),
            _nokw,
            ("enviroment", "environment"),
        ),
        ep(
            "min_jerk_duration",
            lambda c: C.min_jerk_duration,
            lambda c: (Z, Z + 0.1, Z + 1.0),
            _nokw,
            ("minimun", "minimum"),
        ),
        ep(
            "solve_position_ik",
            lambda c: C.solve_position_ik,
            lambda c: (None, "gripper_tool", (1, 0, 1), Z),
            _nokw,
            ("dampng", "damping"),
            ("max_iters", "max_iter"),
            ("collision_fre", "collision_free"),
            ("enviroment", "environment"),
        ),
        ep(
            "check_path",
            lambda c: C.check_path,
            lambda c: (None, None),
            _nokw,
            ("tolerence", "tolerance"),
            ("worlds", "world"),
        ),
        ep("reach_bounds", lambda c: C.reach_bounds, lambda c: (None,)),
        ep(
            "PathCollision",
            lambda c: C.PathCollision,
            _none,
            lambda c: {
                "index": 0,
                "fraction": 0.0,
                "q": Z,
                "pair": ("a", "b"),
                "links": ("a", "b"),
                "distance": -1e-3,
            },
            ("fracton", "fraction"),
        ),
        ep("IKResult", lambda c: C.IKResult, _none, lambda c: _ik_kw()),
        ep("Detection", lambda c: C.Detection, _none, lambda c: _detection_kw()),
        ep(
            "ReconfigEvent",
            lambda c: C.ReconfigEvent,
            _none,
            lambda c: {"t": 0.0, "kind": "plan"},
            ("detial", "detail"),
        ),
        # packbot.analysis
        ep(
            "workspace",
            lambda c: A.workspace,
            lambda c: (None,),
            _nokw,
            ("sample", "samples"),
            ("seeds", "seed"),
            ("q_refs", "q_ref"),
        ),
        ep(
            "loose_joint_equilibria",
            lambda c: A.loose_joint_equilibria,
            lambda c: (None, "shoulder", Z),
            _nokw,
            ("sample", "samples"),
            ("gravty", "gravity"),
        ),
        ep(
            "gravity_torque_on",
            lambda c: A.gravity_torque_on,
            lambda c: (None, "shoulder", Z, [0.0]),
            _nokw,
            ("gravty", "gravity"),
        ),
        ep(
            "reach",
            lambda c: A.reach,
            lambda c: (None, None, (1, 0, 1)),
            _nokw,
            ("seed", "seeds"),
            ("max_iters", "max_iter"),
        ),
        ep("reachable", lambda c: A.reachable, lambda c: (None, None, [(1, 0, 1)]), _nokw),
        ep(
            "reachable_volume",
            lambda c: A.reachable_volume,
            lambda c: (None, None),
            _nokw,
            ("rel_tolerance", "rel_tol"),
            ("max_point", "max_points"),
        ),
        ep(
            "monte_carlo_volume",
            lambda c: A.monte_carlo_volume,
            lambda c: (None, (0, 0, 0), (1, 1, 1)),
            _nokw,
            ("batches", "batch"),
        ),
        ep(
            "plot_workspace",
            lambda c: A.plot_workspace,
            lambda c: ([],),
            _nokw,
            ("label", "labels"),
        ),
        ep("Workspace.volume", lambda c: _workspace().volume, _none, _nokw, ("voxl", "voxel")),
        ep("Workspace", lambda c: A.Workspace, _none, lambda c: _workspace_kw()),
        ep("VolumeEstimate", lambda c: A.VolumeEstimate, _none, lambda c: _volume_kw()),
        # packbot.scenario
        ep("load_scenario", lambda c: S.load_scenario, lambda c: ("collapse",)),
        ep(
            "run_scenario",
            lambda c: S.run_scenario,
            lambda c: (None, None),
            _nokw,
            ("durration", "duration"),
            ("progres", "progress"),
        ),
        ep(
            "save_run",
            lambda c: S.save_run,
            lambda c: (None, None, c.out()),
            _nokw,
            ("stm", "stem"),
        ),
        ep(
            "write_outputs",
            lambda c: S.write_outputs,
            lambda c: (None, None, None, c.out()),
            _nokw,
            ("plot", "plots"),
            ("wrld", "world"),
        ),
        ep(
            "scenario_from_dict",
            lambda c: S.scenario_from_dict,
            lambda c: ({},),
            lambda c: {"name": "x"},
            ("nme", "name"),
            ("source", "source_text"),
        ),
        ep("read_scenario_dict", lambda c: S.read_scenario_dict, lambda c: ("collapse",)),
        ep("scenario_path", lambda c: S.scenario_path, lambda c: ("collapse",)),
        ep("list_scenarios", lambda c: S.list_scenarios),
        ep("json_schema", lambda c: S.json_schema, _none, _nokw, ("robots", "robot")),
        ep(
            "Scenario",
            lambda c: S.Scenario,
            _none,
            lambda c: {"name": "x", "duration": 1.0},
            ("duraton", "duration"),
            ("failure", "failures"),
            ("controler", "controller"),
            ("enviroment", "environment"),
        ),
        ep(
            "Outputs",
            lambda c: S.Outputs,
            _none,
            _nokw,
            ("plot", "plots"),
            ("joint", "joints"),
            ("format", "formats"),
        ),
        ep(
            "OcclusionCheck",
            lambda c: S.OcclusionCheck,
            _none,
            lambda c: {"targets": ((1.0, 0.0, 0.0),)},
            ("target", "targets"),
            ("radus", "radius"),
        ),
        # packbot.matrix
        ep("load_matrix", lambda c: M.load_matrix, lambda c: ("collapse-small",)),
        ep(
            "parse_matrix",
            lambda c: M.parse_matrix,
            lambda c: ("",),
            _nokw,
            ("pth", "path"),
            ("default", "default_name"),
        ),
        ep("expand", lambda c: M.expand, lambda c: (None, {}), _nokw, ("base_txt", "base_text")),
        ep(
            "Matrix",
            lambda c: M.Matrix,
            _none,
            lambda c: {"name": "m", "base": "collapse"},
            ("axis", "axes"),
            ("fixd", "fixed"),
            ("tolerance", "tolerances"),
        ),
        ep("Run", lambda c: M.Run, _none, lambda c: _run_kw()),
        ep("find_matrix", lambda c: M.find_matrix, lambda c: ("collapse-small",)),
        ep(
            "set_dotted", lambda c: M.set_dotted, lambda c: ({}, "a.b", 1), _nokw, ("fild", "field")
        ),
        ep(
            "apply_overrides",
            lambda c: M.apply_overrides,
            lambda c: ({}, {}),
            _nokw,
            ("field_prefx", "field_prefix"),
        ),
        # packbot.batch
        ep(
            "run_batch",
            lambda c: B.run_batch,
            lambda c: (None, c.out()),
            _nokw,
            ("worker", "workers"),
            ("timout", "timeout"),
            ("schedular", "scheduler"),
            ("run", "runs"),
        ),
        ep("execute", lambda c: B.execute, lambda c: (None,), _nokw, ("timout", "timeout")),
        ep("check_runs", lambda c: B.check_runs, lambda c: ([],)),
        ep("read_records", lambda c: B.read_records, lambda c: (c.out(),), _nokw, ("run", "runs")),
        ep("summarize", lambda c: B.summarize, lambda c: (None,)),
        ep("check_matrix", lambda c: B.check_matrix, lambda c: (c.out(), None)),
        ep("RunRecord", lambda c: B.RunRecord, _none, lambda c: _record_kw(), ("stat", "status")),
        ep("BatchLock", lambda c: B.BatchLock, lambda c: (c.out(),), _nokw, ("foldr", "folder")),
        ep("ProgressBar", lambda c: B.ProgressBar, _none, _nokw, ("widht", "width")),
        # packbot.study_matrix
        ep("load_study_matrix", lambda c: SM.load_study_matrix, lambda c: ("collapse-small",)),
        ep(
            "run_study_matrix",
            lambda c: SM.run_study_matrix,
            lambda c: (None, c.out()),
            _nokw,
            ("worker", "workers"),
        ),
        ep(
            "study_cell",
            lambda c: SM.study_cell,
            lambda c: (None, None),
            lambda c: {"options": None},
            ("option", "options"),
        ),
        ep(
            "study_matrix_summary",
            lambda c: SM.study_matrix_summary,
            _nones(lambda c: SM.study_matrix_summary),
        ),
        ep(
            "StudyOptions",
            lambda c: SM.StudyOptions,
            _none,
            _nokw,
            ("tolerence", "tolerance"),
            ("workspace_sample", "workspace_samples"),
        ),
        ep("StudyOptions.from_mapping", lambda c: SM.StudyOptions.from_mapping, lambda c: ({},)),
        # packbot.regress
        ep(
            "run_regression",
            lambda c: R.run_regression,
            lambda c: (None, c.out()),
            _nokw,
            ("updat", "update"),
            ("worker", "workers"),
        ),
        ep("compare", lambda c: R.compare, lambda c: ({}, {}), _nokw, ("tolerance", "tolerances")),
        ep(
            "Tolerances",
            lambda c: R.Tolerances,
            _none,
            _nokw,
            ("qq", "q"),
            ("tme", "time"),
            ("chaotic", "chaotic_q"),
        ),
        ep("read_golden", lambda c: R.read_golden, lambda c: (c.out(),)),
        ep("golden_matrices", lambda c: R.golden_matrices, lambda c: (c.out(),)),
        ep("write_golden", lambda c: R.write_golden, lambda c: (c.out(), "m", [], {})),
        # packbot.plots
        ep(
            "plot_joints",
            lambda c: PL.plot_joints,
            lambda c: (None,),
            _nokw,
            ("joint", "joints"),
            ("zoomed", "zoom"),
        ),
        ep(
            "plot_energy",
            lambda c: PL.plot_energy,
            lambda c: (None,),
            _nokw,
            ("jump_treshold", "jump_threshold"),
        ),
        ep("plot_torques", lambda c: PL.plot_torques, lambda c: (None,), _nokw, ("dpii", "dpi")),
        ep("plot_distance", lambda c: PL.plot_distance, lambda c: (None, None)),
        ep(
            "plot_tool_path",
            lambda c: PL.plot_tool_path,
            lambda c: (None,),
            _nokw,
            ("targt", "target"),
            ("frme", "frame"),
        ),
        ep("sample_distances", lambda c: PL.sample_distances, lambda c: (None, None)),
        # packbot.viz (the viewer is never started: the call fails at binding)
        ep(
            "start_viewer",
            lambda c: V.start_viewer,
            lambda c: (None,),
            _nokw,
            ("prot", "port"),
            ("open_browsr", "open_browser"),
        ),
        ep("contact_spans", lambda c: V.contact_spans, lambda c: (None,)),
        ep("SceneRecorder", lambda c: V.SceneRecorder),
        # the records of results (made by packbot; a user may build one in a test)
        ep("Equilibrium", lambda c: A.Equilibrium, _none, lambda c: _equilibrium_kw()),
        ep("ReachAnswer", lambda c: A.ReachAnswer, _none, lambda c: _reach_kw()),
        ep(
            "RecoveryEvent",
            lambda c: _mod("packbot.control.recovery").RecoveryEvent,
            _none,
            lambda c: {"t": 0.0, "kind": "track"},
        ),
        ep("LooseSettling", lambda c: ST.LooseSettling, _none, lambda c: _loose_kw()),
        ep("ContactSpan", lambda c: _SPAN, _nones(lambda c: _SPAN)),
    ]


def _scenario() -> Any:
    return _mod("packbot.scenario").Scenario(name="x", duration=1.0)


def _failure() -> Any:
    return packbot.Failure(joint="shoulder", kind="loose")


def _workspace_kw() -> dict[str, Any]:
    return {
        "points": np.zeros((0, 3)),
        "q": np.zeros((0, NQ)),
        "n_samples": 0,
        "frozen": None,
        "frame": "gripper_tool",
        "joints": (),
    }


def _workspace() -> Any:
    return _mod("packbot.analysis").Workspace(**_workspace_kw())


def _volume_kw() -> dict[str, Any]:
    return {"volume_m3": 1.0, "stderr_m3": 0.1, "samples": 10, "hits": 5, "converged": True}


def _ik_kw() -> dict[str, Any]:
    return {"q": Z, "error": 0.0, "iterations": 1, "success": True}


def _detection_kw() -> dict[str, Any]:
    return {"joint": 1, "kind": "loose", "t": 0.1, "t_onset": 0.05, "residual": 3.0}


def _run_kw() -> dict[str, Any]:
    return {"id": "r", "index": 0, "params": {}, "scenario": {}, "scenario_name": "x", "digest": ""}


def _record_kw() -> dict[str, Any]:
    return {"id": "r", "index": 0, "params": {}, "digest": "", "status": "ok"}


def _study_result_kw() -> dict[str, Any]:
    names = inspect.signature(packbot.StudyResult).parameters
    return {n: None for n, p in names.items() if p.default is inspect.Parameter.empty}


def _equilibrium_kw() -> dict[str, Any]:
    names = inspect.signature(_mod("packbot.analysis").Equilibrium).parameters
    return {n: None for n, p in names.items() if p.default is inspect.Parameter.empty}


def _reach_kw() -> dict[str, Any]:
    names = inspect.signature(_mod("packbot.analysis").ReachAnswer).parameters
    return {n: None for n, p in names.items() if p.default is inspect.Parameter.empty}


def _loose_kw() -> dict[str, Any]:
    names = inspect.signature(_mod("packbot.study").LooseSettling).parameters
    return {n: None for n, p in names.items() if p.default is inspect.Parameter.empty}


def _valid(params: dict[str, inspect.Parameter]) -> list[str]:
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return [n for n, p in params.items() if p.kind in kinds and n not in ("self", "cls")]


def _params(fn: Callable[..., Any]) -> dict[str, inspect.Parameter]:
    return dict(inspect.signature(fn).parameters)


def _call(entry: Entry, extra_args: tuple[Any, ...] = (), drop: str = "", **extra: Any) -> Any:
    def action(c: Any) -> Any:
        fn = entry.get(c)
        args = entry.args(c) + extra_args
        kwargs = {k: v for k, v in entry.kwargs(c).items() if k != drop}
        if drop and drop not in entry.kwargs(c):  # a positional one: cut the args there
            names = [n for n in _params(fn) if n not in ("self", "cls")]
            args = args[: names.index(drop)]
        kwargs.update(extra)
        return fn(*args, **kwargs)

    return action


def _required(fn: Callable[..., Any]) -> list[str]:
    skip = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
    return [
        n
        for n, p in _params(fn).items()
        if p.default is inspect.Parameter.empty and p.kind not in skip and n not in ("self", "cls")
    ]


def _max_positional(fn: Callable[..., Any]) -> int | None:
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    params = _params(fn)
    if any(p.kind is inspect.Parameter.VAR_POSITIONAL for p in params.values()):
        return None
    return sum(p.kind in kinds and n not in ("self", "cls") for n, p in params.items())


class _Probe:
    """A stand-in Ctx for reading signatures while registering (no robot is loaded)."""

    def __init__(self, catalogue: ModuleType) -> None:
        self._cat = catalogue

    def get(self, entry: Entry) -> Callable[..., Any] | None:
        static = {
            "Robot.pose": packbot.Robot.pose,
            "Robot.q_from": packbot.Robot.q_from,
            "Robot.check_within_limits": packbot.Robot.check_within_limits,
            "SimResult.save": packbot.SimResult.save,
            "SimResult.events_of": packbot.SimResult.events_of,
            "SimResult.joint": packbot.SimResult.joint,
            "SimResult.frame_positions": packbot.SimResult.frame_positions,
            "SimResult.to_dataframe": packbot.SimResult.to_dataframe,
            "Workspace.volume": _mod("packbot.analysis").Workspace.volume,
            "Environment.with_obstacles": packbot.Environment.with_obstacles,
            "Scenario.validate": _mod("packbot.scenario").Scenario.validate,
            "Scenario.initial_state": _mod("packbot.scenario").Scenario.initial_state,
            "Failure.validate": packbot.Failure.validate,
        }
        if entry.name in static:
            return static[entry.name]
        return entry.get(None)


def _kw(cat: ModuleType, id: str, action: Callable[[Any], Any], *words: str) -> None:
    cat.add("keywords", id, action, *words, error=KeywordError)


def _register_api(cat: ModuleType) -> int:
    probe = _Probe(cat)
    n = 0
    for entry in entries():
        fn = probe.get(entry)
        assert fn is not None, entry.name
        shown = entry.name
        valid = _valid(_params(fn))
        first = valid[0] if valid else "none"
        if entry.name == "_UserController":  # its **kwargs go to Controller's constructor
            first = "of Controller (from _UserController.__init__)"
        _kw(cat, f"{entry.name}-unknown", _call(entry, bogus=1), "'bogus'", shown, first)
        n += 1
        for wrong, right in entry.misspelt:
            _kw(cat, f"{entry.name}-{wrong}", _call(entry, **{wrong: 1}), wrong, f"'{right}'")
            n += 1
        required = _required(fn)
        if required:
            last = required[-1]
            _kw(cat, f"{entry.name}-missing-{last}", _call(entry, drop=last), f"'{last}'", shown)
            n += 1
        most = _max_positional(fn)
        if most is not None:
            given = len(entry.args(_DummyCtx())) if _cheap_args(entry) else None
            if given is not None:
                extra = (None,) * (most - given + 1)
                _kw(
                    cat,
                    f"{entry.name}-positional",
                    _call(entry, extra_args=extra),
                    "too many positional arguments",
                    shown,
                )
                n += 1
    return n


class _DummyCtx:
    """Enough of a Ctx to count an entry's positional arguments."""

    robot = None
    result = None
    tmp = __import__("pathlib").Path("/nonexistent")

    def drive(self) -> Any:
        return Z

    def out(self, name: str = "out") -> str:
        return "/nonexistent/out"


def _cheap_args(entry: Entry) -> bool:
    try:
        entry.args(_DummyCtx())
    except Exception:
        return False
    return True


# keywords from files: scenario and matrix keys (the dotted path and the suggestion)
_SCENARIO_KEYS: list[tuple[str, str, tuple[str, ...], bool]] = [
    ("top-duraton", "duraton = 1.0\n[initial]\npose = 'drive'\n", ("duraton", "'duration'"), False),
    (
        "top-descripton",
        "duration = 0.05\ndescripton = 'x'\n",
        ("descripton", "'description'"),
        False,
    ),
    ("top-failure", "[failure]\njoint = 'shoulder'\n", ("failure", "'failures'"), True),
    ("top-controler", "[controler]\nkind = 'pd'\n", ("controler", "'controller'"), True),
    (
        "initial-poses",
        "duration = 0.05\n[initial]\nposes = 'drive'\n",
        ("initial.poses", "'pose'"),
        False,
    ),
    (
        "config-restitutio",
        "[config]\nrestitutio = 0.5\n",
        ("config.restitutio", "'restitution'"),
        True,
    ),
    (
        "config-contact_mod",
        "[config]\ncontact_mod = 'none'\n",
        ("config.contact_mod", "'contact_mode'"),
        True,
    ),
    (
        "config-Restitution",
        "[config]\nRestitution = 0.5\n",
        ("config.Restitution", "'restitution'"),
        True,
    ),
    ("config-sampl_dt", "[config]\nsampl_dt = 0.01\n", ("config.sampl_dt", "'sample_dt'"), True),
    (
        "config-locked_joint",
        "[config]\nlocked_joint = ['camera_tilt']\n",
        ("config.locked_joint", "'locked_joints'"),
        True,
    ),
    (
        "failure-joints",
        "[[failures]]\njoints = 'shoulder'\nkind = 'loose'\n",
        ("failures[0].joints", "'joint'"),
        True,
    ),
    (
        "failure-knd",
        "[[failures]]\njoint = 'shoulder'\nknd = 'loose'\n",
        ("failures[0].knd", "'kind'"),
        True,
    ),
    (
        "failure-missing-joint-and-kind",
        "[[failures]]\nt = 0.5\n",
        ("failures[0].joint",),
        True,
    ),
    ("payload-mas", "[payload]\nmas = 1.0\n", ("payload.mas", "'mass'"), True),
    (
        "payload-frme",
        "[payload]\nmass = 1.0\nfrme = 'gripper_tool'\n",
        ("payload.frme", "'frame'"),
        True,
    ),
    ("controller-kpp", "[controller]\nkind = 'pd'\nkpp = 5.0\n", ("controller.kpp", "'kp'"), True),
    (
        "controller-omga",
        "[controller]\nkind = 'pd'\nomga = 5.0\n",
        ("controller.omga", "'omega'"),
        True,
    ),
    (
        "controller-waypoint",
        "[controller]\nkind = 'computed_torque'\nwaypoint = ['drive', 'stand']\n",
        ("controller.waypoint", "'waypoints'"),
        True,
    ),
    (
        "controller-fram",
        "[controller]\nkind = 'cartesian'\ntarget = [1.0, 0.0, 1.0]\nfram = 'gripper_tool'\n",
        ("controller.fram", "'frame'"),
        True,
    ),
    (
        "controller-speed_fractio",
        "[controller]\nkind = 'reconfig'\ntarget = [0.7, 0.4, 0.2]\nspeed_fractio = 0.5\n",
        ("controller.speed_fractio", "'speed_fraction'"),
        True,
    ),
    (
        "controller-sensor-seeds",
        "[controller]\nkind = 'pd'\nsensor = { seeds = 1 }\n",
        ("controller.sensor.seeds", "'seed'"),
        True,
    ),
    (
        "environment-obstacle",
        "[environment]\nobstacle = []\n",
        ("environment.obstacle", "'obstacles'"),
        True,
    ),
    ("environment-flor", "[environment]\nflor = true\n", ("environment.flor", "'floor'"), True),
    (
        "obstacle-sise",
        "[[environment.obstacles]]\nname = 'crate'\nkind = 'box'\nsise = [1, 1, 1]\n",
        ("environment.obstacles[0].sise", "'size'"),
        True,
    ),
    (
        "obstacle-nme",
        "[[environment.obstacles]]\nnme = 'crate'\nkind = 'box'\nsize = [1, 1, 1]\n",
        ("environment.obstacles[0].nme", "'name'"),
        True,
    ),
    (
        "obstacle-missing-kind",
        "[[environment.obstacles]]\nname = 'crate'\nsize = [1, 1, 1]\n",
        ("environment.obstacles[0].kind",),
        True,
    ),
    ("outputs-plot", "[outputs]\nplot = ['joints']\n", ("outputs.plot", "'plots'"), True),
    ("outputs-joint", "[outputs]\njoint = ['shoulder']\n", ("outputs.joint", "'joints'"), True),
    ("outputs-format", "[outputs]\nformat = ['png']\n", ("outputs.format", "'formats'"), True),
    (
        "occlusion-target",
        "[outputs.occlusion]\ntarget = [[1.0, 0.0, 0.0]]\n",
        ("outputs.occlusion.target", "'targets'"),
        True,
    ),
    (
        "occlusion-radus",
        "[outputs.occlusion]\ntargets = [[1.0, 0.0, 0.0]]\nradus = 0.1\n",
        ("outputs.occlusion.radus", "'radius'"),
        True,
    ),
    (
        "occlusion-missing-targets",
        "[outputs.occlusion]\nradius = 0.1\n",
        ("outputs.occlusion.targets",),
        True,
    ),
]
_MATRIX_KEYS: list[tuple[str, str, tuple[str, ...], type]] = [
    ("axs", "[axs]\n'config.restitution' = [0.0]\n", ("axs", "'axes'"), UnknownNameError),
    ("sets", "[sets]\nduration = 0.02\n", ("sets", "'set'"), UnknownNameError),
    (
        "tolerance",
        "[axes]\n'config.restitution' = [0.0]\n[tolerance]\nq = 1e-6\n",
        ("tolerance", "'tolerances'"),
        UnknownNameError,
    ),
    (
        "includes",
        "[axes]\n'config.restitution' = [0.0]\n[[includes]]\n'config.restitution' = 0.5\n",
        ("includes", "'include'"),
        UnknownNameError,
    ),
    (
        "set-descripton",
        "descripton = 'x'\n[axes]\n'config.restitution' = [0.0]\n",
        ("descripton", "'description'"),
        ConfigurationError,
    ),
    (
        "axis-config-restitutio",
        "[axes]\n'config.restitutio' = [0.0, 0.5]\n",
        ("config.restitutio", "'restitution'"),
        ConfigurationError,
    ),
    (
        "axis-initial-poses",
        "[axes]\n'initial.poses' = ['drive', 'stand']\n",
        ("initial.poses", "'pose'"),
        ConfigurationError,
    ),
    (
        "set-config-mu_",
        "config.muu = 0.3\n[axes]\n'config.restitution' = [0.0]\n",
        ("config.muu", "'mu'"),
        ConfigurationError,
    ),
    (
        "tolerances-qq",
        "[axes]\n'config.restitution' = [0.0]\n[tolerances]\nqq = 1e-6\n",
        ("qq", "'q'"),
        UnknownNameError,
    ),
    (
        "axis-failure-knd",
        "[axes]\n'failures.0.knd' = ['loose']\n'failures.0.joint' = ['elbow1']\n",
        ("knd", "'kind'"),
        ConfigurationError,
    ),
]
_STUDY_MATRIX = (
    'base = "frozen_elbow_reach"\n[set]\nduration = 2.5\n'
    "[axes]\n'failures.0.joint' = ['elbow1']\n"
)
_CLI_OPTIONS: list[tuple[str, list[str], str, str]] = [
    ("run-duraton", ["run", "collapse", "--duraton", "1"], "--duraton", "'--duration'"),
    ("run-overwirte", ["run", "collapse", "--overwirte"], "--overwirte", "'--overwrite'"),
    (
        "batch-workrs",
        ["batch", "collapse-small", "--out", "out", "--workrs", "1"],
        "--workrs",
        "'--workers'",
    ),
    (
        "batch-timout",
        ["batch", "collapse-small", "--out", "out", "--timout", "1"],
        "--timout",
        "'--timeout'",
    ),
    ("regress-upadte", ["regress", "collapse-small", "--upadte"], "--upadte", "'--update'"),
    ("show-prot", ["show", "--prot", "8000"], "--prot", "'--port'"),
    ("collapse-moed", ["collapse", "--moed", "none"], "--moed", "'--mode'"),
    ("generate-srdf-smaples", ["generate-srdf", "--smaples", "5"], "--smaples", "'--samples'"),
]


def _register_files(cat: ModuleType) -> int:
    n = 0
    for id, text, words, base in _SCENARIO_KEYS:
        cat.add(
            "keywords", f"scenario-{id}", cat.scn(text, base=base), *words, error=ConfigurationError
        )
        n += 1
    for id, text, words, _base in _SCENARIO_KEYS[:12]:

        def argv(c: Any, text: str = text, base: bool = _base) -> list[str]:
            path = c.write("bad.toml", (cat.BASE_SCENARIO + "\n" + text) if base else text)
            return ["run", str(path), "--out", c.out()]

        cat.add("keywords", f"run-scenario-{id}", argv, *words, cli=True)
        n += 1
    for id, text, words, error in _MATRIX_KEYS:
        cat.add("keywords", f"matrix-{id}", cat.mtx(text), *words, error=error)
        n += 1
    for id, text, words in [
        ("top-nam", 'nam = "m"\n', ("nam", "'name'")),
        ("top-bse", 'bse = "collapse"\n', ("bse", "'base'")),
        ("top-descripton", 'descripton = "x"\n', ("descripton", "'description'")),
    ]:
        body = text + cat.BASE_MATRIX + "[axes]\n'config.restitution' = [0.0]\n"
        cat.add(
            "keywords", f"matrix-{id}", cat.mtx(body, base=False), *words, error=UnknownNameError
        )
        n += 1
    for id, text, words, _error in _MATRIX_KEYS[:6]:

        def margv(c: Any, text: str = text) -> list[str]:
            path = c.write("m.toml", cat.BASE_MATRIX + text)
            return ["batch", str(path), "--out", c.out(), "--workers", "0", "--no-progress"]

        cat.add("keywords", f"batch-matrix-{id}", margv, *words, cli=True)
        n += 1

    def study_matrix(text: str) -> Callable[[Any], Any]:
        def action(c: Any) -> Any:
            from packbot.study_matrix import load_study_matrix

            return load_study_matrix(c.write("sm.toml", _STUDY_MATRIX + text))

        return action

    for id, text, words in [
        ("tolerence", "[study]\ntolerence = 0.01\n", ("tolerence", "'tolerance'")),
        (
            "workspace_sample",
            "[study]\nworkspace_sample = 100\n",
            ("workspace_sample", "'workspace_samples'"),
        ),
        (
            "failure-knd",
            "'failures.0.knd' = ['frozen']\n[study]\ntolerance = 0.01\n",
            ("knd", "'kind'"),
        ),
    ]:
        cat.add("keywords", f"study-matrix-{id}", study_matrix(text), *words, error=PackbotErrorT)
        n += 1
    for id, argv_list, wrong, right in _CLI_OPTIONS:
        cat.add("keywords", f"cli-{id}", lambda c, a=argv_list: list(a), wrong, right, cli=True)
        n += 1
    return n


PackbotErrorT = packbot.PackbotError


def register(cat: ModuleType) -> None:
    """Add the ``keywords`` cases to the catalogue (``tests/bad_input_cases.py``)."""
    _register_api(cat)
    _register_files(cat)
