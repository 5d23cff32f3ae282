"""Federation schemes as strategy objects behind one interface (:class:`~.base.Scheme`), looked up by name.

* ``paper`` (:mod:`.paper`) — the paper's gradient sharing with model transfer;
* ``fedavg`` (:mod:`.fedavg`) — whole-model averaging, mature workers stay;
* ``pergrad`` (:mod:`.pergrad`) — gradients averaged at every optimisation step (DD-PPO style).

Adding a scheme: write one module here with a :class:`Scheme` subclass, add it to :data:`SCHEMES`, and test it
on hand-computed arrays in tests/federation/test_schemes.py (no broker). Nothing else changes: the chief, the
worker, the learner factory and the launcher only call the scheme object.
"""

from __future__ import annotations

from typing import Any

from fleetrl.federation.schemes.base import (
    COMPLETED,
    FederatedAgent,
    Granularity,
    RoundAnswer,
    RoundContext,
    Scheme,
)
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.schemes.paper import PaperScheme
from fleetrl.federation.schemes.pergrad import PerStepGradientScheme

__all__ = [
    "COMPLETED",
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
    cls.name: cls for cls in (PaperScheme, FedAvgScheme, PerStepGradientScheme)
}
"""Every registered scheme class by name."""


def get_scheme(name: str, **params: Any) -> Scheme:
    """A new scheme object called ``name`` with ``params``; ValueError naming the choices (or the bad
    parameter) otherwise."""
    try:
        cls = SCHEMES[name]
    except KeyError:
        raise ValueError(f"unknown federation scheme {name!r} (choose {' or '.join(SCHEMES)})") from None
    try:
        return cls(**params)
    except TypeError as err:
        raise ValueError(f"scheme {name!r}: bad parameters {sorted(params)}: {err}") from None


def resolve_scheme(scheme: str | Scheme) -> Scheme:
    """``scheme`` itself, or the scheme of that name with its default parameters."""
    return scheme if isinstance(scheme, Scheme) else get_scheme(scheme)
