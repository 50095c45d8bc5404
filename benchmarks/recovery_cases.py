"""The built-in recovery on the testbed's cases (issue 36): failed vs the strategy's run vs kept.

Run by hand (about 15 minutes on 2 busy cores; ``--quick`` skips the weak-shoulder matrix):

    python benchmarks/recovery_cases.py [--quick] [--cases weak-4s,weak-6s,...]

Each case is one :func:`packbot.study` of the user's reach (tests/testbed_user.py's ``Reach``:
computed torque, drive pose to (1.2, 0, 1.0) m in 3 s, elbow up) with ``recovery="builtin"``:
elbow2 weak at 25 % from 1.5 s (4 s and 6 s simulated), with a declared 2 kg payload picked up
at 1.0 s, with a box in the path, elbow2 stuck at -20 N*m, elbow1 frozen at 1.0 s then elbow2
weak, and the weak shoulder over scale 0.3 / 0.4 / 0.5 x failure time 0.5 / 1.0 / 1.5 s (3.5 s,
contact-normal mode, mu = 0.5). Prints one Markdown table: the final distance of gripper_tool
from the task [mm] of the unaware (failed) run, of the strategy's own run, and of the run the
study keeps (the better of the two), whether the strategy's run was applied, the first
detection, and the strategy's note (what it did), with the wall time of each study.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import testbed_user  # the user's controller, from tests/

import packbot
from packbot.environment import Environment, Obstacle
from packbot.failures import Failure
from packbot.payload import Payload
from packbot.scenario import Scenario, scenario_from_dict

BASE = {
    "description": "computed-torque reach drive -> (1.2, 0, 1.0) m, elbow2 weak 25 % from 1.5 s",
    "duration": 4.0,
    "initial": {"pose": "drive"},
    "config": {"locked_joints": ["gripper_jaw"]},
    "failures": [{"joint": "elbow2", "kind": "weak", "t": 1.5, "scale": 0.25}],
}


def cases() -> dict[str, Scenario]:
    """The testbed's cases by name (tests/test_testbed.py's, and the 6 s run)."""
    sc = scenario_from_dict(BASE, name="weak_reach")
    weak = Failure(joint="elbow2", kind="weak", t=1.5, scale=0.25)
    box = Obstacle(name="box", kind="box", size=(0.1, 0.1, 0.1), xyz=(0.40, 0.07, 1.80))
    out = {
        "weak-4s": sc,
        "weak-6s": dataclasses.replace(sc, duration=6.0),
        "payload": dataclasses.replace(sc, payload=Payload(mass=2.0, t_pick=1.0)),
        "box": dataclasses.replace(sc, environment=Environment(obstacles=(box,))),
        "stuck": dataclasses.replace(
            sc, failures=(Failure(joint="elbow2", kind="stuck", t=1.5, torque=-20.0),)
        ),
        "frozen-elbow1+weak-elbow2": dataclasses.replace(
            sc, failures=(Failure(joint="elbow1", kind="frozen", t=1.0), weak)
        ),
    }
    normal = dataclasses.replace(sc.config, contact_mode="normal", mu=0.5)
    for scale in (0.3, 0.4, 0.5):
        for t in (0.5, 1.0, 1.5):
            out[f"shoulder-{scale:g}@{t:g}s"] = dataclasses.replace(
                sc,
                duration=3.5,
                config=normal,
                failures=(Failure(joint="shoulder", kind="weak", t=t, scale=scale),),
            )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the weak-shoulder matrix")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    args = ap.parse_args()
    robot = packbot.load_robot()
    chosen = cases()
    if args.cases:
        chosen = {k: chosen[k] for k in args.cases.split(",")}
    elif args.quick:
        chosen = {k: v for k, v in chosen.items() if not k.startswith("shoulder")}
    print(
        "| case | simulated [s] | failed [mm] | strategy's run [mm] | kept [mm] | applied | "
        "detected | strategy's note | wall [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, sc in chosen.items():
        t0 = time.perf_counter()
        res = packbot.study(
            sc,
            robot=robot,
            controller=testbed_user.Reach,
            recovery="builtin",
            workspace_samples=300,
        )
        wall = time.perf_counter() - t0
        own = res.attempt if res.attempt is not None else res.reconfigured
        fm, om, km = res.failed.metrics, own.metrics, res.reconfigured.metrics
        assert fm is not None and om is not None and km is not None
        dec = res.reconfiguration
        applied = "-" if dec is None else ("yes" if dec.applied else "no")
        det = ", ".join(
            f"{e.joint} {e.detection.kind if e.detection else '?'} {e.t:.3f} s"
            for e in res.reconfigured.detections
        )
        notes = "; ".join(
            e.detail for e in own.controller_log if e.kind in ("weak", "track", "loose")
        )
        print(
            f"| {name} | {res.duration_s:g} | {fm.final_task_error_m * 1000:,.1f} | "
            f"{om.final_task_error_m * 1000:,.1f} | {km.final_task_error_m * 1000:,.1f} | "
            f"{applied} | {det or 'none'} | {notes or '-'} | {wall:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
