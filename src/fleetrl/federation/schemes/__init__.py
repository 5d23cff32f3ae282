"""Federation schemes as strategy objects, found by name: every built-in is one module of this package
with a subclass of a scheme kind that sets ``name``; a user's is named ``package.module:Class``."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from typing import Any, get_type_hints

from fleetrl.coercion import CoercionError, coerce
from fleetrl.envs.unit_factory import load_callable
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import (
    COMPLETED,
    AsyncScheme,
    RoundAnswer,
    RoundContext,
    RoundScheme,
    Scheme,
    StepScheme,
)
from fleetrl.federation.wire.messages import check_scheme_type

DEFAULT_SCHEME = "pergrad"
"""the scheme when none is named: the one that won on the held-out seeds (docs/results.md)"""
USER_FORM = "package.module:Class"

__all__ = [
    "COMPLETED",
    "DEFAULT_SCHEME",
    "SCHEMES",
    "AsyncScheme",
    "FederatedAgent",
    "RoundAnswer",
    "RoundContext",
    "RoundScheme",
    "Scheme",
    "StepScheme",
    "get_scheme",
    "resolve_scheme",
    "scheme_reference",
]


def _discover() -> dict[str, type[Scheme]]:
    """Every concrete scheme class defined in a module of this package, by its ``name``, in module order."""
    found: dict[str, type[Scheme]] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name == "base":
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        for cls in vars(module).values():
            if (
                inspect.isclass(cls) and issubclass(cls, Scheme) and cls.__module__ == module.__name__
                and not inspect.isabstract(cls) and "name" in vars(cls)
            ):  # fmt: skip
                if cls.name in found:
                    raise AssertionError(f"two schemes are named {cls.name!r}")
                found[cls.name] = cls
    return found


SCHEMES: dict[str, type[Scheme]] = _discover()
"""Every built-in scheme class by name."""


def get_scheme(name: str, **params: Any) -> Scheme:
    """A new scheme object called ``name`` (a built-in's, or ``package.module:Class``) with ``params`` typed
    from its constructor's annotations; ValueError naming the choices, an unknown parameter or a bad value."""
    cls = scheme_class(name)
    accepted = scheme_parameters(cls)
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        known = ", ".join(sorted(accepted)) or "none"
        raise ValueError(
            f"scheme {name!r} has no parameter(s) {', '.join(unknown)} (its parameters: {known})"
        )
    typed = {key: _typed(name, key, value, accepted[key]) for key, value in params.items()}
    try:
        return cls(**typed)
    except ValueError as err:
        raise ValueError(f"scheme {name!r}: {err}") from None


def scheme_class(name: str) -> type[Scheme]:
    """The class ``name`` names: a built-in, or a user's ``package.module:Class`` (imported and checked)."""
    if ":" in name:
        return _user_scheme(name)
    try:
        return SCHEMES[name]
    except KeyError:
        names = list(SCHEMES)
        choices = ", ".join(names[:-1]) + " or " + names[-1]
        raise ValueError(
            f"unknown federation scheme {name!r} (choose {choices}, or your own as {USER_FORM})"
        ) from None


def _user_scheme(text: str) -> type[Scheme]:
    what = f"scheme {text!r}"
    cls = load_callable(text, what, USER_FORM, "a RoundScheme or StepScheme subclass")
    if not (inspect.isclass(cls) and issubclass(cls, RoundScheme | StepScheme)):
        raise ValueError(f"{what} is not a subclass of fleetrl.federation.schemes.RoundScheme or StepScheme")
    if inspect.isabstract(cls):
        missing = ", ".join(sorted(getattr(cls, "__abstractmethods__", ())))
        raise ValueError(f"{what} does not define {missing}")
    lacking = [a for a in ("name", "round_message", "stays_after_completion") if not hasattr(cls, a)]
    if lacking:
        raise ValueError(f"{what} does not set {', '.join(lacking)}")
    check_scheme_type(cls.round_message, what)
    return cls


def scheme_reference(scheme: Scheme) -> str:
    """What names ``scheme``'s class for :func:`get_scheme`: a built-in's name, else ``module:Class``."""
    cls = type(scheme)
    if SCHEMES.get(cls.name) is cls:
        return cls.name
    return f"{cls.__module__}:{cls.__qualname__}"


def scheme_parameters(cls: type[Scheme]) -> dict[str, Any]:
    """The keyword parameters of a scheme class's constructor and their annotated types."""
    if cls.__init__ is object.__init__:
        return {}
    hints = get_type_hints(cls.__init__)
    names = [p.name for p in inspect.signature(cls.__init__).parameters.values() if p.name != "self"]
    return {n: hints.get(n, Any) for n in names}


def _typed(scheme: str, key: str, value: Any, kind: Any) -> Any:
    try:
        return coerce(key, value, kind)
    except CoercionError as err:
        raise ValueError(f"scheme {scheme!r}: {err}") from None


def resolve_scheme(scheme: str | Scheme) -> Scheme:
    """``scheme`` itself, or the scheme of that name with its default parameters."""
    return scheme if isinstance(scheme, Scheme) else get_scheme(scheme)
