"""A user's unit type, named on the command line as ``--env package.module:factory``.

``factory(unit: int, fleet_seed: int) -> gymnasium.Env`` builds unit ``unit`` of the user's fleet (its
per-unit parameters drawn from ``fleet_seed``). The module is imported like ``python -m`` would: from the
current directory or the installed packages. Every way the text can fail to name such a callable is a
ValueError of one line that names the text and the problem.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from collections.abc import Callable
from typing import Any

UnitFactory = Callable[[int, int], Any]
"""``factory(unit, fleet_seed)``: builds unit ``unit`` of fleet ``fleet_seed`` (it must be a gymnasium.Env)"""

FACTORY_FORM = "package.module:factory"
SIGNATURE = "factory(unit: int, fleet_seed: int) -> gymnasium.Env"
_DOTTED = r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*"
_REFERENCE = re.compile(rf"(?P<module>{_DOTTED}):(?P<attr>{_DOTTED})")


def is_factory_reference(text: str) -> bool:
    """Whether ``text`` is meant as a factory (it has a ``:``), well-formed or not."""
    return ":" in text


def load_factory(text: str) -> UnitFactory:
    """The callable ``text`` (``package.module:factory``) names; otherwise a ValueError saying what is
    wrong."""
    what = f"unit factory {text!r}"
    match = _REFERENCE.fullmatch(text)
    if match is None:
        raise ValueError(f"{what} is not in {FACTORY_FORM} form")
    module_name, attr = match["module"], match["attr"]
    module = _import(module_name, what)
    target: Any = module
    for part in attr.split("."):
        if not hasattr(target, part):
            raise ValueError(f"{what}: module {module_name!r} has no attribute {attr!r}")
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(
            f"{what}: {attr!r} is a {type(target).__name__}, not callable (it must be {SIGNATURE})"
        )
    factory: UnitFactory = target
    return factory


def _import(module_name: str, what: str) -> Any:
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:  # as `python -m` would: the current directory first
        sys.path.insert(0, here)
    try:
        return importlib.import_module(module_name)
    except ImportError as err:
        raise ValueError(
            f"{what}: cannot import module {module_name!r} ({type(err).__name__}: {err})"
        ) from None
    except Exception as err:  # the module's own code failed while importing
        raise ValueError(
            f"{what}: importing module {module_name!r} raised {type(err).__name__}: {err}"
        ) from None
