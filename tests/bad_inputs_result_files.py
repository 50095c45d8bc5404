"""Bad-input catalogue, category ``result_file``: damaged, hand-made and inconsistent result files.

Each case writes a file into the case's folder and gives it to ``SimResult.load`` (a few to
``packbot.regress.read_trajectories``, which reads a batch's trajectories with the same bounded
reader); the clean outcome is a ``ResultFileError`` (``ResultValueError`` for a stored setting
its constructor refuses) whose message names the entry. The base file is the catalogue's short
valid run (``Ctx.result``) saved by ``SimResult.save``. The kinds:

- ``flip-*``: one byte of a read entry's compressed data inverted (not its last bytes: those
  may hold only the stream's end marker, which the zip module never decodes once it has the
  member's size: such a flip changes nothing read and is no damage);
- ``local-*``: a member's local zip header damaged (its signature, its name);
- ``truncate-*``, ``insert-*``: the file cut short, bytes inserted inside a member;
- ``array-*``, ``event-*``, ``text-*``: an entry replaced (wrong dtype, shape, count, values);
- ``meta-*``: the JSON metadata changed (wrong structure, types, nesting, stored values);
- ``zip-*``: zip-level forgeries (stray, duplicate, encrypted or bzip2 members, sizes that lie,
  headers claiming huge shapes);
- ``trajectory-*``: a batch trajectory file read by ``packbot regress``.

The helpers (:func:`npy`, :func:`zip_bytes`, :func:`layout`, :func:`patch_directory`, ...) are
shared with ``tests/test_result_file.py``.
"""

from __future__ import annotations

import io
import json
import struct
import warnings
import zipfile
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from packbot.errors import ResultFileError, ResultValueError
from packbot.result import SimResult
from packbot.result_file import (
    CONTACT_ARRAYS,
    ENTRIES,
    EVENT_FLOATS,
    IMPACT_ARRAYS,
    MAX_MEMBERS,
    SAMPLE_ARRAYS,
)

#: The entries a load reads, in the order ``save`` writes them.
READ_IN_FILE_ORDER = (
    *SAMPLE_ARRAYS,
    *(f"event_{n}" for n in EVENT_FLOATS),
    "event_v_before_len",
    "event_v_before",
    "event_v_after_len",
    "event_v_after",
    *CONTACT_ARRAYS,
    *IMPACT_ARRAYS,
    "format",
    "meta_json",
)
#: Every entry of a saved file, in the order ``save`` writes them.
FILE_ORDER = (
    *READ_IN_FILE_ORDER,
    "joint_names",
    "scenario_text",
    "packbot_version",
    "config_json",
    "rest_time",
)
assert set(FILE_ORDER) == set(ENTRIES)


# ------------------------------------------------------------------------ file helpers
def npy(arr: Any, *, allow_pickle: bool = False) -> bytes:
    """The ``.npy`` bytes of an array (``allow_pickle`` to forge an object array)."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.asanyarray(arr), allow_pickle=allow_pickle)
    return buf.getvalue()


def npy_header(shape: tuple[int, ...], descr: str, version: tuple[int, int] = (1, 0)) -> bytes:
    """A ``.npy`` header claiming ``shape`` of dtype ``descr`` (no data)."""
    buf = io.BytesIO()
    head = {"descr": descr, "fortran_order": False, "shape": shape}
    if version == (1, 0):
        np.lib.format.write_array_header_1_0(buf, head)
    else:
        np.lib.format.write_array_header_2_0(buf, head)
    return buf.getvalue()


def zip_bytes(members: Mapping[str, bytes], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    """A zip archive of ``members`` (name -> bytes, ``.npy`` added to names without a dot)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=method) as zf:
        for name, data in members.items():
            zf.writestr(name if "." in name else f"{name}.npy", data)
    return buf.getvalue()


def arrays_of(path: Path) -> dict[str, np.ndarray]:
    """Every entry of a valid (trusted) ``.npz`` file."""
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def npz(arrays: Mapping[str, Any], **replace: Any) -> bytes:
    """A compressed ``.npz`` of ``arrays`` with entries replaced (None: dropped; bytes: raw)."""
    merged = {**arrays, **replace}
    members = {}
    for name, value in merged.items():
        if value is None:
            continue
        members[name] = value if isinstance(value, bytes) else npy(value)
    return zip_bytes(members)


def meta_of(arrays: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON metadata of a file's entries."""
    meta: dict[str, Any] = json.loads(str(arrays["meta_json"]))
    return meta


@dataclass(frozen=True)
class Member:
    """Where a zip member lies in the file's bytes."""

    name: str
    header_offset: int  # its local header
    data_start: int  # its compressed data
    data_end: int


def layout(raw: bytes) -> dict[str, Member]:
    """Entry name (without ``.npy``) -> where its member lies in ``raw``."""
    out = {}
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        for info in zf.infolist():
            off = info.header_offset
            n_name, n_extra = struct.unpack("<HH", raw[off + 26 : off + 30])
            start = off + 30 + n_name + n_extra
            out[info.filename.removesuffix(".npy")] = Member(
                info.filename, off, start, start + info.compress_size
            )
    return out


def patch_directory(raw: bytes, name: str, **fields: int) -> bytes:
    """``raw`` with fields of ``name``'s central directory record replaced.

    Fields: ``flag_bits``, ``compress_type``, ``crc``, ``compress_size``, ``file_size``
    (32-bit values: the records ``np.savez`` writes for small files have no zip64 sizes).
    """
    at = {"flag_bits": (8, "<H"), "compress_type": (10, "<H"), "crc": (16, "<I")}
    at |= {"compress_size": (20, "<I"), "file_size": (24, "<I")}
    out = bytearray(raw)
    eocd = raw.rfind(b"PK\x05\x06")
    (count,) = struct.unpack("<H", raw[eocd + 10 : eocd + 12])
    (pos,) = struct.unpack("<I", raw[eocd + 16 : eocd + 20])
    member = name if "." in name else f"{name}.npy"
    for _ in range(count):
        assert raw[pos : pos + 4] == b"PK\x01\x02"
        n_name, n_extra, n_comment = struct.unpack("<HHH", raw[pos + 28 : pos + 34])
        if raw[pos + 46 : pos + 46 + n_name].decode() == member:
            for key, value in fields.items():
                off, fmt = at[key]
                struct.pack_into(fmt, out, pos + off, value)
            return bytes(out)
        pos += 46 + n_name + n_extra + n_comment
    raise KeyError(name)


def flip(raw: bytes, pos: int) -> bytes:
    """``raw`` with the byte at ``pos`` inverted."""
    out = bytearray(raw)
    out[pos] ^= 0xFF
    return bytes(out)


def deflated_zeros(header: bytes, n_zeros: int) -> bytes:
    """A raw deflate stream of ``header`` then ``n_zeros`` zero bytes, made in a blink.

    One MiB of zeros is compressed once, after a full flush (no reference back to earlier
    data), and its bytes repeated: 1 GiB of data in about 1 MB.
    """
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = c.compress(header) + c.flush(zlib.Z_FULL_FLUSH)
    mib = c.compress(bytes(2**20)) + c.flush(zlib.Z_FULL_FLUSH)
    k, rest = divmod(n_zeros, 2**20)
    return head + mib * k + c.compress(bytes(rest)) + c.flush()


def with_raw_member(raw: bytes, name: str, stream: bytes, file_size: int, crc: int = 0) -> bytes:
    """``raw`` with a member ``name`` added whose data is the deflate ``stream`` as it is.

    The zip directory gives it ``file_size`` bytes uncompressed and the CRC ``crc`` (the zip
    module checks the CRC only once it has read the whole member).
    """
    buf = io.BytesIO(raw)
    with zipfile.ZipFile(buf, "a", compression=zipfile.ZIP_STORED) as zf:
        zf.writestr(f"{name}.npy", stream)
    return patch_directory(
        buf.getvalue(), name, compress_type=zipfile.ZIP_DEFLATED, file_size=file_size, crc=crc
    )


# ------------------------------------------------------------------------ the cases
def register(cat: ModuleType) -> None:
    """Add the category's cases to the catalogue module ``cat`` (tests/bad_input_cases.py)."""

    def base(c: Any) -> tuple[bytes, dict[str, np.ndarray]]:
        path = c.result.save(c.tmp / "base.npz")
        return path.read_bytes(), arrays_of(path)

    def case(
        id: str,
        make: Callable[[Any, bytes, dict[str, np.ndarray]], bytes],
        *words: str,
        error: type = ResultFileError,
    ) -> None:
        def action(c: Any) -> Any:
            raw, arrays = base(c)
            return SimResult.load(c.write("r.npz", make(c, raw, arrays)))

        cat.add("result_file", id, action, *words, error=error)

    def replaced(id: str, entry: str, value: Any, *words: str) -> None:
        """A case whose file has ``entry`` replaced by ``value`` (an array or raw bytes)."""
        case(id, lambda c, raw, a: npz(a, **{entry: value}), *words)

    def entry(name: str) -> str:
        return f"entry {name!r}"

    # -- one byte of a read entry's compressed data inverted (the entry's CRC, its stream)
    for name in READ_IN_FILE_ORDER:
        for label, frac in (("first", 0.0), ("middle", 0.5), ("late", 0.75)):

            def make_flip(
                c: Any, raw: bytes, a: Any, name: str = name, frac: float = frac
            ) -> bytes:
                m = layout(raw)[name]
                return flip(raw, m.data_start + round(frac * (m.data_end - m.data_start - 1)))

            case(f"flip-{name}-{label}", make_flip, entry(name))
    for name in FILE_ORDER[len(READ_IN_FILE_ORDER) :]:  # the plain copies: their header's bytes

        def make_flip0(c: Any, raw: bytes, a: Any, name: str = name) -> bytes:
            return flip(raw, layout(raw)[name].data_start)

        case(f"flip-{name}-first", make_flip0, entry(name))

    # -- a member's local header damaged
    for name in FILE_ORDER:

        def make_sig(c: Any, raw: bytes, a: Any, name: str = name) -> bytes:
            return flip(raw, layout(raw)[name].header_offset)

        def make_name(c: Any, raw: bytes, a: Any, name: str = name) -> bytes:
            return flip(raw, layout(raw)[name].header_offset + 30)  # the name's first byte

        case(f"local-signature-{name}", make_sig, entry(name), "damaged")
        case(f"local-name-{name}", make_name, entry(name), "damaged")

    # -- the file cut short (the zip directory is at its end)
    for label, keep in (
        ("empty", lambda n: 0),
        ("1-byte", lambda n: 1),
        ("10pct", lambda n: n // 10),
        ("quarter", lambda n: n // 4),
        ("half", lambda n: n // 2),
        ("three-quarters", lambda n: 3 * n // 4),
        ("90pct", lambda n: 9 * n // 10),
        ("99pct", lambda n: 99 * n // 100),
        ("minus-22", lambda n: n - 22),
        ("minus-1", lambda n: n - 1),
    ):
        case(
            f"truncate-{label}",
            lambda c, raw, a, keep=keep: raw[: keep(len(raw))],
            "r.npz",
            "not a readable .npz file",
        )

    # -- bytes inserted inside a member: the members up to it are no longer where the zip
    # directory says (the first one a load reads: t for an array, the format tag otherwise)
    for k, name in enumerate(FILE_ORDER):
        first = (
            "t"
            if k < len(SAMPLE_ARRAYS) + 8 + len(CONTACT_ARRAYS) + len(IMPACT_ARRAYS)
            else "format"
        )

        def make_insert(c: Any, raw: bytes, a: Any, name: str = name) -> bytes:
            m = layout(raw)[name]
            mid = (m.data_start + m.data_end) // 2
            return raw[:mid] + b"\x00" * 16 + raw[mid:]

        case(f"insert-16-bytes-in-{name}", make_insert, entry(first), "damaged")

    # -- sample arrays replaced: dtype, shape, count, values
    def like(a: dict[str, np.ndarray], name: str, dtype: Any) -> np.ndarray:
        return np.zeros(a[name].shape, dtype=dtype)

    for name in SAMPLE_ARRAYS:
        e = entry(name)
        for label, dtype in (
            ("strings", "<U3"),
            ("bytes", "S3"),
            ("complex", np.complex128),
            ("bools", np.bool_),
            ("longdouble", np.longdouble),
            ("datetime", "datetime64[s]"),
        ):
            if label == "longdouble" and np.dtype(np.longdouble).itemsize <= 8:
                continue  # a platform whose long double is a double: a valid float
            case(
                f"array-{name}-{label}",
                lambda c, raw, a, name=name, dtype=dtype: npz(a, **{name: like(a, name, dtype)}),
                e,
                "dtype",
            )
        case(
            f"array-{name}-objects",
            lambda c, raw, a, name=name: npz(
                a, **{name: npy(a[name].astype(object), allow_pickle=True)}
            ),
            e,
            "Python objects",
        )
        case(
            f"array-{name}-3d",
            lambda c, raw, a, name=name: npz(a, **{name: a[name].reshape(*a[name].shape, 1, 1)}),
            e,
            "shape",
        )
        case(
            f"array-{name}-0d",
            lambda c, raw, a, name=name: npz(a, **{name: np.float64(1.0)}),
            e,
            "shape",
        )
        # one row more: for t, the other arrays no longer match it (q is checked first)
        case(
            f"array-{name}-extra-row",
            lambda c, raw, a, name=name: npz(a, **{name: np.concatenate([a[name], a[name][:1]])}),
            entry("q" if name == "t" else name),
            "shape",
        )
        case(
            f"array-{name}-no-rows",
            lambda c, raw, a, name=name: npz(a, **{name: a[name][:0]}),
            entry(name),
            "no samples" if name == "t" else "shape",
        )
        for label, value in (("nan", np.nan), ("inf", np.inf), ("minus-inf", -np.inf)):

            def make_bad(
                c: Any, raw: bytes, a: Any, name: str = name, value: float = value
            ) -> bytes:
                arr = a[name].copy()
                arr.flat[arr.size // 2] = value
                return npz(a, **{name: arr})

            case(f"array-{name}-{label}", make_bad, e, "finite")
        if name != "t" and name != "energy":
            case(
                f"array-{name}-7-columns",
                lambda c, raw, a, name=name: npz(a, **{name: a[name][:, :7]}),
                e,
                "column",
            )
            case(
                f"array-{name}-transposed",
                lambda c, raw, a, name=name: npz(a, **{name: np.ascontiguousarray(a[name].T)}),
                e,
                "shape",
            )
    case(
        "array-t-decreasing",
        lambda c, raw, a: npz(a, t=a["t"][::-1].copy()),
        entry("t"),
        "decrease",
    )
    case(
        "array-all-empty",
        lambda c, raw, a: npz(a, **{n: a[n][:0] for n in SAMPLE_ARRAYS}),
        entry("t"),
        "no samples",
    )

    def make_35(c: Any, raw: bytes, a: dict[str, np.ndarray]) -> bytes:
        new: dict[str, Any] = {n: np.zeros((35, 8)) for n in SAMPLE_ARRAYS if a[n].ndim == 2}
        new |= {"t": np.linspace(0.0, 0.02, 35), "energy": np.zeros(35), "q": np.zeros((3, 8))}
        return npz(a, **new)

    case("array-q-3-rows-35-times", make_35, entry("q"), "(35, 8)")

    # -- the event arrays
    for name in EVENT_FLOATS:
        e = f"event_{name}"
        replaced(f"event-{name}-strings", e, np.array(["x"]), entry(e), "dtype")
        replaced(f"event-{name}-complex", e, np.array([1j]), entry(e), "dtype")
        replaced(f"event-{name}-two-values", e, np.zeros(2), entry(e), "shape")
        replaced(f"event-{name}-2d", e, np.zeros((1, 1)), entry(e), "shape")
        replaced(f"event-{name}-inf", e, np.array([np.inf]), entry(e), "finite")
    replaced("event-t-nan", "event_t", np.array([np.nan]), entry("event_t"), "finite")
    for name in ("v_before", "v_after"):
        e, n = f"event_{name}", f"event_{name}_len"
        replaced(f"event-{name}-len-floats", n, np.array([8.0]), entry(n), "dtype")
        replaced(f"event-{name}-len-bools", n, np.array([True]), entry(n), "dtype")
        replaced(f"event-{name}-len-3", n, np.array([3]), entry(n), "3")
        replaced(f"event-{name}-len-negative", n, np.array([-8]), entry(n), "-8")
        replaced(f"event-{name}-len-huge", n, np.array([2**62]), entry(n), "expected 0 or 8")
        replaced(f"event-{name}-len-two", n, np.array([8, 0]), entry(n), "shape")
        replaced(f"event-{name}-7-values", e, np.zeros(7), entry(e), "shape")
        replaced(f"event-{name}-9-values", e, np.zeros(9), entry(e), "shape")
        replaced(f"event-{name}-nan", e, np.full(8, np.nan), entry(e), "finite")
        replaced(f"event-{name}-strings", e, np.array(["x"] * 8), entry(e), "dtype")
        replaced(f"event-{name}-2d", e, np.zeros((8, 1)), entry(e), "shape")

    # -- the contact forces' columns
    replaced("contact-sample-floats", "contact_sample", np.zeros(0), entry("contact_sample"))
    replaced("contact-sample-2d", "contact_sample", np.zeros((0, 1), dtype=np.int64), "shape")
    replaced("contact-pair-extra-row", "contact_pair", np.zeros(1, dtype=np.int64), "shape")
    replaced("contact-point-1d", "contact_point", np.zeros(0), entry("contact_point"), "shape")
    replaced("contact-force-4-columns", "contact_force", np.zeros((0, 4)), entry("contact_force"))
    replaced("contact-normal-strings", "contact_normal", np.array([["x"] * 3]), "dtype")
    replaced("contact-sample-missing", "contact_sample", None, entry("contact_sample"), "missing")

    def per_sample(id: str, name: str, make: Callable[[int], Any], *words: str) -> None:
        """A case whose per-sample contact entry ``name`` is ``make(number of samples)``."""
        case(id, lambda c, raw, a: npz(a, **{name: make(len(a["t"]))}), *words)

    per_sample("contact-known-2", "contact_known", lambda n: np.full(n, 2), "0 or 1")
    per_sample("contact-known-short", "contact_known", lambda n: np.ones(1, dtype=int), "shape")
    per_sample("contact-known-floats", "contact_known", np.ones, entry("contact_known"))
    per_sample(
        "contact-limit-inf", "contact_limit_torque", lambda n: np.full((n, 8), np.inf), "finite"
    )
    per_sample("contact-limit-3", "contact_limit_torque", lambda n: np.zeros((n, 3)), "shape")
    replaced("contact-limit-missing", "contact_limit_torque", None, "missing")
    per_sample("contact-clamp-3", "contact_clamp_torque", lambda n: np.zeros((n, 3)), "shape")
    replaced("contact-clamp-missing", "contact_clamp_torque", None, "missing")

    # -- the impacts' entries
    def impacts(id: str, n: int, *words: str, **entries: Any) -> None:
        """A case with ``n`` impacts (their stops' and clamps' impulses zero), ``entries``
        replaced."""
        base = {
            "impact_t": np.linspace(0.0, 0.02, n),
            "impact_limit_impulse": np.zeros((n, 8)),
            "impact_clamp_impulse": np.zeros((n, 8)),
        }
        case(id, lambda c, raw, a: npz(a, **(base | entries)), *words)

    impacts("impact-t-decreasing", 2, entry("impact_t"), "never decrease", impact_t=[0.02, 0.01])
    impacts("impact-t-nan", 1, entry("impact_t"), "finite", impact_t=[np.nan])
    impacts("impact-t-after-the-run", 1, entry("impact_t"), "within", impact_t=[1.0])
    impacts("impact-limit-short", 2, entry("impact_limit_impulse"), "shape",
            impact_limit_impulse=np.zeros((1, 8)))  # fmt: skip
    impacts("impact-clamp-short", 2, entry("impact_clamp_impulse"), "shape",
            impact_clamp_impulse=np.zeros((1, 8)))  # fmt: skip
    rows = {
        f"impact_{n}": np.zeros((1, 3)) for n in ("point", "point1", "point2", "normal", "force")
    }
    impacts("impact-sample-out-of-range", 1, entry("impact_sample"), "impact indices",
            impact_sample=np.array([3]), impact_pair=np.array([0]), **rows)  # fmt: skip
    impacts("impact-pair-out-of-range", 1, entry("impact_pair"), "impact_pairs",
            impact_sample=np.array([0]), impact_pair=np.array([0]), **rows)  # fmt: skip
    replaced("impact-force-4-columns", "impact_force", np.zeros((0, 4)), entry("impact_force"))
    replaced("impact-t-missing", "impact_t", None, entry("impact_t"), "missing")

    # -- the text entries and the plain copies
    replaced("text-format-missing", "format", None, "no format tag")
    replaced("text-meta_json-missing", "meta_json", None, "no format tag")
    replaced("text-format-other-version", "format", np.array("packbot.SimResult/6"), "/6")
    replaced("text-format-empty", "format", np.array(""), entry("format"), "expected")
    replaced("text-format-number", "format", np.array(1.0), entry("format"), "dtype")
    replaced("text-format-1d", "format", np.array(["packbot.SimResult/1"]), entry("format"))
    replaced("text-format-huge", "format", np.array("x" * 5000), entry("format"), "bytes")
    replaced("text-meta_json-number", "meta_json", np.array(3.0), entry("meta_json"), "dtype")
    replaced("text-meta_json-1d", "meta_json", np.array(["{}"]), entry("meta_json"), "shape")
    for name in FILE_ORDER[len(READ_IN_FILE_ORDER) :]:
        replaced(f"text-{name}-missing", name, None, entry(name), "missing")
    replaced("text-joint_names-3", "joint_names", np.array(["a", "b", "c"]), entry("joint_names"))
    replaced("text-joint_names-floats", "joint_names", np.zeros(8), entry("joint_names"), "dtype")
    replaced("text-joint_names-0d", "joint_names", np.array("turret"), entry("joint_names"))
    replaced("text-rest_time-string", "rest_time", np.array("none"), entry("rest_time"), "dtype")
    replaced("text-rest_time-1d", "rest_time", np.zeros(2), entry("rest_time"), "shape")
    replaced("text-config_json-float", "config_json", np.array(1.0), entry("config_json"))
    replaced("text-scenario_text-1d", "scenario_text", np.array(["a"]), entry("scenario_text"))
    replaced("text-packbot_version-int", "packbot_version", np.array(1), entry("packbot_version"))
    replaced("text-extra-numeric", "notes", np.arange(3.0), entry("notes"), "unknown entry")
    replaced("text-extra-1d-text", "notes", np.array(["a", "b"]), entry("notes"), "unknown")
    replaced("text-extra-bool", "notes", np.array(True), entry("notes"), "unknown entry")
    replaced("text-extra-event-name", "event_new", np.array("x"), entry("event_new"), "unknown")

    # -- the JSON metadata
    def meta_case(
        id: str,
        change: Callable[[dict[str, Any]], Any],
        *words: str,
        error: type = ResultFileError,
    ) -> None:
        def make(c: Any, raw: bytes, a: dict[str, np.ndarray]) -> bytes:
            meta = meta_of(a)
            out = change(meta)
            text = out if isinstance(out, str) else json.dumps(meta if out is None else out)
            return npz(a, meta_json=np.array(text))

        case(f"meta-{id}", make, *words, error=error)

    def setter(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
        keys = [int(k) if k.isdigit() else k for k in path.split(".")]

        def change(meta: dict[str, Any]) -> None:
            d: Any = meta
            for k in keys[:-1]:
                d = d[k]
            d[keys[-1]] = value

        return change

    def dropper(key: str, where: str = "") -> Callable[[dict[str, Any]], None]:
        keys = [int(k) if k.isdigit() else k for k in where.split(".") if k]

        def change(meta: dict[str, Any]) -> None:
            d: Any = meta
            for k in keys:
                d = d[k]
            del d[key]

        return change

    m = "meta_json"
    meta_case("not-json", lambda meta: "{not json", entry(m), "JSON")
    meta_case("empty-text", lambda meta: "", entry(m), "JSON")
    meta_case("list", lambda meta: [], entry(m), "object")
    meta_case("string", lambda meta: json.dumps("x"), entry(m), "object")
    meta_case("null", lambda meta: "null", entry(m), "object")
    meta_case("number", lambda meta: 3, entry(m), "object")
    meta_case("deep-arrays", lambda meta: "[" * 100_000 + "]" * 100_000, entry(m), "nested")
    meta_case("deep-objects", lambda meta: '{"a":' * 50_000 + "1" + "}" * 50_000, entry(m))
    meta_case("deep-in-config", setter("config.gravity", [[[[[[[[[[0]]]]]]]]]]), entry(m))
    meta_case(
        "int-of-5000-digits",
        lambda meta: json.dumps(meta).replace(
            '"control_ticks": 0', '"control_ticks": 1' + "0" * 5000
        ),
        entry(m),
        "JSON",
    )
    meta_case("trailing-garbage", lambda meta: json.dumps(meta) + "]", entry(m), "JSON")
    for key in (
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
    ):
        meta_case(f"no-{key}", dropper(key), entry(f"{m}.{key}"), "missing")
    meta_case("unknown-field", setter("colour", "red"), entry(f"{m}.colour"), "unknown")
    meta_case("format-other", setter("format", "packbot.SimResult/6"), entry(f"{m}.format"))
    meta_case("format-older", setter("format", "packbot.SimResult/1"), entry(f"{m}.format"))
    meta_case("contact-pairs-number", setter("contact_pairs", 3), entry(f"{m}.contact_pairs"))
    meta_case("impact-pairs-number", setter("impact_pairs", 3), entry(f"{m}.impact_pairs"))
    meta_case(
        "contact-pairs-three-names",
        setter("contact_pairs", [["link3", "link3/tube", "link1"]]),
        entry(f"{m}.contact_pairs[0]"),
        "four strings",
    )
    meta_case(
        "contact-pairs-numbers",
        setter("contact_pairs", [[1, 2, 3, 4]]),
        entry(f"{m}.contact_pairs[0]"),
    )
    meta_case("format-number", setter("format", 1), entry(f"{m}.format"))
    meta_case("version-number", setter("packbot_version", 1), entry(f"{m}.packbot_version"))
    meta_case("scenario_text-null", setter("scenario_text", None), entry(f"{m}.scenario_text"))
    jn = entry(f"{m}.joint_names")
    meta_case("joint_names-string", setter("joint_names", "turret"), jn)
    meta_case("joint_names-empty", setter("joint_names", []), jn)
    meta_case("joint_names-numbers", setter("joint_names", list(range(8))), jn)
    meta_case("joint_names-duplicate", setter("joint_names", ["turret"] * 8), jn, "distinct")
    meta_case("joint_names-blank", setter("joint_names", [""] * 8), jn)

    def three_joints(meta: dict[str, Any]) -> None:
        meta["joint_names"] = ["turret", "shoulder", "elbow1"]
        for e in meta["events"]:
            e["relevant_joints"] = []

    meta_case("joint_names-3-for-8-columns", three_joints, entry("q"), "joint")
    rt = entry(f"{m}.rest_time")
    meta_case("rest_time-string", setter("rest_time", "0.01"), rt)
    meta_case("rest_time-bool", setter("rest_time", True), rt)
    meta_case("rest_time-nan", setter("rest_time", float("nan")), rt, "finite")
    meta_case("rest_time-inf", setter("rest_time", float("inf")), rt, "finite")
    meta_case("rest_time-huge-int", setter("rest_time", 10**400), rt, "finite")
    meta_case("rest_time-after-end", setter("rest_time", 99.0), rt, "span")
    meta_case("rest_time-negative", setter("rest_time", -1.0), rt, "span")
    meta_case("rest_time-list", setter("rest_time", [0.0]), rt)
    ct = entry(f"{m}.control_ticks")
    meta_case("control_ticks-negative", setter("control_ticks", -1), ct)
    meta_case("control_ticks-float", setter("control_ticks", 1.5), ct)
    meta_case("control_ticks-bool", setter("control_ticks", True), ct)
    meta_case("control_ticks-string", setter("control_ticks", "3"), ct)
    meta_case("control_ticks-null", setter("control_ticks", None), ct)
    cf = f"{m}.config"
    meta_case("config-list", setter("config", []), entry(cf), "object")
    meta_case("config-string", setter("config", "normal"), entry(cf), "object")
    meta_case("config-unknown-key", setter("config.colour", 1), entry(f"{cf}.colour"), "unknown")
    for key, label, value in (
        ("restitution", "2", 2.0),
        ("restitution", "string", "0.5"),
        ("contact_mode", "bogus", "bogus"),
        ("gravity", "two", [0.0, 0.0]),
        ("gravity", "object", {"z": -9.81}),
        ("sample_dt", "negative", -1.0),
        ("max_events", "0", 0),
        ("locked_joints", "string", "camera_tilt"),
        ("rtol", "null", None),
        ("joint_limits", "string", "yes"),
    ):
        meta_case(
            f"config-{key}-{label}",
            setter(f"config.{key}", value),
            entry(cf),
            key,
            error=ResultValueError,
        )
    dg = f"{m}.diagnostics"
    meta_case("diagnostics-list", setter("diagnostics", []), entry(dg), "object")
    meta_case("diagnostics-unknown", setter("diagnostics.bogus", 1), entry(f"{dg}.bogus"))
    meta_case("diagnostics-steps-negative", setter("diagnostics.steps", -1), entry(f"{dg}.steps"))
    meta_case("diagnostics-steps-float", setter("diagnostics.steps", 1.5), entry(f"{dg}.steps"))
    meta_case("diagnostics-steps-bool", setter("diagnostics.steps", True), entry(f"{dg}.steps"))
    meta_case(
        "diagnostics-wall_time-string",
        setter("diagnostics.wall_time", "0"),
        entry(f"{dg}.wall_time"),
    )
    meta_case(
        "diagnostics-min_distance-nan",
        setter("diagnostics.min_distance", float("nan")),
        entry(f"{dg}.min_distance"),
    )
    meta_case(
        "diagnostics-pair-number",
        setter("diagnostics.min_distance_pair", 3),
        entry(f"{dg}.min_distance_pair"),
    )
    fl = f"{m}.failures"
    elbow = {"joint": "elbow1", "kind": "loose", "t": 0.0}
    meta_case("failures-object", setter("failures", {}), entry(fl))
    meta_case("failures-numbers", setter("failures", [1]), entry(fl))
    meta_case(
        "failure-bad-kind",
        setter("failures", [{**elbow, "kind": "broken"}]),
        entry(f"{fl}[0]"),
        "kind",
        error=ResultValueError,
    )
    meta_case(
        "failure-negative-t",
        setter("failures", [{**elbow, "t": -1.0}]),
        entry(f"{fl}[0]"),
        error=ResultValueError,
    )
    meta_case("failure-no-kind", setter("failures", [{"joint": "elbow1"}]), entry(f"{fl}[0]"))
    meta_case(
        "failure-unknown-key",
        setter("failures", [{**elbow, "colour": 1}]),
        entry(f"{fl}[0].colour"),
        "unknown",
    )
    en = f"{m}.environment"
    floor = meta_of_floor()
    meta_case("environment-list", setter("environment", []), entry(en), "object")
    meta_case("environment-extra-key", setter("environment.colour", 1), entry(en), "obstacles")
    obs = entry(f"{en}.obstacles")
    meta_case("environment-obstacles-object", setter("environment.obstacles", {}), obs)
    meta_case("environment-obstacles-numbers", setter("environment.obstacles", [1]), obs)
    meta_case(
        "obstacle-unknown-key",
        setter("environment.obstacles", [{**floor, "colour": 1}]),
        entry(f"{en}.obstacles[0].colour"),
        "unknown",
    )
    meta_case(
        "obstacle-bad-kind",
        setter("environment.obstacles", [{**floor, "kind": "blob"}]),
        entry(f"{en}.obstacles[0]"),
        "kind",
        error=ResultValueError,
    )
    meta_case(
        "obstacle-no-name",
        setter("environment.obstacles", [{k: v for k, v in floor.items() if k != "name"}]),
        entry(f"{en}.obstacles[0]"),
    )
    meta_case(
        "obstacle-normal-nan",
        setter("environment.obstacles", [{**floor, "normal": [0.0, 0.0, float("nan")]}]),
        entry(f"{en}.obstacles[0]"),
        "normal",
        error=ResultValueError,
    )
    meta_case(
        "obstacles-duplicate-names",
        setter("environment.obstacles", [floor, floor]),
        entry(en),
        error=ResultValueError,
    )
    pl = f"{m}.payload"
    meta_case("payload-list", setter("payload", []), entry(pl), "object")
    meta_case(
        "payload-negative-mass",
        setter("payload", {"mass": -1.0}),
        entry(pl),
        "mass",
        error=ResultValueError,
    )
    meta_case(
        "payload-mass-string",
        setter("payload", {"mass": "1"}),
        entry(pl),
        "mass",
        error=ResultValueError,
    )
    meta_case("payload-no-mass", setter("payload", {}), entry(pl))
    meta_case(
        "payload-unknown-key",
        setter("payload", {"mass": 1.0, "colour": 1}),
        entry(f"{pl}.colour"),
        "unknown",
    )
    meta_case(
        "payload-com-two",
        setter("payload", {"mass": 1.0, "com": [0.0, 0.0]}),
        entry(pl),
        "com",
        error=ResultValueError,
    )
    ev = f"{m}.events"
    meta_case("events-object", setter("events", {}), entry(ev))
    meta_case("events-numbers", setter("events", [1]), entry(ev))
    meta_case("events-none", setter("events", []), entry("event_t"), "shape")
    meta_case(
        "events-one-more",
        lambda meta: meta["events"].append(dict(meta["events"][0])),
        entry("event_t"),
        "shape",
    )
    meta_case("event-kind-unknown", setter("events.0.kind", "explosion"), entry(f"{ev}[0].kind"))
    meta_case("event-kind-number", setter("events.0.kind", 3), entry(f"{ev}[0].kind"))
    meta_case("event-link1-null", setter("events.0.link1", None), entry(f"{ev}[0].link1"))
    meta_case("event-unknown-key", setter("events.0.colour", 1), entry(f"{ev}[0]"), "fields")
    meta_case("event-no-piece2", dropper("piece2", "events.0"), entry(f"{ev}[0]"))
    rj = entry(f"{ev}[0].relevant_joints")
    meta_case("event-relevant-string", setter("events.0.relevant_joints", "turret"), rj)
    meta_case("event-relevant-unknown", setter("events.0.relevant_joints", ["wheel"]), rj)
    meta_case("event-relevant-numbers", setter("events.0.relevant_joints", [1]), rj)

    # -- zip-level forgeries
    case(
        "zip-stray-member",
        lambda c, raw, a: zip_bytes({**{k: npy(v) for k, v in a.items()}, "readme.txt": b"hi"}),
        entry("readme.txt"),
        ".npy",
    )

    def make_duplicate(c: Any, raw: bytes, a: Any) -> bytes:
        buf = io.BytesIO(raw)
        with zipfile.ZipFile(buf, "a") as zf, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the zip module's duplicate-name warning
            zf.writestr("q.npy", npy(a["q"]))
        return buf.getvalue()

    case("zip-duplicate-member", make_duplicate, entry("q"), "twice")
    case(
        "zip-encrypted-flag",
        lambda c, raw, a: patch_directory(raw, "q", flag_bits=1),
        entry("q"),
        "encrypted",
    )
    case(
        "zip-bzip2-member",
        lambda c, raw, a: zip_bytes({k: npy(v) for k, v in a.items()}, zipfile.ZIP_BZIP2),
        entry("format"),
        "compression",
    )
    case(
        "zip-lzma-member",
        lambda c, raw, a: zip_bytes({k: npy(v) for k, v in a.items()}, zipfile.ZIP_LZMA),
        entry("format"),
        "compression",
    )
    case(
        "zip-too-many-members",
        lambda c, raw, a: npz(a, **{f"x{k}": np.array("x") for k in range(MAX_MEMBERS)}),
        "zip members",
    )
    case(
        "zip-directory-claims-3-gb",
        lambda c, raw, a: patch_directory(raw, "q", file_size=3 * 2**30),
        entry("q"),
        "zip directory",
    )
    case(
        "zip-directory-size-lies-small",
        lambda c, raw, a: patch_directory(raw, "q", file_size=100),
        entry("q"),
        "damaged",
    )
    case(
        "zip-directory-crc-wrong",
        lambda c, raw, a: patch_directory(raw, "q", crc=12345),
        entry("q"),
        "CRC",
    )
    case(
        "zip-directory-compressed-size-short",
        lambda c, raw, a: patch_directory(raw, "q", compress_size=20),
        entry("q"),
        "damaged",
    )
    replaced(
        "zip-header-claims-huge-shape",
        "q",
        npy_header((2**40, 8), "<f8") + bytes(64),
        entry("q"),
        "header",
    )
    replaced(
        "zip-header-claims-negative-shape",
        "q",
        npy_header((3, 8), "<f8").replace(b"(3, 8)", b"(-3,8)") + bytes(192),
        entry("q"),
    )
    replaced("zip-npy-bad-magic", "q", b"NOTNUMPY" + bytes(200), entry("q"), "header")
    replaced(
        "zip-npy-version-3",
        "q",
        b"\x93NUMPY\x03\x00" + npy(a_q())[8:],
        entry("q"),
        "version",
    )
    replaced(
        "zip-npy-header-not-dict",
        "q",
        b"\x93NUMPY\x01\x00" + struct.pack("<H", 118) + b"[1, 2]".ljust(117) + b"\n",
        entry("q"),
        "header",
    )
    replaced(
        "zip-npy-header-length-4gb",
        "q",
        b"\x93NUMPY\x02\x00" + struct.pack("<I", 2**32 - 1) + bytes(100),
        entry("q"),
        "header",
    )
    replaced(
        "zip-npy-header-truncated",
        "q",
        npy_header((3, 8), "<f8")[:30],
        entry("q"),
        "header",
    )
    replaced(
        "zip-npy-descr-struct",
        "q",
        npy(np.zeros((3, 8), dtype=[("a", "<f8")])),
        entry("q"),
        "dtype",
    )
    replaced(
        "zip-npy-data-short",
        "q",
        npy(np.zeros((3, 8)))[:-8],
        entry("q"),
        "header",
    )

    def make_total(c: Any, raw: bytes, a: Any) -> bytes:
        # Headers claiming 1.2 GB of samples in all, the zip directory's sizes matching them
        # (the data itself missing), over the bound: refused from the headers alone.
        n = 3_000_000  # t and energy 24 MB each, the six others 192 MB each
        buf = io.BytesIO()
        big = {"t": ((n,), 8 * n), "energy": ((n,), 8 * n)}
        big |= {k: ((n, 8), 64 * n) for k in SAMPLE_ARRAYS if a[k].ndim == 2}
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for name, value in a.items():
                if name in big:
                    shape, size = big[name]
                    head = npy_header(shape, "<f8")
                    info = zipfile.ZipInfo(f"{name}.npy")
                    info.compress_type = zipfile.ZIP_DEFLATED
                    zf.writestr(info, head)  # data missing: the sizes below claim it
                else:
                    zf.writestr(f"{name}.npy", npy(value))
        out = buf.getvalue()
        for name, (shape, size) in big.items():
            out = patch_directory(out, name, file_size=len(npy_header(shape, "<f8")) + size)
        return out

    case("zip-entries-over-the-bound", make_total, "uncompressed", "bytes")

    # -- trajectories of a batch (packbot regress reads t and q)
    def traj_case(
        id: str, make: Callable[[bytes, dict[str, np.ndarray]], bytes], *words: str
    ) -> None:
        def action(c: Any) -> Any:
            from packbot.batch import RunRecord
            from packbot.regress import read_trajectories

            raw, arrays = base(c)
            c.write("trajectories/r.npz", make(raw, arrays))
            rec = RunRecord(
                id="r",
                index=0,
                params={},
                digest="",
                status="ok",
                files={"trajectory": "trajectories/r.npz"},
            )
            return read_trajectories(c.tmp, {"r": rec})

        cat.add("result_file", f"trajectory-{id}", action, *words, error=ResultFileError)

    def flip_in(name: str) -> Callable[[bytes, dict[str, np.ndarray]], bytes]:
        def make(raw: bytes, a: dict[str, np.ndarray]) -> bytes:
            m = layout(raw)[name]
            return flip(raw, (m.data_start + m.data_end) // 2)

        return make

    traj_case("flip-t", flip_in("t"), entry("t"), "r.npz")
    traj_case("flip-q", flip_in("q"), entry("q"), "r.npz")
    traj_case("truncated", lambda raw, a: raw[: len(raw) // 2], "r.npz", "not a readable")
    traj_case("t-strings", lambda raw, a: npz(a, t=np.array(["a"] * len(a["t"]))), entry("t"))
    traj_case("t-nan", lambda raw, a: npz(a, t=np.full(len(a["t"]), np.nan)), entry("t"))
    traj_case("q-rows", lambda raw, a: npz(a, q=a["q"][:1]), entry("q"), "shape")
    traj_case("q-inf", lambda raw, a: npz(a, q=np.full_like(a["q"], np.inf)), entry("q"))
    traj_case(
        "q-huge-header",
        lambda raw, a: npz(a, q=npy_header((2**40, 8), "<f8") + bytes(64)),
        entry("q"),
        "header",
    )


def meta_of_floor() -> dict[str, Any]:
    """The floor obstacle as ``save`` stores it."""
    from dataclasses import asdict

    from packbot.environment import FLOOR

    return json.loads(json.dumps(asdict(FLOOR)))


def a_q() -> np.ndarray:
    """A (3, 8) array of zeros (a q of the catalogue's run)."""
    return np.zeros((3, 8))
