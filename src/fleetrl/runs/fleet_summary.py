"""A large fleet at a glance (the plot, live view and TensorBoard above :data:`SUMMARY_ABOVE_UNITS` units):
units completed, quantiles of the units' latest WMA (a unit that left keeps its last), the slowest units."""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

from fleetrl.runs.records import MetricsRow, WorkerProgress

SUMMARY_ABOVE_UNITS = 16
"""fleets of more units than this are summarised (16 panels are the most a plot shows legibly)"""
SLOWEST_SHOWN = 5
QUANTILES = (10.0, 50.0, 90.0)


def summarised(units: int, per_unit_detail: bool) -> bool:
    return units > SUMMARY_ABOVE_UNITS and not per_unit_detail


def wma_quantiles(values: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    """The p10, median and p90 of the finite ``values`` (NaN each when there is none)."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return (math.nan, math.nan, math.nan)
    p10, median, p90 = np.percentile(finite, QUANTILES)
    return (float(p10), float(median), float(p90))


@dataclass(frozen=True)
class FleetSnapshot:
    """The fleet as the run knows it now: its units and those completed, p10, median and p90 of their latest
    WMA, the units not completed with the lowest WMA (lowest first), members online and members."""

    units: int
    completed: int
    wma: tuple[float, float, float]
    slowest: list[tuple[int, WorkerProgress]]
    members_online: int
    """members (workers, or unit hosts) that have reported a round and not ended"""
    members: int


def snapshot(
    progress: dict[int, WorkerProgress],
    ended: Collection[int] = (),
    members: Sequence[Sequence[int]] | None = None,
    slowest: int = SLOWEST_SHOWN,
) -> FleetSnapshot:
    """The fleet's figures from each unit's ``progress``; ``ended``: the units whose worker has ended;
    ``members``: the units each member carries (default: one member per unit)."""
    groups = [[unit] for unit in progress] if members is None else members
    completed = sum(p.completed_at_round is not None for p in progress.values())
    lagging = [(u, p) for u, p in progress.items() if p.completed_at_round is None]
    lagging.sort(key=lambda item: (-math.inf if math.isnan(item[1].wma) else item[1].wma, item[0]))
    online = sum(
        any(u in progress and progress[u].round > 0 and u not in ended for u in units) for units in groups
    )
    return FleetSnapshot(
        units=len(progress),
        completed=completed,
        wma=wma_quantiles([p.wma for p in progress.values()]),
        slowest=lagging[:slowest],
        members_online=online,
        members=len(groups),
    )


@dataclass(frozen=True)
class FleetRounds:
    """The fleet's course over rounds 1 … R: p10, median and p90 of the units' latest WMA (shape (3, R)), the
    units completed by each round, and the units that played."""

    rounds: np.ndarray
    wma: np.ndarray
    completed: np.ndarray
    units: int


def fleet_rounds(records: Sequence[MetricsRow]) -> FleetRounds:
    """Per round: the quantiles of the units' latest WMA and the units completed so far."""
    if not records:
        empty = np.zeros(0)
        return FleetRounds(np.zeros(0, dtype=np.int64), np.zeros((3, 0)), empty.astype(np.int64), 0)
    workers = np.fromiter((r.worker for r in records), dtype=np.int64, count=len(records))
    rounds = np.fromiter((r.round for r in records), dtype=np.int64, count=len(records))
    wma = np.fromiter((r.wma for r in records), dtype=np.float64, count=len(records))
    completes = np.fromiter(
        ("completed" in r.event.split("+") for r in records), dtype=bool, count=len(records)
    )
    units, column = np.unique(workers, return_inverse=True)
    last = int(rounds.max())
    grid = np.full((units.size, last), np.nan)  # unit × round: the WMA of the unit's row of that round
    index = np.clip(rounds - 1, 0, None)
    grid[column, index] = wma
    grid = _forward_filled(grid)
    first_done = np.full(units.size, last + 1, dtype=np.int64)  # a round past the last: never
    np.minimum.at(first_done, column[completes], index[completes] + 1)
    completed = (first_done[None, :] <= np.arange(1, last + 1)[:, None]).sum(axis=1)
    quantiles = np.full((3, last), np.nan)
    played = np.isfinite(grid).any(axis=0)
    if played.any():
        quantiles[:, played] = np.nanpercentile(grid[:, played], QUANTILES, axis=0)
    return FleetRounds(np.arange(1, last + 1), quantiles, completed, int(units.size))


def _forward_filled(grid: np.ndarray) -> np.ndarray:
    """Each row's NaNs replaced by its latest finite value to their left (leading NaNs stay)."""
    positions = np.where(np.isfinite(grid), np.arange(grid.shape[1])[None, :], 0)
    np.maximum.accumulate(positions, axis=1, out=positions)
    filled = grid[np.arange(grid.shape[0])[:, None], positions]
    started = np.maximum.accumulate(np.isfinite(grid), axis=1)
    return np.where(started, filled, np.nan)
