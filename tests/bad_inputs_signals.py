"""Bad-input catalogue, category ``signals``: commands stopped by a signal, a batch killed.

Each case starts ``packbot run``, ``packbot batch`` or ``packbot study`` in a subprocess (its own
folder), waits until it is at work (a file it writes then, its worker processes), sends a signal
and waits for it to end (guards of :data:`GUARD` seconds, never timed assertions). Its ``check``
(see the ``check`` field of ``Case`` in ``tests/bad_input_cases.py``) asserts the exit code
(128 + the signal), one line on stderr naming it, the partial result (``packbot run``), the
batch's summary, and that no process the command started is left running. SIGINT, SIGTERM
and SIGHUP are handled alike; ``kill -9`` of a batch's main process cannot be handled: its
workers must end by themselves. All are ``guard=True`` (pytest runs each in a subprocess).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

#: A guard against a hang [s] (each wait is far shorter).
GUARD = 180.0
_MANIFEST = "packbot-manifest.json"
_SLOW_MATRIX = (
    'base = "loose_shoulder"\n[set]\nduration = 300.0\n'
    '[axes]\n"config.restitution" = [0.0, 0.1, 0.2, 0.3]\n'
)


def _default_sigint() -> None:
    """In the child: SIGINT back to its default disposition before Python starts.

    A command started in the background by a shell without job control (`cmd &` in a CI script)
    inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler: Ctrl-C
    cases would wait for a signal the child never sees.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(c: Any, args: list[str]) -> subprocess.Popen[str]:
    # (cwd: the case's folder, not the checkout, whose source tree `python -m` would import)
    return subprocess.Popen(
        [sys.executable, "-m", "packbot.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=c.tmp,
        preexec_fn=_default_sigint,
    )


def _wait(ready: Callable[[], bool], proc: subprocess.Popen[str]) -> bool:
    deadline = time.monotonic() + GUARD
    while not ready() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    return ready()


def _descendants(pid: int) -> list[Any]:
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _left(procs: list[Any]) -> list[int]:
    """The processes still running a while after their command ended (killed then)."""
    import psutil

    def alive() -> list[Any]:
        out = []
        for p in procs:
            try:
                if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                    out.append(p)
            except psutil.NoSuchProcess:
                pass
        return out

    deadline = time.monotonic() + 30.0  # a guard: they end within a second
    while alive() and time.monotonic() < deadline:
        time.sleep(0.1)
    left = alive()
    for p in left:  # not left to the next case
        p.kill()
    return [p.pid for p in left]


def _finish(proc: subprocess.Popen[str], sig: int | None, children: list[Any]) -> dict[str, Any]:
    """Send ``sig`` (None: SIGKILL), wait for the end; what happened, for the check."""
    try:
        if sig is None:
            proc.kill()
        else:
            proc.send_signal(sig)
        _, err = proc.communicate(timeout=GUARD)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return {"code": proc.returncode, "err": err, "left": _left(children)}


def _run(sig: int, *, after: float = 0.0, twice: bool = False) -> Callable[[Any], Any]:
    """``packbot run loose_shoulder`` (300 s), signalled ``after`` s into the simulation."""

    def action(c: Any) -> dict[str, Any]:
        out = c.tmp / "out"
        proc = _start(c, ["run", "loose_shoulder", "--duration", "300", "--out", str(out)])
        if not _wait((out / _MANIFEST).exists, proc):  # written once the handlers are in place
            return _finish(proc, signal.SIGKILL, []) | {"err": "did not start"}
        time.sleep(after)
        if twice:
            proc.send_signal(sig)
        done = _finish(proc, sig, [])
        partial = out / "loose_shoulder_partial.npz"
        manifest = json.loads((out / _MANIFEST).read_text()) if (out / _MANIFEST).exists() else {}
        return done | {"partial": partial.is_file(), "manifest": manifest}

    return action


def _run_check(sig: int, *, partial: bool = True) -> Callable[[dict[str, Any]], str | None]:
    def check(r: dict[str, Any]) -> str | None:
        lines = r["err"].strip().splitlines()
        name = "interrupted" if sig == signal.SIGINT else signal.Signals(sig).name
        if r["code"] != 128 + sig:
            return f"exit {r['code']}, not {128 + sig}: {r['err'][-300:]!r}"
        if len(lines) != 1 or name not in lines[0]:
            return f"stderr {r['err']!r}: not one line naming {name}"
        if not partial:  # a second signal: stopped at once, or while saving
            return None
        manifest = r.get("manifest", {})
        if not r.get("partial"):
            return "no loose_shoulder_partial.npz"
        if manifest.get("status") != "interrupted":
            return f"manifest status {manifest.get('status')!r}"
        if "loose_shoulder_partial.npz" not in manifest.get("checksums", {}):
            return "the partial file is not in the manifest with its checksum"
        return None

    return check


def _batch(sig: int | None, workers: int = 2) -> Callable[[Any], Any]:
    """``packbot batch`` of 4 long runs on ``workers`` processes, signalled once they work."""

    def action(c: Any) -> dict[str, Any]:
        matrix = c.write("m.toml", _SLOW_MATRIX)
        out = c.tmp / "b"
        args = ["batch", str(matrix), "--out", str(out), "--workers", str(workers)]
        proc = _start(c, [*args, "--no-progress"])
        if workers:  # the workers (and the resource tracker) started
            ready = _wait(lambda: len(_descendants(proc.pid)) >= workers + 1, proc)
        else:
            ready = _wait((out / "matrix.json").exists, proc)
        if not ready:
            return _finish(proc, None, []) | {"err": "did not start", "summary": False}
        time.sleep(1.0)  # at work (a guard: any later moment does as well)
        done = _finish(proc, sig, _descendants(proc.pid))
        return done | {"summary": (out / "summary.csv").is_file()}

    return action


def _batch_check(sig: int | None) -> Callable[[dict[str, Any]], str | None]:
    def check(r: dict[str, Any]) -> str | None:
        if r["left"]:
            return f"processes left running: {r['left']}"
        if sig is None:  # kill -9: nothing else to ask
            return None if r["code"] == -signal.SIGKILL else f"exit {r['code']}"
        lines = r["err"].strip().splitlines()
        name = "interrupted" if sig == signal.SIGINT else signal.Signals(sig).name
        if r["code"] != 128 + sig:
            return f"exit {r['code']}, not {128 + sig}: {r['err'][-300:]!r}"
        if len(lines) != 1 or name not in lines[0] or "rerun" not in lines[0]:
            return f"stderr {r['err']!r}: not one line naming {name}"
        return None if r.get("summary") else "no summary.csv"

    return check


def _study(sig: int) -> Callable[[Any], Any]:
    """``packbot study reconfig_elbow1`` (300 s), signalled once its folder exists."""

    def action(c: Any) -> dict[str, Any]:
        out = c.tmp / "s"
        proc = _start(c, ["study", "reconfig_elbow1", "--duration", "300", "--out", str(out)])
        if not _wait(out.is_dir, proc):
            return _finish(proc, None, []) | {"err": "did not start"}
        time.sleep(1.0)
        return _finish(proc, sig, _descendants(proc.pid))

    return action


def _study_check(sig: int) -> Callable[[dict[str, Any]], str | None]:
    def check(r: dict[str, Any]) -> str | None:
        lines = r["err"].strip().splitlines()
        name = "interrupted" if sig == signal.SIGINT else signal.Signals(sig).name
        if r["code"] != 128 + sig:
            return f"exit {r['code']}, not {128 + sig}: {r['err'][-300:]!r}"
        if len(lines) != 1 or name not in lines[0]:
            return f"stderr {r['err']!r}: not one line naming {name}"
        return None

    return check


def register(catalogue: ModuleType) -> None:
    """Add the ``signals`` cases to the catalogue."""

    def add(id: str, action: Any, check: Any) -> None:
        catalogue.add("signals", id, action, check=check, guard=True)

    term, hup, sigint = signal.SIGTERM, signal.SIGHUP, signal.SIGINT
    add("run-sigterm-at-start", _run(term), _run_check(term))
    add("run-sigterm-after-2s", _run(term, after=2.0), _run_check(term))
    add("run-sighup-at-start", _run(hup), _run_check(hup))
    add("run-sighup-after-2s", _run(hup, after=2.0), _run_check(hup))
    add("run-sigint-after-1s", _run(sigint, after=1.0), _run_check(sigint))
    add("run-sigterm-twice", _run(term, after=0.5, twice=True), _run_check(term, partial=False))
    add("batch-sigterm", _batch(term), _batch_check(term))
    add("batch-sighup", _batch(hup), _batch_check(hup))
    add("batch-sigint", _batch(sigint), _batch_check(sigint))
    add("batch-sigterm-in-process", _batch(term, workers=0), _batch_check(term))
    add("batch-kill-9-main", _batch(None), _batch_check(None))
    add("batch-kill-9-main-one-worker", _batch(None, workers=1), _batch_check(None))
    add("study-sigterm", _study(term), _study_check(term))
    add("study-sighup", _study(hup), _study_check(hup))
    add("study-sigint", _study(sigint), _study_check(sigint))
