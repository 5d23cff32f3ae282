"""A user's unit type named on the command line: ``--env package.module:factory`` with ``factory(unit,
fleet_seed, link=None) -> gymnasium.Env``, and its device side ``--device-driver package.module:function``
with ``driver(unit, fleet_seed, *, realtime) -> DeviceDriver``. Modules are imported as ``python -m`` would;
a text that names no such callable is a one-line ValueError."""

from __future__ import annotations

import importlib
import inspect
import os
import re
import sys
from collections.abc import Callable
from typing import Any

UnitFactory = Callable[..., Any]
"""``factory(unit, fleet_seed, link=None) -> gymnasium.Env``; the ``link`` keyword is optional"""

FACTORY_FORM = "package.module:factory"
SIGNATURE = "factory(unit: int, fleet_seed: int, link=None) -> gymnasium.Env"
DRIVER_FORM = "package.module:function"
DRIVER_SIGNATURE = "driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver"
_DOTTED = r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*"
_REFERENCE = re.compile(rf"(?P<module>{_DOTTED}):(?P<attr>{_DOTTED})")


def is_factory_reference(text: str) -> bool:
    """Whether ``text`` is meant as a factory (it has a ``:``), well-formed or not."""
    return ":" in text


def load_factory(text: str) -> UnitFactory:
    """The callable ``text`` (``package.module:factory``) names, or a ValueError saying what is wrong."""
    factory: UnitFactory = load_callable(text, f"unit factory {text!r}", FACTORY_FORM, SIGNATURE)
    return factory


def load_driver_function(text: str) -> Callable[..., Any]:
    """The driver function ``text`` (``package.module:function``) names, or a ValueError."""
    return load_callable(text, f"device driver {text!r}", DRIVER_FORM, DRIVER_SIGNATURE)


def takes_link(factory: Callable[..., Any]) -> bool:
    """Whether ``factory`` accepts a ``link`` keyword (or any keyword): it can build a unit over a link."""
    try:
        parameters = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):  # no signature to read (some builtins): assume not
        return False
    return any(
        (p.name == "link" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)) or p.kind is p.VAR_KEYWORD
        for p in parameters
    )


def load_callable(text: str, what: str, form: str, signature: str) -> Any:
    """The callable ``text`` (``package.module:attr``) names, or a ValueError naming ``what``."""
    match = _REFERENCE.fullmatch(text)
    if match is None:
        raise ValueError(f"{what} is not in {form} form")
    module_name, attr = match["module"], match["attr"]
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:  # as `python -m` would: the current directory first
        sys.path.insert(0, here)
    try:
        target: Any = importlib.import_module(module_name)
    except ImportError as err:
        raise ValueError(
            f"{what}: cannot import module {module_name!r} ({type(err).__name__}: {err})"
        ) from None
    except Exception as err:  # the module's own code failed while importing
        raise ValueError(
            f"{what}: importing module {module_name!r} raised {type(err).__name__}: {err}"
        ) from None
    for part in attr.split("."):
        if not hasattr(target, part):
            raise ValueError(f"{what}: module {module_name!r} has no attribute {attr!r}")
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(
            f"{what}: {attr!r} is a {type(target).__name__}, not callable (it must be {signature})"
        )
    return target
