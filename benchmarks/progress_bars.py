"""packbot's batch progress bar against tqdm and rich.progress, as a user sees them.

A fake batch of ``--runs`` runs finishing ``--pace`` seconds apart (one failed run in ten) drives
each bar twice: into a file (a CI log, ``2> log``, a cluster job's output) and into a stream that
says it is a terminal of 80 columns. For the log: the lines and bytes written and the carriage
returns in them; for the terminal: the last line as the terminal shows it (``\\r`` returning to
the line's start), and whether anything of a longer earlier line is left on it. Import times are
the median of ``--samples`` fresh interpreters (the import alone, timed inside the process).
tqdm and rich are optional here: a missing one is skipped.

    python benchmarks/progress_bars.py [--runs 200] [--pace 0.02] [--samples 5]
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import re
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

from packbot.batch import ProgressBar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True

    def last_line(self) -> str:
        """The last line as shown: ``\\r`` goes to its start, ESC [2K blanks it."""
        cells: list[str] = []
        line = re.sub(r"\x1b\[\?25[hl]", "", self.getvalue()).rstrip("\n").split("\n")[-1]
        for part in line.split("\r"):
            if part.startswith("\x1b[2K"):
                cells = []
            part = re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", part)
            cells[: len(part)] = part
        return "".join(cells)


def _ours(stream: io.StringIO) -> tuple[Callable[[int, int, int], None], Callable[[], None]]:
    bar = ProgressBar(stream)
    return bar, lambda: None


def _tqdm(stream: io.StringIO) -> tuple[Callable[[int, int, int], None], Callable[[], None]]:
    from tqdm import tqdm

    bar = tqdm(total=None, file=stream, unit="run", ncols=80)

    def update(done: int, failed: int, total: int) -> None:
        bar.total = total
        if failed:
            bar.set_postfix(failed=failed, refresh=False)
        bar.update(done - bar.n)

    return update, bar.close


def _rich(stream: io.StringIO) -> tuple[Callable[[int, int, int], None], Callable[[], None]]:
    from rich.console import Console
    from rich.progress import Progress

    tty = stream.isatty()
    console = Console(file=stream, width=80, force_terminal=tty, force_interactive=tty)
    prog = Progress(console=console)
    prog.start()
    task = prog.add_task("runs", total=None)

    def update(done: int, failed: int, total: int) -> None:
        prog.update(task, completed=done, total=total, description=f"runs ({failed} failed)")

    return update, prog.stop


def _drive(make, stream: io.StringIO, runs: int, pace: float) -> float:
    update, close = make(stream)
    t0 = time.perf_counter()
    update(0, 0, runs)
    for done in range(1, runs + 1):
        time.sleep(pace)
        update(done, done // 10, runs)
    close()
    return time.perf_counter() - t0


def _import_time(module: str, samples: int) -> float:
    code = f"import time; t = time.perf_counter(); import {module}; print(time.perf_counter() - t)"
    times = [
        float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout)
        for _ in range(samples + 1)
    ][1:]
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--pace", type=float, default=0.02, help="seconds between runs")
    ap.add_argument("--samples", type=int, default=5)
    args = ap.parse_args()
    bars = {"packbot": (_ours, "packbot.batch"), "tqdm": (_tqdm, "tqdm")}
    bars["rich.progress"] = (_rich, "rich.progress")
    print(f"{args.runs} runs, {args.pace * 1000:.0f} ms apart, 1 in 10 failed\n")
    print("| bar | import [ms] | log: lines | log: bytes | log: `\\r` | terminal: last line |")
    print("|---|---|---|---|---|---|")
    for name, (make, module) in bars.items():
        if importlib.util.find_spec(module.split(".")[0]) is None:
            print(f"| {name} | not installed | | | | |")
            continue
        log = io.StringIO()
        _drive(make, log, args.runs, args.pace)
        term = _Terminal()
        _drive(make, term, args.runs, args.pace)
        text = log.getvalue()
        imp = "0 (in packbot.batch)"
        if module != "packbot.batch":
            imp = f"{_import_time(module, args.samples) * 1000:.0f}"
        print(
            f"| {name} | {imp} | {text.count(chr(10))} | {len(text)} | "
            f"{text.count(chr(13))} | `{term.last_line().rstrip()}` |"
        )


if __name__ == "__main__":
    main()
