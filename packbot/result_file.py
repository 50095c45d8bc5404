"""The result file format: the ``.npz`` file :meth:`packbot.SimResult.save` writes, read safely.

One concept: reading and checking that file (docs/simulator.md, "Saving and loading results").
:class:`ResultArchive` opens the zip archive and reads its members on demand: a member's ``.npy``
header is parsed first (through a reader that never gives more than a header's worth of bytes)
and must agree with the size the zip directory gives the member; its data is then read in
chunks, never past that size, so neither a header claiming a huge shape nor a lying zip
directory can make the reader allocate more than the file's checked size. :func:`read_saved`
checks every entry of a result file (names, dtypes, shapes, counts, finiteness, the JSON
metadata's structure) and reads only the entries :meth:`~packbot.SimResult.load` uses, before
anything is built from them; :func:`read_trajectory` reads the sample times and joint positions
alone (``packbot regress``). Every refusal is a :class:`~packbot.errors.ResultFileError` naming
the file and the entry.
"""

from __future__ import annotations

import json
import math
import re
import struct
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import IO, Any, NoReturn

import numpy as np
from numpy.lib import format as npy_format
from numpy.typing import NDArray

from packbot.errors import ResultFileError
from packbot.validation import MAX_EVENTS_LIMIT, MAX_SAMPLES

__all__ = [
    "COLUMN_ARRAYS",
    "CONTACT_ARRAYS",
    "CONTACT_INTS",
    "CONTACT_SAMPLES",
    "CONTACT_VECTORS",
    "ENTRIES",
    "EVENT_FLOATS",
    "EVENT_STRINGS",
    "EVENT_VELOCITIES",
    "IMPACT_ARRAYS",
    "MAX_JSON_DEPTH",
    "MAX_MEMBERS",
    "MAX_META_CHARS",
    "MAX_RESULT_BYTES",
    "MAX_RESULT_SAMPLES",
    "META_FIELDS",
    "PLAIN_COPIES",
    "READ_ENTRIES",
    "RESULT_FORMAT",
    "RESULT_FORMAT_1",
    "RESULT_FORMAT_2",
    "RESULT_FORMAT_3",
    "RESULT_FORMAT_4",
    "SAMPLE_ARRAYS",
    "NpyHeader",
    "ResultArchive",
    "SavedResult",
    "check_meta",
    "check_value",
    "parse_json",
    "read_saved",
    "read_trajectory",
]

#: The format tag of a file written by :meth:`SimResult.save` (its version after the slash).
RESULT_FORMAT = "packbot.SimResult/5"
#: The tag of the format before the contact forces (read: a result without them).
RESULT_FORMAT_1 = "packbot.SimResult/1"
#: The tag of the format before the stops' torques and the known mask (read: every sample
#: counted known, as that format stored an unknown sample as one without contacts; the
#: stops' torques NaN).
RESULT_FORMAT_2 = "packbot.SimResult/2"
#: The tag of the format before the impacts' impulses (read: a result without impacts).
RESULT_FORMAT_3 = "packbot.SimResult/3"
#: The tag of the format before the report's law's clamp torques (read: clamp torques 0 where
#: the forces are known, NaN where not; the impacts' clamp impulses 0).
RESULT_FORMAT_4 = "packbot.SimResult/4"
#: The entries :data:`RESULT_FORMAT_4` does not have.
CLAMP_ARRAYS = ("contact_clamp_torque", "impact_clamp_impulse")
#: The sample arrays, one row per sample time: ``t`` and ``energy`` of shape (N,), the others
#: (N, number of joints).
SAMPLE_ARRAYS = ("t", "q", "v", "tau", "energy", "tau_cmd", "tau_friction", "effort")
#: The sample arrays with one column per joint.
COLUMN_ARRAYS = ("q", "v", "tau", "tau_cmd", "tau_friction", "effort")
#: The float fields of an event (saved as arrays ``event_<name>``, one value per event).
EVENT_FLOATS = ("t", "distance", "energy_before", "energy_after")
#: The string fields of an event (saved in the JSON metadata).
EVENT_STRINGS = ("kind", "link1", "link2", "piece1", "piece2")
#: The events' velocities (``event_<name>``: concatenated; ``event_<name>_len``: each length).
EVENT_VELOCITIES = ("v_before", "v_after")
#: The contact forces' integer columns (``contact_<name>``: one row per contact and sample).
CONTACT_INTS = ("sample", "pair")
#: The contact forces' vector columns, shape (K, 3) each (:class:`packbot.ContactTable`).
CONTACT_VECTORS = ("point", "point1", "point2", "normal", "force")
#: The contact forces' per-sample entries: ``contact_known`` (N,) 0/1,
#: ``contact_limit_torque`` and ``contact_clamp_torque`` (N, number of joints) [N*m] (NaN where
#: not known).
CONTACT_SAMPLES = ("known", "limit_torque", "clamp_torque")
#: The contact forces' entries.
CONTACT_ARRAYS = tuple(f"contact_{n}" for n in (*CONTACT_INTS, *CONTACT_VECTORS, *CONTACT_SAMPLES))
#: The impacts' entries (:class:`packbot.ImpactTable`): ``impact_t`` (I,) [s], the rows'
#: ``impact_sample`` (the impact's index) and ``impact_pair`` (of ``meta_json.impact_pairs``),
#: their vectors (K, 3) (``impact_force``: the impulses [N*s]), ``impact_limit_impulse`` and
#: ``impact_clamp_impulse`` (I, number of joints) [N*m*s].
IMPACT_ARRAYS = (
    "impact_t",
    *(f"impact_{n}" for n in (*CONTACT_INTS, *CONTACT_VECTORS)),
    "impact_limit_impulse",
    "impact_clamp_impulse",
)
#: The event floats that may be NaN (not measured): the distance and the energies.
_EVENT_NAN_OK = ("distance", "energy_before", "energy_after")
#: Plain copies for a reader with NumPy alone: checked by their headers, never read.
PLAIN_COPIES = ("joint_names", "scenario_text", "packbot_version", "config_json", "rest_time")
#: The entries :meth:`SimResult.load` reads.
READ_ENTRIES: tuple[str, ...] = (
    "format",
    "meta_json",
    *SAMPLE_ARRAYS,
    *(f"event_{n}" for n in EVENT_FLOATS),
    *(f"event_{n}{s}" for n in EVENT_VELOCITIES for s in ("_len", "")),
    *CONTACT_ARRAYS,
    *IMPACT_ARRAYS,
)
#: Every entry a result file has (any other is an ``extra``: a 0-d text entry).
ENTRIES: tuple[str, ...] = (*READ_ENTRIES, *PLAIN_COPIES)
#: The fields of the JSON metadata (``meta_json``), each required.
META_FIELDS = (
    "format",
    "packbot_version",
    "joint_names",
    "rest_time",
    "control_ticks",
    "config",
    "diagnostics",
    "failures",
    "environment",
    "payload",
    "scenario_text",
    "events",
    "contact_pairs",
    "impact_pairs",
)
#: The fields of an event in the JSON metadata.
_EVENT_META = (*EVENT_STRINGS, "relevant_joints")

#: The most samples a result of :func:`packbot.simulate` holds: every ``sample_dt``
#: (``validation.MAX_SAMPLES``), the final state, and the instants just before and after each
#: event (``validation.MAX_EVENTS_LIMIT``).
MAX_RESULT_SAMPLES = MAX_SAMPLES + 1 + 2 * MAX_EVENTS_LIMIT
#: The most characters of the JSON metadata (64 Mi): the events' names take about 200 per event,
#: 20 M at ``MAX_EVENTS_LIMIT`` events; settings, obstacles and the scenario text are small.
MAX_META_CHARS = 64 * 2**20
#: The most bytes the entries a load reads may hold in all, uncompressed (1 GiB): the largest
#: result is about 560 MB (``MAX_RESULT_SAMPLES`` samples of 6 arrays of 8 joints and 2 of one,
#: 400 B each: 280 MB; 100,000 events of 22 floats: 18 MB; the JSON metadata at
#: ``MAX_META_CHARS``, 4 B a character as NumPy stores text: 256 MiB), so the bound leaves twice
#: that room while keeping a damaged or hostile file from taking more memory than a real one.
MAX_RESULT_BYTES = 2**30
#: The deepest nesting of the JSON metadata (its deepest legitimate value, an obstacle's point,
#: is 6 levels deep: metadata, environment, obstacles, obstacle, points, point).
MAX_JSON_DEPTH = 8
#: The most members of a result file's zip archive (23 entries, plus ``save``'s extras).
MAX_MEMBERS = 1000
#: The most bytes of a ``.npy`` header: NumPy's own safe bound (10,000 characters) plus the magic
#: string and the length field.
_HEADER_BYTES = 10_000 + 12
#: Bytes read from a member at a time.
_CHUNK = 2**20
#: The most bytes of the ``format`` entry (the tag is 19 characters, 76 B).
_FORMAT_BYTES = 4096

#: What reading a damaged member's stream raises (the zip module's CRC check, zlib, a short file).
_STREAM_ERRORS: tuple[type[BaseException], ...] = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
)
#: What the zip module and zlib raise on a damaged archive or member.
_ZIP_ERRORS: tuple[type[BaseException], ...] = (
    zipfile.BadZipFile,
    zipfile.LargeZipFile,
    zlib.error,
    struct.error,
    OSError,
    EOFError,
    ValueError,
    OverflowError,
    IndexError,
    KeyError,
    NotImplementedError,
    RuntimeError,
)


def _name(exc: BaseException) -> str:
    """The exception's class name, with its module for zlib's (whose class is ``error``)."""
    return "zlib.error" if isinstance(exc, zlib.error) else type(exc).__name__


def _short(value: object, n: int = 80) -> str:
    """``repr(value)``, cut to ``n`` characters (a hostile value may be huge)."""
    text = repr(value)
    return text if len(text) <= n else text[: n - 3] + "..."


@dataclass(frozen=True)
class NpyHeader:
    """A member's ``.npy`` header.

    Attributes:
        shape: The array's shape.
        fortran_order: Whether its data is in Fortran order.
        dtype: Its dtype.
        offset: Bytes of the magic string and header (where the data starts).
    """

    shape: tuple[int, ...]
    fortran_order: bool
    dtype: np.dtype[Any]
    offset: int

    @property
    def nbytes(self) -> int:
        """Bytes of the array's data."""
        return math.prod(self.shape) * self.dtype.itemsize

    @property
    def kind(self) -> str:
        """``"real"`` (float up to 64 bits, or integer), ``"int"``, ``"text"`` or ``"other"``."""
        k = self.dtype.kind
        if k == "f" and self.dtype.itemsize <= 8:
            return "real"
        if k in "iu":
            return "int"
        return "text" if k == "U" else "other"


class _Overrun(ValueError):
    """A read past a member's bound."""


class _Bounded:
    """A member's stream that gives at most ``limit`` bytes in all; asking for more is an error."""

    def __init__(self, fp: IO[bytes], limit: int) -> None:
        self.fp = fp
        self.limit = limit
        self.pos = 0

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0 or self.pos + n > self.limit:
            raise _Overrun(f"a read of {n} bytes at byte {self.pos}, past the bound {self.limit}")
        data = self.fp.read(n)
        self.pos += len(data)
        return data


class ResultArchive:
    """An open ``.npz`` file: its zip directory read, its members read on demand, each bounded.

    Every member must be a ``.npy`` array (``np.savez`` writes nothing else), stored or
    deflated, not encrypted, under :data:`MAX_RESULT_BYTES` and named once; there are at most
    :data:`MAX_MEMBERS`. Use as a context manager.

    Attributes:
        path: The file.
        members: Entry name (the member's name without ``.npy``) -> its zip directory record.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            what = "not a regular file" if self.path.exists() else "no such file"
            raise ResultFileError(self.path, what)
        try:
            self._zip = zipfile.ZipFile(self.path)
            infos = self._zip.infolist()
        except _ZIP_ERRORS as exc:
            raise ResultFileError(self.path, f"not a readable .npz file ({exc})") from exc
        self._headers: dict[str, NpyHeader] = {}
        self.members: dict[str, zipfile.ZipInfo] = {}
        try:
            if len(infos) > MAX_MEMBERS:
                self.fail("", f"{len(infos)} zip members (expected at most {MAX_MEMBERS})")
            for info in infos:
                name = info.filename
                if not name.endswith(".npy"):
                    self.fail(name, "a zip member that is not a .npy array (expected NAME.npy)")
                if name[:-4] in self.members:
                    self.fail(name[:-4], "twice in the zip directory (expected once)")
                self.members[name[:-4]] = info
        except ResultFileError:
            self.close()
            raise

    def __enter__(self) -> ResultArchive:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the file."""
        self._zip.close()

    def fail(self, entry: str, reason: str) -> NoReturn:
        """Raise the :class:`~packbot.errors.ResultFileError` of ``entry`` of this file."""
        raise ResultFileError(self.path, reason, entry)

    def _member(self, entry: str) -> zipfile.ZipInfo:
        info = self.members.get(entry)
        if info is None:
            self.fail(entry, "missing (no such zip member)")
        return info

    def _open(self, entry: str) -> IO[bytes]:
        info = self._member(entry)
        if info.flag_bits & 0x1:
            self.fail(entry, "an encrypted zip member (np.savez writes none)")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            self.fail(
                entry,
                f"zip compression method {info.compress_type} (expected stored or deflated)",
            )
        if info.file_size > MAX_RESULT_BYTES:
            self.fail(
                entry,
                f"the zip directory gives it {info.file_size:,} bytes "
                f"(expected at most {MAX_RESULT_BYTES:,})",
            )
        try:
            return self._zip.open(info)
        except _ZIP_ERRORS as exc:
            self.fail(entry, f"a damaged zip member ({_name(exc)}: {exc})")

    def header(self, entry: str) -> NpyHeader:
        """The ``.npy`` header of ``entry``, checked against the member's size.

        Only the header's bytes are decompressed. The data's size (shape times item size) plus
        the header's must be the size the zip directory gives the member; the dtype must not
        hold Python objects (nothing is unpickled) and must have a size.
        """
        if entry in self._headers:
            return self._headers[entry]
        with self._open(entry) as raw:
            size = self.members[entry].file_size
            fp = _Bounded(raw, min(size, _HEADER_BYTES))
            try:
                version = npy_format.read_magic(fp)
                if version == (1, 0):
                    shape, fortran, dtype = npy_format.read_array_header_1_0(fp)
                elif version == (2, 0):
                    shape, fortran, dtype = npy_format.read_array_header_2_0(fp)
                else:
                    raise ValueError(f"npy format version {version} (expected 1.0 or 2.0)")
            except _STREAM_ERRORS as exc:
                self.fail(entry, f"a damaged zip member ({_name(exc)}: {exc})")
            except Exception as exc:  # NumPy's header parser on untrusted bytes: any error
                self.fail(entry, f"not a valid .npy header ({type(exc).__name__}: {exc})")
        head = NpyHeader(tuple(shape), bool(fortran), np.dtype(dtype), fp.pos)
        if head.dtype.hasobject:
            self.fail(entry, f"dtype {head.dtype} holds Python objects (expected plain data)")
        if head.dtype.itemsize == 0 or any(d < 0 for d in head.shape):
            self.fail(entry, f"dtype {head.dtype} of shape {head.shape} (expected a real array)")
        if head.offset + head.nbytes != size:
            self.fail(
                entry,
                f"its header says shape {head.shape} of {head.dtype} ({head.nbytes:,} bytes of "
                f"data) but the zip directory gives the member {size:,} bytes, {head.offset} of "
                "them header",
            )
        self._headers[entry] = head
        return head

    def array(self, entry: str) -> NDArray[Any]:
        """The array of ``entry``: its header checked, its data read to exactly its size.

        The data is decompressed in chunks into a buffer that grows with what actually arrives,
        never past the header's size; the zip module checks the member's CRC at its end.
        """
        head = self.header(entry)
        buf = bytearray()
        with self._open(entry) as raw:
            fp = _Bounded(raw, head.offset + head.nbytes)
            try:
                fp.read(head.offset)
                while len(buf) < head.nbytes:
                    chunk = fp.read(min(_CHUNK, head.nbytes - len(buf)))
                    if not chunk:
                        self.fail(
                            entry,
                            f"its data ends after {len(buf):,} of {head.nbytes:,} bytes",
                        )
                    buf += chunk
            except _ZIP_ERRORS as exc:
                self.fail(entry, f"a damaged zip member ({_name(exc)}: {exc})")
        arr = np.frombuffer(buf, dtype=head.dtype, count=math.prod(head.shape))
        return arr.reshape(head.shape, order="F" if head.fortran_order else "C")

    def text(self, entry: str) -> str:
        """The text of a 0-d text entry."""
        return str(self.array(entry)[()])


@dataclass(frozen=True)
class SavedResult:
    """A result file's checked contents, for :meth:`SimResult.load` to build a result from.

    Attributes:
        path: The file.
        arrays: Each of :data:`SAMPLE_ARRAYS`, float64.
        event_floats: Each of :data:`EVENT_FLOATS` -> one value per event, float64.
        event_velocities: ``"v_before"``, ``"v_after"`` -> each event's velocities, float64.
        meta: The JSON metadata, its structure checked (:func:`check_meta`).
        contacts: Each of :data:`CONTACT_INTS` and :data:`CONTACT_VECTORS` -> its column
            (int64, float64), checked against the samples and ``meta["contact_pairs"]``
            (empty for a file of the format before them).
        impacts: ``t`` and the impacts' columns as ``contacts`` (``limit_torque``: the stops'
            impulses), checked against ``meta["impact_pairs"]`` (empty for a file of the
            formats before them).
    """

    path: Path
    arrays: dict[str, NDArray[np.float64]]
    event_floats: dict[str, NDArray[np.float64]]
    event_velocities: dict[str, list[NDArray[np.float64]]]
    meta: dict[str, Any]
    contacts: dict[str, NDArray[Any]]
    impacts: dict[str, NDArray[Any]] = field(default_factory=dict)

    def fail(self, entry: str, reason: str) -> NoReturn:
        """Raise the :class:`~packbot.errors.ResultFileError` of ``entry`` of this file."""
        raise ResultFileError(self.path, reason, entry)


_SHAPES = {
    "format": "0-d text",
    "meta_json": "0-d text",
    "scenario_text": "0-d text",
    "packbot_version": "0-d text",
    "config_json": "0-d text",
    "joint_names": "1-d text",
    "rest_time": "0-d real",
    "t": "1-d real",
    "energy": "1-d real",
    **dict.fromkeys(COLUMN_ARRAYS, "2-d real"),
    **{f"event_{n}": "1-d real" for n in (*EVENT_FLOATS, *EVENT_VELOCITIES)},
    **{f"event_{n}_len": "1-d int" for n in EVENT_VELOCITIES},
    **{f"contact_{n}": "1-d int" for n in CONTACT_INTS},
    **{f"contact_{n}": "2-d real" for n in CONTACT_VECTORS},
    "contact_known": "1-d int",
    "contact_limit_torque": "2-d real",
    "contact_clamp_torque": "2-d real",
    "impact_t": "1-d real",
    **{f"impact_{n}": "1-d int" for n in CONTACT_INTS},
    **{f"impact_{n}": "2-d real" for n in CONTACT_VECTORS},
    "impact_limit_impulse": "2-d real",
    "impact_clamp_impulse": "2-d real",
}
_WHAT = {
    "text": "text (a NumPy str array)",
    "real": "real numbers (a float dtype of at most 64 bits, or an integer dtype)",
    "int": "integers",
}


def _check_header(archive: ResultArchive, entry: str, want: str) -> NpyHeader:
    """The header of ``entry``, whose dimensions and kind must be ``want`` ("1-d real", ...)."""
    head = archive.header(entry)
    ndim, kind = int(want[0]), want.split()[1]
    ok = head.kind == kind or (kind == "real" and head.kind == "int")
    if not ok:
        archive.fail(entry, f"dtype {head.dtype} (expected {_WHAT[kind]})")
    if len(head.shape) != ndim:
        archive.fail(entry, f"shape {head.shape} (expected a {ndim}-d array)")
    return head


def read_saved(path: str | Path) -> SavedResult:
    """Read and check a result file: every entry's header, then the entries a load uses.

    Args:
        path: The file.

    Returns:
        Its checked contents.

    Raises:
        ResultFileError: The file is missing, not a readable ``.npz`` archive, not a packbot
            result (no or another format tag), or damaged or inconsistent; the error names the
            entry.
    """
    with ResultArchive(path) as archive:
        if "format" not in archive.members or "meta_json" not in archive.members:
            archive.fail("format", f"no format tag (expected {RESULT_FORMAT!r})")
        if _check_header(archive, "format", "0-d text").nbytes > _FORMAT_BYTES:
            archive.fail("format", f"a tag of over {_FORMAT_BYTES} bytes")
        tag = archive.text("format")
        if tag not in (
            RESULT_FORMAT,
            RESULT_FORMAT_4,
            RESULT_FORMAT_3,
            RESULT_FORMAT_2,
            RESULT_FORMAT_1,
        ):
            archive.fail("format", f"format {_short(tag)}, expected {RESULT_FORMAT!r}")
        version_1 = tag == RESULT_FORMAT_1
        heads = _check_entries(archive, tag)
        meta_head = heads["meta_json"]
        if meta_head.nbytes > 4 * MAX_META_CHARS:
            archive.fail(
                "meta_json",
                f"{meta_head.nbytes // 4:,} characters (expected at most {MAX_META_CHARS:,})",
            )
        total = sum(heads[e].nbytes for e in READ_ENTRIES if e in heads)
        if total > MAX_RESULT_BYTES:
            archive.fail(
                "",
                f"its entries hold {total:,} bytes uncompressed (expected at most "
                f"{MAX_RESULT_BYTES:,}, the bound of docs/simulator.md)",
            )
        meta = check_meta(
            parse_json(archive.text("meta_json"), archive.fail), archive.fail, tag=tag
        )
        _check_shapes(archive, heads, len(meta["joint_names"]), len(meta["events"]))
        arrays = {name: _floats(archive, name) for name in SAMPLE_ARRAYS}
        t = arrays["t"]
        if not np.all(t[1:] >= t[:-1]):
            k = int(np.flatnonzero(t[1:] < t[:-1])[0])
            archive.fail(
                "t",
                f"t[{k + 1}] = {float(t[k + 1])!r} < t[{k}] = {float(t[k])!r} (expected times "
                "that never decrease)",
            )
        rest = meta["rest_time"]
        if rest is not None and not t[0] <= rest <= t[-1]:
            archive.fail(
                "meta_json.rest_time",
                f"{rest!r} (expected None or a time in [{float(t[0])!r}, {float(t[-1])!r}], the "
                "samples' span)",
            )
        floats = {
            name: _floats(archive, f"event_{name}", nan_ok=name in _EVENT_NAN_OK)
            for name in EVENT_FLOATS
        }
        vels = {
            name: _velocities(archive, name, len(meta["joint_names"])) for name in EVENT_VELOCITIES
        }
        n_joints = len(meta["joint_names"])
        contacts = {} if version_1 else _contacts(archive, len(t), len(meta["contact_pairs"]))
        if tag == RESULT_FORMAT_2:
            contacts["known"] = np.ones(len(t), dtype=bool)
            contacts["limit_torque"] = np.full((len(t), n_joints), np.nan)
            contacts["clamp_torque"] = np.full((len(t), n_joints), np.nan)
        elif not version_1:
            contacts.update(_contact_samples(archive, len(t), n_joints, tag == RESULT_FORMAT))
        impacts = (
            _impacts(archive, (float(t[0]), float(t[-1])), n_joints, meta, tag == RESULT_FORMAT)
            if tag in (RESULT_FORMAT, RESULT_FORMAT_4)
            else {}
        )
    return SavedResult(archive.path, arrays, floats, vels, meta, contacts, impacts)


def _impacts(
    archive: ResultArchive,
    span: tuple[float, float],
    n_joints: int,
    meta: dict[str, Any],
    clamps: bool = True,
) -> dict[str, NDArray[Any]]:
    """The impacts' entries: their times, rows, stops' and clamps' impulses.

    The times never decrease and lie within the samples' ``span`` [s]; the rows' pairs are
    those of ``meta["impact_pairs"]``. ``clamps`` False: a file of :data:`RESULT_FORMAT_4`
    (no clamp impulses: zeros).
    """
    n = archive.header("impact_t").shape[0]
    for name in ("impact_limit_impulse", "impact_clamp_impulse")[: 2 if clamps else 1]:
        shape = archive.header(name).shape
        if shape != (n, n_joints):
            archive.fail(name, f"shape {shape} (expected {(n, n_joints)}: a row per impact)")
    t = _floats(archive, "impact_t")
    if not np.all(t[1:] >= t[:-1]):
        k = int(np.flatnonzero(t[1:] < t[:-1])[0])
        archive.fail(
            "impact_t", f"impact_t[{k + 1}] < impact_t[{k}] (expected times that never decrease)"
        )
    outside = (t < span[0]) | (t > span[1])
    if outside.any():
        k = int(np.flatnonzero(outside)[0])
        archive.fail(
            "impact_t",
            f"impact_t[{k}] = {float(t[k])!r} (expected times within the samples' "
            f"[{span[0]!r}, {span[1]!r}])",
        )
    out = _contacts(archive, n, len(meta["impact_pairs"]), "impact_")
    out["t"] = t
    out["limit_torque"] = _floats(archive, "impact_limit_impulse")
    out["clamp_torque"] = (
        _floats(archive, "impact_clamp_impulse") if clamps else np.zeros((n, n_joints))
    )
    return out


def _contacts(
    archive: ResultArchive, n_samples: int, n_pairs: int, prefix: str = "contact_"
) -> dict[str, NDArray[Any]]:
    """The contact columns: K rows each, samples in order, pairs of ``contact_pairs``.

    ``prefix`` ``"impact_"``: the impacts' rows (their "samples" the impacts, their pairs
    ``impact_pairs``).
    """
    k = archive.header(f"{prefix}sample").shape[0]
    for name in CONTACT_INTS:
        shape = archive.header(f"{prefix}{name}").shape
        if shape != (k,):
            archive.fail(f"{prefix}{name}", f"shape {shape} (expected ({k},), as {prefix}sample)")
    for name in CONTACT_VECTORS:
        shape = archive.header(f"{prefix}{name}").shape
        if shape != (k, 3):
            archive.fail(f"{prefix}{name}", f"shape {shape} (expected ({k}, 3): a row per contact)")
    out: dict[str, NDArray[Any]] = {}
    what = "impact" if prefix == "impact_" else "sample"
    for name, bound in (("sample", n_samples), ("pair", n_pairs)):
        col = np.asarray(archive.array(f"{prefix}{name}"), dtype=np.int64)
        bad = (col < 0) | (col >= bound)
        if name == "sample" and len(col) > 1:
            bad[1:] |= col[1:] < col[:-1]
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            archive.fail(
                f"{prefix}{name}",
                f"{prefix}{name}[{i}] = {int(col[i])} (expected "
                + (
                    f"non-decreasing {what} indices in [0, {n_samples}))"
                    if name == "sample"
                    else f"an index of meta_json.{prefix}pairs, in [0, {n_pairs}))"
                ),
            )
        out[name] = col
    for name in CONTACT_VECTORS:
        out[name] = _floats(archive, f"{prefix}{name}")
    return out


def _contact_samples(
    archive: ResultArchive, n_samples: int, n_joints: int, clamps: bool = True
) -> dict[str, NDArray[Any]]:
    """The per-sample contact entries: the known mask (0/1), the stops' and clamps' torques.

    ``clamps`` False: a file of :data:`RESULT_FORMAT_4` (clamp torques 0 where known, NaN
    where not).
    """
    names = ("known", "limit_torque", "clamp_torque")[: 3 if clamps else 2]
    for name in names:
        want = (n_samples,) if name == "known" else (n_samples, n_joints)
        shape = archive.header(f"contact_{name}").shape
        if shape != want:
            archive.fail(f"contact_{name}", f"shape {shape} (expected {want}: a row per sample)")
    known = np.asarray(archive.array("contact_known"), dtype=np.int64)
    bad = (known != 0) & (known != 1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        archive.fail("contact_known", f"contact_known[{i}] = {int(known[i])} (expected 0 or 1)")
    limit = _floats(archive, "contact_limit_torque", nan_ok=True)
    if clamps:
        clamp = _floats(archive, "contact_clamp_torque", nan_ok=True)
    else:
        clamp = np.where(known.astype(bool)[:, None], 0.0, np.nan) * np.ones((1, n_joints))
    return {"known": known.astype(bool), "limit_torque": limit, "clamp_torque": clamp}


def _check_entries(archive: ResultArchive, tag: str = RESULT_FORMAT) -> dict[str, NpyHeader]:
    """Every entry's header: the format's entries present and of their kind, extras 0-d text.

    A file of the format before the contact forces (:data:`RESULT_FORMAT_1`) has no contact
    entries; one before the stops' torques (:data:`RESULT_FORMAT_2`) no per-sample ones.
    """
    absent: tuple[str, ...] = ()
    if tag == RESULT_FORMAT_1:
        absent = CONTACT_ARRAYS + IMPACT_ARRAYS
    elif tag == RESULT_FORMAT_2:
        absent = tuple(f"contact_{n}" for n in CONTACT_SAMPLES) + IMPACT_ARRAYS
    elif tag == RESULT_FORMAT_3:
        absent = IMPACT_ARRAYS + CLAMP_ARRAYS
    elif tag == RESULT_FORMAT_4:
        absent = CLAMP_ARRAYS
    entries = [e for e in ENTRIES if e not in absent]
    missing = [e for e in entries if e not in archive.members]
    if missing:
        archive.fail(
            missing[0], f"corrupt: missing (a result file has the entries {', '.join(entries)})"
        )
    heads = {e: _check_header(archive, e, _SHAPES[e]) for e in entries}
    for entry in archive.members:
        if entry in heads:
            continue
        if entry.startswith(("event_", "contact_", "impact_")):
            archive.fail(
                entry, "an unknown entry (the event_, contact_ and impact_ names are the format's)"
            )
        head = archive.header(entry)
        if head.kind != "text" or head.shape != ():
            archive.fail(
                entry,
                f"an unknown entry of dtype {head.dtype} and shape {head.shape} (expected one of "
                f"the format's entries, or a 0-d text entry of save(extra=...))",
            )
    return heads


def _check_shapes(
    archive: ResultArchive, heads: dict[str, NpyHeader], n_joints: int, n_events: int
) -> None:
    """The entries' shapes agree: samples with ``t``, columns with the joints, events."""
    n = heads["t"].shape[0]
    if n < 1:
        archive.fail("t", "no samples (expected at least one: a result holds its start)")
    for name in SAMPLE_ARRAYS[1:]:
        want = (n,) if name == "energy" else (n, n_joints)
        if heads[name].shape != want:
            archive.fail(
                name,
                f"shape {heads[name].shape} (expected {want}: a row per sample time of t"
                + (")" if name == "energy" else f", a column per joint of {n_joints})"),
            )
    if heads["joint_names"].shape != (n_joints,):
        archive.fail(
            "joint_names",
            f"shape {heads['joint_names'].shape} (expected ({n_joints},), the metadata's joints)",
        )
    for name in (*EVENT_FLOATS, *(f"{v}_len" for v in EVENT_VELOCITIES)):
        if heads[f"event_{name}"].shape != (n_events,):
            archive.fail(
                f"event_{name}",
                f"shape {heads[f'event_{name}'].shape} (expected ({n_events},): a value per "
                "event of meta_json.events)",
            )


def _floats(archive: ResultArchive, entry: str, nan_ok: bool = False) -> NDArray[np.float64]:
    """A real entry as float64; every value finite (or NaN where ``nan_ok``)."""
    arr = np.asarray(archive.array(entry), dtype=np.float64)
    bad = ~np.isfinite(arr)
    if nan_ok:
        bad &= ~np.isnan(arr)
    if bad.any():
        k = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
        index = ", ".join(str(int(i)) for i in k)
        archive.fail(
            entry,
            f"{entry}[{index}] = {float(arr[k])!r} (expected finite values"
            + (" or NaN)" if nan_ok else ")"),
        )
    return arr


def _velocities(archive: ResultArchive, name: str, n_joints: int) -> list[NDArray[np.float64]]:
    """The events' velocities ``name``: each event's length 0 or the joints', summing up."""
    lens = archive.array(f"event_{name}_len")
    bad = (lens != 0) & (lens != n_joints)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        archive.fail(
            f"event_{name}_len",
            f"event {k}'s length {int(lens[k])} (expected 0 or {n_joints}, the joints)",
        )
    head = archive.header(f"event_{name}")
    total = int(np.count_nonzero(lens)) * n_joints
    if head.shape != (total,):
        archive.fail(
            f"event_{name}",
            f"shape {head.shape} (expected ({total},): the sum of event_{name}_len)",
        )
    flat = _floats(archive, f"event_{name}")
    ends = np.cumsum(np.asarray(lens, dtype=np.int64))
    return [flat[e - int(n) : e].copy() for e, n in zip(ends, lens, strict=True)]


# ------------------------------------------------------------------------------- the metadata
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")

Fail = Callable[[str, str], NoReturn]


def parse_json(text: str, fail: Fail, entry: str = "meta_json") -> Any:
    """The JSON ``text``, its nesting at most :data:`MAX_JSON_DEPTH` deep (checked first)."""
    brackets = _NOT_BRACKET.sub("", _STRING.sub("", text)).encode("ascii")
    if brackets:
        steps = np.frombuffer(brackets, dtype=np.uint8)
        depth = np.cumsum(np.where((steps == ord("[")) | (steps == ord("{")), 1, -1))
        if int(depth.max()) > MAX_JSON_DEPTH:
            fail(entry, f"JSON nested {int(depth.max())} deep (expected at most {MAX_JSON_DEPTH})")
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        fail(entry, f"not valid JSON ({type(exc).__name__}: {_short(str(exc), 200)})")


def _is_real(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _list_of(value: object, kind: type, fail: Fail, entry: str, what: str) -> list[Any]:
    if not isinstance(value, list) or not all(isinstance(v, kind) for v in value):
        fail(entry, f"{_short(value)} (expected {what})")
    return value


def check_meta(meta: object, fail: Fail, tag: str = RESULT_FORMAT) -> dict[str, Any]:
    """The JSON metadata, its structure checked: every field present, known and of its type.

    The settings', diagnostics', failures', obstacles' and payload's own fields are checked by
    :meth:`SimResult.load` (their constructors); here each must be an object of string keys.

    Args:
        meta: The parsed JSON.
        fail: Raises the error of an entry (``fail(entry, reason)``).
        tag: The file's format tag (:data:`RESULT_FORMAT_1`: no ``contact_pairs``; a format
            before :data:`RESULT_FORMAT`: no ``impact_pairs``).

    Returns:
        ``meta``, with ``rest_time`` a float or None (and ``contact_pairs`` and
        ``impact_pairs`` lists of tuples, empty for the formats before them).
    """
    if not isinstance(meta, dict):
        fail("meta_json", f"a JSON {type(meta).__name__} (expected an object)")
    fields = [
        k
        for k in META_FIELDS
        if not (tag == RESULT_FORMAT_1 and k == "contact_pairs")
        and not (tag not in (RESULT_FORMAT, RESULT_FORMAT_4) and k == "impact_pairs")
    ]
    for key in fields:
        if key not in meta:
            fail(f"meta_json.{key}", "missing (expected in the metadata)")
    for key in meta:
        if key not in fields:
            fail(f"meta_json.{key}", f"an unknown field (expected {', '.join(fields)})")
    if meta["format"] != tag:
        fail("meta_json.format", f"{_short(meta['format'])} (expected {tag!r})")
    for name in ("contact_pairs", "impact_pairs"):
        pairs = _list_of(meta.get(name, []), list, fail, f"meta_json.{name}", "pairs")
        for k, pair in enumerate(pairs):
            if len(pair) != 4 or not all(isinstance(x, str) for x in pair):
                fail(
                    f"meta_json.{name}[{k}]",
                    f"{_short(pair)} (expected [link1, piece1, link2, piece2], four strings)",
                )
        meta[name] = [tuple(p) for p in pairs]
    for key in ("packbot_version", "scenario_text"):
        if not isinstance(meta[key], str):
            fail(f"meta_json.{key}", f"{_short(meta[key])} (expected a string)")
    names = _list_of(meta["joint_names"], str, fail, "meta_json.joint_names", "joint names")
    if not names or len(set(names)) != len(names) or not all(names):
        fail("meta_json.joint_names", f"{_short(names)} (expected distinct non-empty names)")
    rest = meta["rest_time"]
    if rest is not None:
        if not _is_real(rest) or not math.isfinite(_as_float(rest)):
            fail("meta_json.rest_time", f"{_short(rest)} (expected None or a finite time [s])")
        meta["rest_time"] = float(rest)
    ticks = meta["control_ticks"]
    if not isinstance(ticks, int) or isinstance(ticks, bool) or ticks < 0:
        fail("meta_json.control_ticks", f"{_short(ticks)} (expected an integer >= 0)")
    for key in ("config", "diagnostics"):
        _object(meta[key], fail, f"meta_json.{key}")
    for k, f in enumerate(_list_of(meta["failures"], dict, fail, "meta_json.failures", "a list")):
        _object(f, fail, f"meta_json.failures[{k}]")
    if meta["payload"] is not None:
        _object(meta["payload"], fail, "meta_json.payload")
    env = meta["environment"]
    if env is not None:
        _object(env, fail, "meta_json.environment")
        if set(env) != {"obstacles"}:
            fail("meta_json.environment", f"fields {sorted(env)} (expected ['obstacles'])")
        obstacles = _list_of(
            env["obstacles"], dict, fail, "meta_json.environment.obstacles", "a list of objects"
        )
        for k, ob in enumerate(obstacles):
            _object(ob, fail, f"meta_json.environment.obstacles[{k}]")
    events = _list_of(meta["events"], dict, fail, "meta_json.events", "a list of objects")
    known = set(names)
    for k, ev in enumerate(events):
        where = f"meta_json.events[{k}]"
        if set(ev) != set(_EVENT_META):
            fail(where, f"fields {_short(sorted(ev))} (expected {', '.join(_EVENT_META)})")
        for key in EVENT_STRINGS:
            if not isinstance(ev[key], str):
                fail(f"{where}.{key}", f"{_short(ev[key])} (expected a string)")
        joints = _list_of(ev["relevant_joints"], str, fail, f"{where}.relevant_joints", "names")
        if not known.issuperset(joints):
            fail(
                f"{where}.relevant_joints",
                f"{_short(joints)} (expected names of meta_json.joint_names)",
            )
    return meta


def _as_float(value: int | float) -> float:
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _object(value: object, fail: Fail, entry: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        fail(entry, f"{_short(value)} (expected a JSON object)")
    return value


def check_value(value: object, fail: Fail, entry: str, kind: str) -> None:
    """A stored number of kind ``"int"`` (>= 0), ``"float"`` (not NaN) or ``"str"``."""
    if kind == "int":
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
        what = "an integer >= 0"
    elif kind == "float":
        ok = _is_real(value) and not math.isnan(_as_float(value))  # type: ignore[arg-type]
        what = "a number"
    else:
        ok, what = isinstance(value, str), "a string"
    if not ok:
        fail(entry, f"{_short(value)} (expected {what})")


# ------------------------------------------------------------------------------- trajectories
def read_trajectory(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The sample times [s] and joint positions [rad] of an ``.npz`` file, read with bounds.

    Only the entries ``t`` and ``q`` are read (the rest of the archive is not checked): ``t``
    1-d, finite, never decreasing, at least one sample; ``q`` 2-d, a row per time, finite.

    Args:
        path: The file.

    Returns:
        ``(t, q)``, or None when the file has no ``t`` or no ``q`` (not a result's file).

    Raises:
        ResultFileError: The file is missing, not a readable archive, or ``t`` or ``q`` is
            damaged, of another dtype or shape, or not finite.
    """
    with ResultArchive(path) as archive:
        if "t" not in archive.members or "q" not in archive.members:
            return None
        t_head = _check_header(archive, "t", "1-d real")
        q_head = _check_header(archive, "q", "2-d real")
        if t_head.nbytes + q_head.nbytes > MAX_RESULT_BYTES:
            archive.fail("q", f"t and q hold over {MAX_RESULT_BYTES:,} bytes")
        n = t_head.shape[0]
        if n < 1:
            archive.fail("t", "no samples (expected at least one)")
        if q_head.shape[0] != n:
            archive.fail("q", f"shape {q_head.shape} (expected ({n}, joints): a row per time)")
        t, q = _floats(archive, "t"), _floats(archive, "q")
        if not np.all(t[1:] >= t[:-1]):
            archive.fail("t", "times that decrease (expected never decreasing)")
        return t, q
