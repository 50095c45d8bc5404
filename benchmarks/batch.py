"""Batch throughput: runs per minute in this process, on the local pool, on a Dask LocalCluster.

Run by hand (about two minutes on 2 cores):

    python benchmarks/batch.py [--runs 36] [--matrix collapse-study] [--no-dask]

Prints two tables:

1. Real runs (the first N runs of a matrix, 2 s collapses): wall time of the whole batch (process
   start-up included), runs per minute, speed-up over sequential and parallel efficiency
   (speed-up / workers). Expect little from 2 cores shared with other work: the efficiency is
   printed as measured.
2. Per-run overhead: a run that does nothing, so the time per run is the machinery's own cost
   (pickling, queues, the atomic writes of its record), in this process, on the local pool and on
   a Dask ``LocalCluster`` (processes, one thread each, on 127.0.0.1, no dashboard).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from collections.abc import Callable
from typing import Any

from packbot.batch import RunFiles, run_batch
from packbot.matrix import Run, load_matrix


def noop_runner(run: Run, progress: Callable[[float], None]) -> tuple[dict[str, Any], RunFiles]:
    """A run that does nothing: the batch machinery's cost alone."""
    progress(0.0)
    quantities = {"joint_names": ("a",), "final_q": (0.0,), "energy_change": 0.0, "t_end": 0.0}
    return quantities, {"trajectory": (f"{run.id}.txt", b"0")}


def timed(fn: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--matrix", default="collapse-study")
    parser.add_argument("--runs", type=int, default=36, help="real runs per configuration")
    parser.add_argument("--noop-runs", type=int, default=200, help="runs of the overhead table")
    parser.add_argument("--no-dask", action="store_true")
    args = parser.parse_args()
    ncpu = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover
        load = float("nan")
    matrix = load_matrix(args.matrix)
    runs = matrix.runs()[: args.runs]
    print(f"{ncpu} CPUs, load average {load:.2f} at start; matrix {matrix.name}, {len(runs)} runs")
    print()

    configs = [("sequential (this process)", 0, 1)]
    configs += [(f"local pool, {n} workers", n, n) for n in (1, 2)]
    print(f"{'real runs':<28}{'wall [s]':>10}{'runs/min':>10}{'speed-up':>10}{'efficiency':>12}")
    base = None
    for label, workers, n in configs:
        with tempfile.TemporaryDirectory() as tmp:
            wall = timed(lambda w=workers, d=tmp: run_batch(matrix, d, runs=runs, workers=w))
        base = wall if base is None else base
        rate = len(runs) / wall * 60
        speed = base / wall
        print(f"{label:<28}{wall:10.2f}{rate:10.0f}{speed:10.2f}{speed / n:12.0%}")
    print()

    noop = matrix.runs()
    noop = (noop * (args.noop_runs // len(noop) + 1))[: args.noop_runs]
    noop = [dataclasses.replace(r, id=f"{r.id}-{i}", index=i) for i, r in enumerate(noop)]

    def pool(d: str, n: int) -> Any:
        return run_batch(matrix, d, runs=noop[:n], workers=2, runner=noop_runner)

    print(f"{'per-run overhead':<40}{'wall [s]':>10}{'per run [ms]':>14}")
    with tempfile.TemporaryDirectory() as tmp:
        wall = timed(lambda d=tmp: run_batch(matrix, d, runs=noop, workers=0, runner=noop_runner))
    print(f"{'this process':<40}{wall:10.2f}{wall / len(noop) * 1e3:14.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        start = timed(lambda d=tmp: pool(d, 2))
    with tempfile.TemporaryDirectory() as tmp:
        wall = timed(lambda d=tmp: pool(d, len(noop)))
    per_run = (wall - start) / (len(noop) - 2) * 1e3
    print(f"{'local pool, 2 workers':<40}{wall:10.2f}{per_run:14.2f}")
    print(f"(pool start-up, 2 runs: {start:.2f} s, subtracted)")
    if args.no_dask:
        return
    try:
        import distributed
    except ImportError:
        print("dask.distributed not installed: pip install 'packbot[distributed]'")
        return
    t0 = time.perf_counter()
    with (
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        start = time.perf_counter() - t0
        for label in ("Dask LocalCluster, 2 workers (warm-up)", "Dask LocalCluster, 2 workers"):
            with tempfile.TemporaryDirectory() as tmp:
                wall = timed(
                    lambda d=tmp: run_batch(
                        matrix, d, runs=noop, scheduler=client, runner=noop_runner
                    )
                )
            print(f"{label:<40}{wall:10.2f}{wall / len(noop) * 1e3:14.2f}")
        print(f"(cluster start-up {start:.2f} s, not included)")
        print()
        with tempfile.TemporaryDirectory() as tmp:
            wall = timed(lambda d=tmp: run_batch(matrix, d, runs=runs, scheduler=client))
        print(f"{'real runs on Dask, 2 workers':<28}{wall:10.2f}{len(runs) / wall * 60:10.0f}")


if __name__ == "__main__":
    main()
