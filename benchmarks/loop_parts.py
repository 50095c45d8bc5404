"""Where a run's time goes, by the event loop's parts: collapses, random starts, a controlled run.

    python benchmarks/loop_parts.py                  # every table: 5 collapses of each law,
                                                     # 2 wrist-free random starts, one 60 s run
    python benchmarks/loop_parts.py --duration 10    # reconfig_elbow1 for 10 s only

The tables: the joint_clamp collapse (5 s from "drive", wrist locked); the contact-normal
collapse (the same, mu 0.5: ``benchmarks/peers.py``'s); the contact-normal mode from the
wrist-free random starts 16 and 21 of ``benchmarks/robustness.py`` (seed 2026, mu 0,
restitution 0, 3 s each: event storms and time-stepping windows); ``reconfig_elbow1``.

Timers (``time.perf_counter``) are put around the loop's parts of one run object (the stepper's
steps, the law's end-of-step checks and its collision sweeps, the samples, the event handling,
the ticks and the controller's ``step``; for the contact-normal mode also its stretches of steps in
one native call, the events' location and restarts, the re-patches after a step, and the
windows' steps: the native runs of steps that keep their contact set, and the steps taken one
by one, split by whether the step changed its contact set: a patch rebuilt, a pair or a
limit in or out); each part's time
includes the parts it calls, so the shares of the nested rows (the sweep inside the checks, the
controller inside the ticks) are not added to their parent's. Each row also gives its calls and
the time per call. The timers cost about 0.3 us a call; the table's shares are what
compares (on a loaded machine the wall times grow, the shares much less). Also printed: the CPU
time of the run without timers (median of the repeats).
"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from robustness import start_poses  # (benchmarks/: the script's folder, first on sys.path)

import packbot
from packbot import integrator
from packbot.collision import CollisionWorld
from packbot.contact import normal_law
from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.timestep import MoreauJeanStepper
from packbot.scenario import load_scenario

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
#: (label, how to reach the object from the run, method name); nested rows are indented.
PARTS = (
    ("building the run", None, "__init__"),
    ("steps (stepper, right-hand sides)", "stepper", "step"),
    ("stretches of steps in one native call", "law", "stretch"),
    ("end-of-step checks (watch)", "law", "watch"),
    ("  the collision sweeps", "CollisionWorld", "sweep"),
    ("samples", "rec", "record"),
    ("events' location", None, "locate"),
    ("events' handling", "law", "handle"),
    ("  the contact set's restarts", "NormalContacts", "restart"),
    ("after-step work (re-patches, windows' ends)", "law", "after_step"),
    ("  the contact set's re-patches", "NormalContacts", "repatch"),
    ("windows' steps", "law", "advance"),
    ("  native runs of kept steps", "normal_law", "run_native"),
    ("  keeping their contact set", "MoreauJeanStepper", "step"),
    ("  changing it (a patch rebuilt, a pair in or out)", "MoreauJeanStepper", "step"),
    ("stepper restarts", "stepper", "reset"),
    ("ticks inside held steps", "ticks", "inside"),
    ("  the controller's step()", "ctrl_obj", "step"),
    ("ticks that change the command", None, "cut_at_tick"),
    ("scheduled actions (ticks at a step's end)", None, "run_scheduled"),
)


#: The rows timed at their class (every phase's object) or module, not at the run's attributes.
CLASSES: dict[str, Any] = {
    "normal_law": normal_law,
    "CollisionWorld": CollisionWorld,
    "NormalContacts": NormalContacts,
    "MoreauJeanStepper": MoreauJeanStepper,
}


def _timed(acc: dict[str, float], label: str, f: Callable[..., Any]) -> Callable[..., Any]:
    def w(*a: Any, **k: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            acc[label] = acc.get(label, 0.0) + time.perf_counter() - t0
            acc[label + "#"] = acc.get(label + "#", 0) + 1

    return w


def _window_step(acc: dict[str, float], f: Callable[..., Any]) -> Callable[..., Any]:
    """A window's step timed into one of two rows: did it change its contact set?"""

    def w(self: Any, *a: Any, **k: Any) -> Any:
        version = self.contacts._version  # (changed by any patch built or pair removed)
        t0 = time.perf_counter()
        try:
            return f(self, *a, **k)
        finally:
            kept = self.contacts._version == version
            label = (
                "  keeping their contact set"
                if kept
                else "  changing it (a patch rebuilt, a pair in or out)"
            )
            acc[label] = acc.get(label, 0.0) + time.perf_counter() - t0
            acc[label + "#"] = acc.get(label + "#", 0) + 1

    return w


def measured(run_once: Callable[[], Any]) -> tuple[float, dict[str, float]]:
    """(wall [s], part -> time [s]) of one run with the timers in place."""
    acc: dict[str, float] = {}
    orig_init = integrator._Run.__init__

    def init(self: Any, *a: Any, **k: Any) -> None:
        t0 = time.perf_counter()
        orig_init(self, *a, **k)
        acc["building the run"] = time.perf_counter() - t0
        for label, path, name in PARTS[1:]:
            if path in CLASSES:
                continue  # every phase's object: timed at the class (below)
            obj: Any = self
            for attr in path.split(".") if path else ():
                obj = getattr(obj, attr, None)
            if obj is not None and hasattr(obj, name):
                setattr(obj, name, _timed(acc, label, getattr(obj, name)))
        # the stepper keeps its own reference to the right-hand side: nothing to rewire

    integrator._Run.__init__ = init  # type: ignore[method-assign]
    saved: list[tuple[type, str, Any]] = []
    for label, path, name in PARTS:
        cls = CLASSES.get(path or "")
        if cls is None or any(c is cls and n == name for c, n, _ in saved):
            continue  # (the window steps' two rows share one wrapper)
        f = getattr(cls, name)
        saved.append((cls, name, f))
        setattr(
            cls, name, _window_step(acc, f) if cls is MoreauJeanStepper else _timed(acc, label, f)
        )
    try:
        t0 = time.perf_counter()
        run_once()
        wall = time.perf_counter() - t0
    finally:
        integrator._Run.__init__ = orig_init  # type: ignore[method-assign]
        for cls, name, f in saved:
            setattr(cls, name, f)
    return wall, acc


def cpu_time(run_once: Callable[[], Any], repeats: int) -> float:
    """Median CPU time [s] of the run without timers."""
    out = []
    for _ in range(repeats):
        c0 = time.process_time()
        run_once()
        out.append(time.process_time() - c0)
    return float(np.median(out))


def table(title: str, run_once: Callable[[], Any], repeats: int) -> None:
    run_once()  # warm: imports, caches
    cpu = cpu_time(run_once, repeats)
    wall, acc = measured(run_once)
    print(f"\n{title}: CPU time without timers {cpu * 1e3:.1f} ms (median of {repeats})")
    print(f"{'part':48s} {'time [ms]':>10s} {'share':>7s} {'calls':>7s} {'per call [us]':>14s}")
    for label, _, _ in PARTS:
        if label in acc:
            n = int(acc.get(label + "#", 1))
            per = acc[label] / n * 1e6
            print(
                f"{label:48s} {acc[label] * 1e3:10.1f} {acc[label] / wall:7.1%} {n:7d} {per:14.1f}"
            )
    print(f"{'the whole run (with timers)':48s} {wall * 1e3:10.1f}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=60.0, help="reconfig_elbow1: simulated [s]")
    ap.add_argument("--repeats", type=int, default=5, help="collapse runs (CPU time median)")
    args = ap.parse_args(argv)
    robot = packbot.load_robot()
    cfg = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    q0, v0 = robot.pose("drive"), np.zeros(robot.nq)

    def collapse() -> Any:
        return packbot.simulate(robot, q0, v0, 5.0, config=cfg)

    normal = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)

    def normal_collapse() -> Any:
        return packbot.simulate(robot, q0, v0, 5.0, config=normal)

    free = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    starts = start_poses(robot, 22, 2026, 2 * free.contact_tolerance)

    def random_starts() -> Any:
        quiet = logging.getLogger("packbot")
        level = quiet.level
        quiet.setLevel(logging.ERROR)  # (mu = 0's warning, once a run)
        try:
            for k in (16, 21):
                packbot.simulate(robot, starts[k].copy(), v0, 3.0, config=free)
        finally:
            quiet.setLevel(level)

    sc = load_scenario("reconfig_elbow1")

    def reconfig() -> Any:
        q, v = sc.initial_state(robot)
        return packbot.simulate(
            robot,
            q,
            v,
            args.duration,
            controller=sc.build_controller(robot),
            environment=sc.environment,
            config=sc.config,
            failures=list(sc.failures),
            inform_controller=sc.inform_controller,
        )

    table("joint_clamp collapse, 5 s", collapse, args.repeats)
    table("contact-normal collapse, mu 0.5, 5 s", normal_collapse, args.repeats)
    table("contact-normal, wrist-free random starts 16 and 21, mu 0, 3 s each", random_starts, 1)
    table(f"reconfig_elbow1, {args.duration:g} s", reconfig, 1)


if __name__ == "__main__":
    main()
