"""Completion criterion: linear-weight WMA of the last 10 scores, full window required."""

import math

import pytest

from fleetrl.agent.criterion import CompletionCriterion


def test_wma_weights_newest_heaviest() -> None:
    criterion = CompletionCriterion(threshold=100.0, window=3)
    for score in (10.0, 20.0, 30.0):
        criterion.add(score)
    assert math.isclose(criterion.wma, (1 * 10 + 2 * 20 + 3 * 30) / 6)
    criterion.add(60.0)  # oldest (10) drops out
    assert math.isclose(criterion.wma, (1 * 20 + 2 * 30 + 3 * 60) / 6)


def test_done_needs_a_full_window_and_the_threshold() -> None:
    criterion = CompletionCriterion(threshold=475.0)
    assert criterion.wma == 0.0 and not criterion.done
    for _ in range(9):
        criterion.add(500.0)
    assert criterion.wma == 500.0 and not criterion.done  # 9 scores only
    criterion.add(500.0)
    assert criterion.done
    criterion.add(0.0)  # newest weighs 10/55
    assert math.isclose(criterion.wma, 500.0 * 45 / 55) and not criterion.done


def test_threshold_is_inclusive_and_window_checked() -> None:
    criterion = CompletionCriterion(threshold=2450.0)
    for _ in range(10):
        criterion.add(2450.0)
    assert criterion.done
    with pytest.raises(ValueError, match="window"):
        CompletionCriterion(1.0, window=0)
