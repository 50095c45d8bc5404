"""Start-up times: ``import packbot`` against its own heavy dependencies, and the main command.

Each sample is a fresh interpreter (a subprocess), timed from spawn to exit; the table gives the
median over ``--runs`` samples after one warm-up. Byte-code caching is on, as a user has it (this
machine sets PYTHONDONTWRITEBYTECODE, which would add ~0.05-0.1 s of compiling to every import):
the caches go to a temporary ``PYTHONPYCACHEPREFIX``, so the tree stays clean.

    python benchmarks/startup.py [--runs 7] [--src DIR] [--against DIR]

``--src DIR`` measures another checkout of packbot (put first on PYTHONPATH), e.g. the previous
commit unpacked with ``git archive HEAD~1 | tar -x -C /tmp/before``. ``--against DIR`` compares
this checkout (or ``--src``) with the one in DIR: the two are sampled in turn, so that a change
of the machine's load falls on both; the table then has a column for each, wall and CPU time
(user + system of the process).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DEPS = "import numpy, pinocchio, coal"
RUN = "import sys; from packbot.cli import main; sys.exit(main(sys.argv[1:]))"


def _sample(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU time [s] of one execution of ``cmd``."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime


def median_time(cmd: list[str], env: dict[str, str], runs: int) -> float:
    """Median wall time [s] of ``runs`` executions of ``cmd`` (after one warm-up)."""
    return median_times({"": env}, cmd, runs)[""][0]


def median_times(
    envs: dict[str, dict[str, str]], cmd: list[str], runs: int
) -> dict[str, tuple[float, float]]:
    """Median (wall, CPU) time [s] of ``cmd`` in each environment, sampled in turn."""
    samples: dict[str, list[tuple[float, float]]] = {k: [] for k in envs}
    for k in range(runs + 1):
        for name, env in envs.items():
            # each checkout writes to its own folder ("{out}" in cmd: its OUT variable)
            s = _sample([c.replace("{out}", env.get("OUT", "")) for c in cmd], env)
            if k:  # the first round warms the caches
                samples[name].append(s)
    return {
        name: (statistics.median(w for w, _ in s), statistics.median(c for _, c in s))
        for name, s in samples.items()
    }


def _env(tmp: str, tag: str, src: Path | None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / f"pycache-{tag}")
    env["OUT"] = str(Path(tmp) / f"out-{tag}")
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src.resolve()), env.get("PYTHONPATH", "")])
    return env


def main() -> None:
    """Print the start-up table (markdown)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="samples per row (median)")
    ap.add_argument("--src", type=Path, default=None, help="packbot checkout to measure")
    ap.add_argument("--against", type=Path, default=None, help="checkout to compare with")
    args = ap.parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        envs = {"this": _env(tmp, "this", args.src)}
        if args.against is not None:
            envs = {"before": _env(tmp, "before", args.against), "after": envs["this"]}
        out = "{out}"
        rows = [
            ("python -c 'import numpy, pinocchio, coal'", [py, "-c", DEPS]),
            ("python -c 'import packbot'", [py, "-c", "import packbot"]),
            ("packbot run collapse --out DIR", [py, "-c", RUN, "run", "collapse", "--out", out]),
            (
                "packbot run collapse --out DIR --plot",
                [py, "-c", RUN, "run", "collapse", "--out", out, "--plot"],
            ),
        ]
        times = {name: median_times(envs, cmd, args.runs) for name, cmd in rows}
    names = list(envs)
    print(f"| command (median of {args.runs} fresh processes) | ", end="")
    print(" | ".join(f"{n} wall [s] | {n} CPU [s]" for n in names) + " |")
    print("|---|" + "---:|" * (2 * len(names)))
    for name, _ in rows:
        cells = " | ".join(f"{times[name][n][0]:.2f} | {times[name][n][1]:.2f}" for n in names)
        print(f"| `{name}` | {cells} |")
    base, imp = rows[0][0], rows[1][0]
    cells = " | ".join(f"{times[imp][n][0] / times[base][n][0]:.2f} | " for n in names)
    print(f"| ratio `import packbot` / `import numpy, pinocchio, coal` (wall) | {cells}|")


if __name__ == "__main__":
    main()
