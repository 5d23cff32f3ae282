"""Aggregation rules, Flower-style: hand-computed arrays, no network."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.aggregation import aggregator_names, get_aggregator, mean, register_aggregator


def test_mean_of_hand_computed_arrays() -> None:
    # Prepare
    gradients = [np.array([1.0, 2.0], np.float32), np.array([3.0, 4.0], np.float32)]
    # Execute
    result = mean(gradients)
    # Assert
    assert result.dtype == np.float32
    np.testing.assert_allclose(result, [2.0, 3.0])


def test_mean_of_three_workers() -> None:
    gradients = [
        np.array([1.0, -2.0, 0.5], np.float32),
        np.array([4.0, 2.0, 0.5], np.float32),
        np.zeros(3, np.float32),
    ]
    np.testing.assert_allclose(mean(gradients), [5 / 3, 0.0, 1 / 3], rtol=1e-6)


def test_registry_by_name() -> None:
    assert "mean" in aggregator_names()
    assert get_aggregator("mean") is mean
    with pytest.raises(ValueError, match=r"unknown aggregator 'mode' \(choose .*mean"):
        get_aggregator("mode")


def test_a_rule_registers_once() -> None:
    with pytest.raises(ValueError, match="already registered"):
        register_aggregator("mean")(mean)


def test_mean_rejects_empty_input() -> None:
    with pytest.raises(ValueError, match="nothing to aggregate"):
        mean([])
