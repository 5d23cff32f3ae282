"""What the chief of an asynchronous scheme counts per worker: the contributions it applied or left out, their
staleness, and the worker's last round taken (so a re-sent contribution is answered again, never applied
twice). Kept in the chief's state (:class:`~.chief.state.ChiefState`) and written to chief.json."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any


@dataclass
class Contributions:
    """One worker's contributions to an asynchronous run."""

    applied: int = 0
    """contributions mixed into the fleet model"""
    left_out: int = 0
    """contributions taken but not applied: staler than the run's bound (``max_staleness``)"""
    last_round: int = 0
    """the worker's last round taken (its own count); a contribution of this round or an earlier one is a
    re-send"""
    staleness_total: int = 0
    """the sum of the staleness of the contributions taken"""
    staleness_max: int = 0
    """the largest staleness of a contribution taken"""

    def take(self, rnd: int, staleness: int, *, applied: bool) -> None:
        """Count the worker's contribution of round ``rnd`` and staleness ``staleness``."""
        self.last_round = rnd
        self.staleness_total += staleness
        self.staleness_max = max(self.staleness_max, staleness)
        if applied:
            self.applied += 1
        else:
            self.left_out += 1

    def to_dict(self) -> dict[str, Any]:
        """The counts, and the mean staleness (chief.json)."""
        taken = self.applied + self.left_out
        mean = round(self.staleness_total / taken, 3) if taken else 0.0
        return {**asdict(self), "staleness_mean": mean}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Contributions:
        """The record :meth:`to_dict` wrote."""
        return cls(**{key: int(data[key]) for key in cls.__dataclass_fields__})
