"""Start-up times: ``import packbot`` against its own heavy dependencies, and the main command.

Each sample is a fresh interpreter (a subprocess), timed from spawn to exit; the table gives the
median over ``--runs`` samples after one warm-up. Byte-code caching is on, as a user has it (this
machine sets PYTHONDONTWRITEBYTECODE, which would add ~0.05-0.1 s of compiling to every import):
the caches go to a temporary ``PYTHONPYCACHEPREFIX``, so the tree stays clean.

    python benchmarks/startup.py [--runs 7] [--src DIR]

``--src DIR`` measures another checkout of packbot (put first on PYTHONPATH), e.g. the previous
commit unpacked with ``git archive HEAD~1 | tar -x -C /tmp/before``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DEPS = "import numpy, pinocchio, coal"
RUN = "import sys; from packbot.cli import main; sys.exit(main(sys.argv[1:]))"


def median_time(cmd: list[str], env: dict[str, str], runs: int) -> float:
    """Median wall time [s] of ``runs`` executions of ``cmd`` (after one warm-up)."""
    samples = []
    for k in range(runs + 1):
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
        if k:
            samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def main() -> None:
    """Print the start-up table (markdown)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="samples per row (median)")
    ap.add_argument("--src", type=Path, default=None, help="packbot checkout to measure")
    args = ap.parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
        if args.src is not None:
            paths = [str(args.src.resolve()), env.get("PYTHONPATH", "")]
            env["PYTHONPATH"] = os.pathsep.join(paths)
        out = str(Path(tmp) / "out")
        rows = [
            ("python -c 'import numpy, pinocchio, coal'", [py, "-c", DEPS]),
            ("python -c 'import packbot'", [py, "-c", "import packbot"]),
            ("packbot run collapse --out DIR", [py, "-c", RUN, "run", "collapse", "--out", out]),
            (
                "packbot run collapse --out DIR --plot",
                [py, "-c", RUN, "run", "collapse", "--out", out, "--plot"],
            ),
        ]
        times = {name: median_time(cmd, env, args.runs) for name, cmd in rows}
    base, imp = times[rows[0][0]], times[rows[1][0]]
    print(f"| command (median of {args.runs} fresh processes) | time [s] |")
    print("|---|---:|")
    for name, _ in rows:
        print(f"| `{name}` | {times[name]:.2f} |")
    print(f"| ratio `import packbot` / `import numpy, pinocchio, coal` | {imp / base:.2f} |")


if __name__ == "__main__":
    main()
