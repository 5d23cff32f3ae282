"""fleetrl_lab.trailer_course on hand-written metrics.csv rows: completion rounds, the last units, the
units holding a target and the fleet's median entropy, round by round."""

from __future__ import annotations

from fleetrl.runs.records import CSV_COLUMNS, MetricsRow
from fleetrl_lab.trailer_course import read_course


def row(round_: int, unit: int, wma: float, entropy: float, event: str = "step_gradient") -> MetricsRow:
    """A metrics.csv row as the run writes it (the columns not read here: 1)."""
    named = {"round": round_, "worker": unit, "wma": wma, "entropy": entropy, "event": event}
    return MetricsRow.from_csv_row({c: str(named.get(c, 1)) for c in CSV_COLUMNS})


ROWS = [
    row(1, 0, 100, 1.0), row(1, 1, 200, 0.8), row(1, 2, 50, 0.6),
    row(2, 0, 2500, 0.5, "completed"), row(2, 1, 900, 0.7), row(2, 2, 60, 0.9),
    row(3, 0, 2400, 0.4, "completed"), row(3, 1, 2460, 0.3, "completed+transfer_out"), row(3, 2, 70, 0.2),
]  # fmt: skip


def test_completion_is_the_first_completed_row_and_the_last_units_come_latest_first() -> None:
    course = read_course(ROWS)
    assert course.rounds == [1, 2, 3]
    assert course.units == [0, 1, 2]
    assert course.completed_at == {0: 2, 1: 3}
    assert course.last_units(2) == [2, 1]  # unit 2 never completed: it comes first
    assert [course.completed_by(r) for r in (1, 2, 3)] == [0, 1, 2]


def test_holding_counts_this_rounds_wma_and_the_entropy_is_the_median_over_units() -> None:
    course = read_course(ROWS)
    assert [course.holding(r, 2450) for r in (1, 2, 3)] == [0, 1, 1]  # unit 0 fell below in round 3
    assert course.median_entropy(1) == 0.8
    assert course.median_entropy(3) == 0.3
