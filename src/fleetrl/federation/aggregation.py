"""Aggregation rules for the chief, looked up by name; ``mean`` is the paper's (Algorithm 1, line 12).

A rule takes the workers' flat float32 gradients in the fixed order of their sorted worker ids and returns one
flat float32 vector. It must be deterministic for a given input order, so a run gives the same numbers
whatever order the messages arrived in. Robust rules (clipping, median, trimmed mean — issue 7) register
themselves with :func:`register_aggregator`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

Aggregator = Callable[[Sequence[np.ndarray]], np.ndarray]
"""A rule: gradients (same shape, float32, in sorted-worker order) → aggregate (float32)."""

_REGISTRY: dict[str, Aggregator] = {}


def register_aggregator(name: str) -> Callable[[Aggregator], Aggregator]:
    """Decorator registering an aggregation rule under ``name``."""

    def add(rule: Aggregator) -> Aggregator:
        if name in _REGISTRY:
            raise ValueError(f"aggregator {name!r} is already registered")
        _REGISTRY[name] = rule
        return rule

    return add


def aggregator_names() -> list[str]:
    """Names of the registered rules."""
    return sorted(_REGISTRY)


def get_aggregator(name: str) -> Aggregator:
    """The rule registered as ``name``; ValueError naming the choices if there is none."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown aggregator {name!r} (choose {', '.join(aggregator_names())})") from None


def _stack(gradients: Sequence[np.ndarray]) -> np.ndarray:
    if not gradients:
        raise ValueError("nothing to aggregate")
    return np.stack([np.asarray(g, dtype=np.float32) for g in gradients])


@register_aggregator("mean")
def mean(gradients: Sequence[np.ndarray]) -> np.ndarray:
    """Element-wise arithmetic mean (accumulated in float64, returned as float32): the paper's average ḡ."""
    return np.asarray(np.mean(_stack(gradients), axis=0, dtype=np.float64), dtype=np.float32)
