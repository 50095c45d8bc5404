"""A worker process that runs bad-input cases one at a time, with a timeout per case.

``python tests/bad_input_cases.py --worker`` reads case keys on stdin and answers one JSON line
per case on stdout. A case that does not answer within its timeout is a hang (the caller then
closes the worker and starts another); a worker that dies is a crash. Used by
tests/test_bad_inputs.py (the guard cases: a hang fails one test instead of stopping the run)
and benchmarks/bad_inputs.py (every case).
"""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
from pathlib import Path

WORKER = [sys.executable, str(Path(__file__).resolve().parent / "bad_input_cases.py"), "--worker"]


class Worker:
    """A worker process running cases one at a time, with a timeout per case."""

    def __init__(self) -> None:
        env = dict(os.environ, MPLBACKEND="Agg")
        self.proc = subprocess.Popen(
            WORKER,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,  # C++ libraries' own warnings
            text=True,
            bufsize=1,
            env=env,
        )
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.sel = selectors.DefaultSelector()
        self.sel.register(self.proc.stdout, selectors.EVENT_READ)

    def ask(self, key: str, timeout: float) -> dict[str, str]:
        """The answer ``{"key", "status", "detail"}``; status "hang" after ``timeout`` s."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        try:
            self.proc.stdin.write(key + "\n")
            self.proc.stdin.flush()
        except BrokenPipeError:
            return {"key": key, "status": "traceback", "detail": "the worker died"}
        if not self.sel.select(timeout):
            return {"key": key, "status": "hang", "detail": f"no answer within {timeout:g} s"}
        line = self.proc.stdout.readline()
        if not line:
            detail = f"the worker died (exit {self.proc.wait()})"
            return {"key": key, "status": "traceback", "detail": detail}
        return json.loads(line)

    @property
    def usable(self) -> bool:
        """Whether the worker can take another case (alive, not stuck in a hung one)."""
        return self.proc.poll() is None

    def close(self) -> None:
        """Stop the worker (killed if still running)."""
        self.sel.close()
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
