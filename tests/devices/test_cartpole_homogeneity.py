"""The CartPole homogeneity test: its two figures, the same trials for every unit, and a wide fleet's units
less alike than a standard fleet's."""

import math

import numpy as np
import pytest

from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.homogeneity import (
    START_SPAN,
    cartpole_changes,
    correlation,
    pooled_cartpole_homogeneity,
    relative_difference,
)


def test_the_figures_of_equal_scaled_and_opposite_changes() -> None:
    a = np.random.default_rng(0).normal(size=50)
    assert correlation(a, a) == pytest.approx(1.0) and relative_difference(a, a) == 0.0
    assert correlation(a, 3.0 * a) == pytest.approx(1.0)  # blind to size
    assert relative_difference(a, 3.0 * a) == pytest.approx(2.0 / math.sqrt(5.0))  # not blind to it
    assert relative_difference(a, -a) == pytest.approx(2.0)


def test_every_unit_plays_the_same_seeded_trials() -> None:
    cart, pole = cartpole_changes(units=3, fleet_seed=2, trials=20, seed=4, pushes=6, profile="wide")
    assert cart.shape == pole.shape == (3, 20)
    again = cartpole_changes(3, 2, 20, 4, pushes=6, profile="wide")
    np.testing.assert_array_equal(cart, again[0])
    np.testing.assert_array_equal(pole, again[1])
    rng = np.random.default_rng(4)  # trial 0 of unit 1, played by hand
    start = rng.uniform(-START_SPAN, START_SPAN, size=(20, 4))[0]
    pushes = rng.integers(0, 2, size=(20, 6))[0]
    device = CartPoleDevice.from_fleet(1, 2, profile="wide")
    device.set_state(start)
    for action in pushes:
        device.step(int(action))
    assert (cart[1, 0], pole[1, 0]) == (device.state[0] - start[0], device.state[2] - start[2])
    assert not np.array_equal(pole[0], pole[1])  # the units differ
    standard = cartpole_changes(3, 2, 20, 4, pushes=6)
    np.testing.assert_array_equal(standard[1], cartpole_changes(3, 2, 20, 4, pushes=6, profile="standard")[1])
    assert not np.array_equal(standard[1], pole)


def test_a_wide_fleets_units_are_less_alike_than_a_standard_fleets() -> None:
    standard = pooled_cartpole_homogeneity(range(3), range(2))
    wide = pooled_cartpole_homogeneity(range(3), range(2), profile="wide")
    assert (standard.profile, wide.profile) == ("standard", "wide")
    assert standard.cart_correlation.shape == standard.pole_difference.shape == (3 * 2 * 3,)  # 3 pairs a test
    for part in ("cart", "pole"):
        narrow_r, wide_r = (np.median(getattr(f, f"{part}_correlation")) for f in (standard, wide))
        narrow_d, wide_d = (np.median(getattr(f, f"{part}_difference")) for f in (standard, wide))
        assert 0.98 < wide_r < narrow_r < 1.0, part  # the correlation barely sees the spread
        assert wide_d > 2.5 * narrow_d > 0.0, part  # the relative difference does


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="units must be an integer of at least 2"):
        cartpole_changes(units=1)
    with pytest.raises(ValueError, match="trials must be an integer of at least 3"):
        cartpole_changes(trials=2)
    with pytest.raises(ValueError, match="pushes must be a positive integer"):
        cartpole_changes(pushes=0)
    with pytest.raises(ValueError, match="fleet_seed must be a non-negative integer"):
        cartpole_changes(fleet_seed=-1)
    with pytest.raises(ValueError, match="unknown cartpole fleet profile 'table2'"):
        cartpole_changes(profile="table2")
    with pytest.raises(ValueError, match="give at least one fleet seed and one seed"):
        pooled_cartpole_homogeneity([], [0])
