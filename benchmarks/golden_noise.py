"""How far other BLAS kernels move the golden results, against each run's measured noise.

Another machine rounds differently; on one machine, OpenBLAS's kernel choice
(``OPENBLAS_CORETYPE``) changes the order of the sums in numpy's linear algebra, which is the
same kind of difference. For each kernel this runs a matrix in a fresh process and prints, per
quantity, the largest ``|new - golden|``, its ratio to the run's measured noise (the spread of its
perturbed copies, stored in the golden file) and to the tolerance actually applied
(``max(absolute tolerance, NOISE_FACTOR * noise)``). Ratios to the tolerance below 1 mean the
regression passes with that kernel; docs/batch.md quotes the table.

    python benchmarks/golden_noise.py [MATRIX ...] [--kernels Prescott,Haswell,...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

KERNELS = ("Prescott", "Core2", "Nehalem", "Sandybridge", "Haswell", "SkylakeX", "Zen")


def child(matrix: str, out: str) -> None:
    from packbot.batch import run_batch
    from packbot.matrix import load_matrix
    from packbot.regress import read_trajectories

    m = load_matrix(matrix)
    rep = run_batch(m, out, workers=0)
    traj = read_trajectories(out, rep.records)
    data = {
        rid: {
            "final_q": list(r.final_q),
            "event_times": list(r.event_times),
            "event_kinds": list(r.event_kinds),
            "rest_time": r.rest_time,
            "min_distance": r.min_distance,
            "energy_change": r.energy_change,
            "status": r.status,
            "t": traj[rid][0].tolist() if rid in traj else [],
            "q": traj[rid][1].tolist() if rid in traj else [],
        }
        for rid, r in rep.records.items()
    }
    Path(out, "dump.json").write_text(json.dumps(data))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("matrices", nargs="*", default=["collapse-small", "collapse-study"])
    p.add_argument("--kernels", default=",".join(KERNELS))
    p.add_argument("--child", nargs=2, metavar=("MATRIX", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        child(*args.child)
        return
    import numpy as np

    from packbot.regress import (
        NOISE_FACTOR,
        Sensitivity,
        Tolerances,
        default_golden_dir,
        read_golden,
    )

    print(
        "| matrix | kernel | quantity | largest diff | diff / noise | diff / tolerance | drift? |"
    )
    print("|---|---|---|---|---|---|---|")
    for matrix in args.matrices:
        _, golden = read_golden(default_golden_dir() / matrix)
        tol = Tolerances()
        for kernel in args.kernels.split(","):
            with tempfile.TemporaryDirectory() as tmp:
                env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
                subprocess.run(
                    [sys.executable, __file__, "--child", matrix, tmp],
                    env=env,
                    check=True,
                    stderr=subprocess.DEVNULL,
                )
                new = json.loads(Path(tmp, "dump.json").read_text())
            worst: dict[str, tuple[float, float, float]] = {}

            def note(
                name: str,
                diff: float,
                noise: float,
                limit: float,
                worst: dict[str, tuple[float, float, float]] = worst,
            ) -> None:
                r_noise = diff / noise if noise > 0 else (0.0 if diff == 0 else float("inf"))
                cur = worst.get(name, (0.0, 0.0, 0.0))
                worst[name] = (max(cur[0], diff), max(cur[1], r_noise), max(cur[2], diff / limit))

            for rid, g in golden.items():
                n = new[rid]
                s = Sensitivity.from_json(g.get("sensitivity", {}))
                lim = {
                    k: max(getattr(tol, k), NOISE_FACTOR * getattr(s, k))
                    for k in ("q", "time", "distance", "energy")
                }
                if n["status"] != g["status"] or n["event_kinds"] != g["event_kinds"]:
                    note("event sequence", float("inf"), 1.0, 1.0)
                    continue
                dq = float(np.max(np.abs(np.array(n["final_q"]) - np.array(g["final_q"]))))
                cp = g.get("checkpoints", {"t": [], "q": []})
                t = np.array(n["t"])
                for tk, qk in zip(cp["t"], cp["q"], strict=True):
                    i = int(np.argmin(np.abs(t - tk)))
                    dq = max(dq, float(np.max(np.abs(np.array(n["q"][i]) - np.array(qk)))))
                note("q [rad]", dq, s.q, lim["q"])
                dt = max(
                    [abs(a - b) for a, b in zip(n["event_times"], g["event_times"], strict=True)]
                    + [0.0]
                )
                if n["rest_time"] is not None and g["rest_time"] is not None:
                    dt = max(dt, abs(n["rest_time"] - g["rest_time"]))
                note("time [s]", dt, s.time, lim["time"])
                gd = float(g["min_distance"])
                if np.isfinite(gd):
                    note("distance [m]", abs(n["min_distance"] - gd), s.distance, lim["distance"])
                note(
                    "energy [J]",
                    abs(n["energy_change"] - g["energy_change"]),
                    s.energy,
                    lim["energy"],
                )
            for name, (diff, r_noise, r_lim) in worst.items():
                print(
                    f"| {matrix} | {kernel} | {name} | {diff:.2g} | {r_noise:.2g} | "
                    f"{r_lim:.2g} | {'yes' if r_lim > 1 else 'no'} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
