"""Robust aggregation rules (issue 7), Flower-style: hand-computed arrays, no network."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.aggregation import (
    aggregator_names,
    clipped_mean,
    get_aggregator,
    median,
    trimmed_mean,
)


def f32(*rows: list[float]) -> list[np.ndarray]:
    return [np.array(r, np.float32) for r in rows]


def test_coordinate_wise_median_ignores_one_poisoned_worker() -> None:
    # Prepare
    gradients = f32([1.0, 2.0], [3.0, 4.0], [1000.0, -1000.0])
    # Execute
    result = median(gradients)
    # Assert
    assert result.dtype == np.float32
    np.testing.assert_allclose(result, [3.0, 2.0])


def test_median_of_an_even_count_is_the_mean_of_the_middle_two() -> None:
    np.testing.assert_allclose(median(f32([1.0], [2.0], [4.0], [100.0])), [3.0])


def test_trimmed_mean_cuts_both_ends_per_coordinate() -> None:
    gradients = f32([1.0, 50.0], [2.0, 0.0], [3.0, -50.0], [4.0, 1.0], [100.0, 2.0])
    # trim 0.2 of 5 → drop one value at each end per coordinate: [2, 3, 4] and [0, 1, 2]
    np.testing.assert_allclose(trimmed_mean(gradients), [3.0, 1.0])
    np.testing.assert_allclose(trimmed_mean(gradients, trim=0.0), [22.0, 0.6], rtol=1e-6)


def test_trimmed_mean_of_few_workers_keeps_at_least_one_value() -> None:
    np.testing.assert_allclose(trimmed_mean(f32([1.0], [5.0]), trim=0.49), [3.0])


def test_clipped_mean_with_a_fixed_norm() -> None:
    # norms 5 and 0.5; C = 1 scales [3, 4] to [0.6, 0.8] and leaves [0.3, 0.4]
    np.testing.assert_allclose(clipped_mean(f32([3.0, 4.0], [0.3, 0.4]), max_norm=1.0), [0.45, 0.6])


def test_clipped_mean_defaults_to_the_median_norm() -> None:
    # norms 1, 2, 100 → C = 2: [0, 100] becomes [0, 2]
    gradients = f32([1.0, 0.0], [0.0, 2.0], [0.0, 100.0])
    np.testing.assert_allclose(clipped_mean(gradients), [1 / 3, 4 / 3], rtol=1e-6)


@pytest.mark.parametrize(
    ("spec", "expected"),
    [("median", [3.0]), ("trimmed_mean:0.34", [3.0]), ("trimmed_mean", [35.0]), ("clipped_mean:1", [1.0])],
)
def test_rules_are_selected_by_name_with_an_optional_parameter(spec: str, expected: list[float]) -> None:
    rule = get_aggregator(spec)
    np.testing.assert_allclose(rule(f32([1.0], [3.0], [101.0])), expected)


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("median:3", "takes no parameter"),
        ("trimmed_mean:x", "not a number"),
        ("trimmed_mean:0.5", r"trim must be in \[0, 0.5\)"),
        ("clipped_mean:0", "max_norm must be > 0"),
        ("clipped_mean:nan", "max_norm must be > 0"),
    ],
)
def test_bad_rule_parameters_are_refused_at_once(spec: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        get_aggregator(spec)


def test_all_rules_are_registered() -> None:
    assert {"mean", "median", "trimmed_mean", "clipped_mean"} <= set(aggregator_names())
