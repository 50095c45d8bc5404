"""Run the bad-input catalogue (tests/bad_input_cases.py) and print a table of its outcomes.

Each case runs in a worker process (``python tests/bad_input_cases.py --worker``) that answers
one line per case; a case that does not answer within ``--timeout`` seconds is a hang: the
worker is killed and a new one takes the next case. A worker that dies is a crash, counted with
the tracebacks. Outcomes (see tests/bad_input_cases.py):

- clean: the expected PackbotError naming the field (command line: exit 2, one stderr line);
- unclear: a PackbotError of another kind or not naming the field (or another exit code, or
  more than one line);
- traceback: another exception escaped (or a traceback was printed, or the worker died);
- hang: no answer within the timeout;
- accepted: no error at all (silently accepted nonsense).

Usage::

    python benchmarks/bad_inputs.py                 # every case, the table
    python benchmarks/bad_inputs.py --category cli  # one category
    python benchmarks/bad_inputs.py -v              # and every case's message
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parent.parent / "tests"
sys.path.insert(0, str(TESTS))

from bad_input_cases import CASES, CATEGORIES  # noqa: E402
from bad_input_worker import Worker  # noqa: E402

COLUMNS = (
    ("clean", "clean PackbotError / exit 2"),
    ("unclear", "unclear error"),
    ("traceback", "tracebacks"),
    ("hang", "hangs"),
    ("accepted", "silently accepted"),
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--category", choices=CATEGORIES, action="append", help="only these")
    parser.add_argument("--timeout", type=float, default=60.0, help="per case [s] (60)")
    parser.add_argument(
        "--guard-timeout",
        type=float,
        default=300.0,
        help="per case that starts processes of its own (guard cases: signals, slow sizes) [s]",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="print every outcome")
    args = parser.parse_args()
    cases = [c for c in CASES if not args.category or c.category in args.category]
    counts: Counter[tuple[str, str]] = Counter()
    bad: list[str] = []
    wall = time.perf_counter()
    worker = Worker()
    try:
        for case in cases:
            # The first case of a worker also imports packbot and loads the robot.
            answer = worker.ask(case.key, args.guard_timeout if case.guard else args.timeout)
            status = answer["status"]
            if status == "hang" or not worker.usable:  # killed, or it died
                worker.close()
                worker = Worker()
            counts[(case.category, status)] += 1
            line = f"{status:9} {case.key}: {answer['detail']}"
            if status != "clean":
                bad.append(line)
            if args.verbose:
                print(line)
    finally:
        worker.close()
    wall = time.perf_counter() - wall
    print(f"| category | cases | {' | '.join(title for _, title in COLUMNS)} |")
    print("|---" * (len(COLUMNS) + 2) + "|")
    cats = [c for c in CATEGORIES if any(k[0] == c for k in counts)]
    for cat in [*cats, "total"]:
        row = [sum(n for (c, _), n in counts.items() if cat in (c, "total")) for _ in (0,)]
        for status, _ in COLUMNS:
            row.append(
                sum(n for (c, s), n in counts.items() if s == status and cat in (c, "total"))
            )
        name = f"**{cat}**" if cat == "total" else cat
        print(f"| {name} | " + " | ".join(str(x) for x in row) + " |")
    print(
        f"\n{len(cases)} cases in {wall:.1f} s (worker processes, timeout {args.timeout:g} s per "
        f"case, {args.guard_timeout:g} s per guard case; {platform.machine()}, "
        f"Python {platform.python_version()}, {os.cpu_count()} CPUs)"
    )
    if bad:
        print("\nNot clean:")
        print("\n".join(bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
