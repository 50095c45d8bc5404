"""Scenario files: packbot's own checks against pydantic and cattrs, and what the schema catches.

Three tables:

1. Import cost [ms] of each library (median of ``--samples`` fresh interpreters, the import
   alone, timed inside the process) beside ``import packbot``, and pydantic's time to build
   models of the five dataclasses a scenario file loads into (their fields and type hints).
2. The messages a user gets for the same bad values: packbot's loader, and pydantic (strict,
   extra keys forbidden) validating models with the same fields and hints. Skipped without
   pydantic.
3. The bad scenario files of ``tests/bad_input_cases.py``: how many the JSON Schema
   (``sims/scenario.schema.json``) flags in an editor, how many only the loader refuses (ranges,
   rules that tie fields together, the robot model, the run itself), and which. Skipped without
   jsonschema.

    python benchmarks/scenario_schema.py [--samples 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import inspect
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

BAD_VALUES: list[tuple[str, str]] = [
    ("a misspelt choice", '[config]\ncontact_mode = "nromal"\n'),
    ("a bool for a number", "[config]\nrestitution = true\n"),
    ("a string for a number", '[[failures]]\njoint = "elbow1"\nkind = "loose"\nt = "0.5"\n'),
    ("an unknown key", '[[failures]]\njoint = "elbow1"\nkind = "loose"\ntt = 0.5\n'),
    ("NaN", "[config]\nrestitution = nan\n"),
    ("out of range", "[config]\nrestitution = 1.5\n"),
    ("a vector too short", "[payload]\nmass = 1.0\ncom = [0.0, 0.0]\n"),
]


def _import_ms(code: str, samples: int) -> float:
    probe = f"import time; t = time.perf_counter(); {code}; print(time.perf_counter() - t)"
    runs = [
        float(subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True).stdout)
        for _ in range(samples + 1)
    ][1:]
    return statistics.median(runs) * 1000


def _have(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def import_table(samples: int) -> None:
    print("| import | [ms] |\n|---|---|")
    rows = {"packbot": "import packbot", "packbot.scenario": "import packbot.scenario"}
    for lib in ("pydantic", "cattrs", "jsonschema"):
        if _have(lib):
            rows[lib] = f"import {lib}"
    if _have("pydantic"):
        rows["pydantic models of SimConfig, Failure, Payload, Obstacle, Outputs"] = (
            "import pydantic\nfrom packbot.config import SimConfig\n"
            "from packbot.failures import Failure\nfrom packbot.payload import Payload\n"
            "from packbot.environment import Obstacle\nfrom packbot.scenario import Outputs\n"
            "import sys; sys.path.insert(0, 'benchmarks')\n"
            "from scenario_schema import _pydantic_model\n"
            "t = time.perf_counter()\n"
            "[_pydantic_model(c) for c in (SimConfig, Failure, Payload, Obstacle, Outputs)]"
        )
    for name, code in rows.items():
        print(f"| {name} | {_import_ms(code, samples):.0f} |")
    print()


def _ours(text: str) -> str:
    from packbot.errors import PackbotError
    from packbot.scenario import load_scenario

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bad.toml"
        path.write_text('duration = 0.05\n[initial]\npose = "drive"\n' + text)
        try:
            load_scenario(path)
        except PackbotError as exc:
            return f"{type(exc).__name__}: {exc}"
    return "(accepted)"


def _pydantic_model(cls: type) -> Any:
    """A pydantic model with a dataclass's fields and type hints (what a port would start from)."""
    import typing

    import pydantic

    hints = typing.get_type_hints(cls)
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            fields[f.name] = (hints[f.name], f.default)
        elif f.default_factory is not dataclasses.MISSING:
            fields[f.name] = (hints[f.name], pydantic.Field(default_factory=f.default_factory))
        else:
            fields[f.name] = (hints[f.name], ...)
    config = pydantic.ConfigDict(strict=True, extra="forbid")
    return pydantic.create_model(cls.__name__, __config__=config, **fields)


def _pydantic(text: str) -> str:
    import pydantic

    from packbot.config import SimConfig
    from packbot.failures import Failure
    from packbot.payload import Payload

    data = tomllib.loads(text)
    section, cls = next(
        (k, c)
        for k, c in (("config", SimConfig), ("failures", Failure), ("payload", Payload))
        if k in data
    )
    value = data[section][0] if isinstance(data[section], list) else data[section]
    model = _pydantic_model(cls)
    try:
        model.model_validate(value)
    except pydantic.ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(map(str, first["loc"]))
        return f"{loc}: {first['msg']} [input_value={first['input']!r}]"
    except Exception as exc:  # the dataclass's own check, run by its __post_init__
        return f"{type(exc).__name__}: {exc}"
    return "(accepted)"


def message_table() -> None:
    if not _have("pydantic"):
        print("(pydantic not installed: no message comparison)\n")
        return
    print("| bad value | packbot | pydantic (strict, extra forbidden) |\n|---|---|---|")
    for what, text in BAD_VALUES:
        print(f"| {what} | {_ours(text)} | {_pydantic(text)} |")
    print()


def _scenario_texts() -> list[tuple[str, str]]:
    sys.path.insert(0, str(ROOT / "tests"))
    import bad_input_cases as cat

    texts = []
    for case in cat.CASES:
        if case.category != "scenario" or case.cli:
            continue
        try:
            free = inspect.getclosurevars(case.action).nonlocals
        except TypeError:
            continue
        if "text" in free and "base" in free:
            body = cat.BASE_SCENARIO + "\n" + free["text"] if free["base"] else free["text"]
            texts.append((case.id, body))
    return texts


def schema_table() -> None:
    if not _have("jsonschema"):
        print("(jsonschema not installed: no schema coverage)")
        return
    import json

    import jsonschema

    schema = json.loads((ROOT / "sims" / "scenario.schema.json").read_text())
    validator = jsonschema.Draft7Validator(schema)
    syntax, flagged, missed = [], [], []
    for key, text in _scenario_texts():
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError:
            syntax.append(key)
            continue
        (flagged if any(True for _ in validator.iter_errors(data)) else missed).append(key)
    n = len(syntax) + len(flagged) + len(missed)
    print(f"| {n} bad scenario files | files |\n|---|---|")
    print(f"| not TOML (the editor's TOML parser flags them) | {len(syntax)} |")
    print(f"| flagged by the schema (type, key, choice, name) | {len(flagged)} |")
    print(f"| refused by the loader only | {len(missed)} |")
    print()
    print("refused by the loader only:", ", ".join(missed))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=5)
    args = ap.parse_args()
    t0 = time.perf_counter()
    import_table(args.samples)
    message_table()
    schema_table()
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
