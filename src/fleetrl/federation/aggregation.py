"""Aggregation rules for the chief, looked up by name (``name`` or ``name:value``): ``mean`` (the paper's,
Algorithm 1, line 12), and the robust ``median``, ``trimmed_mean[:β]`` and ``clipped_mean[:C]``. A rule takes
flat float32 vectors in sorted worker order and one weight each (``mean`` and ``clipped_mean`` weigh, the
others count members); ``mean`` is one float64 sum, so it decomposes into edge aggregators' sums.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np


class Aggregator(Protocol):
    """A rule: gradients (float32, sorted-worker order) and optionally a weight each (≥ 0) → float32."""

    def __call__(
        self, gradients: Sequence[np.ndarray], weights: Sequence[float] | None = None
    ) -> np.ndarray: ...


_REGISTRY: dict[str, tuple[Callable[..., np.ndarray], str | None]] = {}


def register_aggregator(
    name: str, *, parameter: str | None = None
) -> Callable[[Callable[..., np.ndarray]], Callable[..., np.ndarray]]:
    """Decorator registering an aggregation rule under ``name`` (``--aggregation NAME``); ``parameter``: the
    keyword argument that ``NAME:VALUE`` sets, if the rule takes one."""

    def add(rule: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
        if name in _REGISTRY:
            raise ValueError(f"aggregator {name!r} is already registered")
        _REGISTRY[name] = (rule, parameter)
        return rule

    return add


def aggregator_names() -> list[str]:
    """Names of the registered rules."""
    return sorted(_REGISTRY)


def get_aggregator(spec: str) -> Aggregator:
    """The rule named by ``spec`` (``name`` or ``name:value``); ValueError naming the choices otherwise."""
    name, _, value = spec.partition(":")
    try:
        rule, parameter = _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown aggregator {name!r} (choose {', '.join(aggregator_names())})") from None
    if not value:
        return rule
    if parameter is None:
        raise ValueError(f"aggregator {name!r} takes no parameter (got {spec!r})")
    try:
        number = float(value)
    except ValueError:
        raise ValueError(f"bad {parameter} {value!r} for aggregator {name!r}: not a number") from None
    bound: Any = functools.partial(rule, **{parameter: number})
    rule(_PROBE, **{parameter: number})  # check the value now, not in the middle of a run
    return bound


def _stack(gradients: Sequence[np.ndarray]) -> np.ndarray:
    if not gradients:
        raise ValueError("nothing to aggregate")
    return np.stack([np.asarray(g, dtype=np.float32) for g in gradients])


_PROBE = [np.zeros(1, np.float32)] * 3


def _weights(weights: Sequence[float] | None, n: int) -> np.ndarray:
    """The weights as float64 (None: 1 each); ValueError unless ``n`` finite numbers >= 0, not all 0."""
    if weights is None:
        return np.ones(n)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n,) or not np.isfinite(w).all() or (w < 0).any() or not w.sum() > 0:
        raise ValueError(f"weights must be {n} finite numbers >= 0, not all 0; got {list(weights)}")
    return w


def weighted_sum(
    vectors: Sequence[np.ndarray], weights: Sequence[float] | None = None, *, summed: Sequence[bool] = ()
) -> tuple[np.ndarray, float]:
    """(Σ wᵢ·xᵢ, Σ wᵢ): the vectors weighted and added in float64, one after the other in the given order.

    :param summed: per vector, whether it is already a weighted sum (an edge aggregator's float64 Σ w·x,
        whose weight is its total): added as it is. Empty: none is.
    """
    if not vectors:
        raise ValueError("nothing to aggregate")
    w = _weights(weights, len(vectors))
    flags = list(summed) or [False] * len(vectors)
    total = np.zeros(np.shape(vectors[0]), dtype=np.float64)
    for vector, weight, is_sum in zip(vectors, w, flags, strict=True):
        if is_sum:
            total += np.asarray(vector, dtype=np.float64)
        else:
            total += weight * np.asarray(vector, dtype=np.float32).astype(np.float64)
    return total, float(w.sum())


def mean_of_parts(
    vectors: Sequence[np.ndarray], weights: Sequence[float], summed: Sequence[bool]
) -> np.ndarray:
    """fl32(Σ parts / Σ weights) of members some of which are edge aggregators' sums."""
    total, weight = weighted_sum(vectors, weights, summed=summed)
    return np.asarray(total / weight, dtype=np.float32)


@register_aggregator("mean")
def mean(gradients: Sequence[np.ndarray], weights: Sequence[float] | None = None) -> np.ndarray:
    """The paper's average ḡ, weighted: fl32(Σ wᵢ gᵢ / Σ wᵢ) in float64 (equal weights: np.mean's numbers)."""
    total, weight = weighted_sum(gradients, weights)
    return np.asarray(total / weight, dtype=np.float32)


def decomposes(spec: str) -> bool:
    """Whether the rule ``spec`` can be applied in two levels (edge aggregators' sums, then the chief) with
    the numbers of one level: only ``mean``."""
    return spec.partition(":")[0] == "mean"


@register_aggregator("median")
def median(gradients: Sequence[np.ndarray], weights: Sequence[float] | None = None) -> np.ndarray:
    """Coordinate-wise median (of an even count: the mean of the two middle values); weights not used."""
    return np.asarray(np.median(_stack(gradients).astype(np.float64), axis=0), dtype=np.float32)


@register_aggregator("trimmed_mean", parameter="trim")
def trimmed_mean(
    gradients: Sequence[np.ndarray], weights: Sequence[float] | None = None, trim: float = 0.2
) -> np.ndarray:
    """Per coordinate, drop the ⌊trim·n⌋ smallest and largest values (``trim`` in [0, 0.5)) and average the
    rest; weights not used."""
    if not 0.0 <= trim < 0.5:
        raise ValueError(f"trim must be in [0, 0.5), got {trim}")
    ordered = np.sort(_stack(gradients).astype(np.float64), axis=0)
    cut = int(np.floor(trim * len(ordered)))
    kept = ordered[cut : len(ordered) - cut]
    return np.asarray(kept.mean(axis=0), dtype=np.float32)


@register_aggregator("clipped_mean", parameter="max_norm")
def clipped_mean(
    gradients: Sequence[np.ndarray], weights: Sequence[float] | None = None, max_norm: float | None = None
) -> np.ndarray:
    """Weighted mean after scaling each gradient down to L2 norm ``max_norm`` (C > 0; None: the median of
    the norms) if it is longer."""
    stacked = _stack(gradients).astype(np.float64)
    norms = np.linalg.norm(stacked.reshape(len(stacked), -1), axis=1)
    limit = float(np.median(norms)) if max_norm is None else float(max_norm)
    if not limit >= 0.0 or (max_norm is not None and limit == 0.0):
        raise ValueError(f"max_norm must be > 0, got {max_norm}")
    scale = np.where(norms > limit, limit / np.where(norms > 0, norms, 1.0), 1.0)
    clipped = stacked * scale.reshape((-1,) + (1,) * (stacked.ndim - 1))
    w = _weights(weights, len(stacked))
    if (w == w[0]).all():  # every vector counts the same
        return np.asarray(clipped.mean(axis=0), dtype=np.float32)
    return np.asarray(np.tensordot(w / w.sum(), clipped, axes=1), dtype=np.float32)
