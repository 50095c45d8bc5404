"""The cost of ``packbot.sample_robots(n)`` per arm, and of using each arm.

Run: ``python benchmarks/sample_robots.py``. Prints a Markdown table: for each n, the wall time
of drawing the values alone (``sample_values``), of building the arms (``sample_robots``: the
design, its URDF and meshes written to a temporary folder, ``load_robot``), per arm, and of one
arm's first collision world and a 0.3 s collapse under the report's law (its first run includes
the collision world's build). The figures depend on the machine and its load; docs/model.md
quotes one run.
"""

from __future__ import annotations

import logging
import time

import numpy as np

import packbot

log = logging.getLogger("sample_robots")

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    packbot.sample_robots(1, seed=0)  # warm-up: imports, the nominal efforts and volumes
    config = packbot.SimConfig(contact_mode="joint_clamp", locked_joints=WRIST)
    log.info("| n | values [ms] | arms [s] | per arm [ms] | world + 0.3 s collapse per arm [ms] |")
    log.info("|---|---|---|---|---|")
    for n in (1, 8, 32, 128):
        t0 = time.perf_counter()
        packbot.sample_values(n, seed=n)
        t_values = time.perf_counter() - t0
        t0 = time.perf_counter()
        arms = packbot.sample_robots(n, seed=n)
        t_arms = time.perf_counter() - t0
        runs = []
        for arm in list(arms)[:8]:
            t0 = time.perf_counter()
            packbot.CollisionWorld(arm)
            packbot.simulate(arm, arm.pose("drive"), np.zeros(8), 0.3, config=config)
            runs.append(time.perf_counter() - t0)
        log.info(
            "| %d | %.1f | %.2f | %.0f | %.0f |",
            n,
            1e3 * t_values,
            t_arms,
            1e3 * t_arms / n,
            1e3 * float(np.median(runs)),
        )


if __name__ == "__main__":
    main()
