"""SimResult.load checks a file before it trusts it (packbot/result_file.py).

A property test damages a small saved result at random (byte flips, truncations, insertions,
members replaced): every outcome is a load of an internally consistent result or a
ResultFileError, never another exception. Then one test per finding of issue 35 (item 3):
damaged archives, hand-made files that used to raise raw errors, inconsistent files that used
to load, the memory bombs, and entries a load does not need (never decompressed).
"""

from __future__ import annotations

import dataclasses
import json
import tracemalloc
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from bad_inputs_result_files import (
    FILE_ORDER,
    READ_IN_FILE_ORDER,
    arrays_of,
    deflated_zeros,
    flip,
    layout,
    meta_of,
    npy,
    npy_header,
    npz,
    with_raw_member,
)
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import packbot
from packbot.errors import ConfigurationError, ResultFileError, ResultValueError
from packbot.regress import read_trajectories
from packbot.result import EVENT_KINDS, SimResult
from packbot.result_file import (
    COLUMN_ARRAYS,
    MAX_JSON_DEPTH,
    MAX_RESULT_BYTES,
    READ_ENTRIES,
    ResultArchive,
)

#: Peak traced memory a refused or lightly read bomb may take [bytes]. What it covers: the
#: small file's own arrays and JSON, the zip directory, header parsing, one read chunk (1 MiB)
#: and the interpreter's bookkeeping, about 1 MB in all; a bomb that got through would take
#: hundreds of MB to GB, so 50 MB separates the two on any machine.
PEAK_LIMIT = 50 * 2**20


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, dict[str, np.ndarray]]:
    """A 0.02 s run from the drive pose, saved: its bytes and its entries."""
    r = packbot.load_robot()
    res = packbot.simulate(r, r.pose("drive"), np.zeros(8), 0.02)
    path = res.save(tmp_path_factory.mktemp("saved") / "small.npz")
    return path.read_bytes(), arrays_of(path)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("scratch") / "r.npz"


def _load(path: Path, data: bytes) -> SimResult:
    path.write_bytes(data)
    return SimResult.load(path)


def _assert_consistent(res: SimResult) -> None:
    """A loaded result's parts agree: shapes, dtypes, finiteness, event fields."""
    n, j = len(res.t), len(res.joint_names)
    assert n >= 1 and j >= 1 and len(set(res.joint_names)) == j
    assert res.t.shape == (n,) and res.energy.shape == (n,)
    for name in COLUMN_ARRAYS:
        arr = getattr(res, name)
        assert arr.shape == (n, j) and arr.dtype == np.float64, name
        assert np.all(np.isfinite(arr)), name
    assert np.all(np.isfinite(res.t)) and np.all(np.diff(res.t) >= 0)
    for ev in res.events:
        assert ev.kind in EVENT_KINDS
        assert ev.v_before.shape in ((0,), (j,)) and ev.v_after.shape in ((0,), (j,))
        assert set(ev.relevant_joints) <= set(res.joint_names)
    assert res.rest_time is None or res.t[0] <= res.rest_time <= res.t[-1]


# ------------------------------------------------------------------------ the property test
_DTYPES = st.sampled_from(["<f8", ">f8", "<f4", "<i8", "|b1", "<c16", "<U4", "|S2", "<M8[s]"])
_NEW_MEMBER = st.one_of(
    st.binary(max_size=300),  # not an .npy at all
    hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=9)).map(npy),
)
_BYTE_OPS = st.lists(
    st.one_of(
        st.tuples(st.just("flip"), st.floats(0, 1, exclude_max=True), st.integers(1, 255)),
        st.tuples(st.just("truncate"), st.floats(0, 1, exclude_max=True)),
        st.tuples(st.just("insert"), st.floats(0, 1), st.binary(min_size=1, max_size=40)),
    ),
    max_size=3,
)


def _damage(raw: bytes, ops: list[tuple]) -> bytes:
    out = bytearray(raw)
    for op in ops:
        at = int(op[1] * len(out))
        if op[0] == "flip" and out:
            out[min(at, len(out) - 1)] ^= op[2]
        elif op[0] == "truncate":
            del out[at:]
        elif op[0] == "insert":
            out[at:at] = op[2]
    return bytes(out)


# 250 examples take 6 to 12 s on the project's shared 2-core machine (about 4 s of CPU: each a
# zip rebuilt, damaged and loaded); the deadline is off because the machine is shared.
@settings(
    max_examples=250, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    replace=st.dictionaries(st.sampled_from((*FILE_ORDER, "notes")), _NEW_MEMBER, max_size=2),
    ops=_BYTE_OPS,
)
def test_random_damage_loads_consistently_or_is_a_result_file_error(saved, scratch, replace, ops):
    raw, arrays = saved
    data = npz(arrays, **replace) if replace else raw
    try:
        res = _load(scratch, _damage(data, ops))
    except ResultFileError as exc:
        assert exc.path == str(scratch) and isinstance(exc.entry, str)
        event("refused: " + ("the file" if not exc.entry else "an entry"))
        return
    event("loaded")
    _assert_consistent(res)


# ------------------------------------------------------------------------ the findings
def test_300_one_byte_flips_never_raise_a_raw_zlib_error(saved, scratch):
    # The finding: 78 of 300 flips raised zlib.error. Every flip is now a load or a
    # ResultFileError; a flip inside a read entry's compressed data (but its last bytes, which
    # may hold only the stream's end marker) names that entry.
    raw, _ = saved
    members = layout(raw)
    named = 0
    for pos in np.linspace(0, len(raw) - 1, 300).astype(int):
        inside = [
            name
            for name in READ_IN_FILE_ORDER
            if members[name].data_start <= pos < members[name].data_end - 2
        ]
        try:
            res = _load(scratch, flip(raw, int(pos)))
        except ResultFileError as exc:
            if inside:
                assert exc.entry == inside[0], (pos, exc)
                named += 1
            continue
        assert not inside, f"a flip at {pos} inside {inside} was not noticed"
        _assert_consistent(res)
    assert named > 100  # most of the file is the read entries' data


def _meta_text(arrays: dict, text: str) -> bytes:
    return npz(arrays, meta_json=np.array(text))


def _meta(arrays: dict, change) -> bytes:
    meta = meta_of(arrays)
    change(meta)
    return _meta_text(arrays, json.dumps(meta))


HAND_MADE = {
    # the raw exception the file used to raise -> (file, the entry now named)
    "AttributeError-meta-a-list": (lambda a: _meta_text(a, "[]"), "meta_json"),
    "AttributeError-config-a-list": (
        lambda a: _meta(a, lambda m: m.update(config=[])),
        "meta_json.config",
    ),
    "OverflowError-rest_time-10**400": (
        lambda a: _meta(a, lambda m: m.update(rest_time=10**400)),
        "meta_json.rest_time",
    ),
    "RecursionError-deep-nesting": (
        lambda a: _meta_text(a, "[" * 100_000 + "]" * 100_000),
        "meta_json",
    ),
    "TypeError-unknown-config-key": (
        lambda a: _meta(a, lambda m: m["config"].update(colour="red")),
        "meta_json.config.colour",
    ),
    "TypeError-failure-not-an-object": (
        lambda a: _meta(a, lambda m: m.update(failures=[1])),
        "meta_json.failures",
    ),
    "TypeError-joint_names-a-number": (
        lambda a: _meta(a, lambda m: m.update(joint_names=8)),
        "meta_json.joint_names",
    ),
    "MemoryError-header-claims-huge-shape": (
        lambda a: npz(a, q=npy_header((2**40, 8), "<f8") + bytes(64)),
        "q",
    ),
    "MemoryError-event-lengths-huge": (
        lambda a: npz(a, event_v_before_len=np.array([2**62])),
        "event_v_before_len",
    ),
}


@pytest.mark.parametrize("kind", sorted(HAND_MADE))
def test_hand_made_files_give_a_result_file_error_naming_the_entry(saved, scratch, kind):
    make, entry = HAND_MADE[kind]
    with pytest.raises(ResultFileError) as info:
        _load(scratch, make(saved[1]))
    assert info.value.entry == entry
    assert f"entry {entry!r}" in str(info.value) and str(scratch) in str(info.value)


def _all_samples(n: int) -> dict:
    return {
        "t": np.linspace(0.0, 0.02, n),
        "energy": np.zeros(n),
        **{name: np.zeros((n, 8)) for name in COLUMN_ARRAYS},
    }


INCONSISTENT = {
    # 13 kinds of file that used to load without error -> (file, entry named)
    "q-3-rows-for-35-times": (lambda a: npz(a, **{**_all_samples(35), "q": np.zeros((3, 8))}), "q"),
    "q-of-strings": (lambda a: npz(a, q=np.full((3, 8), "0.0")), "q"),
    "q-of-complex": (lambda a: npz(a, q=np.zeros((3, 8), complex)), "q"),
    "tau-of-bools": (lambda a: npz(a, tau=np.zeros((3, 8), bool)), "tau"),
    "empty-arrays": (lambda a: npz(a, **_all_samples(0)), "t"),
    "3-joint-names-for-8-columns": (
        lambda a: _meta(
            a,
            lambda m: m.update(
                joint_names=["turret", "shoulder", "elbow1"],
                events=[{**e, "relevant_joints": []} for e in m["events"]],
            ),
        ),
        "q",
    ),
    "energy-2d": (lambda a: npz(a, energy=np.zeros((3, 1))), "energy"),
    "t-decreasing": (lambda a: npz(a, t=a["t"][::-1].copy()), "t"),
    "t-nan": (lambda a: npz(a, t=np.array([0.0, np.nan, 0.02])), "t"),
    "event_t-for-two-events": (lambda a: npz(a, event_t=np.zeros(2)), "event_t"),
    "event-velocities-do-not-add-up": (
        lambda a: npz(a, event_v_before=np.zeros(16)),
        "event_v_before",
    ),
    "event-velocity-length-3": (
        lambda a: npz(a, event_v_after_len=np.array([3]), event_v_after=np.zeros(3)),
        "event_v_after_len",
    ),
    "relevant-joint-unknown": (
        lambda a: _meta(a, lambda m: m["events"][0].update(relevant_joints=["wheel"])),
        "meta_json.events[0].relevant_joints",
    ),
}


@pytest.mark.parametrize("kind", sorted(INCONSISTENT))
def test_inconsistent_files_are_refused(saved, scratch, kind):
    make, entry = INCONSISTENT[kind]
    with pytest.raises(ResultFileError) as info:
        _load(scratch, make(saved[1]))
    assert info.value.entry == entry, info.value


def _peak_while(fn) -> tuple[object, int]:
    """fn()'s outcome (its value or the exception) and the peak traced memory it took."""
    tracemalloc.start()
    try:
        try:
            out: object = fn()
        except ResultFileError as exc:
            out = exc
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_member_claiming_a_huge_size_is_refused_without_allocating_it(saved, scratch):
    # q's header claims 2**24 + 1 rows of 8 (just over 1 GiB) and the zip directory agrees; the
    # member holds its header alone (the file is a few kB).
    _raw, arrays = saved
    n = 2**24 + 1
    head = npy_header((n, 8), "<f8")
    data = with_raw_member(npz(arrays, q=None), "q", deflated_zeros(head, 0), len(head) + 64 * n)
    scratch.write_bytes(data)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, ResultFileError) and out.entry == "q", out
    assert "zip directory" in out.reason and f"{MAX_RESULT_BYTES:,}" in out.reason
    assert peak < PEAK_LIMIT


def test_a_member_decompressing_to_1_gib_is_refused_without_decompressing_it(saved, scratch):
    # A real bomb: q holds 1 GiB + 64 B of zeros (1 MB compressed); refused from the sizes.
    _raw, arrays = saved
    n = 2**24 + 1
    head = npy_header((n, 8), "<f8")
    data = with_raw_member(
        npz(arrays, q=None), "q", deflated_zeros(head, 64 * n), len(head) + 64 * n
    )
    assert len(data) < 2 * 2**20
    scratch.write_bytes(data)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, ResultFileError) and out.entry == "q"
    assert peak < PEAK_LIMIT


def test_an_800_mb_entry_under_the_bound_is_refused_from_the_headers(saved, scratch):
    # t holds 10**8 real zeros (800 MB, under the bound), the other arrays 3 rows: the shapes
    # disagree, which the headers tell before any data is decompressed.
    _raw, arrays = saved
    head = npy_header((10**8,), "<f8")
    data = with_raw_member(
        npz(arrays, t=None), "t", deflated_zeros(head, 8 * 10**8), len(head) + 8 * 10**8
    )
    scratch.write_bytes(data)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, ResultFileError) and out.entry == "q" and "shape" in out.reason
    assert peak < PEAK_LIMIT


def test_a_lying_zip_directory_cannot_make_the_reader_decompress_more(saved, scratch):
    # The zip directory (and q's header) say 3 rows of 8, the member's stream holds 1 GiB of
    # zeros; its CRC is that of the first 3 rows. The reader stops at the directory's size:
    # the load gets those 3 rows and nothing more.
    _raw, arrays = saved
    head = npy_header((3, 8), "<f8")
    size = len(head) + 192
    stream = deflated_zeros(head, 2**30)
    data = with_raw_member(
        npz(arrays, q=None), "q", stream, size, crc=zlib.crc32(head + bytes(192))
    )
    scratch.write_bytes(data)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, SimResult) and np.array_equal(out.q, np.zeros((3, 8)))
    assert peak < PEAK_LIMIT


def test_a_huge_unused_entry_is_never_decompressed(saved, scratch, monkeypatch):
    # An extra text entry of 256 MiB of real data (what save(extra=...) writes, only larger):
    # allowed, checked by its header alone, never read.
    raw, _arrays = saved
    n = 2**28
    head = npy_header((), f"<U{n // 4}")
    scratch.write_bytes(with_raw_member(raw, "notes", deflated_zeros(head, n), len(head) + n))
    read: list[str] = []
    real_array = ResultArchive.array

    def spy(self: ResultArchive, entry: str) -> np.ndarray:
        read.append(entry)
        return real_array(self, entry)

    monkeypatch.setattr(ResultArchive, "array", spy)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, SimResult), out
    assert sorted(read) == sorted(READ_ENTRIES)  # once each; not notes, not the plain copies
    assert peak < PEAK_LIMIT


def test_a_2_gib_extra_entry_is_refused_from_its_size(saved, scratch):
    # The finding's own bomb: a 2 MB file holding an unused 2 GiB entry took 2 GiB to load.
    raw, _arrays = saved
    n = 2**31
    head = npy_header((), f"<U{n // 4}")
    data = with_raw_member(raw, "notes", deflated_zeros(head, n), len(head) + n)
    assert len(data) < 3 * 2**20
    scratch.write_bytes(data)
    out, peak = _peak_while(lambda: SimResult.load(scratch))
    assert isinstance(out, ResultFileError) and out.entry == "notes"
    assert peak < PEAK_LIMIT


# ------------------------------------------------------------------------ what loads
def test_the_error_names_file_and_entry_and_keeps_its_signature(saved, scratch):
    err = ResultFileError("x.npz", "no such file")  # the old signature still works
    assert err.entry == "" and err.path == "x.npz" and err.reason == "no such file"
    with pytest.raises(ResultValueError) as info:
        _load(scratch, _meta(saved[1], lambda m: m["config"].update(restitution=2.0)))
    exc = info.value
    assert isinstance(exc, ResultFileError) and isinstance(exc, ConfigurationError)
    assert exc.entry == "meta_json.config" and exc.field == "restitution" and exc.value == 2.0


def test_float64_compatible_arrays_load(saved, scratch):
    # Integers, float32, big-endian and Fortran-ordered arrays are real numbers: converted.
    _raw, arrays = saved
    res = _load(
        scratch,
        npz(
            arrays,
            t=arrays["t"].astype(">f8"),
            q=np.asfortranarray(arrays["q"]),
            tau=arrays["tau"].astype(np.float32),
            effort=np.round(arrays["effort"]).astype(np.int32),
        ),
    )
    assert res.t.dtype == np.float64 and np.array_equal(res.t, arrays["t"])
    assert np.array_equal(res.q, arrays["q"])
    assert np.array_equal(res.tau, arrays["tau"].astype(np.float32))
    assert np.array_equal(res.effort, np.round(arrays["effort"]))
    _assert_consistent(res)


def test_a_file_of_an_earlier_packbot_takes_the_defaults(saved, scratch):
    # Settings and diagnostics fields added since (handoff, windows) may be missing.
    def older(meta: dict) -> None:
        del meta["config"]["handoff"], meta["diagnostics"]["windows"]

    res = _load(scratch, _meta(saved[1], older))
    assert res.config.handoff is False and res.diagnostics.windows == 0


def test_the_deepest_legitimate_metadata_loads(saved, scratch, tmp_path):
    # A convex obstacle's points are the metadata's deepest value, within MAX_JSON_DEPTH.
    base = _load(scratch, saved[0])
    cube = [(x, y, z) for x in (0.0, 0.1) for y in (0.0, 0.1) for z in (0.0, 0.1)]
    box = packbot.Obstacle(name="rock", kind="convex", points=tuple(cube), xyz=(2.0, 0.0, 0.0))
    rich = dataclasses.replace(base, environment=packbot.Environment().with_obstacles(box))
    back = SimResult.load(rich.save(tmp_path / "rich.npz"))
    assert back.environment == rich.environment
    assert MAX_JSON_DEPTH >= 6


def test_regress_reads_trajectories_through_the_bounded_reader(saved, tmp_path):
    from packbot.batch import RunRecord

    raw, arrays = saved
    folder = tmp_path / "batch"
    (folder / "trajectories").mkdir(parents=True)
    rec = RunRecord(
        id="r",
        index=0,
        params={},
        digest="",
        status="ok",
        files={"trajectory": "trajectories/r.npz"},
    )
    (folder / "trajectories" / "r.npz").write_bytes(raw)
    t, q = read_trajectories(folder, {"r": rec})["r"]
    assert np.array_equal(t, arrays["t"]) and np.array_equal(q, arrays["q"])
    m = layout(raw)["q"]
    (folder / "trajectories" / "r.npz").write_bytes(flip(raw, (m.data_start + m.data_end) // 2))
    with pytest.raises(ResultFileError) as info:
        read_trajectories(folder, {"r": rec})
    assert info.value.entry == "q"
    # a file without t and q (another runner's) is skipped, as before
    (folder / "trajectories" / "r.npz").write_bytes(npz({"x": np.zeros(2)}))
    assert read_trajectories(folder, {"r": rec}) == {}


def test_a_stray_zip_member_is_refused(saved, scratch):
    _raw, arrays = saved
    with_stray = npz(arrays, **{"notes.txt": b"hello"})
    with pytest.raises(ResultFileError) as info:
        _load(scratch, with_stray)
    assert info.value.entry == "notes.txt"
    assert zipfile.is_zipfile(scratch)  # a zip archive, but not one np.savez writes
