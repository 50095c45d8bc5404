"""Argument binding checks: an unknown, misspelt or missing keyword gets a clean error.

:func:`checked_arguments` decorates a public function, method or class (for a class, its own
``__init__``: a dataclass's generated one too, so apply it above ``@dataclass``). A call whose
arguments do not bind to the signature (an unknown keyword, a missing one, too many positional
arguments, a value given twice) raises :class:`~packbot.errors.KeywordError` instead of
Python's bare ``TypeError``: it names the keyword, suggests the closest valid one
(``SimConfig(restitutio=0.5)``: "did you mean 'restitution'?") and lists the valid keywords.
``KeywordError`` is a ``TypeError`` too, so code catching ``TypeError`` keeps working.

The check costs nothing on a valid call: the call is made as it is, and only when it raises a
``TypeError`` are the arguments bound to the signature (:func:`inspect.Signature.bind`); if they
bind, the ``TypeError`` came from the body and passes unchanged.

:func:`check_subclass` is what :class:`packbot.control.Controller` calls from
``__init_subclass__``, so that every subclass (a user's own too) gets the check on its
``__init__`` without a decorator. The close match is :func:`packbot.errors.close_match`, the
rule of every unknown name's suggestion (scenario and matrix keys, joints, poses...).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ParamSpec, TypeVar

from packbot.errors import KeywordError, close_match

__all__ = ["check_subclass", "checked_arguments", "keyword_error"]

P = ParamSpec("P")
R = TypeVar("R")
F = TypeVar("F", bound=Callable[..., Any])

#: Attribute set on a wrapper, so that nothing is wrapped twice.
_MARK = "__packbot_checked__"


def _is_method(sig: inspect.Signature) -> bool:
    params = list(sig.parameters.values())
    return bool(params) and params[0].name in ("self", "cls")


def _describe(
    sig: inspect.Signature, args: Sequence[Any], kwargs: Mapping[str, Any]
) -> tuple[str, dict[str, Any]] | None:
    """What is wrong with binding ``args``, ``kwargs`` to ``sig`` (None: they bind).

    Returns:
        The problem's kind (``"unknown"``, ``"missing"``, ``"positional"``, ``"twice"``) and
        its details, the first problem in the order Python reports them.
    """
    try:
        sig.bind(*args, **kwargs)
    except TypeError:
        pass
    else:
        return None
    params = list(sig.parameters.values())
    skip = 1 if _is_method(sig) else 0
    own = params[skip:]
    kinds = inspect.Parameter
    positional = [p for p in own if p.kind in (kinds.POSITIONAL_ONLY, kinds.POSITIONAL_OR_KEYWORD)]
    var_positional = any(p.kind is kinds.VAR_POSITIONAL for p in own)
    var_keyword = any(p.kind is kinds.VAR_KEYWORD for p in own)
    keywords = tuple(
        p.name for p in own if p.kind in (kinds.POSITIONAL_OR_KEYWORD, kinds.KEYWORD_ONLY)
    )
    given = len(args) - skip
    if given > len(positional) and not var_positional:
        return "positional", {
            "given": given,
            "positional": tuple(p.name for p in positional),
            "valid": keywords,
        }
    filled = {p.name for p in positional[: max(given, 0)]}
    for key in kwargs:
        if key in filled and key in keywords:
            return "twice", {"keyword": key, "valid": keywords}
        if key not in keywords and not var_keyword:
            return "unknown", {"keyword": key, "value": kwargs[key], "valid": keywords}
    required = tuple(
        p.name
        for p in own
        if p.default is kinds.empty and p.kind not in (kinds.VAR_POSITIONAL, kinds.VAR_KEYWORD)
    )
    missing = tuple(n for n in required if n not in filled and n not in kwargs)
    if missing:
        return "missing", {"missing": missing, "required": required, "valid": keywords}
    return "unknown", {"keyword": None, "value": None, "valid": keywords}  # not reached


def keyword_error(
    name: str, sig: inspect.Signature, args: Sequence[Any], kwargs: Mapping[str, Any]
) -> KeywordError | None:
    """The error of a call ``name(*args, **kwargs)`` whose arguments do not bind to ``sig``.

    Args:
        name: What was called, for the message (``"SimConfig"``, ``"SimResult.save"``).
        sig: Its signature (a method's includes ``self``, and ``args`` holds it).
        args: The positional arguments.
        kwargs: The keyword arguments.

    Returns:
        The error to raise, or None if the arguments bind (the call failed for another reason).
    """
    problem = _describe(sig, args, kwargs)
    if problem is None:
        return None
    kind, info = problem
    valid: tuple[str, ...] = info["valid"]
    if kind == "unknown":
        return KeywordError(
            name,
            valid,
            keyword=info["keyword"],
            value=info["value"],
            suggestion=close_match(info["keyword"], valid),
        )
    if kind == "missing":
        return KeywordError(name, valid, missing=info["missing"], required=info["required"])
    if kind == "twice":
        return KeywordError(name, valid, keyword=info["keyword"], twice=True)
    return KeywordError(name, valid, given=info["given"], positional=info["positional"])


def _call_name(
    func: Callable[..., Any], owner: type | None, sig: inspect.Signature, args: Sequence[Any]
) -> str:
    """The name of what was called, as the user wrote it (``"JointPD"``, ``"Robot.pose"``)."""
    if not (_is_method(sig) and args):
        return func.__qualname__.rsplit("<locals>.", 1)[-1]
    first = args[0]
    cls = first if isinstance(first, type) else type(first)
    if func.__name__ != "__init__" or owner is None:
        return f"{cls.__name__}.{func.__name__}"
    # a class inheriting this __init__ is what was called; else it is reached through
    # super().__init__ from the class's own
    called = next((vars(k)["__init__"] for k in cls.__mro__ if "__init__" in vars(k)), None)
    if called is vars(owner).get("__init__"):
        return cls.__name__
    return f"{owner.__name__} (from {cls.__name__}.__init__)"


def _wrap(func: Callable[P, R], owner: type | None = None) -> Callable[P, R]:
    """``func`` with its arguments checked when a call raises ``TypeError``."""
    if getattr(func, _MARK, False):
        return func
    signature: list[inspect.Signature] = []  # computed at the first failed call

    @functools.wraps(func)
    def checked(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except TypeError:
            if not signature:
                signature.append(inspect.signature(func))
            sig = signature[0]
            error = keyword_error(_call_name(func, owner, sig, args), sig, args, kwargs)
            if error is None:
                raise
            raise error from None

    setattr(checked, _MARK, True)
    return checked


def _wrap_init(cls: type) -> None:
    init = cls.__dict__.get("__init__")
    if init is None or getattr(init, _MARK, False):
        return
    setattr(cls, "__init__", _wrap(init, owner=cls))  # noqa: B010 (mypy: a method)


def check_subclass(cls: type) -> None:
    """Check the arguments of ``cls``'s own ``__init__`` (for ``__init_subclass__`` hooks)."""
    _wrap_init(cls)


def checked_arguments(obj: F) -> F:
    """Decorate a function, method or class: bad arguments raise :class:`KeywordError`.

    A class gets its own ``__init__`` checked (apply the decorator above ``@dataclass``, so
    that the generated ``__init__`` is the one wrapped); its fields, ``repr``, equality,
    pickling and signature are unchanged. A method is decorated in its class body (below
    ``@classmethod``); the message then names ``Class.method``.

    Args:
        obj: The function or class.

    Returns:
        The same class (its ``__init__`` wrapped), or the function wrapped (same signature,
        name and docstring).

    Raises:
        KeywordError: (from the decorated callable) An unknown or misspelt keyword (with the
            closest valid one), a missing required argument, too many positional arguments,
            or an argument given twice. The valid keywords are listed.
    """
    if isinstance(obj, type):
        _wrap_init(obj)
        return obj
    return _wrap(obj)  # type: ignore[return-value]
