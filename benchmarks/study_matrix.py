"""Wall time of a study matrix: the shipped example in this process, on the local pool, resumed.

Run by hand (about two minutes on 2 cores):

    python benchmarks/study_matrix.py [--matrix study-frozen-elbows] [--workers 2]

Prints one table: for each way of running it, the wall time of the whole call
(:func:`packbot.study_matrix.run_study_matrix`: the cells' studies, their reports, the summary,
the heat maps and the matrix's report; process start-up of the pool included), the cells made
and the cells' own wall times (from their records: the three runs, the reach test and the
cell's files). Then the time of the summary alone (study-matrix.json, heat maps, report.html).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from packbot.study_matrix import load_study_matrix, run_study_matrix
from packbot.viz.study_matrix_report import write_matrix_report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--matrix", default="study-frozen-elbows")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    sm = load_study_matrix(args.matrix)
    print(f"matrix {sm.name}: {len(sm.runs())} cells, {os.cpu_count()} CPUs")
    print("| how | cells made | wall time [s] | sum of the cells' wall times [s] |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for label, workers, folder in (
            ("this process (`--workers 0`)", 0, "a"),
            (f"local pool (`--workers {args.workers}`)", args.workers, "b"),
            ("resumed, all done (`--workers 0`)", 0, "a"),
        ):
            out = Path(tmp) / folder
            t0 = time.perf_counter()
            report = run_study_matrix(sm, out, workers=workers)
            wall = time.perf_counter() - t0
            made = report.batch.executed
            cells = sum(report.batch.records[r].wall_time for r in made)
            print(f"| {label} | {len(made)} | {wall:.1f} | {cells:.1f} |")
        summary = json.loads((Path(tmp) / "a" / "study-matrix.json").read_text())
        t0 = time.perf_counter()
        write_matrix_report(summary, Path(tmp) / "a")
        print(
            f"summary alone (study-matrix.json, heat maps, report.html): "
            f"{time.perf_counter() - t0:.2f} s"
        )


if __name__ == "__main__":
    main()
