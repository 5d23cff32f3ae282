"""Summaries of repeated runs: rounds to completion, medians with spread, speed-up ratios."""

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Completion:
    """Rounds to completion of one run: per worker, and for the fleet (its last worker)."""

    per_worker: dict[str, int | None]
    """round at which each worker's criterion held (None: not within the run)"""
    max_rounds: int
    """the run's M (an incomplete worker is counted as M, a lower bound, and flagged)"""

    @property
    def fleet(self) -> int:
        """Round at which the last worker completed (M if one never did)."""
        return max(self.max_rounds if r is None else r for r in self.per_worker.values())

    @property
    def complete(self) -> bool:
        """Every worker completed within M rounds."""
        return all(r is not None for r in self.per_worker.values())

    def worker_rounds(self) -> list[int]:
        """Every worker's rounds to completion (M for an incomplete one)."""
        return [self.max_rounds if r is None else r for r in self.per_worker.values()]


def spread(values: list[float] | list[int]) -> str:
    """``median [q1–q3] (min–max)`` of ``values`` (IQR by linear interpolation); "-" if empty."""
    if not values:
        return "-"
    low, q1, median, q3, high = np.percentile(np.asarray(values, dtype=float), [0, 25, 50, 75, 100])
    return f"{median:.0f} [{q1:.0f}–{q3:.0f}] ({low:.0f}–{high:.0f})"


def bootstrap_ratio(
    numerator: list[float] | list[int], denominator: list[float] | list[int], seed: int = 0, draws: int = 2000
) -> tuple[float, float, float]:
    """median(numerator) / median(denominator) with a 95 % bootstrap interval (resampling both samples)."""
    a = np.asarray(numerator, dtype=float)
    b = np.asarray(denominator, dtype=float)
    point = float(np.median(a) / np.median(b))
    rng = np.random.default_rng(seed)
    # the resampled indices drawn in the order rng.choice(a), rng.choice(b) draws them, so every interval
    # stays the one the records' reports show; the medians in one vectorised pass
    picks_a = np.empty((draws, a.size), dtype=np.int64)
    picks_b = np.empty((draws, b.size), dtype=np.int64)
    for k in range(draws):
        picks_a[k] = rng.integers(0, a.size, a.size)
        picks_b[k] = rng.integers(0, b.size, b.size)
    ratios = np.median(a[picks_a], axis=1) / np.median(b[picks_b], axis=1)
    low, high = np.percentile(ratios, [2.5, 97.5])
    return point, float(low), float(high)


@dataclass(frozen=True)
class Interval:
    """A point estimate with its 95 % bootstrap interval."""

    point: float
    low: float
    high: float

    def format(self, digits: int = 0, unit: str = "") -> str:
        """``91 (80–120)`` or ``1.59× (1.10–2.30)``; ``-`` for an empty sample."""
        if math.isnan(self.point):
            return "-"
        return f"{self.point:.{digits}f}{unit} ({self.low:.{digits}f}–{self.high:.{digits}f})"


def bootstrap_median(values: list[float] | list[int], seed: int = 0, draws: int = 2000) -> Interval:
    """The median of ``values`` with a 95 % percentile-bootstrap interval (NaNs for an empty sample)."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return Interval(math.nan, math.nan, math.nan)
    rng = np.random.default_rng(seed)
    medians = np.median(rng.choice(a, (draws, a.size)), axis=1)
    low, high = np.percentile(medians, [2.5, 97.5])
    return Interval(float(np.median(a)), float(low), float(high))


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    """A GitHub-flavoured markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)
