"""Memory of a long controlled run: peak memory of the run, and the size of its saved result.

Runs ``reconfig_elbow1`` (sims/reconfig_elbow1.toml) for ``--duration`` (60) s, each
measurement in a fresh Python process (so that nothing from an earlier run is counted):

- ``traced peak``: the peak of Python's allocations during :func:`packbot.scenario.run_scenario`
  above those before it (``tracemalloc``, robot and scenario already loaded): the run's own
  memory (samples, events, the integrator's state);
- ``samples``: the memory of the result's sample arrays (t, q, v, the torques, the energy);
- ``max RSS``: the process's peak resident set size (``resource.getrusage``), in a second
  process without ``tracemalloc`` (which slows the run and adds its own memory), the
  interpreter, NumPy, Pinocchio and Coal included;
- ``npz``: the size of ``SimResult.save`` (compressed, ``np.savez_compressed``), next to the
  same arrays written uncompressed (``np.savez``) for comparison.

Run: python benchmarks/memory.py [--duration S]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

MB = 1024.0 * 1024.0


def _child(mode: str, duration: float) -> dict[str, Any]:
    import resource
    import tracemalloc

    import numpy as np

    import packbot
    from packbot.scenario import load_scenario, run_scenario

    robot = packbot.load_robot()
    scenario = load_scenario("reconfig_elbow1")
    out: dict[str, Any] = {}
    if mode == "trace":
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
    t0 = time.perf_counter()
    res = run_scenario(scenario, robot, duration=duration)
    out["wall"] = time.perf_counter() - t0
    if mode == "trace":
        out["traced_peak"] = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
    else:
        out["max_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0
        arrays = ("t", "q", "v", "tau", "energy", "tau_cmd", "tau_friction", "effort")
        out["samples"] = len(res.t)
        out["events"] = len(res.events)
        out["sample_bytes"] = sum(np.asarray(getattr(res, a)).nbytes for a in arrays)
        with tempfile.TemporaryDirectory() as tmp:
            path = res.save(Path(tmp) / "run.npz")
            out["npz"] = path.stat().st_size
            raw = Path(tmp) / "raw.npz"
            np.savez(raw, **{a: getattr(res, a) for a in arrays})
            out["npz_uncompressed_arrays"] = raw.stat().st_size
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="simulated time [s]")
    ap.add_argument("--child", choices=("trace", "rss"), default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        print(json.dumps(_child(args.child, args.duration)))
        return
    got: dict[str, Any] = {}
    for mode in ("rss", "trace"):
        cmd = [sys.executable, __file__, "--child", mode, "--duration", repr(args.duration)]
        done = subprocess.run(cmd, check=True, capture_output=True, text=True)
        got |= json.loads(done.stdout.strip().splitlines()[-1])
    print(
        f"reconfig_elbow1, {args.duration:g} s simulated: {got['samples']} samples, "
        f"{got['events']} events, {got['wall']:.1f} s wall (under tracemalloc)"
    )
    print(f"  traced peak of the run      {got['traced_peak'] / MB:8.2f} MB")
    print(f"  sample arrays of the result {got['sample_bytes'] / MB:8.2f} MB")
    print(f"  max RSS of the process      {got['max_rss'] / MB:8.2f} MB")
    print(f"  saved result (.npz)         {got['npz'] / MB:8.2f} MB")
    print(f"  its arrays, uncompressed    {got['npz_uncompressed_arrays'] / MB:8.2f} MB")


if __name__ == "__main__":
    main()
