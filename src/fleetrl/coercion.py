"""One typed coercion for every setting read from outside (a config file, a flag, a scheme parameter, a PPO
override): a value and the type a field declares in, the value as that type out, or a ValueError naming what
was wrong and what is accepted.

Nothing here imports fleetrl: every layer may use it.
"""

from __future__ import annotations

import types
from pathlib import Path
from typing import Any, Literal, Union, get_args, get_origin


class CoercionError(ValueError):
    """A value that is not of its setting's type: ``name = value: expected …``."""


def describe(kind: Any) -> str:
    """What a type accepts, in words (``a number``, ``one of 'tanh', 'relu'``, …)."""
    origin, args = get_origin(kind), get_args(kind)
    if origin in (Union, types.UnionType):
        return " or ".join(describe(a) for a in args if a is not type(None)) + " (or unset)"
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in args)
    if origin is tuple:
        return f"a list of {describe(args[0])}s"
    if origin is dict or kind is dict:
        return "a table of settings"
    names = {bool: "true or false", int: "an integer", float: "a number", str: "a string", Path: "a path"}
    return names.get(kind, getattr(kind, "__name__", str(kind)))


def coerce(name: str, value: Any, kind: Any) -> Any:
    """``value`` as the type ``kind``: an int where a float is declared becomes a float, a string a Path, a
    list a tuple; a bool is never an int; a ``Literal`` takes only its values. Else :class:`CoercionError`
    (``name`` says which setting)."""
    origin, args = get_origin(kind), get_args(kind)
    if kind is Any:
        return value
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        for option in (a for a in args if a is not type(None)):
            try:
                return coerce(name, value, option)
            except CoercionError:
                continue
    elif origin is Literal:
        if value in args and not isinstance(value, bool):
            return value
    elif origin is tuple and isinstance(value, list | tuple):
        return tuple(coerce(name, item, args[0]) for item in value)
    elif (origin is dict or kind is dict) and isinstance(value, dict):
        return dict(value)
    elif (kind is bool and isinstance(value, bool)) or (
        kind is int and isinstance(value, int) and not isinstance(value, bool)
    ):
        return value
    elif kind is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    elif kind is str and isinstance(value, str):
        return value
    elif kind is Path and isinstance(value, str | Path) and str(value):
        return Path(value)
    raise CoercionError(f"{name} = {value!r}: expected {describe(kind)}")
