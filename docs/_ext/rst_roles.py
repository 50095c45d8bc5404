"""A Griffe extension: packbot's reStructuredText markup in docstrings, rendered by mkdocstrings.

packbot's docstrings are Google-style with a few reStructuredText constructs (kept so that they
read well in ``help()`` and in an editor): cross-reference roles (``:func:`simulate```,
``:class:`~packbot.errors.ConfigurationError```, ``:meth:`SimResult.load```, ``:mod:``,
``:attr:``, ``:data:``) and literal blocks introduced by a paragraph ending in ``::``.
mkdocstrings renders Markdown, so once the package is loaded this extension rewrites each
docstring:

- a role becomes a link to the object's entry in the API reference: the name is resolved from
  the docstring's scope (the object, its class, its module, as Python would) to the canonical
  path of the object (``packbot.simulate`` -> ``packbot.integrator.simulate``); the link is
  optional, so a target that the reference does not render (an internal module) shows as
  code, without a warning; ``~`` keeps only the last component as the title, as in Sphinx;
- ``text::`` before an indented block becomes ``text:`` (the block is already a Markdown code
  block); a lone ``::`` line is dropped.

It changes no source file. mkdocs.yml loads it with ``extensions: [docs/_ext/rst_roles.py]``.
"""

from __future__ import annotations

import html
import re
from typing import Any

import griffe

ROLE = re.compile(
    r":(?:py:)?(?:func|meth|class|mod|attr|data|obj|exc|const):`(~?)([^`<>]+?)(\(\))?`"
)
LITERAL_INTRO = re.compile(r"(?m)^(.*\S)::[ \t]*$")
LONE_LITERAL = re.compile(r"(?m)^[ \t]*::[ \t]*\n")


def _canonical(root: griffe.Module, path: str) -> str | None:
    """The canonical path of ``path`` (an alias followed to its target), or None if unknown."""
    parts = path.split(".")
    if parts[0] != root.name:
        return None
    obj: Any = root
    try:
        for name in parts[1:]:
            obj = obj.members[name]
            while obj.is_alias:
                target = obj.target_path
                if not target.startswith(root.name + "."):
                    return target
                obj = root[target.removeprefix(root.name + ".")]
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None
    return str(obj.path)


def _resolve(obj: griffe.Object, root: griffe.Module, name: str) -> str | None:
    """Resolve a role's target from ``obj``'s scope to a canonical path, or None."""
    if name.startswith(root.name + ".") or name == root.name:
        return _canonical(root, name)
    head, _, rest = name.partition(".")
    try:
        base = obj.resolve(head)
    except griffe.NameResolutionError:
        return None
    path = f"{base}.{rest}" if rest else base
    return _canonical(root, path) if path.startswith(root.name) else None


def _rewrite(text: str, obj: griffe.Object, root: griffe.Module) -> str:
    def role(match: re.Match[str]) -> str:
        tilde, name, call = match.group(1), match.group(2).strip(), match.group(3) or ""
        title = (name.rsplit(".", 1)[-1] if tilde else name) + call
        code = f"<code>{html.escape(title)}</code>"
        target = _resolve(obj, root, name)
        if target is None:
            return f"`{title}`"
        return f'<autoref identifier="{html.escape(target)}" optional>{code}</autoref>'

    text = ROLE.sub(role, text)
    text = LONE_LITERAL.sub("", text)
    return LITERAL_INTRO.sub(r"\1:", text)


def _walk(obj: griffe.Object, root: griffe.Module, seen: set[str]) -> None:
    if obj.path in seen:
        return
    seen.add(obj.path)
    if obj.docstring is not None:
        obj.docstring.value = _rewrite(obj.docstring.value, obj, root)
    for member in obj.members.values():
        if not member.is_alias:
            _walk(member, root, seen)


class RstRoles(griffe.Extension):
    """Rewrite reStructuredText roles and literal-block markers into Markdown, per package."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Rewrite every docstring of the package once it is fully loaded.

        Args:
            pkg: The loaded package.
            **kwargs: Other arguments of the event (unused).
        """
        _walk(pkg, pkg, set())
