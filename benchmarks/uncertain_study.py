"""An uncertain study of ``reconfig_elbow1`` and its cost per sampled arm.

Run: ``python benchmarks/uncertain_study.py [N] [DURATION] [WORKERS...]`` (default 8 arms,
2.5 s per run, workers 1 and 2). Prints a Markdown table of the quantiles of each run's final
task error and peak torque ratio, the recovery probability with its Wilson interval, the top of
the sensitivity ranking of the failed run's final task error, and the cost: the arms studied in
this process (``packbot.uncertain_study``) and through the batch machinery on a local pool of
each worker count (``packbot.uncertain_batch.run_uncertain_study``, a fresh folder each), the
wall time of the whole call and per arm, and whether the quantiles are this process's. The
figures of the table are the same on any machine for the same seed (to rounding); the times
depend on the machine and its load. docs/study.md ("Over the model's uncertainty") quotes one
run.
"""

from __future__ import annotations

import logging
import sys
import tempfile
import time

import packbot
from packbot.study import RUN_NAMES
from packbot.uncertain_batch import run_uncertain_study

log = logging.getLogger("uncertain_study")

SCENARIO = "reconfig_elbow1"
SEED = 1


def main(argv: list[str]) -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("packbot").setLevel(logging.WARNING)  # the table, not each arm's steps
    n = int(argv[0]) if argv else 8
    duration = float(argv[1]) if len(argv) > 1 else 2.5
    workers = [int(w) for w in argv[2:]] or [1, 2]
    start = time.perf_counter()
    unc = packbot.uncertain_study(SCENARIO, samples=n, seed=SEED, duration=duration)
    walls = {"this process": time.perf_counter() - start}
    results = {"this process": unc}
    for w in workers:
        with tempfile.TemporaryDirectory(prefix="bench-unc-") as tmp:
            start = time.perf_counter()
            rep = run_uncertain_study(
                SCENARIO, tmp, samples=n, seed=SEED, duration=duration, workers=w
            )
            where = f"local pool, {w} worker{'s' if w != 1 else ''}"
            walls[where] = time.perf_counter() - start
            results[where] = rep.result
    log.info(
        "%s, %.1f s per run, %d arms (Sobol, seed %d): %s",
        SCENARIO,
        duration,
        n,
        SEED,
        unc.counts,
    )
    log.info("")
    log.info("| run | final task error 5 / 50 / 95 % [mm] | peak torque ratio 5 / 50 / 95 % |")
    log.info("|---|---|---|")
    for run in RUN_NAMES:
        e = unc.quantiles(run, "final_task_error_m")
        r = unc.quantiles(run, "peak_torque_ratio")
        log.info(
            "| %s | %.2f / %.2f / %.2f | %.3f / %.3f / %.3f |",
            run,
            1e3 * e[5],
            1e3 * e[50],
            1e3 * e[95],
            r[5],
            r[50],
            r[95],
        )
    lo, hi = unc.recovery_interval
    log.info("")
    log.info(
        "recovery within %g mm: %d of %d arms, p = %.2f, 95 %% Wilson interval %.2f .. %.2f; "
        "the studies judged recovery possible on %.0f %% of the arms",
        unc.tolerance_m * 1e3,
        unc.recovery_successes,
        unc.recovery_trials,
        unc.recovery_probability,
        lo,
        hi,
        100 * unc.possible_share,
    )
    log.info("")
    log.info("| parameter | Spearman rho with the failed run's final task error |")
    log.info("|---|---|")
    for name, rho in unc.sensitivity("failed", "final_task_error_m")[:5]:
        log.info("| `%s` | %+.2f |", name, rho)
    log.info("")
    log.info("| where the arms run | wall time [s] | per arm [s] | the quantiles of this process |")
    log.info("|---|---|---|---|")
    ref = unc.quantiles("failed", "final_task_error_m")
    for where, res in results.items():
        same = res.quantiles("failed", "final_task_error_m") == ref
        log.info("| %s | %.1f | %.2f | %s |", where, walls[where], walls[where] / n, same)


if __name__ == "__main__":
    main(sys.argv[1:])
