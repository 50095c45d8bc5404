"""The ``packbot`` command line: subcommands, each importing what it needs when it runs.

Exit codes (:data:`EXIT_OK`, ...): 0 success; 1 failure of the task itself (a simulation that
could not continue: the message says what and when; a regression that drifted); 2 bad input
(usage, a bad option value, a bad or missing file, an ``--out`` folder that cannot be used: one
line on stderr, no traceback); 130 interrupted by Ctrl-C, 143 by SIGTERM, 129 by SIGHUP (128 +
the signal: every command stops on these as on Ctrl-C; ``packbot run`` saves the trajectory up
to then, as a failed run does). The handlers are installed for the time of the command only.

``packbot run`` keeps a manifest in its ``--out`` folder (:data:`MANIFEST_NAME`) listing the files
it wrote with the SHA-256 and size of each; the next run into that folder deletes those files
first, if they still match (and are plain files, not symbolic links), so a rerun leaves only its
own files. A folder holding anything else (a file packbot cannot prove it wrote) is refused unless
``--overwrite`` is given.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any, NamedTuple, NoReturn

from packbot.errors import PackbotError, SimulationError, close_match

if TYPE_CHECKING:
    from packbot.model import Robot
    from packbot.result import SimResult
    from packbot.scenario import Scenario
    from packbot.uncertain_batch import UncertainReport

__all__ = [
    "EXIT_FAILED",
    "EXIT_HANGUP",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_TERMINATED",
    "EXIT_USAGE",
    "MANIFEST_NAME",
    "build_parser",
    "main",
]

log = logging.getLogger("packbot")

#: Exit code: success.
EXIT_OK = 0
#: Exit code: the task itself failed (a simulation that could not continue, a regression drift).
EXIT_FAILED = 1
#: Exit code: bad input (usage, option values, files, the output folder).
EXIT_USAGE = 2
#: Exit code: interrupted by Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 130
#: Exit code: stopped by SIGTERM (128 + 15), as by Ctrl-C (``packbot run`` saves the partial run).
EXIT_TERMINATED = 143
#: Exit code: stopped by SIGHUP (128 + 1; a closed terminal), as by Ctrl-C.
EXIT_HANGUP = 129
#: The file in a ``packbot run --out`` folder listing the files that run wrote there.
MANIFEST_NAME = "packbot-manifest.json"
_MANIFEST_FORMAT = 2  # 2: with each file's SHA-256 and size
#: The Dask schemes ``--scheduler`` accepts (besides "local").
_DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


class _UsageError(PackbotError):
    """Bad command-line input: printed as one line, exit code 2."""


class _Interrupted(SimulationError):
    """Ctrl-C (or SIGTERM, SIGHUP) during a simulation, raised at its next step.

    The result up to then is kept.
    """

    def __init__(self, t: float, signum: int = signal.SIGINT) -> None:
        what = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        super().__init__(f"interrupted ({what})", t)
        self.signum = int(signum)


# ---------------------------------------------------------------------------------- option types
def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"invalid value {text!r}: expected an integer >= 1")
    return value


def _nonnegative_length(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(
            f"invalid value {text!r}: expected a finite length >= 0 [m]"
        )
    return value


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"invalid port {text!r}: expected an integer in 1..65535")
    return value


def _folder(text: str) -> str:
    """An ``--out`` or ``--golden`` folder: a non-empty path ("" would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            f"invalid folder {text!r}: expected a path (write . for the current folder)"
        )
    if "\0" in text:
        raise argparse.ArgumentTypeError(f"invalid folder {text!r}: a path has no NUL character")
    return text


_SCHEDULER_RE = re.compile(
    r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
    r":(?P<port>[0-9]{1,5})"
)


def _scheduler(text: str) -> str:
    """A Dask scheduler address checked for its form (nothing is connected to here)."""
    if text == "local":
        return text
    m = _SCHEDULER_RE.fullmatch(text)
    ok = m is not None and (m["scheme"] or "tcp") in _DASK_SCHEMES and 1 <= int(m["port"]) <= 65535
    if not ok:
        raise argparse.ArgumentTypeError(
            f"invalid scheduler address {text!r}: expected 'local' or a Dask scheduler's "
            f"address SCHEME://HOST:PORT, e.g. tcp://127.0.0.1:8786 (SCHEME one of "
            f"{', '.join(_DASK_SCHEMES)}; PORT in 1..65535)"
        )
    return text


def _root_dir(value: str | None) -> Path:
    """The ``--root`` of generate-model/-srdf: an existing folder (default: this checkout)."""
    from packbot.resources import repo_root

    if value is None:
        root = repo_root()
        if root is None:
            raise _UsageError("not in a source checkout; pass --root DIR")
        return root
    root = Path(value)
    if not root.is_dir():
        what = "is not a directory" if root.exists() else "does not exist"
        raise _UsageError(f"--root {root} {what}; pass the source checkout's root")
    return root


def _cli_robot(args: argparse.Namespace) -> Robot:
    """The arm of ``--urdf`` and ``--package-dir`` (PackBot without them).

    Raises:
        PackbotError: The loader's errors (a missing file, a bad URDF).
        _UsageError: A parser's own error on the file (still bad input).
    """
    from packbot.model import load_robot

    try:
        return load_robot(args.urdf, package_dirs=args.package_dir or None)
    except PackbotError:
        raise
    except (ValueError, RuntimeError) as exc:  # a parser's own error: still bad input
        raise _UsageError(f"--urdf {args.urdf}: not a loadable URDF: {exc}") from None


def _cmd_info(args: argparse.Namespace) -> int:
    import numpy as np
    import pinocchio as pin

    robot = _cli_robot(args)
    m, p = robot.model, robot.params
    title = "PackBot EOD model" if robot.is_packbot else f"arm {m.name!r}"
    out = [f"{title}: {robot.urdf_path}", f"nq = {m.nq}, nv = {m.nv}", ""]
    w = max(13, *(len(n) + 1 for n in p.names))
    out.append(
        f"{'joint':<{w}}{'lower':>8}{'upper':>8}{'vel':>7}{'effort':>8}{'ratio':>7}"
        f"{'armature':>10}{'viscous':>9}{'coulomb':>9}   [rad, rad/s, N*m, kg*m^2, N*m*s/rad]"
    )
    for i, name in enumerate(p.names):
        out.append(
            f"{name:<{w}}{p.lower[i]:8.3f}{p.upper[i]:8.3f}{p.velocity[i]:7.2f}{p.effort[i]:8.1f}"
            f"{p.gear_ratio[i]:7.0f}{p.armature[i]:10.5f}{p.viscous[i]:9.3f}{p.coulomb[i]:9.3f}"
        )
    out.append("")
    out.append(f"{'body':<18}{'mass [kg]':>10}   centre of mass in body frame [m]")
    total = 0.0
    for i, inertia in enumerate(m.inertias):
        body = "base_link (fixed)" if i == 0 else m.names[i] + " ->"
        total += inertia.mass
        c = " ".join(f"{v:7.3f}" for v in inertia.lever)
        out.append(f"{body:<18}{inertia.mass:10.3f}   {c}")
    out.append(f"{'total':<18}{total:10.3f}")
    out.append(f"collision pieces: {robot.collision_model.ngeoms} convex")
    out.append("")
    data = m.createData()
    tool = m.getFrameId(robot.tool_frame)
    out.append(f"{'pose':<8} q [rad] in joint order; {robot.tool_frame} position in the base [m]")
    for name, q in robot.poses.items():
        pin.framesForwardKinematics(m, data, q)
        xyz = " ".join(f"{v:6.3f}" for v in data.oMf[tool].translation)
        out.append(f"{name:<8} {np.array2string(q, precision=3, suppress_small=True)}  tool: {xyz}")
    print("\n".join(out))
    return 0


def _cmd_generate_model(args: argparse.Namespace) -> int:
    from packbot.urdfgen import generate

    root = _root_dir(args.root)
    paths = generate(root, check=args.check)
    if args.check:
        if paths:
            print("out of date (run `packbot generate-model`):")
            print("\n".join(f"  {p}" for p in paths))
            return 1
        print("generated model files are up to date")
        return 0
    print(f"wrote {len(paths)} files under {root}")
    return 0


def _cmd_decompose(args: argparse.Namespace) -> int:
    from packbot.decompose import decompose_meshes

    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise _UsageError(f"--out {out}: expected a new or empty folder")
    urdf, report = decompose_meshes(
        args.urdf,
        out,
        package_dirs=args.package_dir or None,
        excess=args.excess,
        threshold=args.threshold,
    )
    w = max(5, *(len(r.link) + 1 for r in report)) if report else 5
    head = ("volume [cm3]", "hull", "pieces", "pieces vol", "[s]")
    print(f"{'link':<{w}} {head[0]:>12} {head[1]:>8} {head[2]:>7} {head[3]:>10} {head[4]:>6}")
    for r in report:
        kept = not r.pieces
        pieces = "hull" if kept else str(len(r.pieces))
        tight = "" if r.pieces_excess is None else f"{100 * r.pieces_excess:+.1f} %"
        print(
            f"{r.link:<{w}} {r.volume * 1e6:12.1f} {100 * r.hull_excess:+7.1f}% {pieces:>7} "
            f"{tight:>10} {r.seconds:6.1f}"
        )
    print(f"wrote {urdf} (load it with load_robot; pass the same --package-dir folders)")
    return 0


def _cmd_generate_srdf(args: argparse.Namespace) -> int:
    from packbot.model import load_robot
    from packbot.srdfgen import generate_srdf, write_srdf

    if args.out is not None or args.urdf is not None:  # an arm's SRDF, to a file
        if args.out is None:
            raise _UsageError("--urdf needs --out FILE (the SRDF to write)")
        if args.root is not None:
            raise _UsageError("--out and --root exclude each other")
        out = Path(args.out)
        if out.is_dir() or not out.parent.is_dir():
            raise _UsageError(f"--out {out}: expected a file path in an existing folder")
        robot = _cli_robot(args)
        out.write_text(generate_srdf(robot, samples=args.samples, clearance=args.clearance))
        print(f"wrote {out}")
        return 0
    root = _root_dir(args.root)
    if not (root / "urdf").is_dir():
        print(
            f"error: --root {root} has no urdf/ folder; pass the source checkout's root",
            file=sys.stderr,
        )
        return 2
    path = write_srdf(load_robot(), root, samples=args.samples, clearance=args.clearance)
    print(f"wrote {path}")
    return 0


class _Progress:
    """A progress bar in simulated time on stderr (only drawn on a terminal)."""

    def __init__(self, duration: float, label: str) -> None:
        self.duration = duration
        self.label = label
        self.last = -1.0

    def __call__(self, t: float) -> None:
        import time

        now = time.monotonic()
        if now - self.last < 0.1 and t < self.duration:
            return
        self.last = now
        frac = min(max(t / self.duration, 0.0), 1.0)
        n = int(30 * frac)
        sys.stderr.write(
            f"\r{self.label} [{'#' * n}{'.' * (30 - n)}] {t:7.3f} / {self.duration:g} s"
        )
        sys.stderr.flush()

    def close(self) -> None:
        sys.stderr.write("\n")
        sys.stderr.flush()


def _summary(res: SimResult, scenario: Scenario, duration: float, dist: Any) -> list[str]:
    import math

    import numpy as np

    cfg = res.config
    d = res.diagnostics
    big = ("turret", "shoulder", "elbow1", "elbow2")  # PackBot's; another arm: all its joints
    shown = big if set(big) <= set(res.joint_names) else res.joint_names
    final = "  ".join(f"{n}={res.q[-1, res.joint(n)]:+.4f}" for n in shown)
    kinds: dict[str, int] = {}
    for e in res.events:
        kinds[e.kind] = kinds.get(e.kind, 0) + 1
    rest = (
        f"not at rest (some joint speed >= {cfg.rest_speed:g} rad/s at the end)"
        if res.rest_time is None
        else f"{res.rest_time:.4f} s (all joint speeds < {cfg.rest_speed:g} rad/s after it)"
    )
    rtf = duration / d.wall_time if d.wall_time > 0 else math.inf
    lines = [
        f"{scenario.name}: {scenario.description}" if scenario.description else scenario.name,
        f"  contact_mode={cfg.contact_mode}, controller={scenario.controller}, "
        f"{len(scenario.failures)} failure(s), {duration:g} s",
        f"  rest time:        {rest}",
        f"  final angles:     {final} [rad]",
        f"  events:           {len(res.events)}"
        + (" (" + ", ".join(f"{n} {k}" for k, n in kinds.items()) + ")" if kinds else ""),
    ]
    kept = (
        f"{d.min_distance:.3e} m over the kept states ({d.min_distance_pair})"
        if math.isfinite(d.min_distance)
        else ""
    )
    if dist is not None:
        k = int(np.argmin(dist))
        sampled = f"{dist[k]:.3e} m at t = {res.t[k]:.3f} s (samples)"
        lines.append(f"  min distance:     {sampled}" + (f", {kept}" if kept else ""))
    elif kept:
        lines.append(f"  min distance:     {kept}")
    lines.append(f"  energy:           {res.energy[0]:.3f} J -> {res.energy[-1]:.3f} J")
    lines.append(f"  wall time:        {d.wall_time:.3f} s simulation ({rtf:.0f}x real time)")
    return lines


# ---------------------------------------------------------------------------------- --out folder
def _is_plain_name(name: object) -> bool:
    """Whether a manifest entry is a bare file name (nothing outside the folder, no ``..``)."""
    from packbot.paths import is_plain_name

    return is_plain_name(name) and name != MANIFEST_NAME


class _Manifest(NamedTuple):
    """What an ``--out`` folder's manifest says (:func:`_read_manifest`)."""

    checksums: dict[str, tuple[str, int]]  # name -> (SHA-256, size [bytes]) of each written file
    unverified: set[str]  # names listed without a checksum (an older packbot, an unfinished run)
    ignored: list[str]  # what was ignored and why (said in the refusal's line, logged at INFO)


def _read_manifest(out: Path) -> _Manifest | None:
    """The files ``out``'s manifest lists (bare names only), or None if it has none.

    A manifest that is a symbolic link, unreadable or not packbot's lists nothing; an entry that
    is not a bare file name is ignored (:attr:`_Manifest.ignored` says which and why).
    """
    path = out / MANIFEST_NAME
    if not (path.is_symlink() or path.exists()):
        return None
    manifest = _Manifest({}, set(), [])
    if path.is_symlink() or not path.is_file():
        manifest.ignored.append(f"{MANIFEST_NAME} ignored: not a plain file")
        return manifest
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:  # unreadable, not UTF-8, not JSON
        manifest.ignored.append(f"{MANIFEST_NAME} ignored: not a packbot manifest ({exc})")
        return manifest
    files = data.get("files") if isinstance(data, dict) else None
    if not isinstance(data, dict) or data.get("tool") != "packbot" or not isinstance(files, list):
        manifest.ignored.append(f"{MANIFEST_NAME} ignored: not a packbot manifest")
        return manifest
    sums = data.get("checksums")
    sums = sums if isinstance(sums, dict) else {}
    for name in files:
        if not _is_plain_name(name):
            manifest.ignored.append(f"entry {name!r} ignored (not a file name inside the folder)")
            continue
        entry = sums.get(name)
        sha = entry.get("sha256") if isinstance(entry, dict) else None
        size = entry.get("size") if isinstance(entry, dict) else None
        if (
            isinstance(sha, str)
            and len(sha) == 64
            and isinstance(size, int)
            and not isinstance(size, bool)
        ):
            manifest.checksums[name] = (sha.lower(), size)
        else:
            manifest.unverified.add(name)
    return manifest


def _why_foreign(out: Path, name: str, manifest: _Manifest | None) -> str | None:
    """Why ``out/name`` is not a file an earlier packbot run can be proven to have written.

    None: it is (listed by the manifest with the SHA-256 and size it has now, a plain file, not
    a symbolic link), or it is the manifest itself; else the reason, for the message.
    """
    from packbot.batch import file_sha256

    path = out / name
    if path.is_symlink():
        return "a symbolic link"
    if not path.is_file():
        return "a directory" if path.is_dir() else "not a plain file"
    if name == MANIFEST_NAME:
        return None
    if manifest is not None and name in manifest.unverified:
        return "listed without a checksum"
    if manifest is None or name not in manifest.checksums:
        return "not listed"
    sha, size = manifest.checksums[name]
    try:
        if path.stat().st_size != size or file_sha256(path) != sha:
            return "changed since packbot wrote it"
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    return None


def _prepare_out(out_arg: str, overwrite: bool) -> tuple[Path, list[Path]]:
    """Check (or create) a run's ``--out`` folder.

    Returns:
        The folder, and the files of the earlier packbot run in it (to delete before writing):
        only files its manifest lists with the SHA-256 and size they still have.

    Raises:
        _UsageError: A path that is a file or cannot be created, a folder that is not writable,
            or one holding files packbot cannot prove it wrote (without ``overwrite``).
    """
    out = Path(out_arg)
    if out.exists() and not out.is_dir():
        raise _UsageError(f"--out {out} exists and is not a directory")
    if not out.exists():
        for parent in out.parents:
            if parent.exists() and not parent.is_dir():
                raise _UsageError(f"--out {out}: {parent} is a file, not a directory")
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _UsageError(
                f"--out {out}: cannot create the directory ({exc.strerror})"
            ) from None
    elif not os.access(out, os.W_OK | os.X_OK):
        raise _UsageError(f"--out {out}: the directory is not writable")
    try:
        names = sorted(p.name for p in out.iterdir())
    except OSError as exc:
        raise _UsageError(f"--out {out}: cannot list the directory ({exc.strerror})") from None
    manifest = _read_manifest(out)
    for note in manifest.ignored if manifest is not None else ():
        log.info("%s: %s", out, note)
    why = {n: _why_foreign(out, n, manifest) for n in names}
    foreign = [n for n in names if why[n] is not None]
    if foreign and not overwrite:
        shown = ", ".join(
            n if why[n] == "not listed" else f"{n} ({why[n]})" for n in foreign[:3]
        ) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        old = (
            " (an older packbot's manifest, or a run that did not finish, lists files without "
            "their SHA-256: packbot deletes only files it can prove it wrote)"
            if any(why[n] == "listed without a checksum" for n in foreign)
            else ""
        )
        if manifest is not None and manifest.ignored:
            old += f" ({'; '.join(manifest.ignored)})"
        raise _UsageError(
            f"--out {out} holds files an earlier packbot run did not list ({shown}){old}; pass "
            "--overwrite to write into it anyway (those files are kept), or choose another folder"
        )
    return out, [out / n for n in names if why[n] is None and n != MANIFEST_NAME]


def _planned_files(out: Path, scenario: Scenario, *, plots: bool, html: bool) -> list[Path]:
    """Every file a run of ``scenario`` may write into ``out``."""
    stem = scenario.name
    names = [f"{stem}.npz", f"{stem}_events.csv", f"{stem}_partial.npz"]
    names.append(f"{stem}_partial_events.csv")
    if scenario.outputs.occlusion is not None:
        names.append(f"{stem}_occlusion.csv")
    if plots:
        fmts = scenario.outputs.formats
        names += [f"{stem}_{kind}.{fmt}" for kind in scenario.plot_kinds() for fmt in fmts]
    if html:
        names.append(f"{stem}.html")
    return [out / n for n in names]


def _write_manifest(out: Path, scenario: Scenario, status: str, files: Iterable[Path]) -> None:
    """Write ``out/packbot-manifest.json``: the files of this run (bare names), its status.

    Each file that exists (a plain file, written by this run) is listed with its SHA-256 and
    size under ``checksums``: the next run deletes only the files that still match. The files
    a running run may still write are listed without (``status = "running"``).
    """
    from packbot import __version__
    from packbot.batch import file_sha256
    from packbot.paths import atomic_write

    names = sorted({p.name for p in files if p.parent == out and _is_plain_name(p.name)})
    checksums = {}
    for name in names:
        path = out / name
        if path.is_file() and not path.is_symlink():
            checksums[name] = {"sha256": file_sha256(path), "size": path.stat().st_size}
    data = {
        "tool": "packbot",
        "format": _MANIFEST_FORMAT,
        "packbot_version": __version__,
        "scenario": scenario.name,
        "status": status,
        "files": names,
        "checksums": checksums,
    }
    text = json.dumps(data, indent=2) + "\n"
    atomic_write(out / MANIFEST_NAME, lambda fh: fh.write(text), binary=False)


def _written_files(paths: dict[str, Any], scenario: Scenario) -> list[Path]:
    """The files behind the paths ``save_run``, ``write_outputs`` and ``write_html`` returned."""
    from packbot.scenario import PLOT_KINDS

    files: list[Path] = []
    for key, path in paths.items():
        if not isinstance(path, Path):
            continue
        if key in PLOT_KINDS:  # one entry per plot: its first format
            files += [path.with_suffix(f".{fmt}") for fmt in scenario.outputs.formats]
        else:
            files.append(path)
    return files


# ---------------------------------------------------------------------------------- signals
#: The signals that stop a command as Ctrl-C does: SIGINT, SIGTERM (``timeout``, systemd,
#: docker, cluster schedulers) and SIGHUP (a closed terminal), where the platform has them.
STOP_SIGNALS: tuple[int, ...] = tuple(
    int(s) for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s
)


class _Stopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where Ctrl-C raises KeyboardInterrupt (the same clean-up runs).

    Attributes:
        signum: The signal's number (the exit code is 128 + it).
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _signum(exc: BaseException | None) -> int:
    """The signal behind a KeyboardInterrupt: SIGINT unless it is a :class:`_Stopped`."""
    return int(getattr(exc, "signum", signal.SIGINT))


def _exit_code(signum: int) -> int:
    """The exit code of a command stopped by a signal: 128 + its number, as a shell says."""
    return 128 + int(signum)


def _by(signum: int) -> str:
    """``""`` for Ctrl-C (the messages as they were), else ``" by SIGTERM"``."""
    return "" if signum == signal.SIGINT else f" by {signal.Signals(signum).name}"


class _Handlers:
    """Signal handlers installed (in the main thread only), the earlier ones put back on leaving.

    Only the command line installs any: a library call never does.
    """

    def __init__(self, handler: Callable[[int, FrameType | None], None], signals: Sequence[int]):
        self._handler = handler
        self._signals = tuple(signals)
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> _Handlers:
        if threading.current_thread() is threading.main_thread():
            for s in self._signals:
                self._previous[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for s, previous in self._previous.items():
            if previous is None:  # set outside Python: back to the default
                previous = signal.default_int_handler if s == signal.SIGINT else signal.SIG_DFL
            signal.signal(s, previous)
        self._previous.clear()


def _raise_stopped(signum: int, frame: FrameType | None) -> None:
    raise _Stopped(signum)


def _terminate_as_interrupt() -> _Handlers:
    """SIGTERM and SIGHUP raise :class:`_Stopped` (a KeyboardInterrupt) while active.

    Every command then stops on them as on Ctrl-C (its clean-up, its message, exit 128 + the
    signal).
    """
    return _Handlers(_raise_stopped, [s for s in STOP_SIGNALS if s != signal.SIGINT])


class _SigintFlag:
    """Ctrl-C, SIGTERM or SIGHUP as a request to stop a simulation at its next step.

    While active (in the main thread only), the first of these signals sets :attr:`requested`
    (its number); a second one raises KeyboardInterrupt (:class:`_Stopped` for SIGTERM and
    SIGHUP) at once.
    """

    def __init__(self) -> None:
        self.requested = 0
        self._handlers = _Handlers(self._handle, STOP_SIGNALS)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.requested:
            if signum == signal.SIGINT:
                raise KeyboardInterrupt
            raise _Stopped(signum)
        self.requested = signum

    def __enter__(self) -> _SigintFlag:
        self._handlers.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._handlers.__exit__()


def _check_name(scenario: Scenario) -> None:
    """A scenario's name names its files (``<name>.npz``, ``out/<name>``): one file name."""
    from packbot.errors import ConfigurationError
    from packbot.paths import check_stem

    try:
        check_stem("scenario.name", scenario.name)
    except ConfigurationError as exc:
        raise _UsageError(f"scenario {scenario.name!r}: {exc}") from None


def _duration(value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise _UsageError(f"invalid --duration {value}: expected a finite positive time [s]")


def _stderr_line(text: str) -> None:
    """One line on stderr (after the progress bar's line, on a terminal)."""
    print(text, file=sys.stderr)


def _run(
    scenario_name: str,
    out_arg: str | None,
    duration_arg: float | None,
    *,
    plot: bool,
    html: bool,
    view: bool,
    overwrite: bool,
) -> int:
    import time

    from packbot.errors import ConfigurationError
    from packbot.inputs import check_initial_state
    from packbot.scenario import (
        load_scenario,
        run_scenario,
        save_run,
        scenario_robot,
        write_outputs,
    )

    _duration(duration_arg)
    wall0 = time.perf_counter()
    try:
        scenario = load_scenario(scenario_name)
    except ConfigurationError as exc:
        raise _UsageError(f"scenario {scenario_name}: {exc}") from None
    _check_name(scenario)
    out, old = _prepare_out(out_arg if out_arg is not None else f"out/{scenario.name}", overwrite)
    robot = scenario_robot(scenario)
    try:
        scenario.validate(robot)
        # the initial collision check too, before the earlier run's files are deleted
        check_initial_state(
            robot,
            scenario.initial_state(robot)[0],
            environment=scenario.environment,
            config=scenario.config,
        )
    except ConfigurationError as exc:
        raise _UsageError(f"scenario {scenario_name}: {exc}") from None
    duration = scenario.duration if duration_arg is None else float(duration_arg)
    html = html or scenario.outputs.html
    bar = _Progress(duration, scenario.name) if sys.stderr.isatty() else None
    stop = _SigintFlag()

    def progress(t: float) -> None:
        if stop.requested:
            raise _Interrupted(t, stop.requested)
        if bar is not None:
            bar(t)

    interrupted: _Interrupted | None = None
    try:
        with stop:  # from here on, Ctrl-C stops the simulation at its next step
            # The earlier run's files go now, once the scenario is known to be good; the
            # manifest names every file this run may write until it lists the ones it did.
            for path in old:
                path.unlink(missing_ok=True)
            planned = _planned_files(out, scenario, plots=plot, html=html)
            _write_manifest(out, scenario, "running", [p for p in planned if not p.exists()])
            res = run_scenario(scenario, robot, duration=duration, progress=progress)
        if stop.requested:  # Ctrl-C after the last step: stopped all the same
            interrupted = _Interrupted(float(res.t[-1]), stop.requested)
            interrupted.result = res
    except _Interrupted as exc:
        interrupted = exc
    except SimulationError as exc:
        if bar is not None:
            bar.close()
        written: list[Path] = []
        partial = ""
        if exc.result is not None:
            saved = save_run(exc.result, scenario, out, f"{scenario.name}_partial")
            written = list(saved.values())
            partial = f"\n  the trajectory up to then: {saved['trajectory']}"
        _write_manifest(out, scenario, "failed", written)
        _stderr_line(f"error: the simulation of {scenario.name} failed: {exc}{partial}")
        return EXIT_FAILED
    except KeyboardInterrupt as exc:  # a second Ctrl-C: no result to save
        if bar is not None:
            bar.close()
        _write_manifest(out, scenario, "interrupted", [])
        _stderr_line(
            f"interrupted{_by(_signum(exc))}: {scenario.name} stopped at once, nothing saved"
        )
        return _exit_code(_signum(exc))
    if bar is not None:
        bar.close()
    if interrupted is not None:
        written = []
        where = "nothing saved (no sample yet)"
        if interrupted.result is not None:
            saved = save_run(interrupted.result, scenario, out, f"{scenario.name}_partial")
            written = list(saved.values())
            where = f"the trajectory up to then is in {saved['trajectory']}"
        _write_manifest(out, scenario, "interrupted", written)
        by = _by(interrupted.signum)
        _stderr_line(f"interrupted{by} at t = {interrupted.t:.6g} s: {where}")
        return _exit_code(interrupted.signum)
    paths: dict[str, Any] = dict(save_run(res, scenario, out))
    try:
        paths |= write_outputs(res, scenario, robot, out, plots=plot)
        dist = paths.pop("min_distance", None)
        if html:
            from packbot.viz import write_html

            paths["html"] = write_html(robot, res, out / f"{scenario.name}.html")
    except KeyboardInterrupt as exc:
        _write_manifest(out, scenario, "interrupted", _written_files(paths, scenario))
        _stderr_line(
            f"interrupted{_by(_signum(exc))} while writing the plots: the trajectory is in "
            f"{paths['trajectory']}"
        )
        return _exit_code(_signum(exc))
    _write_manifest(out, scenario, "ok", _written_files(paths, scenario))
    print("\n".join(_summary(res, scenario, duration, dist)))
    print(f"  wrote ({time.perf_counter() - wall0:.2f} s in all):")
    for p in (*paths.values(), out / MANIFEST_NAME):
        print(f"    {p}")
    if view:
        from packbot.viz import start_viewer

        viewer = start_viewer(robot, environment=scenario.environment)
        viewer.play(res)  # once: the page replays it (Open Controls > Animations)
        print(f"viewer at {viewer.url} (Ctrl-C to quit)")
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass
        finally:
            viewer.close()
    return EXIT_OK


def _cmd_run(args: argparse.Namespace) -> int:
    if args.uncertain is not None:
        return _uncertain_run(args)
    for flag in ("seed", "workers", "scheduler", "timeout"):
        if getattr(args, flag) is not None:
            raise _UsageError(f"--{flag} applies to a run on sampled arms (--uncertain N)")
    if args.no_progress:
        raise _UsageError("--no-progress applies to a run on sampled arms (--uncertain N)")
    return _run(
        args.scenario,
        args.out,
        args.duration,
        plot=args.plot,
        html=args.html,
        view=args.view,
        overwrite=args.overwrite,
    )


def _cmd_collapse(args: argparse.Namespace) -> int:
    name = {
        "joint_clamp": "collapse",
        "normal": "collapse_physical",
        "none": "collapse_no_collisions",
    }[args.mode]
    return _run(
        name, args.out, args.duration, plot=True, html=True, view=False, overwrite=args.overwrite
    )


def _cmd_schema(args: argparse.Namespace) -> int:
    from packbot.scenario_schema import schema_text

    text = schema_text()
    if args.out is None:
        sys.stdout.write(text)
        return EXIT_OK
    out = Path(args.out)
    if out.is_dir():
        from packbot.scenario_schema import SCHEMA_FILE

        out = out / SCHEMA_FILE
    if args.check:
        if not out.is_file() or out.read_text(encoding="utf-8") != text:
            print(f"out of date: {out} (run `packbot schema --out {args.out}`)")
            return EXIT_FAILED
        print(f"{out} is up to date")
        return EXIT_OK
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out}")
    return EXIT_OK


def _cmd_list(args: argparse.Namespace) -> int:
    import numpy as np

    from packbot.params import POSES
    from packbot.resources import data_dir
    from packbot.scenario import list_scenarios, load_scenario

    print(f"scenarios ({data_dir('sims')}; run one with `packbot run NAME`):")
    for name in list_scenarios():
        try:
            desc = load_scenario(name).description
        except Exception as exc:  # list the others even if one is broken
            desc = f"(invalid: {exc})"
        print(f"  {name:<26} {desc}")
    print("")
    print("poses (`packbot show POSE`; joints not named are 0) [rad]:")
    for name, values in POSES.items():
        text = ", ".join(f"{j}={np.round(v, 3):g}" for j, v in values.items())
        print(f"  {name:<8} {text}")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    import time

    from packbot.model import load_robot
    from packbot.viz import start_viewer

    robot = load_robot()
    q = robot.pose(args.pose)
    viewer = start_viewer(robot, port=args.port)
    try:
        viewer.display(q)
        print(f"pose {args.pose!r} at {viewer.url} (Ctrl-C to quit)", flush=True)
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
    return EXIT_OK


def _cmd_batch(args: argparse.Namespace) -> int:
    from packbot.batch import ProgressBar, run_batch
    from packbot.matrix import load_matrix

    matrix = load_matrix(args.matrix)
    bar = None if args.no_progress else ProgressBar()
    try:
        report = run_batch(
            matrix,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.timeout,
            progress=bar,
        )
    except KeyboardInterrupt as exc:
        _interrupted_line(
            f"interrupted{_by(_signum(exc))}: the finished runs are kept; rerun the same command "
            "to finish"
        )
        return _exit_code(_signum(exc))
    print(f"matrix {matrix.name}: {report.describe()}")
    return EXIT_FAILED if report.failed else EXIT_OK


def _cmd_regress(args: argparse.Namespace) -> int:
    from packbot.batch import ProgressBar
    from packbot.matrix import load_matrix
    from packbot.regress import default_golden_dir, golden_matrices, run_regression

    golden = Path(args.golden) if args.golden else default_golden_dir()
    names = [args.matrix] if args.matrix else golden_matrices(golden)
    if not names:
        raise _UsageError(f"no golden results in {golden} (create them with --update)")
    drift = False
    for name in names:
        matrix = load_matrix(name)
        out = None
        if args.out:
            out = Path(args.out) / matrix.name if len(names) > 1 else Path(args.out)
        try:
            result = run_regression(
                matrix,
                golden,
                out_dir=out,
                update=args.update,
                workers=args.workers,
                scheduler=args.scheduler,
                progress=None if args.no_progress else ProgressBar(),
            )
        except KeyboardInterrupt as exc:
            _interrupted_line(f"interrupted{_by(_signum(exc))}: no comparison made")
            return _exit_code(_signum(exc))
        print(result.text())
        drift = drift or (bool(result.drifts) and not args.update)
    return EXIT_FAILED if drift else EXIT_OK


#: ``packbot study`` options for one scenario (a study matrix sets these in its file).
_SCENARIO_STUDY_OPTIONS = {
    "duration": "--duration",
    "tolerance": "--tolerance",
    "contact_mode": "--contact-mode",
    "no_html": "--no-html",
    "overwrite": "--overwrite",
}
#: ``packbot study`` options for a study matrix (its batch).
_MATRIX_STUDY_OPTIONS = {
    "workers": "--workers",
    "scheduler": "--scheduler",
    "timeout": "--timeout",
    "no_progress": "--no-progress",
}


def _is_study_matrix(text: str) -> bool:
    """Whether ``packbot study``'s argument is a matrix (a file with a base, or a matrix name).

    A file is a matrix if its TOML has ``base``, ``axes`` or ``study`` (a scenario has none of
    them); a name is a shipped scenario's first, else a shipped matrix's.
    """
    from packbot import tomlfile
    from packbot.matrix import matrix_names
    from packbot.scenario import list_scenarios

    path = Path(text)
    if path.is_file():
        try:
            tomlfile.check_file_size(path, "scenario", text)
            data = tomlfile.loads(path.read_text(encoding="utf-8"), "scenario", text)
        except (OSError, UnicodeDecodeError, PackbotError):
            return False  # the scenario reader reports it
        return any(k in data for k in ("base", "axes", "study"))
    if path.parent != Path(".") or text in list_scenarios():
        return False
    return path.name.removesuffix(".toml") in matrix_names()


def _cmd_study_matrix(args: argparse.Namespace) -> int:
    from packbot.batch import ProgressBar
    from packbot.study_matrix import load_study_matrix, run_study_matrix

    for flag in ("--uncertain", "--seed"):
        if getattr(args, flag[2:]) is not None:
            raise _UsageError(
                f"{flag} applies to one scenario (an uncertain study), not to a study matrix "
                f"({args.scenario!r})"
            )
    for dest, flag in _SCENARIO_STUDY_OPTIONS.items():
        if getattr(args, dest) not in (None, False):
            raise _UsageError(
                f"{flag} applies to one scenario: a study matrix sets it in its file ([set] "
                'duration, "config.contact_mode"; [study] tolerance, html); its --out folder '
                "is resumed"
            )
    matrix = load_study_matrix(args.scenario)
    controller, recovery = _user_code(args)
    bar = None if args.no_progress else ProgressBar()
    try:
        report = run_study_matrix(
            matrix,
            args.out or f"out/{matrix.name}",
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.timeout,
            progress=bar,
            controller=controller,
            recovery=recovery,
        )
    except KeyboardInterrupt as exc:
        _interrupted_line(
            f"interrupted{_by(_signum(exc))}: the finished cells are kept; rerun the same "
            "command to finish"
        )
        return _exit_code(_signum(exc))
    print(f"study matrix {matrix.name}: {report.describe()}")
    return EXIT_FAILED if report.batch.failed else EXIT_OK


def _user_code(args: argparse.Namespace) -> tuple[str | None, str]:
    """``--controller`` and ``--recovery``, checked (imported) before anything runs.

    The current folder goes first on ``sys.path``, as ``python -m`` puts it, so that a module
    beside the user is found. A bad path is a ConfigurationError (one line, exit 2).
    """
    from packbot.control.user_code import controller_factory, strategy_factory

    if args.controller is not None or ":" in args.recovery:
        cwd = os.getcwd()
        if cwd not in sys.path:
            sys.path.insert(0, cwd)
    if args.controller is not None:
        controller_factory(args.controller, "--controller")
    strategy_factory(args.recovery, "--recovery")
    return args.controller, args.recovery


def _cmd_study(args: argparse.Namespace) -> int:
    from packbot.scenario import list_scenarios, load_scenario
    from packbot.study import DEFAULT_TOLERANCE, study, verdict_text
    from packbot.viz.study_report import write_study

    if _is_study_matrix(args.scenario):
        return _cmd_study_matrix(args)
    for dest, flag in _MATRIX_STUDY_OPTIONS.items():
        if args.uncertain is not None:
            break  # an uncertain study's arms are a batch too
        if getattr(args, dest) not in (None, False):
            raise _UsageError(
                f"{flag} applies to a study matrix (sims/matrices/ or a matrix file with "
                f"[study]) or to an uncertain study (--uncertain N), not to one scenario "
                f"({args.scenario!r})"
            )
    _duration(args.duration)
    if args.tolerance is None:
        args.tolerance = DEFAULT_TOLERANCE
    if not (math.isfinite(args.tolerance) and args.tolerance > 0):
        raise _UsageError(f"invalid --tolerance {args.tolerance}: expected a distance > 0 [m]")
    scenario = load_scenario(args.scenario)
    if not scenario.failures:
        shipped = [n for n in list_scenarios() if load_scenario(n).failures]
        raise _UsageError(
            f"scenario {scenario.name!r} has no [[failures]]: a study compares a healthy, a "
            f"failed and a reconfigured run (shipped scenarios with failures: "
            f"{', '.join(shipped)})"
        )
    _check_name(scenario)
    controller, recovery = _user_code(args)
    if args.uncertain is None and args.seed is not None:
        raise _UsageError("--seed applies to an uncertain study (--uncertain N)")
    if args.uncertain is not None:
        return _uncertain_study(args, scenario.name, controller, recovery)
    out, old = _prepare_out(args.out or f"out/{scenario.name}_study", args.overwrite)
    for path in old:
        path.unlink(missing_ok=True)
    result = study(
        scenario,
        duration=args.duration,
        tolerance=args.tolerance,
        contact_mode=args.contact_mode,
        controller=controller,
        recovery=recovery,
        progress=lambda text: log.info("%s", text),
    )
    written = write_study(result, out, html=not args.no_html)
    _write_manifest(out, scenario, "study", written.values())
    print(verdict_text(result))
    for name, run in result.runs.items():
        m = run.metrics
        if m is None:
            print(f"  {name:<13} {run.status}: {run.reason}")
            continue
        detect = (
            ""
            if m.detect_time_s is None
            else f", detected {m.detected_joint} {m.detected_kind} at {m.detect_time_s:.3f} s"
        )
        print(
            f"  {name:<13} final task error {m.final_task_error_m * 1000:8.1f} mm, RMS "
            f"{m.rms_task_error_m * 1000:7.1f} mm, peak torque {m.peak_torque_ratio:.0%} of its "
            f"limit, {m.contacts} contacts{detect}"
        )
    print(f"wrote {out / 'study.json'}" + ("" if args.no_html else f" and {out / 'report.html'}"))
    return EXIT_OK


def _uncertain_study(
    args: argparse.Namespace, name: str, controller: str | None, recovery: str
) -> int:
    """``packbot study SCENARIO --uncertain N``: the study on N sampled arms (a resumed batch)."""
    from packbot.uncertain_batch import run_uncertain_study

    if args.overwrite:
        raise _UsageError(
            "--overwrite does not apply to --uncertain: its --out folder is a batch folder, "
            "resumed (another draw is refused: use another --out)"
        )
    return _uncertain_batch(
        args,
        name,
        run_uncertain_study,
        tolerance=args.tolerance,
        contact_mode=args.contact_mode,
        controller=controller,
        recovery=recovery,
        html=not args.no_html,
    )


def _uncertain_run(args: argparse.Namespace) -> int:
    """``packbot run SCENARIO --uncertain N``: the run on N sampled arms (a resumed batch)."""
    from packbot.uncertain_batch import run_uncertain_runs

    for flag in ("plot", "html", "view", "overwrite"):
        if getattr(args, flag):
            raise _UsageError(
                f"--{flag} does not apply to --uncertain (it writes uncertain-run.json and "
                "uncertain_run.png/svg into a batch folder, resumed)"
            )
    if args.duration is not None:
        _duration(args.duration)
    from packbot.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    _check_name(scenario)
    return _uncertain_batch(args, scenario.name, run_uncertain_runs)


def _uncertain_batch(
    args: argparse.Namespace,
    name: str,
    run: Callable[..., UncertainReport],
    **options: Any,
) -> int:
    """Run ``run`` (an uncertain batch) on the arguments' arms; print its report.

    Args:
        args: The command's arguments (the scenario, ``--uncertain``, ``--seed``,
            ``--duration``, ``--workers``, ``--scheduler``, ``--timeout``, ``--out``,
            ``--no-progress``).
        name: The scenario's name (the default ``--out`` is ``out/<name>_uncertain``).
        run: :func:`~packbot.uncertain_batch.run_uncertain_study` or
            :func:`~packbot.uncertain_batch.run_uncertain_runs`.
        **options: Its other keyword arguments.
    """
    from packbot.batch import ProgressBar

    out = args.out or f"out/{name}_uncertain"
    bar = None if args.no_progress else ProgressBar()
    try:
        report = run(
            args.scenario,
            out,
            samples=args.uncertain,
            seed=0 if args.seed is None else args.seed,
            duration=args.duration,
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.timeout,
            progress=bar,
            **options,
        )
    except KeyboardInterrupt as exc:
        _interrupted_line(
            f"interrupted{_by(_signum(exc))}: the finished arms are kept; rerun the same "
            "command to finish"
        )
        return _exit_code(_signum(exc))
    print(report.result.text())
    print(report.describe())
    return EXIT_FAILED if report.batch.failed else EXIT_OK


def _interrupted_line(text: str) -> None:
    """A Ctrl-C message: one line (after a progress bar's line on a terminal)."""
    sys.stderr.write(("\n" if sys.stderr.isatty() else "") + text + "\n")
    sys.stderr.flush()


class _Parser(argparse.ArgumentParser):
    """argparse, reporting a usage error in one line (exit code 2).

    An unrecognized option gets the closest option of its subcommand, if one is close
    (``packbot run collapse --duraton 1``: "did you mean '--duration'?").
    """

    _argv: list[str] | None = None

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        self._argv = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def _option_hint(self, message: str) -> str:
        if not message.startswith("unrecognized arguments: ") or self._argv is None:
            return ""
        options = list(self._option_string_actions)
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                command = next((a for a in self._argv if a in action.choices), None)
                if command is not None:
                    options += list(action.choices[command]._option_string_actions)
        for word in message.split(": ", 1)[1].split():
            match = close_match(word.split("=", 1)[0], options) if word.startswith("-") else None
            if match is not None:
                return f"; did you mean {match!r}?"
        return ""

    def error(self, message: str) -> NoReturn:
        message += self._option_hint(message)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def _version() -> str:
    """The version of packbot (PEP 440)."""
    from packbot import __version__

    return __version__


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = _Parser(
        prog="packbot",
        description="Simulate the iRobot PackBot EOD manipulator: kinematics, dynamics, "
        "collisions and joint failures.",
        epilog="Exit codes: 0 success; 1 a simulation failed or a regression drifted; 2 bad input "
        "(usage, option values, files, the output folder: one line on stderr); 130 interrupted "
        "(Ctrl-C), 143 SIGTERM, 129 SIGHUP (`packbot run` saves the trajectory up to then as "
        "<name>_partial.npz).",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {_version()}", help="print the version"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("info", help="print the model's joints, limits, masses and named poses")
    p.add_argument(
        "--urdf",
        default=None,
        help="a URDF to load instead of the shipped one, or an arm's name (ur5, panda)",
    )
    p.add_argument(
        "--package-dir",
        action="append",
        default=[],
        help="a folder holding the ROS packages of the URDF's package:// meshes (repeatable)",
    )
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser(
        "generate-model",
        help="regenerate urdf/ and docs/parameters.md from packbot/params.py",
    )
    p.add_argument("--check", action="store_true", help="only report files that are out of date")
    p.add_argument(
        "--root", type=_folder, default=None, help="repository root (default: this checkout)"
    )
    p.set_defaults(func=_cmd_generate_model)

    p = sub.add_parser(
        "generate-srdf",
        help="sample the joint space and write urdf/packbot/packbot_eod.srdf, or an arm's SRDF "
        "to --out (groups, pairs)",
    )
    p.add_argument(
        "--samples", type=_positive_int, default=20000, help="random configurations (20000)"
    )
    p.add_argument(
        "--clearance", type=_nonnegative_length, default=0.05, help="'never' below this [m] (0.05)"
    )
    p.add_argument(
        "--root", type=_folder, default=None, help="repository root (default: this checkout)"
    )
    p.add_argument(
        "--urdf",
        default=None,
        help="another arm: a URDF or an arm's name (ur5, panda); with --out",
    )
    p.add_argument(
        "--package-dir",
        action="append",
        default=[],
        help="a folder holding the ROS packages of the URDF's package:// meshes (repeatable)",
    )
    p.add_argument(
        "--out", default=None, help="write the SRDF to this file (pass it as load_robot(srdf=))"
    )
    p.set_defaults(func=_cmd_generate_srdf)

    p = sub.add_parser(
        "decompose",
        help="split an arm's concave collision meshes into convex pieces (CoACD) and write a "
        "URDF using them to --out",
    )
    p.add_argument("--urdf", required=True, help="the arm: a URDF or an arm's name (ur5, panda)")
    p.add_argument(
        "--package-dir",
        action="append",
        default=[],
        help="a folder holding the ROS packages of the URDF's package:// meshes (repeatable)",
    )
    p.add_argument("--out", required=True, help="a new (or empty) folder to write into")
    p.add_argument(
        "--excess",
        type=float,
        default=0.25,
        help="decompose a mesh whose hull adds more than this fraction of its volume (0.25)",
    )
    p.add_argument(
        "--threshold", type=float, default=0.05, help="CoACD's concavity threshold (0.05)"
    )
    p.set_defaults(func=_cmd_decompose)

    out_help = (
        "output directory ({}); a rerun deletes the files the earlier run listed in its "
        f"{MANIFEST_NAME} first; a directory holding other files is refused without --overwrite"
    )
    overwrite_help = (
        "write into an --out directory that holds files packbot did not write: the earlier "
        "run's listed files are deleted, the others are kept (same-named ones are replaced)"
    )
    p = sub.add_parser(
        "run",
        help="run a scenario (a name in sims/ or a TOML file): trajectory, event log, plots",
        epilog="Exit codes: 0 done; 1 the simulation failed (the trajectory up to then is saved "
        "as <name>_partial.npz); 2 bad input; 130 Ctrl-C, 143 SIGTERM, 129 SIGHUP (the trajectory "
        "up to then is saved as <name>_partial.npz).",
    )
    p.add_argument(
        "scenario", metavar="SCENARIO", help="scenario name (see `packbot list`) or path"
    )
    p.add_argument(
        "--out", type=_folder, default=None, help=out_help.format("./out/<scenario name>")
    )
    p.add_argument("--overwrite", action="store_true", help=overwrite_help)
    p.add_argument("--plot", action="store_true", help="write the scenario's plots (PNG, SVG)")
    p.add_argument("--html", action="store_true", help="write the browser animation")
    p.add_argument("--view", action="store_true", help="play the result in a live viewer")
    p.add_argument("--duration", type=float, default=None, help="simulated time [s] instead")
    p.add_argument(
        "--uncertain",
        metavar="N",
        type=int,
        default=None,
        help="run N arms drawn within the model's tolerances: the final angles, where link 3 "
        "ends and the events as distributions (uncertain-run.json, uncertain_run.png/svg; "
        "the --out folder is a batch, resumed: ./out/<scenario name>_uncertain)",
    )
    p.add_argument("--seed", type=int, default=None, help="--uncertain: seed of the draw (0)")
    p.add_argument(
        "--workers", type=int, default=None, help="--uncertain: processes (CPUs; 0: this one)"
    )
    p.add_argument(
        "--scheduler",
        "--dask",
        dest="scheduler",
        type=_scheduler,
        default=None,
        help="--uncertain: Dask scheduler SCHEME://HOST:PORT, or 'local'",
    )
    p.add_argument(
        "--timeout", type=float, default=None, help="--uncertain: wall-time limit per arm [s]"
    )
    p.add_argument("--no-progress", action="store_true", help="--uncertain: no progress bar")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("list", help="list the shipped scenarios and the named poses")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser(
        "schema",
        help="print the JSON Schema of scenario files (for editors: docs/scenarios.md)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="write it to this file, or to DIR/scenario.schema.json (the shipped copy: sims/)",
    )
    p.add_argument(
        "--check", action="store_true", help="with --out: exit 1 if the file is out of date"
    )
    p.set_defaults(func=_cmd_schema)

    p = sub.add_parser("show", help="show a named pose in a live viewer (meshcat)")
    p.add_argument("pose", nargs="?", default="drive", help="pose name (drive)")
    p.add_argument(
        "--port", type=_port, default=None, help="viewer port, 1..65535 (the first free from 7000)"
    )
    p.set_defaults(func=_cmd_show)

    p = sub.add_parser(
        "collapse",
        help="the report's collapse with its plots (the same as `packbot run collapse --plot`)",
    )
    p.add_argument(
        "--out", type=_folder, default="out/collapse", help=out_help.format("./out/collapse")
    )
    p.add_argument("--overwrite", action="store_true", help=overwrite_help)
    p.add_argument(
        "--mode",
        choices=("joint_clamp", "normal", "none"),
        default="joint_clamp",
        help="contact mode: the report's law (sims/collapse.toml, link 3 propped upright), the "
        "contact-normal mode with friction 0.5 (collapse_physical, link 3 folded back), or no "
        "collisions (joint_clamp)",
    )
    p.add_argument("--duration", type=float, default=None, help="simulated time [s] (5)")
    p.set_defaults(func=_cmd_collapse)

    scheduler_help = "Dask scheduler SCHEME://HOST:PORT (e.g. tcp://127.0.0.1:8786), or 'local'"
    p = sub.add_parser(
        "study",
        help="failure study of a scenario with [[failures]]: healthy, failed and reconfigured "
        "runs, study.json, figures and report.html; of a study matrix: one study per cell "
        "(resumable, local pool or Dask) and the heat maps",
        epilog="A study matrix (a matrix file with a [study] table, docs/study.md) writes "
        "DIR/<cell>/ (each cell's study), DIR/report.html, DIR/study-matrix.json and "
        "DIR/study_heat_map.png/svg; rerun to resume. Exit codes: 0 done; 1 a cell failed; "
        "2 bad input; 130 Ctrl-C.",
    )
    p.add_argument(
        "scenario",
        metavar="SCENARIO|MATRIX",
        help="scenario name (see `packbot list`) or path; or a study matrix: a name in "
        "sims/matrices/ or a matrix file with [study]",
    )
    p.add_argument(
        "--out",
        type=_folder,
        default=None,
        help=out_help.format("./out/<scenario name>_study")
        + "; a study matrix's: resumed if it exists (./out/<matrix name>)",
    )
    p.add_argument("--overwrite", action="store_true", help=overwrite_help)
    p.add_argument("--duration", type=float, default=None, help="simulated time [s] instead")
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        help="recovery tolerance on the gripper's task error [m] (0.01)",
    )
    p.add_argument(
        "--contact-mode",
        choices=("none", "joint_clamp", "normal"),
        default=None,
        help="contact mode instead of the scenario's (a combination the simulator refuses is "
        "reported per run)",
    )
    p.add_argument("--no-html", action="store_true", help="no report.html (JSON and figures)")
    p.add_argument(
        "--controller",
        metavar="MODULE:NAME",
        default=None,
        help="your controller instead of the scenario's: a packbot.control.Controller subclass "
        "or a factory robot -> Controller, imported from MODULE (the current folder first on "
        "sys.path)",
    )
    p.add_argument(
        "--recovery",
        metavar="builtin|none|MODULE:NAME",
        default="builtin",
        help="the reconfigured run's strategy: the built-in one (builtin), your controller's own "
        "on_failure hook (none), or your packbot.control.RecoveryStrategy",
    )
    p.add_argument(
        "--uncertain",
        metavar="N",
        type=int,
        default=None,
        help="one scenario: study N arms drawn within the model's tolerances and write "
        "uncertain.json (quantiles, recovery probability, sensitivity), its figures and "
        "report.html instead of study.json (the --out folder is a batch, resumed: "
        "./out/<scenario name>_uncertain)",
    )
    p.add_argument("--seed", type=int, default=None, help="--uncertain: seed of the draw (0)")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="a matrix or --uncertain: processes (CPUs; 0: this one)",
    )
    p.add_argument(
        "--scheduler",
        "--dask",
        dest="scheduler",
        type=_scheduler,
        default=None,
        help="a matrix or --uncertain: " + scheduler_help,
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=None,
        help="a matrix or --uncertain: wall-time limit per cell or arm [s]",
    )
    p.add_argument(
        "--no-progress", action="store_true", help="a matrix or --uncertain: no progress bar"
    )
    p.set_defaults(func=_cmd_study)

    p = sub.add_parser(
        "batch",
        help="run a scenario matrix (sims/matrices/) in parallel; rerun to resume",
    )
    p.add_argument("matrix", metavar="MATRIX", help="matrix name (sims/matrices/) or TOML file")
    p.add_argument(
        "--out", type=_folder, required=True, help="output directory (resumed if it exists)"
    )
    p.add_argument("--workers", type=int, default=None, help="processes (CPUs; 0: this one)")
    p.add_argument("--scheduler", type=_scheduler, default=None, help=scheduler_help)
    p.add_argument("--timeout", type=float, default=None, help="wall-time limit per run [s]")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_batch)

    p = sub.add_parser(
        "regress",
        help="run matrices and compare with golden results; exit 1 on drift",
    )
    p.add_argument(
        "matrix",
        metavar="MATRIX",
        nargs="?",
        default=None,
        help="matrix name or file (default: every matrix with golden results)",
    )
    p.add_argument(
        "--golden", type=_folder, default=None, help="golden results folder (sims/golden)"
    )
    p.add_argument(
        "--out", type=_folder, default=None, help="keep the batch output here (default: temporary)"
    )
    p.add_argument("--update", action="store_true", help="rewrite the golden files (on purpose)")
    p.add_argument("--workers", type=int, default=None, help="processes (CPUs; 0: this one)")
    p.add_argument("--scheduler", type=_scheduler, default=None, help=scheduler_help)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_regress)
    return parser


def _os_error_text(exc: OSError) -> str:
    """One line for a file-system error: what, and which file."""
    what = exc.strerror or str(exc) or type(exc).__name__
    names = [repr(str(f)) for f in (exc.filename, exc.filename2) if f is not None]
    return f"{what}: {' -> '.join(names)}" if names else what


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (:data:`EXIT_OK`, ...)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "func", None):
        parser.print_help()
        _stderr_line("packbot: error: no command given (the commands are listed above)")
        return EXIT_USAGE
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        with _terminate_as_interrupt():  # SIGTERM, SIGHUP: as Ctrl-C (restored on return)
            return int(func(args))
    except PackbotError as exc:
        _stderr_line(f"error: {exc}")
        return EXIT_USAGE
    except OSError as exc:  # a file or folder that cannot be read or written, a refused connection
        _stderr_line(f"error: {_os_error_text(exc)}")
        return EXIT_USAGE
    except KeyboardInterrupt as exc:
        _interrupted_line(f"interrupted{_by(_signum(exc))}")
        return _exit_code(_signum(exc))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
