"""How a fleet's last units fared round by round beside the rest of the fleet, from a run's metrics.csv."""

from __future__ import annotations

import statistics
from collections.abc import Iterable
from dataclasses import dataclass, field

from fleetrl.runs.records import MetricsRow


@dataclass
class Course:
    """Per round: the units' WMA and entropy; per unit: the round it completed (absent: never)."""

    wma: dict[int, dict[int, float]] = field(default_factory=dict)
    entropy: dict[int, dict[int, float]] = field(default_factory=dict)
    completed_at: dict[int, int] = field(default_factory=dict)

    @property
    def rounds(self) -> list[int]:
        """Every round with a row, in order."""
        return sorted(self.wma)

    @property
    def units(self) -> list[int]:
        """Every unit with a row."""
        return sorted({u for by_unit in self.wma.values() for u in by_unit})

    def completed_by(self, round_: int) -> int:
        """How many units had completed by the end of ``round_``."""
        return sum(1 for r in self.completed_at.values() if r <= round_)

    def holding(self, round_: int, target: float) -> int:
        """How many units' WMA was at least ``target`` in ``round_`` (completed or not)."""
        return sum(1 for wma in self.wma[round_].values() if wma >= target)

    def median_entropy(self, round_: int) -> float:
        """The median over the units' rows of ``round_`` of π_θ's entropy."""
        return statistics.median(self.entropy[round_].values())

    def last_units(self, n: int) -> list[int]:
        """The ``n`` units that completed last (those that never did first), latest first."""
        never = max(self.rounds, default=0) + 1
        return sorted(self.units, key=lambda u: (-self.completed_at.get(u, never), u))[:n]


def read_course(rows: Iterable[MetricsRow]) -> Course:
    """The course of a run from its metrics.csv rows (:func:`fleetrl.runs.records.read_metrics`)."""
    course = Course()
    for row in rows:
        course.wma.setdefault(row.round, {})[row.worker] = row.wma
        course.entropy.setdefault(row.round, {})[row.worker] = row.entropy
        if "completed" in row.event.split("+") and row.worker not in course.completed_at:
            course.completed_at[row.worker] = row.round
    return course
