"""Storing a result: writing :meth:`packbot.SimResult.save`'s file, and building it back.

One concept: the two ends of a result's round trip through its ``.npz`` file (docs/simulator.md,
"Saving and loading results"). :func:`write_result` writes the file atomically;
:func:`rebuild_result` builds a result from the contents :func:`packbot.result_file.read_saved`
has checked, every stored object through its own constructor (so its checks run again). The
format itself, and its safe reading, is :mod:`packbot.result_file`'s. The classes of
:mod:`packbot.result` are passed in (this module does not import it: it imports this one).
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable, Mapping
from dataclasses import asdict, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from packbot.config import SimConfig
from packbot.contact_forces import ContactTable
from packbot.contact_impulses import ImpactTable
from packbot.errors import ConfigurationError, PackbotError, ResultValueError
from packbot.failures import Failure
from packbot.paths import atomic_write
from packbot.result_file import (
    CONTACT_INTS,
    CONTACT_VECTORS,
    EVENT_FLOATS,
    EVENT_STRINGS,
    RESULT_FORMAT,
    SAMPLE_ARRAYS,
    SavedResult,
    check_value,
)

if TYPE_CHECKING:
    from packbot.result import Diagnostics, Event, SimResult

__all__ = ["rebuild_result", "write_result"]

T = TypeVar("T")
R = TypeVar("R", bound="SimResult")


def write_result(result: SimResult, path: str | Path, extra: Mapping[str, str] | None) -> Path:
    """Write ``result`` to one compressed ``.npz`` file, atomically (:meth:`SimResult.save`).

    Args:
        result: The result.
        path: The file to write (written as given: no suffix is added).
        extra: Further plain text entries, name -> text, or None.

    Returns:
        The path written.

    Raises:
        PackbotError: ``path`` is a directory.
        ConfigurationError: An ``extra`` name that the file's own entries use.
    """
    from packbot import __version__

    out = Path(path)
    if out.is_dir():
        raise PackbotError(f"cannot save a result to {str(out)!r}: it is a directory")
    arrays: dict[str, Any] = {
        name: np.asarray(getattr(result, name), dtype=np.float64) for name in SAMPLE_ARRAYS
    }
    ev = result.events
    for name in EVENT_FLOATS:
        arrays[f"event_{name}"] = np.array([getattr(e, name) for e in ev], dtype=np.float64)
    for name in ("v_before", "v_after"):
        vs = [np.asarray(getattr(e, name), dtype=np.float64).ravel() for e in ev]
        arrays[f"event_{name}_len"] = np.array([len(x) for x in vs], dtype=np.int64)
        arrays[f"event_{name}"] = np.concatenate(vs) if vs else np.zeros(0)
    table = result.contacts
    for name in CONTACT_INTS:
        arrays[f"contact_{name}"] = np.asarray(getattr(table, name), dtype=np.int64)
    for name in CONTACT_VECTORS:
        arrays[f"contact_{name}"] = np.asarray(getattr(table, name), dtype=np.float64)
    arrays["contact_known"] = result.contacts_known.astype(np.int64)
    arrays["contact_limit_torque"] = result.limit_torque
    arrays["contact_clamp_torque"] = result.clamp_torque
    imp = result.impacts
    arrays["impact_t"] = np.asarray(imp.t, dtype=np.float64)
    for name in CONTACT_INTS:
        arrays[f"impact_{name}"] = np.asarray(getattr(imp.rows, name), dtype=np.int64)
    for name in CONTACT_VECTORS:
        arrays[f"impact_{name}"] = np.asarray(getattr(imp.rows, name), dtype=np.float64)
    arrays["impact_limit_impulse"] = np.asarray(imp.limit_impulse).reshape(
        len(imp), len(result.joint_names)
    )
    arrays["impact_clamp_impulse"] = np.asarray(imp.clamp_impulse).reshape(
        len(imp), len(result.joint_names)
    )
    meta = {
        "format": RESULT_FORMAT,
        "packbot_version": __version__,
        "joint_names": list(result.joint_names),
        "rest_time": result.rest_time,
        "control_ticks": int(result.control_ticks),
        "config": asdict(result.config),
        "diagnostics": asdict(result.diagnostics),
        "failures": [asdict(f) for f in result.failures],
        "environment": None if result.environment is None else asdict(result.environment),
        "payload": None if result.payload is None else asdict(result.payload),
        "scenario_text": result.scenario_text,
        "events": [
            {
                **{name: getattr(e, name) for name in EVENT_STRINGS},
                "relevant_joints": list(e.relevant_joints),
            }
            for e in ev
        ],
        "contact_pairs": [list(p) for p in table.pairs],
        "impact_pairs": [list(p) for p in imp.rows.pairs],
    }
    arrays["format"] = np.array(RESULT_FORMAT)
    arrays["meta_json"] = np.array(json.dumps(meta, allow_nan=True))
    # Plain copies for a reader with NumPy alone (the keys of packbot's scenario writer);
    # load() reads meta_json.
    arrays |= {
        "joint_names": np.array(result.joint_names, dtype=str),
        "scenario_text": np.array(result.scenario_text),
        "packbot_version": np.array(__version__),
        "config_json": np.array(json.dumps(meta["config"])),
        "rest_time": np.array(np.nan if result.rest_time is None else result.rest_time),
    }
    for name, text in (extra or {}).items():
        if name in arrays or name.startswith("event_"):
            raise ConfigurationError(
                f"extra[{name!r}]", name, "a name the file's own entries do not use"
            )
        arrays[name] = np.array(str(text))
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write(out, lambda fh: fh.write(buf.getvalue()), binary=True)
    return out


def rebuild_result(
    saved: SavedResult,
    result: type[R],
    event: type[Event],
    diagnostics: type[Diagnostics],
    event_kinds: tuple[str, ...],
) -> R:
    """The result from a file's checked contents (the objects through their constructors).

    Args:
        saved: The file's contents, as :func:`~packbot.result_file.read_saved` checked them.
        result: The class to build (:class:`~packbot.result.SimResult`).
        event: The class of the events (:class:`~packbot.result.Event`).
        diagnostics: The class of the diagnostics (:class:`~packbot.result.Diagnostics`).
        event_kinds: The event kinds a file may hold (:data:`~packbot.result.EVENT_KINDS`).

    Returns:
        The result.

    Raises:
        ResultFileError: An unknown event kind, or a stored object's field or value refused.
        ResultValueError: A stored setting, obstacle, failure or payload that its constructor
            refuses.
    """
    from packbot.environment import Environment, Obstacle
    from packbot.payload import Payload

    meta = saved.meta
    env = meta["environment"]
    environment = None
    if env is not None:
        obstacles = tuple(
            _rebuild(saved, f"meta_json.environment.obstacles[{k}]", Obstacle, ob)
            for k, ob in enumerate(env["obstacles"])
        )
        environment = _rebuild(
            saved, "meta_json.environment", Environment, {"obstacles": obstacles}
        )
    pay = meta["payload"]
    ev_meta = meta["events"]
    for k, em in enumerate(ev_meta):
        if em["kind"] not in event_kinds:
            saved.fail(
                f"meta_json.events[{k}].kind",
                f"{em['kind']!r} (expected one of {', '.join(event_kinds)})",
            )
    floats, vels = saved.event_floats, saved.event_velocities
    events = [
        event(
            t=float(floats["t"][k]),
            kind=em["kind"],
            link1=em["link1"],
            link2=em["link2"],
            piece1=em["piece1"],
            piece2=em["piece2"],
            distance=float(floats["distance"][k]),
            relevant_joints=tuple(em["relevant_joints"]),
            v_before=vels["v_before"][k],
            v_after=vels["v_after"][k],
            energy_before=float(floats["energy_before"][k]),
            energy_after=float(floats["energy_after"][k]),
        )
        for k, em in enumerate(ev_meta)
    ]
    diag = meta["diagnostics"]
    _known_fields(saved, "meta_json.diagnostics", diagnostics, diag)
    for f in fields(diagnostics):
        if f.name in diag:
            kind = type(f.default).__name__  # int, float or str
            check_value(diag[f.name], saved.fail, f"meta_json.diagnostics.{f.name}", kind)
    return result(
        **saved.arrays,
        events=events,
        rest_time=meta["rest_time"],
        joint_names=tuple(meta["joint_names"]),
        config=_rebuild(saved, "meta_json.config", SimConfig, meta["config"]),
        diagnostics=diagnostics(**diag),
        failures=tuple(
            _rebuild(saved, f"meta_json.failures[{k}]", Failure, f)
            for k, f in enumerate(meta["failures"])
        ),
        control_ticks=meta["control_ticks"],
        environment=environment,
        payload=None if pay is None else _rebuild(saved, "meta_json.payload", Payload, pay),
        scenario_text=meta["scenario_text"],
        contacts=ContactTable(pairs=tuple(meta["contact_pairs"]), **saved.contacts),
        impacts=_impacts(saved, len(meta["joint_names"])),
    )


def _impacts(saved: SavedResult, n_joints: int) -> ImpactTable:
    """The impacts of a file's checked contents (none for a file of an earlier format)."""
    cols = dict(saved.impacts)
    if not cols:
        return ImpactTable(
            rows=ContactTable(
                limit_torque=np.zeros((0, n_joints)), clamp_torque=np.zeros((0, n_joints))
            )
        )
    t = cols.pop("t")
    rows = ContactTable(
        pairs=tuple(saved.meta["impact_pairs"]), known=np.ones(len(t), dtype=bool), **cols
    )
    return ImpactTable(t=t, rows=rows)


def _tuples(value: Any) -> Any:
    """JSON lists back to the tuples the dataclasses hold (recursively)."""
    if isinstance(value, list):
        return tuple(_tuples(v) for v in value)
    return value


def _known_fields(saved: SavedResult, entry: str, cls: type, values: Mapping[str, Any]) -> None:
    """Every key of ``values`` is a field of the dataclass ``cls`` (else the entry's error)."""
    names = [f.name for f in fields(cls)]
    for key in values:
        if key not in names:
            saved.fail(f"{entry}.{key}", f"an unknown field (expected one of {', '.join(names)})")


def _rebuild(saved: SavedResult, entry: str, cls: Callable[..., T], values: Mapping[str, Any]) -> T:
    """``cls(**values)`` (JSON lists as tuples), its refusal an error naming the file's entry.

    Raises:
        ResultValueError: The constructor refused a value (a ``ConfigurationError``).
        ResultFileError: An unknown or missing field, or another refusal of the constructor.
    """
    _known_fields(saved, entry, cls, values)  # type: ignore[arg-type]
    try:
        return cls(**{k: _tuples(v) for k, v in values.items()})
    except ConfigurationError as exc:
        raise ResultValueError(saved.path, entry, exc) from exc
    except (PackbotError, TypeError, ValueError, OverflowError) as exc:
        saved.fail(entry, f"{type(exc).__name__}: {exc}")
