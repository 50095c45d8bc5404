"""The API reference: every public name documented and on a page; every example in the docs runs.

- Public modules are listed below (PUBLIC_MODULES); every other module of the package is listed as
  internal, so a new module needs a decision. A public module's public names are its ``__all__``.
- Each public name has a docstring where it is defined (a class's or function's docstring; for a
  constant or a type alias, ``#:`` comment lines above it, an inline ``#:`` comment or a string
  right after it: what the API site renders), read from the source, as the site builder does.
- Each public module has a page ``docs/api/<name>.md`` that renders it (``::: module``), listed
  in mkdocs.yml's nav; with mkdocs installed (the ``docs`` extra), the site is built with
  ``--strict`` and each public name must have its entry (its HTML anchor) on its module's page;
  every relative link and ``#anchor`` of the built site leads to a file and an anchor in it.
- Every ```python block of README.md and docs/ (but docs/dev/) runs, page by page in one
  namespace, in a fresh folder, unless the line before it is ``<!-- docs-test: skip (why) -->``
  (or ``<!-- docs-test: requires MODULE -->`` and MODULE, an optional extra, is not installed);
  every API page has at least one block that runs.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import os
import pkgutil
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

import packbot

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API = DOCS / "api"

#: module -> its page under docs/api/ (the API reference's nav, in mkdocs.yml)
PUBLIC_MODULES = {
    "packbot": "index.md",
    "packbot.model": "model.md",
    "packbot.resources": "resources.md",
    "packbot.robots": "robots.md",
    "packbot.params": "params.md",
    "packbot.uncertainty": "uncertainty.md",
    "packbot.config": "config.md",
    "packbot.integrator": "integrator.md",
    "packbot.result": "result.md",
    "packbot.contact_forces": "contact_forces.md",
    "packbot.contact_impulses": "contact_impulses.md",
    "packbot.failures": "failures.md",
    "packbot.actuators": "actuators.md",
    "packbot.payload": "payload.md",
    "packbot.environment": "environment.md",
    "packbot.collision": "collision.md",
    "packbot.control": "control.md",
    "packbot.analysis": "analysis.md",
    "packbot.study": "study.md",
    "packbot.study_matrix": "study_matrix.md",
    "packbot.uncertain_study": "uncertain_study.md",
    "packbot.uncertain_run": "uncertain_run.md",
    "packbot.uncertain_batch": "uncertain_batch.md",
    "packbot.identification": "identification.md",
    "packbot.scenario": "scenario.md",
    "packbot.matrix": "matrix.md",
    "packbot.batch": "batch.md",
    "packbot.regress": "regress.md",
    "packbot.plots": "plots.md",
    "packbot.viz": "viz.md",
    "packbot.errors": "errors.md",
}

#: the loop's parts, generators, checks and the command line: documented in their source and in
#: docs/*.md, not in the API reference (packages: their public names are their __init__'s)
INTERNAL_MODULES = {
    "packbot._native",
    "packbot._native_coal",
    "packbot.native_sweep",
    "packbot.native_joints",
    "packbot.cli",
    "packbot.collision_build",
    "packbot.collision_queries",
    "packbot.collision_records",
    "packbot.continuous_joints",
    "packbot.csv_cells",
    "packbot.decompose",
    "packbot.dh",
    "packbot.drive",
    "packbot.geometry",
    "packbot.impact_gain",
    "packbot.inputs",
    "packbot.keywords",
    "packbot.labels",
    "packbot.mujoco_model",
    "packbot.ode",
    "packbot.outputs",
    "packbot.paths",
    "packbot.recorder",
    "packbot.result_file",
    "packbot.result_store",
    "packbot.scenario_robot",
    "packbot.scenario_schema",
    "packbot.schedule",
    "packbot.srdfgen",
    "packbot.step_control",
    "packbot.study_matrix_format",
    "packbot.system",
    "packbot.ticks",
    "packbot.tolerances",
    "packbot.tomlfile",
    "packbot.urdf_check",
    "packbot.urdfgen",
    "packbot.validation",
}
INTERNAL_PACKAGES = ("packbot.contact", "packbot.control.", "packbot.viz.")

#: ``<!-- docs-test: skip (why) -->`` or ``<!-- docs-test: requires pandas -->`` before a block
MARK = re.compile(r"<!--\s*docs-test:\s*(skip\b|requires\s+[\w.]+)")
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.M | re.S)


def all_modules() -> list[str]:
    names = ["packbot"]
    for info in pkgutil.walk_packages(packbot.__path__, "packbot."):
        names.append(info.name)
    return names


def public_names(module: str) -> list[str]:
    mod = importlib.import_module(module)
    return list(mod.__all__)


def _module_ast(module: str) -> tuple[ast.Module, list[str]]:
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None, module
    text = Path(spec.origin).read_text()
    return ast.parse(text), text.splitlines()


def _has_attribute_doc(body: list[ast.stmt], i: int, lines: list[str]) -> bool:
    node = body[i]
    nxt = body[i + 1] if i + 1 < len(body) else None
    if (
        isinstance(nxt, ast.Expr)
        and isinstance(nxt.value, ast.Constant)
        and isinstance(nxt.value.value, str)
        and nxt.value.value.strip()
    ):
        return True
    above = lines[node.lineno - 2] if node.lineno >= 2 else ""
    if above.lstrip().startswith("#:") and above.lstrip()[2:].strip():
        return True
    return node.end_lineno == node.lineno and "#:" in lines[node.lineno - 1]


def _defines(node: ast.stmt, name: str) -> bool:
    if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
        return node.name == name
    if isinstance(node, ast.Assign):  # also A, B = ... (each target of a tuple)
        targets = [e for t in node.targets for e in (t.elts if isinstance(t, ast.Tuple) else [t])]
        return any(isinstance(t, ast.Name) and t.id == name for t in targets)
    if isinstance(node, ast.AnnAssign):
        return isinstance(node.target, ast.Name) and node.target.id == name
    type_alias = getattr(ast, "TypeAlias", None)
    return type_alias is not None and isinstance(node, type_alias) and node.name.id == name


def definition(module: str, name: str) -> tuple[str, bool]:
    """Where ``module.name`` is defined (module path) and whether it has a docstring there."""
    tree, lines = _module_ast(module)
    for i, node in enumerate(tree.body):
        if _defines(node, name):
            if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                return module, bool((ast.get_docstring(node) or "").strip())
            return module, _has_attribute_doc(tree.body, i, lines)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("packbot"):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    return definition(node.module, alias.name)
    raise AssertionError(f"{module}.{name} is in __all__ but not defined or imported there")


def public_home(module: str, name: str) -> str:
    """The public module whose page documents ``module.name``: where it is defined, or the last
    public module that re-exports it from an internal one (``packbot.collision.Contact``,
    defined in the internal ``packbot.collision_records``)."""
    tree, _ = _module_ast(module)
    if any(_defines(node, name) for node in tree.body):
        return module
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("packbot"):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    home = public_home(node.module, alias.name)
                    return home if home in PUBLIC_MODULES or module == "packbot" else module
    raise AssertionError(f"{module}.{name} is in __all__ but not defined or imported there")


# --------------------------------------------------------------------------- public names


def test_every_module_is_public_or_internal() -> None:
    unclassified = [
        m
        for m in all_modules()
        if m not in PUBLIC_MODULES
        and m not in INTERNAL_MODULES
        and not m.startswith(INTERNAL_PACKAGES)
    ]
    assert unclassified == [], "classify these modules in tests/test_api_docs.py"
    assert not set(PUBLIC_MODULES) & INTERNAL_MODULES


@pytest.mark.parametrize("module", sorted(PUBLIC_MODULES))
def test_public_names_have_docstrings(module: str) -> None:
    mod = importlib.import_module(module)
    assert (mod.__doc__ or "").strip(), f"{module} has no module docstring"
    names = public_names(module)
    assert names, f"{module} has an empty __all__"
    missing = [n for n in names if not definition(module, n)[1]]
    assert not missing, f"public names of {module} without a docstring: {missing}"


def test_top_level_names_are_documented_in_public_modules() -> None:
    # packbot.__all__ re-exports: each is a public name of the public module defining it, so its
    # entry is on that module's page, and the overview page links to it.
    overview = (API / "index.md").read_text()
    for name in packbot.__all__:
        where = public_home("packbot", name)
        assert where in PUBLIC_MODULES, f"packbot.{name} is defined in internal {where}"
        assert name in public_names(where), f"packbot.{name} is not in {where}.__all__"
        if where != "packbot":
            assert f"[`{name}`][{where}.{name}]" in overview, f"overview lacks packbot.{name}"


def test_every_public_module_has_a_page_in_the_nav() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    for module, page in PUBLIC_MODULES.items():
        text = (API / page).read_text()
        assert re.search(rf"^::: {re.escape(module)}\s*$", text, re.M), f"{page} lacks ::: {module}"
        assert f"api/{page}" in nav, f"mkdocs.yml's nav lacks api/{page}"


def test_definition_finds_missing_docstrings(tmp_path: Path) -> None:
    # The checker itself: a constant without a comment and a class without a docstring fail.
    tree = ast.parse('A = 1\n#: doc\nB = 2\nC = 3  #: inline\nD = 4\n"""after"""\n')
    lines = ["A = 1", "#: doc", "B = 2", "C = 3  #: inline", "D = 4", '"""after"""']
    found = {
        node.targets[0].id: _has_attribute_doc(tree.body, i, lines)  # type: ignore[attr-defined]
        for i, node in enumerate(tree.body)
        if isinstance(node, ast.Assign)
    }
    assert found == {"A": False, "B": True, "C": True, "D": True}


# --------------------------------------------------------------------------- the built site


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    pytest.importorskip("mkdocstrings_handlers.python", reason="the docs extra is not installed")
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-4000:]
    return out


@pytest.mark.nonnumeric
@pytest.mark.parametrize("module", sorted(PUBLIC_MODULES))
def test_public_names_have_entries_on_their_page(site: Path, module: str) -> None:
    page = PUBLIC_MODULES[module].removesuffix(".md")
    html = (site / "api" / ("" if page == "index" else page) / "index.html").read_text()
    ids = set(re.findall(r'id="([^"]+)"', html))
    if module == "packbot":
        # the overview links each re-export to its entry on its module's page
        for name in packbot.__all__:
            where = public_home("packbot", name)
            target = f"#{where}.{name}" if where != "packbot" else None
            assert target is None or target in html, f"overview has no link to {where}.{name}"
        assert "packbot.__version__" in ids
        return
    missing = [n for n in public_names(module) if f"{module}.{n}" not in ids]
    assert not missing, f"names of {module} without an entry on api/{page}: {missing}"


class _Links(HTMLParser):
    """A page's link targets (``href`` of a, link; ``src`` of img, script) and its anchors."""

    def __init__(self) -> None:
        super().__init__()
        self.targets: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        for key in ("id", "name") if tag == "a" else ("id",):
            if a.get(key):
                self.ids.add(str(a[key]))
        key = {"a": "href", "link": "href", "img": "src", "script": "src"}.get(tag)
        if key and a.get(key):
            self.targets.append(str(a[key]))


def broken_links(site: Path) -> list[str]:
    """Every relative link of the built site whose file, or whose ``#anchor`` in it, is missing.

    External links (a scheme or a host), ``mailto:`` and ``data:`` are not followed; a path
    from the site's root (``/assets/...``, the 404 page's) is read from the site's root; a
    folder stands for its ``index.html``.
    """
    root = site.resolve()
    pages: dict[Path, _Links] = {}
    for f in sorted(root.rglob("*.html")):
        parser = _Links()
        parser.feed(f.read_text(errors="replace"))
        pages[f] = parser
    bad = []
    for f, parser in pages.items():
        for link in parser.targets:
            url = urlsplit(link)
            if url.scheme or url.netloc:
                continue
            path = unquote(url.path)
            if path.startswith("/"):
                target = (root / path.lstrip("/")).resolve()
            else:
                target = (f.parent / path).resolve() if path else f
            if target.is_dir():
                target = target / "index.html"
            where = f"{f.relative_to(root)}: {link}"
            if not target.is_file():
                bad.append(f"{where} (no file {target.relative_to(root)})")
            elif (
                url.fragment
                and target.suffix == ".html"
                and unquote(url.fragment) not in pages[target].ids
            ):
                bad.append(f"{where} (no anchor in {target.relative_to(root)})")
    return bad


def test_no_broken_link_in_the_site(site: Path) -> None:
    """Every relative link and anchor of the built site (the guide, the API pages, their
    cross-references) leads somewhere."""
    assert len(list(site.rglob("*.html"))) > 30
    bad = broken_links(site)
    assert not bad, f"{len(bad)} broken links:\n" + "\n".join(bad[:40])


def test_the_link_check_finds_missing_files_and_anchors(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "index.html").write_text('<h2 id="here">x</h2><a href="#here">ok</a>')
    (tmp_path / "index.html").write_text(
        '<a href="a/">ok</a> <a href="a/#here">ok</a> <a href="/a/index.html">ok</a>'
        '<a href="https://example.org/x">external</a> <a href="mailto:x@y">mail</a>'
        '<a href="a/#gone">anchor</a> <a href="b/">file</a> <img src="figures/x.png">'
    )
    bad = broken_links(tmp_path)
    assert len(bad) == 3, bad
    assert "a/#gone (no anchor" in bad[0] and "b/ (no file" in bad[1] and "x.png" in bad[2]


def test_site_excludes_developer_notes(site: Path) -> None:
    assert not (site / "dev").exists()
    assert (site / "index.html").is_file()
    assert (site / "simulator" / "index.html").is_file()


# --------------------------------------------------------------------------- examples


def doc_pages() -> list[Path]:
    pages = [ROOT / "README.md"]
    pages += sorted(p for p in DOCS.rglob("*.md") if "dev" not in p.relative_to(DOCS).parts)
    return pages


def python_blocks(path: Path) -> list[tuple[int, str, str]]:
    """The ```python blocks of a page: (first code line, code, mark: "", "skip" or a module)."""
    text = path.read_text()
    blocks = []
    for m in FENCE.finditer(text):
        if m.group(1).strip().split(" ")[0] not in ("python", "py"):
            continue
        start = text.count("\n", 0, m.start())
        before = text.splitlines()[start - 1] if start else ""
        mark = MARK.search(before)
        how = "" if mark is None else mark.group(1).split()[-1]
        blocks.append((start + 2, m.group(2), how))
    return blocks


def page_id(path: Path) -> str:
    return str(path.relative_to(ROOT))


@pytest.mark.parametrize("path", doc_pages(), ids=page_id)
def test_python_blocks_run(path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = python_blocks(path)
    if path.parent == API:
        assert any(how == "" for _, _, how in blocks), f"{page_id(path)} has no example"
    if not blocks:
        pytest.skip("no python block")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict[str, object] = {"__name__": "__docs__"}
    not_run = []
    for line, code, how in blocks:
        # line numbers of the page in tracebacks
        compiled = compile("\n" * (line - 1) + code, page_id(path), "exec")
        if how == "skip" or (how and importlib.util.find_spec(how) is None):
            not_run.append(f"line {line}: {how}")
            continue
        exec(compiled, namespace)
    if len(not_run) == len(blocks):
        pytest.skip("no block runs here: " + ", ".join(not_run))


def test_marks_are_found(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text(
        "x\n\n```python\na = 1\n```\n\n<!-- docs-test: skip (a browser) -->\n```python\nb\n```\n"
        "<!-- docs-test: requires pandas -->\n```python\nc\n```\n```bash\nls\n```\n"
    )
    assert python_blocks(page) == [(4, "a = 1\n", ""), (9, "b\n", "skip"), (13, "c\n", "pandas")]


def test_ci_builds_the_site_with_the_docs_extra() -> None:
    # .ci/run installs the docs extra's requirements (read from pyproject.toml) beside the
    # tested install and builds the site with warnings as errors.
    ci = (ROOT / ".ci" / "run").read_text()
    extras = re.search(r"for name in \(([^)]*)\) for r in extras\[name\]", ci)
    assert extras is not None and '"docs"' in extras.group(1)
    assert "pip install --quiet -r .venv/extras.txt" in ci
    assert "mkdocs build --strict" in ci
