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


def test_a_weighted_mean_weighs_each_vector_by_what_it_stands_for() -> None:
    gradients = [np.array([1.0, 2.0], np.float32), np.array([4.0, 8.0], np.float32)]
    # one unit and two units: (1·1 + 2·4) / 3 = 3, (1·2 + 2·8) / 3 = 6
    np.testing.assert_allclose(mean(gradients, weights=[1, 2]), [3.0, 6.0])
    np.testing.assert_allclose(get_aggregator("clipped_mean:100")(gradients, weights=[1, 2]), [3.0, 6.0])
    # the robust rules count members, whatever each claims to stand for
    np.testing.assert_array_equal(get_aggregator("median")(gradients, weights=[1, 99]), [2.5, 5.0])
    with pytest.raises(ValueError, match="weights must be 2 finite numbers"):
        mean(gradients, weights=[1, -1])


def test_equal_weights_give_the_unweighted_mean_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    gradients = [rng.standard_normal(1000).astype(np.float32) for _ in range(3)]
    plain = mean(gradients)
    for weights in ([1, 1, 1], [200.0, 200.0, 200.0]):
        assert mean(gradients, weights=weights).tobytes() == plain.tobytes()


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
