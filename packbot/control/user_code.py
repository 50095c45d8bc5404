"""A user's controller and recovery strategy, named by an object or an import path.

Every feature that runs a built-in controller or strategy also takes the user's own:

- a **controller** is a :class:`~packbot.control.Controller` subclass (instantiated with no
  arguments, a fresh one per run), a factory ``robot -> Controller`` (called once per run), or
  the import path of either, ``"module:Name"`` (``"my_lab.reach:Reach"``, dotted names after the
  colon allowed);
- a **recovery strategy** is ``"builtin"`` (:class:`~packbot.control.strategies.
  BaselineRecovery`), ``"none"`` (:class:`~packbot.control.strategies.NoRecovery`: the
  controller's own ``on_failure`` hook), a :class:`~packbot.control.strategies.
  RecoveryStrategy` subclass (no arguments), a factory ``() -> RecoveryStrategy``, or the
  import path of either.

Instances are refused (a run must not inherit another run's state). A scenario file names no
code: ``packbot study --controller module:Name`` imports the module, with the current folder on
``sys.path`` as ``python -m`` has it. Work spread over processes (a study matrix's workers)
needs a spec that pickles: an import path, or a class or function defined at a module's top
level (not a lambda, not a function defined inside another).
"""

from __future__ import annotations

import importlib
import pickle
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeAlias

from packbot.control.base import Controller
from packbot.control.strategies import (
    STRATEGY_NAMES,
    BaselineRecovery,
    NoRecovery,
    RecoveryStrategy,
)
from packbot.errors import ConfigurationError

if TYPE_CHECKING:
    from packbot.model import Robot

__all__ = [
    "ControllerSpec",
    "StrategySpec",
    "check_picklable",
    "controller_factory",
    "describe_spec",
    "import_object",
    "strategy_factory",
]

#: A user's controller: a Controller subclass, a factory robot -> Controller, an import path.
ControllerSpec: TypeAlias = "type[Controller] | Callable[[Robot], Controller | None] | str"
#: A recovery strategy: a name, a RecoveryStrategy subclass, a factory, an import path.
StrategySpec: TypeAlias = "str | type[RecoveryStrategy] | Callable[[], RecoveryStrategy]"

_PATH = "an import path 'module:Name' (e.g. 'my_lab.reach:Reach')"


def import_object(path: str, field: str) -> Any:
    """The object an import path ``"module:Name"`` names (``Name`` may be dotted).

    Raises:
        ConfigurationError: Not of that form, the module cannot be imported (its error is
            given), or it has no such name (names the field and the value).
    """
    if not isinstance(path, str) or path.count(":") != 1:
        raise ConfigurationError(field, path, _PATH)
    module_name, _, attr = path.partition(":")
    if not module_name or not attr or not all(p.isidentifier() for p in attr.split(".")):
        raise ConfigurationError(field, path, _PATH)
    try:
        obj: Any = importlib.import_module(module_name)
    except Exception as exc:  # the user's module: any error in it is a bad setting
        raise ConfigurationError(
            field, path, f"{_PATH}: importing {module_name!r} raised {type(exc).__name__}: {exc}"
        ) from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigurationError(field, path, f"{_PATH}: {module_name!r} has no {attr!r}")
        obj = getattr(obj, part)
    return obj


def describe_spec(spec: Any) -> str:
    """A name of a spec for reports: the import path, or ``module:qualified name``."""
    if isinstance(spec, str):
        return spec
    module = getattr(spec, "__module__", None)
    name = getattr(spec, "__qualname__", None) or type(spec).__name__
    return f"{module}:{name}" if module else str(name)


def controller_factory(
    spec: Any, field: str = "controller"
) -> Callable[[Robot], Controller | None]:
    """A factory ``robot -> Controller`` (a fresh one per call) from a controller spec.

    Raises:
        ConfigurationError: Not a Controller subclass, factory or import path of one (an
            instance is refused: each run needs a fresh controller).
    """
    obj = import_object(spec, field) if isinstance(spec, str) else spec
    expected = (
        "a packbot.control.Controller subclass (made with no arguments), a factory "
        f"robot -> Controller, or {_PATH}"
    )
    if isinstance(obj, Controller):
        raise ConfigurationError(
            field, spec, f"{expected}; not an instance: each run needs a fresh controller"
        )
    if isinstance(obj, type):
        if not issubclass(obj, Controller):
            raise ConfigurationError(field, spec, expected)
        cls = obj

        def make_instance(robot: Robot) -> Controller | None:
            try:
                return cls()
            except TypeError as exc:
                raise ConfigurationError(
                    field, spec, f"{expected} ({cls.__name__}() raised: {exc})"
                ) from None

        return make_instance
    if not callable(obj):
        raise ConfigurationError(field, spec, expected)
    factory = obj

    def make(robot: Robot) -> Controller | None:
        ctrl = factory(robot)
        if ctrl is not None and not isinstance(ctrl, Controller):
            raise ConfigurationError(
                field, spec, f"{expected} (the factory returned {type(ctrl).__name__})"
            )
        return ctrl

    return make


def strategy_factory(spec: Any, field: str = "recovery") -> Callable[[], RecoveryStrategy]:
    """A factory of fresh recovery strategies from a strategy spec (module docstring).

    Raises:
        ConfigurationError: Not a strategy name, subclass, factory or import path of one.
    """
    if spec is None or spec == "builtin":
        return BaselineRecovery
    if spec == "none":
        return NoRecovery
    expected = (
        f"one of {', '.join(STRATEGY_NAMES)}, a packbot.control.RecoveryStrategy subclass "
        f"(made with no arguments), a factory () -> RecoveryStrategy, or {_PATH}"
    )
    if isinstance(spec, str) and ":" not in spec:
        raise ConfigurationError(field, spec, expected)
    obj = import_object(spec, field) if isinstance(spec, str) else spec
    if isinstance(obj, RecoveryStrategy):
        raise ConfigurationError(
            field, spec, f"{expected}; not an instance: each run needs a fresh strategy"
        )
    if isinstance(obj, type) and not issubclass(obj, RecoveryStrategy):
        raise ConfigurationError(field, spec, expected)
    if not callable(obj):
        raise ConfigurationError(field, spec, expected)
    factory = obj

    def make() -> RecoveryStrategy:
        try:
            strategy = factory()
        except TypeError as exc:
            raise ConfigurationError(
                field, spec, f"{expected} (calling it raised: {exc})"
            ) from None
        if not isinstance(strategy, RecoveryStrategy):
            raise ConfigurationError(
                field, spec, f"{expected} (it returned {type(strategy).__name__})"
            )
        return strategy

    return make


def check_picklable(spec: Any, field: str) -> None:
    """Refuse a spec that cannot reach worker processes (a lambda, a local function).

    Raises:
        ConfigurationError: It does not pickle.
    """
    try:
        pickle.dumps(spec)
    except Exception as exc:  # pickling's errors vary (PicklingError, AttributeError, ...)
        raise ConfigurationError(
            field,
            describe_spec(spec),
            f"{_PATH}, or a class or function defined at a module's top level, that worker "
            f"processes can import (this one does not pickle: {exc})",
        ) from None
