"""A refactor changes no result: every array of many runs compared exactly, before and after.

    python benchmarks/bit_identity.py record /tmp/before      # on the old code
    python benchmarks/bit_identity.py record /tmp/after       # on the new code
    python benchmarks/bit_identity.py compare /tmp/before /tmp/after
    python benchmarks/bit_identity.py compare-batch /tmp/base-small /tmp/new-small

``record`` runs every scenario in sims/*.toml for its full duration and 40 more runs that reach
what the scenarios do not (the hand-off, joint friction and brakes under the report's law, the
contact-normal mode with restitution, without friction, all joints free, a frozen joint; random
starts in each contact mode; runs stopped by ``max_events``, whose partial result is kept; a
motor lag with a torque function) and saves, per run, t, q, v, the torques, the energy, every
event's fields, the diagnostics' counters (not the wall time) and the error of a run that
failed. ``compare`` says which arrays differ (``np.array_equal``, NaN equal to NaN: zero
tolerance). ``compare-batch`` does the same for two output folders of ``packbot batch`` (every
trajectory array, event file and run record but its wall time and checksum). Extra arguments to
``record`` keep only the runs whose names start with one of them. About 80 s on one core.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

import packbot
from packbot.scenario import load_scenario, run_scenario, scenario_path

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
SIMS = scenario_path("collapse").parent


def dump(res):
    out = {}
    for k in ("t", "q", "v", "tau", "energy", "tau_cmd", "tau_friction", "effort"):
        val = getattr(res, k, None)
        if val is not None:
            out[k] = np.asarray(val)
    ev = res.events
    out["ev_t"] = np.array([e.t for e in ev], dtype=float)
    out["ev_kind"] = np.array([e.kind for e in ev], dtype=str)
    out["ev_names"] = np.array(
        ["|".join([e.link1, e.link2, e.piece1, e.piece2, " ".join(e.relevant_joints)]) for e in ev],
        dtype=str,
    )
    out["ev_d"] = np.array([e.distance for e in ev], dtype=float)
    out["ev_vb"] = np.array([e.v_before for e in ev], dtype=float)
    out["ev_va"] = np.array([e.v_after for e in ev], dtype=float)
    out["ev_e"] = np.array([[e.energy_before, e.energy_after] for e in ev], dtype=float)
    diag = {k: v for k, v in vars(res.diagnostics).items() if k != "wall_time"}
    out["diag"] = np.array(json.dumps(diag, sort_keys=True, default=str))
    out["rest"] = np.array(np.nan if res.rest_time is None else res.rest_time)
    out["ticks"] = np.array(res.control_ticks)
    return out


def _ramp_env():
    ramp = packbot.Obstacle(
        name="ramp", kind="box", size=(0.6, 0.8, 0.5), xyz=(1.3, 0.0, 0.2), rpy=(-0.5, 0.0, 0.0)
    )
    return packbot.Environment().with_obstacles(ramp)


def _push_back(t, q, v):
    tau = np.zeros(8)
    tau[0] = -3.0 if t > 0.2 else 0.0
    return tau


def runs(robot):
    """Name -> a function returning the run's SimResult."""
    out = {}
    for f in sorted(SIMS.glob("*.toml")):
        out[f.stem] = lambda name=f.stem: run_scenario(load_scenario(name), robot)
    drive = robot.pose("drive")
    sim = packbot.simulate
    locked = tuple(n for n in robot.joint_names if n not in ("turret", "shoulder"))
    v0 = np.zeros(8)
    v0[0], v0[1] = 0.15, -0.3
    for flag in (False, True):
        cfg = packbot.SimConfig(
            contact_mode="joint_clamp",
            locked_joints=locked,
            clamp_rule="velocity",
            mu=0.0,  # frictionless: the handed-off finger slides down the ramp
            handoff=flag,
        )
        out[f"x_ramp_handoff{int(flag)}"] = lambda cfg=cfg: sim(
            robot,
            robot.pose("stand"),
            v0,
            1.0,
            environment=_ramp_env(),
            controller=_push_back,
            config=cfg,
        )
        cfg = packbot.SimConfig(
            contact_mode="joint_clamp",
            locked_joints=WRIST,
            reset_rule="momentum",
            restitution=0.3,
            mu=0.5,
            handoff=flag,
        )
        out[f"x_collapse_handoff{int(flag)}"] = lambda cfg=cfg: sim(
            robot, drive, np.zeros(8), 2.4, config=cfg
        )
    brake = [packbot.Failure(joint="elbow1", t=0.3, kind="brake")]
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST, joint_friction=True)
    out["x_clamp_friction"] = lambda: sim(
        robot, drive, np.zeros(8), 2.0, config=cfg, failures=brake
    )
    cfg2 = packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=WRIST,
        joint_friction=True,
        restitution=0.5,
        reset_rule="momentum",
    )
    out["x_clamp_friction_e05"] = lambda: sim(
        robot, robot.pose("stand"), np.zeros(8), 2.0, config=cfg2
    )
    for name, kw, pose, duration in [
        ("x_normal_e03", {"restitution": 0.3, "mu": 0.5, "locked_joints": WRIST}, "drive", 2.0),
        ("x_normal_mu0", {"mu": 0.0, "locked_joints": WRIST}, "drive", 1.5),
        ("x_normal_stand", {"mu": 0.8, "locked_joints": WRIST}, "stand", 2.0),
        ("x_normal_high_free", {"mu": 0.5}, "high", 1.5),
        ("x_normal_loose", {"mu": 0.5, "locked_joints": WRIST}, "drive", 1.5),
    ]:
        c = packbot.SimConfig(contact_mode="normal", **kw)
        fl = [packbot.Failure(joint="shoulder", t=0.2, kind="frozen")] if "loose" in name else []
        out[name] = lambda c=c, pose=pose, d=duration, fl=fl: sim(
            robot, robot.pose(pose), np.zeros(8), d, config=c, failures=fl
        )
    for name, kw, duration, ctrl in [
        ("x_maxev_clamp", {"contact_mode": "joint_clamp", "max_events": 2}, 1.0, None),
        ("x_maxev_normal", {"contact_mode": "normal", "mu": 0.5, "max_events": 40}, 2.0, None),
        (
            "x_maxev_handoff",
            {
                "contact_mode": "joint_clamp",
                "reset_rule": "momentum",
                "restitution": 0.3,
                "mu": 0.5,
                "handoff": True,
                "max_events": 60,
            },
            2.4,
            None,
        ),
        ("x_maxev_none", {"contact_mode": "none", "restitution": 0.5, "max_events": 6}, 3.0, None),
        (
            "x_lag_fn",
            {"contact_mode": "joint_clamp", "motor_lag": 0.02, "joint_friction": True},
            1.5,
            lambda t, q, v: -20.0 * v,
        ),
    ]:
        c = packbot.SimConfig(locked_joints=WRIST, **kw)
        out[name] = lambda c=c, d=duration, ctrl=ctrl: sim(
            robot, drive, np.zeros(8), d, config=c, controller=ctrl
        )
    rng = np.random.default_rng(16)
    lo, hi = robot.params.lower, robot.params.upper
    world = packbot.CollisionWorld(robot, packbot.Environment())
    wrist = [robot.params.index(n) for n in WRIST]
    starts = []
    while len(starts) < 8:
        q0 = lo + (hi - lo) * rng.random(8)
        q0[wrist] = drive[wrist]
        if world.sweep(q0).min_distance > 0.0:
            starts.append(q0)
    for i, q0 in enumerate(starts):
        for mode in ("none", "joint_clamp", "normal"):
            c = packbot.SimConfig(
                contact_mode=mode,
                locked_joints=WRIST,
                restitution=0.3 if i % 2 else 0.0,
                mu=0.5,
                reset_rule="momentum" if i % 3 == 0 else "zero",
            )
            out[f"x_rand{i}_{mode}"] = lambda c=c, q0=q0: sim(robot, q0, np.zeros(8), 1.5, config=c)
    return out


def record(folder, only):
    Path(folder).mkdir(parents=True, exist_ok=True)
    for name, fn in runs(packbot.load_robot()).items():
        if only and not any(name.startswith(o) for o in only):
            continue
        wall = time.perf_counter()
        try:
            arrays = dump(fn())
            arrays["error"] = np.array("")
        except packbot.PackbotError as exc:
            arrays = {"error": np.array(f"{type(exc).__name__}: {exc}")}
            if getattr(exc, "result", None) is not None:
                arrays.update(dump(exc.result))
        np.savez(Path(folder) / f"{name}.npz", **arrays)
        print(f"{name}: {time.perf_counter() - wall:.1f} s, {len(arrays.get('ev_t', []))} events")


def _equal(x, y):
    if x.shape != y.shape:
        return False
    return np.array_equal(x, y, equal_nan=x.dtype.kind == "f")


def compare(base, new):
    n_runs = n_arrays = n_bad = 0
    for f in sorted(Path(new).glob("*.npz")):
        a, b = np.load(Path(base) / f.name), np.load(f)
        n_runs += 1
        bad = sorted(set(a.files) ^ set(b.files))
        for k in set(a.files) & set(b.files):
            n_arrays += 1
            if not _equal(a[k], b[k]):
                bad.append(k)
        if bad:
            n_bad += 1
            print("DIFFERS", f.stem, bad)
    print(f"{n_runs} runs, {n_arrays} arrays compared: {n_bad} runs differ")
    return n_bad


def compare_batch(base, new):
    base, new = Path(base), Path(new)
    n_runs = n_arrays = n_bad = 0
    for f in sorted((new / "trajectories").glob("*.npz")):
        a, b = np.load(base / "trajectories" / f.name), np.load(f)
        n_runs += 1
        for k in a.files:
            n_arrays += 1
            if not _equal(a[k], b[k]):
                n_bad += 1
                print("DIFFERS", f.name, k)
        ev = f.name[:-4] + "_events.csv"
        if (base / "trajectories" / ev).read_text() != (new / "trajectories" / ev).read_text():
            n_bad += 1
            print("DIFFERS", ev)
        records = []
        for folder in (base, new):
            rec = json.loads((folder / "runs" / (f.name[:-4] + ".json")).read_text())
            for k in ("wall_time", "record_sha256", "worker"):
                rec.pop(k, None)
            records.append(rec)
        if records[0] != records[1]:
            n_bad += 1
            print("DIFFERS record", f.name[:-4])
    print(f"{n_runs} runs, {n_arrays} arrays, their event files and records: {n_bad} differ")
    return n_bad


if __name__ == "__main__":
    cmd, *args = sys.argv[1:]
    if cmd == "record":
        record(args[0], args[1:])
    elif cmd == "compare":
        sys.exit(1 if compare(*args) else 0)
    elif cmd == "compare-batch":
        sys.exit(1 if compare_batch(*args) else 0)
    else:
        sys.exit(__doc__)
