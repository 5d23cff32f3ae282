"""Federation schemes as strategy objects behind one interface (:class:`~.base.Scheme`), looked up by name.

* ``paper`` (:mod:`.paper`) — the paper's gradient sharing with model transfer;
* ``fedavg`` (:mod:`.fedavg`) — whole-model averaging, mature workers stay;
* ``pergrad`` (:mod:`.pergrad`) — gradients averaged at every optimisation step (DD-PPO style).
* ``fedavgm``, ``fedadam`` (:mod:`.fedopt`) — fedavg with a server optimiser (momentum, Adam) on the average.

Adding a scheme: write one module here with a :class:`Scheme` subclass, add it to :data:`SCHEMES`, and test it
on hand-computed arrays in tests/federation/test_schemes.py (no broker). Nothing else changes: the chief, the
worker, the learner factory and the launcher only call the scheme object.
"""

from __future__ import annotations

import inspect
from typing import Any, get_type_hints

from fleetrl.coercion import CoercionError, coerce
from fleetrl.federation.schemes.base import (
    COMPLETED,
    FederatedAgent,
    Granularity,
    RoundAnswer,
    RoundContext,
    Scheme,
)
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.schemes.fedopt import FedAdamScheme, FedAvgMScheme
from fleetrl.federation.schemes.paper import PaperScheme
from fleetrl.federation.schemes.pergrad import PerStepGradientScheme

DEFAULT_SCHEME = "pergrad"
"""the scheme of ``fleetrl demo``, ``fleetrl train --mode federated``, ``chief`` and ``worker`` when none is
named: the one that won on the held-out seeds (docs/results.md); ``--scheme paper`` is the paper's"""

__all__ = [
    "COMPLETED",
    "DEFAULT_SCHEME",
    "SCHEMES",
    "FederatedAgent",
    "Granularity",
    "RoundAnswer",
    "RoundContext",
    "Scheme",
    "get_scheme",
    "resolve_scheme",
]

SCHEMES: dict[str, type[Scheme]] = {
    cls.name: cls for cls in (PaperScheme, FedAvgScheme, FedAvgMScheme, FedAdamScheme, PerStepGradientScheme)
}
"""Every registered scheme class by name."""


def get_scheme(name: str, **params: Any) -> Scheme:
    """A new scheme object called ``name`` with ``params``, each typed from the scheme's constructor
    annotations (an int where a float is expected is taken); ValueError naming the choices, the unknown
    parameter or the bad value otherwise."""
    try:
        cls = SCHEMES[name]
    except KeyError:
        names = list(SCHEMES)
        choices = ", ".join(names[:-1]) + " or " + names[-1]
        raise ValueError(f"unknown federation scheme {name!r} (choose {choices})") from None
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
