"""First-run cost of the contact-normal mode's compiled kernels (numba), and the cached cost.

:mod:`packbot.contact.kernels` is compiled by numba on a machine's first contact-normal run
and cached on disk. This script runs, in fresh processes, the same short contact-normal
collapse (0.3 s simulated, mu 0.5, wrist locked) with an empty numba cache (``NUMBA_CACHE_DIR``
pointing at a new temporary folder: the first run on a new machine), then again with that
cache filled, and prints each process's phases: ``import packbot``, importing the kernels
(numba and its cache index), and the run itself. Medians over ``--runs`` fresh processes each.

    python benchmarks/compile_time.py [--runs N]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = """
import json, time
t0 = time.perf_counter()
import numpy as np
import packbot
t1 = time.perf_counter()
from packbot.contact import kernels
t2 = time.perf_counter()
robot = packbot.load_robot()
cfg = packbot.SimConfig(
    contact_mode="normal", mu=0.5,
    locked_joints=["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"],
)
t3 = time.perf_counter()
packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.3, config=cfg)
t4 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "kernels": t2 - t1, "run": t4 - t3}))
"""


def _child(cache: str) -> dict[str, float]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    out = subprocess.run(
        [sys.executable, "-c", CHILD], env=env, check=True, capture_output=True, text=True
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="fresh processes per row")
    args = ap.parse_args()
    cold: list[dict[str, float]] = []
    warm: list[dict[str, float]] = []
    for _ in range(args.runs):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(_child(cache))  # empty cache: compiles
            warm.append(_child(cache))  # the cache just written
    print(f"contact-normal collapse, 0.3 s simulated; medians of {args.runs} fresh processes")
    print("| numba cache | import packbot [s] | import kernels [s] | run [s] |")
    print("|---|---|---|---|")
    for name, rows in (("empty (first run on a machine)", cold), ("filled", warm)):
        med = {k: statistics.median(r[k] for r in rows) for k in ("import", "kernels", "run")}
        print(f"| {name} | {med['import']:.2f} | {med['kernels']:.2f} | {med['run']:.2f} |")


if __name__ == "__main__":
    main()
