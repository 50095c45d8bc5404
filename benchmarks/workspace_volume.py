"""Workspace volume against the sample count: the voxel count of the samples (grows) against the
Monte Carlo reachable volume (converges, with its standard error).

Run: ``python benchmarks/workspace_volume.py [URDF]``. Prints two tables (Markdown) for the
healthy arm and elbow1 frozen at -0.912 rad (where sims/reconfig_elbow1.toml freezes it), and
the IK recall on held-out samples (reachable by construction).
"""

from __future__ import annotations

import logging
import sys
import time
import warnings

import numpy as np

import packbot
from packbot.analysis import reachable, reachable_volume, workspace

log = logging.getLogger("workspace_volume")

FROZEN = ("elbow1", -0.912)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    robot = packbot.load_robot(sys.argv[1] if len(sys.argv) > 1 else None)
    log.info("| case | samples | voxel count (5 cm) [m^3] | reachable volume [m^3] | points | s |")
    log.info("|---|---|---|---|---|---|")
    for name, frozen in (("healthy", None), ("elbow1 frozen", FROZEN)):
        for n in (2000, 5000, 20000, 80000):
            ws = workspace(robot, frozen, samples=n, seed=0)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                vox = ws.volume()
            t0 = time.perf_counter()
            est = reachable_volume(robot, ws, rel_tol=0.03, seed=1)
            dt = time.perf_counter() - t0
            log.info(
                "| %s | %d | %.3f | %.3f +- %.3f | %d | %.0f |",
                name,
                n,
                vox,
                est.volume_m3,
                est.stderr_m3,
                est.samples,
                dt,
            )
        ws = workspace(robot, frozen, samples=20000, seed=0)
        for seeds in (4, 16):
            est = reachable_volume(robot, ws, rel_tol=0.01, seeds=seeds, seed=3)
            log.info("%s, 20000 samples, rel_tol 1 %%, %d IK seeds: %s", name, seeds, est)
        ws = workspace(robot, frozen, samples=5000, seed=0)
        held = workspace(robot, frozen, samples=400, seed=99)
        ok = reachable(robot, ws, held.points)
        log.info("%s: IK recall on %d held-out samples: %.3f", name, len(ok), float(np.mean(ok)))


if __name__ == "__main__":
    main()
