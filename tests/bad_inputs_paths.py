"""Bad-input catalogue, category ``paths``: names that would write or delete outside the folder.

- stems of :func:`save_run` and :func:`write_outputs`, scenario names (the default stem; the
  default ``--out`` of ``packbot run`` and ``packbot study``) and hand-made run ids given to
  :func:`run_batch`: each refused with a ConfigurationError naming the field, nothing written;
- ``--out`` values that are not a path (a NUL character): exit 2;
- ``packbot run --out DIR`` manifests that list foreign, changed, symbolically linked or
  outside files, or none at all: the folder is refused without ``--overwrite`` (exit 2, one
  line naming the file), and with it those files are kept (a ``check`` reads them back).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from types import ModuleType
from typing import Any

from packbot.errors import ConfigurationError

_MATRIX = 'base = "collapse"\n[set]\nduration = 0.02\n[axes]\n"config.restitution" = [0.0]\n'
#: Stems that are not one file name, by id ({abs}: an absolute path in the case's folder).
BAD_STEMS: dict[str, Any] = {
    "parent": "../x",
    "grandparent": "../../x",
    "dot-dot": "..",
    "dot": ".",
    "absolute": "{abs}",
    "slash": "a/b",
    "trailing-slash": "x/",
    "inner-dot-dot": "sub/../x",
    "backslash": "a\\b",
    "drive": "C:x",
    "nul": "a\x00b",
    "newline": "a\nb",
    "too-long": "x" * 300,
    "empty": "",
    "int": 5,
    "none-byte-dot-dot": "..\x00",
}
_NAMES = ("parent", "grandparent", "dot-dot", "absolute", "slash", "nul", "empty", "too-long")
_RUN_IDS = ("parent", "absolute", "slash", "dot-dot", "empty", "nul")


def _study_text() -> str:
    """A scenario with a failure (``packbot study`` needs one), written as ``...toml``."""
    from packbot.scenario import scenario_path

    return scenario_path("reconfig_elbow1").read_text(encoding="utf-8")


def _value(c: Any, value: Any) -> Any:
    return value.replace("{abs}", str(c.tmp / "elsewhere")) if isinstance(value, str) else value


def _sha(data: bytes) -> dict[str, Any]:
    return {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}


def register(catalogue: ModuleType) -> None:
    """Add the ``paths`` cases to the catalogue."""
    from packbot.scenario import Scenario, save_run, write_outputs

    def api(id: str, action: Any, *words: str, **kw: Any) -> None:
        catalogue.add("paths", id, action, *words, error=ConfigurationError, **kw)

    def cli(id: str, argv: Any, *words: str) -> None:
        catalogue.add("paths", id, argv, *words, cli=True, code=2)

    def sc(name: str = "s") -> Scenario:
        return Scenario(name=name, duration=0.02, pose="drive")

    for key, stem in BAD_STEMS.items():
        api(
            f"save_run-stem-{key}",
            lambda c, s=stem: save_run(c.result, sc(), c.out(), stem=_value(c, s)),
            "stem",
        )
    for key in _NAMES:
        api(
            f"save_run-scenario-name-{key}",
            lambda c, s=BAD_STEMS[key]: save_run(c.result, sc(_value(c, s)), c.out()),
            "scenario.name",
        )
    for key in ("parent", "absolute"):
        api(
            f"write_outputs-stem-{key}",
            lambda c, s=BAD_STEMS[key]: write_outputs(
                c.result, sc(), c.robot, c.out(), stem=_value(c, s)
            ),
            "stem",
        )
    for key in _RUN_IDS:
        api(f"run_batch-run-id-{key}", _batch_with_id(BAD_STEMS[key]), "runs[0].id")
    api("run_batch-run-id-hidden", _batch_with_id(".hidden"), "runs[0].id")
    api("run_batch-run-not-a-run", _batch_with_id(None), "runs[0]")

    # scenario files whose name (the file's stem) is ".." (the default --out: out/..)
    for command in ("run", "study"):
        cli(
            f"{command}-scenario-named-dot-dot",
            lambda c, cmd=command: [cmd, str(c.write("...toml", _study_text()))],
            "scenario.name",
        )
    for command in ("run", "batch", "study"):
        what = "collapse-small" if command == "batch" else "collapse"
        cli(f"{command}-out-nul", lambda c, a=[command, what, "--out", "a\x00b"]: a, "NUL")
    cli("run-out-under-a-symlinked-file", _out_under_symlinked_file, "is a file")

    # manifests
    def run(c: Any, *extra: str) -> list[str]:
        return ["run", "collapse", "--duration", "0.02", "--out", c.out(), *extra]

    for key, (make, word) in _MANIFESTS.items():
        cli(f"manifest-{key}", lambda c, m=make: (m(c), run(c))[1], word)
        catalogue.add(
            "paths",
            f"manifest-{key}-overwrite-keeps-it",
            lambda c, m=make: _overwrite(catalogue, c, m, run(c, "--overwrite")),
            check=_kept,
        )
    for key, entry in _OUTSIDE.items():
        catalogue.add(
            "paths",
            f"manifest-entry-{key}-never-followed",
            lambda c, e=entry: _outside_entry(catalogue, c, e, run(c, "--overwrite")),
            check=_kept,
        )


def _batch_with_id(rid: Any) -> Any:
    def action(c: Any) -> Any:
        import dataclasses

        from packbot.batch import run_batch
        from packbot.matrix import load_matrix

        matrix = load_matrix(c.write("m.toml", _MATRIX))
        run: Any = rid if rid is None else dataclasses.replace(matrix.runs()[0], id=_value(c, rid))
        return run_batch(matrix, c.out(), runs=[run], workers=0)

    return action


def _out_under_symlinked_file(c: Any) -> list[str]:
    target = c.write("afile", "a file")
    (c.tmp / "link").symlink_to(target)
    return ["run", "collapse", "--out", str(c.tmp / "link" / "sub")]


# ------------------------------------------------------------------------ manifests
def _manifest(c: Any, files: list[Any], sums: dict[str, Any] | None = None, fmt: int = 2) -> None:
    data: dict[str, Any] = {"tool": "packbot", "format": fmt, "files": files}
    if sums is not None:
        data["checksums"] = sums
    c.write("out/packbot-manifest.json", json.dumps(data))


def _precious(c: Any) -> bytes:
    data = b"precious\n"
    c.write("out/precious.txt", data)
    return data


def _no_checksum(c: Any) -> None:
    _precious(c)
    _manifest(c, ["precious.txt"])


def _format_1(c: Any) -> None:
    _precious(c)
    _manifest(c, ["precious.txt"], fmt=1)


def _wrong_sha(c: Any) -> None:
    _precious(c)
    _manifest(c, ["precious.txt"], {"precious.txt": {"sha256": "0" * 64, "size": 9}})


def _wrong_size(c: Any) -> None:
    data = _precious(c)
    _manifest(c, ["precious.txt"], {"precious.txt": {**_sha(data), "size": 99}})


def _bool_size(c: Any) -> None:
    data = _precious(c)
    _manifest(c, ["precious.txt"], {"precious.txt": {**_sha(data), "size": True}})


def _edited_after(c: Any) -> None:
    data = _precious(c)
    _manifest(c, ["precious.txt"], {"precious.txt": _sha(data)})
    c.write("out/precious.txt", "edited since\n")


def _symlink(c: Any) -> None:
    data = b"precious\n"
    target = c.write("precious.txt", data)  # outside the folder
    (c.tmp / "out").mkdir()
    (c.tmp / "out" / "precious.txt").symlink_to(target)
    _manifest(c, ["precious.txt"], {"precious.txt": _sha(data)})


def _symlinked_manifest(c: Any) -> None:
    data = _precious(c)
    sums = {"precious.txt": _sha(data)}
    manifest = {"tool": "packbot", "format": 2, "files": ["precious.txt"], "checksums": sums}
    elsewhere = c.write("m.json", json.dumps(manifest))
    (c.tmp / "out" / "packbot-manifest.json").symlink_to(elsewhere)


def _directory(c: Any) -> None:
    _precious(c)
    (c.tmp / "out" / "sub").mkdir()
    _manifest(c, ["precious.txt", "sub"], {"precious.txt": {"sha256": "1" * 64, "size": 9}})


def _broken(c: Any) -> None:
    _precious(c)
    c.write("out/packbot-manifest.json", "{not json")


def _not_packbot(c: Any) -> None:
    _precious(c)
    c.write("out/packbot-manifest.json", json.dumps({"tool": "other", "files": ["precious.txt"]}))


def _no_manifest(c: Any) -> None:
    _precious(c)


def _temp_file(c: Any) -> None:
    data = _precious(c)
    _manifest(c, ["precious.txt"], {"precious.txt": {**_sha(data), "size": 1}})
    c.write("out/.collapse.npz.abc.tmp", "a killed run's temporary file, or is it?")


#: Manifest setups: each leaves ``out/precious.txt`` (or a link to it) that packbot did not
#: write (or cannot prove it did), and the word the refusal must name.
_MANIFESTS: dict[str, tuple[Any, str]] = {
    "lists-foreign-file": (_no_checksum, "precious.txt"),
    "format-1": (_format_1, "SHA-256"),
    "sha-mismatch": (_wrong_sha, "changed since"),
    "size-mismatch": (_wrong_size, "precious.txt"),
    "size-bool": (_bool_size, "listed without a checksum"),
    "edited-after": (_edited_after, "changed since"),
    "symlinked-file": (_symlink, "symbolic link"),
    "symlinked-manifest": (_symlinked_manifest, "precious.txt"),
    "lists-a-directory": (_directory, "sub"),
    "broken-json": (_broken, "precious.txt"),
    "not-packbot": (_not_packbot, "precious.txt"),
    "none": (_no_manifest, "precious.txt"),
    "temp-file": (_temp_file, ".collapse.npz.abc.tmp"),
}


def _run_cli(catalogue: ModuleType, c: Any, argv: list[str]) -> tuple[Any, str]:
    import os

    cwd = os.getcwd()
    os.chdir(c.tmp)
    try:
        code, _, err, exc = catalogue._run_cli(argv)
    finally:
        os.chdir(cwd)
    if exc is not None:
        raise exc
    return code, err


def _overwrite(catalogue: ModuleType, c: Any, make: Any, argv: list[str]) -> dict[str, Any]:
    make(c)
    precious = c.tmp / "out" / "precious.txt"
    before = precious.read_bytes() if precious.exists() else None
    code, err = _run_cli(catalogue, c, argv)
    return {"code": code, "err": err, "before": before, "path": precious}


def _kept(out: dict[str, Any]) -> str | None:
    if out["code"] != 0:
        return f"exit {out['code']}: {out['err'].strip()!r}"
    path: Path = out["path"]
    if out["before"] is not None and (not path.exists() or path.read_bytes() != out["before"]):
        return f"{path} deleted or changed"
    return None


#: Manifest entries pointing outside the folder (with a checksum that matches the file there).
_OUTSIDE: dict[str, str] = {
    "parent": "../outside.txt",
    "absolute": "{outside}",
    "subfolder": "sub/outside.txt",
    "backslash": "..\\outside.txt",
}


def _outside_entry(catalogue: ModuleType, c: Any, entry: str, argv: list[str]) -> dict[str, Any]:
    data = b"keep\n"
    outside = c.write("outside.txt", data)
    c.write("out/sub/outside.txt", data)
    name = entry.replace("{outside}", str(outside))
    _manifest(c, [name], {name: _sha(data)})
    code, err = _run_cli(catalogue, c, argv)
    for path in (outside, c.tmp / "out" / "sub" / "outside.txt"):
        if not path.is_file() or path.read_bytes() != data:
            return {"code": 1, "err": f"{path} deleted or changed", "before": None, "path": path}
    return {"code": code, "err": err, "before": data, "path": outside}
