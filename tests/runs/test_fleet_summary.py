"""A large fleet's summary: the WMA quantiles and completions per round, the snapshot the live view and
TensorBoard show, on hand-computed fleets."""

import math

import numpy as np
import pytest

from fleetrl.runs.fleet_summary import (
    SUMMARY_ABOVE_UNITS,
    fleet_rounds,
    snapshot,
    summarised,
    wma_quantiles,
)
from fleetrl.runs.records import MetricsRow, WorkerProgress


def row(worker: int, round_: int, wma: float, event: str = "gradient") -> MetricsRow:
    return MetricsRow(round_, worker, wma, wma, event=event)


# unit 0 completes at round 2 and leaves; unit 1 plays every round; unit 2 joins at round 2, completes at
# round 3 and again at 4 (a scheme whose criterion may hold again)
FLEET = [
    row(1, 3, 50.0),
    row(0, 1, 10.0),
    row(1, 1, 30.0),
    row(2, 2, 60.0),
    row(0, 2, 20.0, "completed"),
    row(1, 2, 40.0),
    row(2, 3, 70.0, "gradient+completed"),
    row(2, 4, 80.0, "completed"),
]


def test_the_fleet_per_round_takes_each_unit_s_latest_wma_and_its_first_completion() -> None:
    fleet = fleet_rounds(FLEET)
    assert fleet.units == 3
    assert fleet.rounds.tolist() == [1, 2, 3, 4]
    # round 1: {10, 30}; 2: {20, 40, 60}; 3: {20 (unit 0 kept), 50, 70}; 4: {20, 50 (kept), 80}
    p10, median, p90 = fleet.wma
    assert median.tolist() == [20.0, 40.0, 50.0, 50.0]
    assert p10 == pytest.approx([12.0, 24.0, 26.0, 26.0])
    assert p90 == pytest.approx([28.0, 56.0, 66.0, 74.0])
    assert fleet.completed.tolist() == [0, 1, 2, 2]


def test_a_fleet_without_rows_has_no_rounds() -> None:
    fleet = fleet_rounds([])
    assert fleet.units == 0 and fleet.rounds.size == 0 and fleet.wma.shape == (3, 0)


def test_quantiles_leave_out_units_without_a_wma() -> None:
    assert wma_quantiles([math.nan, 10.0, 30.0]) == pytest.approx((12.0, 20.0, 28.0))
    assert all(math.isnan(q) for q in wma_quantiles([math.nan]))


def test_a_fleet_is_summarised_above_the_threshold_unless_detail_is_asked_for() -> None:
    assert not summarised(SUMMARY_ABOVE_UNITS, per_unit_detail=False)
    assert summarised(SUMMARY_ABOVE_UNITS + 1, per_unit_detail=False)
    assert not summarised(1000, per_unit_detail=True)


def progress(
    round_: int, wma: float, completed: int | None = None, state: str = "learning"
) -> WorkerProgress:
    return WorkerProgress(round=round_, score=wma, wma=wma, completed_at_round=completed, state=state)


def test_the_snapshot_names_the_slowest_units_not_completed_and_counts_members_online() -> None:
    units = {
        0: progress(5, 400.0, completed=4, state="completed"),
        1: progress(5, 50.0),
        2: progress(0, math.nan, state="starting"),  # no round yet: the slowest of all
        3: progress(5, 10.0, completed=5, state="completed"),  # completed: never among the slowest
        4: progress(4, 20.0, state="stopped"),
        5: progress(5, 300.0),
    }
    fleet = snapshot(units, ended={4}, members=[[0, 1], [2, 3], [4, 5]], slowest=3)
    assert (fleet.units, fleet.completed) == (6, 2)
    assert [u for u, _ in fleet.slowest] == [2, 4, 1]
    assert fleet.wma == pytest.approx(tuple(np.percentile([400, 50, 10, 20, 300], [10, 50, 90])))
    # host 0-1 reports; host 2-3 has unit 3 reporting; host 4-5 has unit 5 (4 ended)
    assert (fleet.members_online, fleet.members) == (3, 3)
    assert snapshot(units, ended={4, 5}, members=[[0, 1], [2, 3], [4, 5]]).members_online == 2
    assert snapshot(units).members == 6 and snapshot(units).members_online == 5  # unit 2: no round yet


def test_an_interrupted_round_without_figures_keeps_the_unit_s_last_wma() -> None:
    fleet = fleet_rounds(
        [row(0, 1, 10.0), row(1, 1, 30.0), row(0, 2, math.nan, "interrupted"), row(1, 2, 50.0)]
    )
    assert fleet.wma[1].tolist() == [20.0, 30.0]  # round 2: {10 (kept), 50}
