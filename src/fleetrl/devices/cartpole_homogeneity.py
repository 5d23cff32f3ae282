"""A homogeneity test of simulated CartPole units, after the paper's (section 5.3, Table 2; ``homogeneity``
runs that one on QUBE units): every unit plays the same seeded trials, each from the same start state (drawn
as CartPole-v1's reset draws one) with the same pushes (directions drawn), and the changes of its cart
position and pole angle over each trial are recorded. A pair of units is compared over the trials by two
figures:

- the Pearson correlation of their changes (the paper's figure, 1 for identical units): it does not see a
  change's size, so units that differ mostly in how far they move correlate near 1;
- their relative difference, the RMS of the pair's differences over the RMS of their changes (0 for identical
  units): it sees size.

Unlike the QUBE test the trials do not follow one another: an upright pole falls within a second under pushes
alone, and a hanging one, undamped, swings on forever, so each trial starts afresh, as an episode does.
"""

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.cartpole_profiles import cartpole_fleet_profile
from fleetrl.devices.variation import check_unit

START_SPAN = 0.05
"""every start state component is drawn uniformly from ±this (CartPole-v1's reset)"""


def cartpole_changes(
    units: int = 3,
    fleet_seed: int = 0,
    trials: int = 100,
    seed: int = 0,
    *,
    pushes: int = 10,
    profile: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The changes (units × trials) of cart position (m) and pole angle (rad) of units 0 … units−1 of fleet
    ``fleet_seed``, drawn with fleet profile ``profile`` (None: the default), over ``trials`` trials of
    ``pushes`` steps each (10: 0.2 s); ``seed`` draws the trials' start states and pushes, the same for every
    unit."""
    if isinstance(units, bool) or not isinstance(units, int) or units < 2:
        raise ValueError(f"units must be an integer of at least 2, got {units!r}")
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 3:
        raise ValueError(f"trials must be an integer of at least 3, got {trials!r}")
    if isinstance(pushes, bool) or not isinstance(pushes, int) or pushes < 1:
        raise ValueError(f"pushes must be a positive integer, got {pushes!r}")
    check_unit(0, fleet_seed)
    chosen = cartpole_fleet_profile(profile).name
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-START_SPAN, START_SPAN, size=(trials, 4))
    actions = rng.integers(0, 2, size=(trials, pushes)).tolist()
    cart = np.empty((units, trials))
    pole = np.empty((units, trials))
    for unit in range(units):
        device = CartPoleDevice.from_fleet(unit, fleet_seed, profile=chosen)
        for i, start in enumerate(starts):
            device.set_state(start)
            for action in actions[i]:
                device.step(action)
            end = device.state
            cart[unit, i] = end[0] - start[0]
            pole[unit, i] = end[2] - start[2]
    return cart, pole


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """The Pearson correlation of ``a`` and ``b``."""
    return float(np.corrcoef(a, b)[0, 1])


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """RMS(a − b) / √((RMS(a)² + RMS(b)²) / 2): 0 for equal changes, 2 for opposite ones."""
    scale = math.sqrt((float(np.mean(a**2)) + float(np.mean(b**2))) / 2.0)
    return float(np.sqrt(np.mean((a - b) ** 2))) / scale


@dataclass(frozen=True)
class CartPoleHomogeneity:
    """The pairs of many CartPole tests, pooled (one entry per pair of units per (fleet seed, seed))."""

    profile: str
    fleet_seeds: tuple[int, ...]
    seeds: tuple[int, ...]
    cart_correlation: np.ndarray
    pole_correlation: np.ndarray
    cart_difference: np.ndarray
    """relative differences (:func:`relative_difference`) of cart position changes"""
    pole_difference: np.ndarray


def pooled_cartpole_homogeneity(
    fleet_seeds: Iterable[int],
    seeds: Iterable[int],
    *,
    units: int = 3,
    trials: int = 100,
    pushes: int = 10,
    profile: str | None = None,
) -> CartPoleHomogeneity:
    """Run :func:`cartpole_changes` for every (fleet seed, seed) and pool every pair of units' figures (a
    fleet is judged by their medians, as a QUBE fleet by ``pooled_homogeneity``)."""
    fleets, trial_seeds = tuple(fleet_seeds), tuple(seeds)
    tests = [
        cartpole_changes(units, fleet_seed, trials, seed, pushes=pushes, profile=profile)
        for fleet_seed in fleets
        for seed in trial_seeds
    ]
    if not tests:
        raise ValueError("give at least one fleet seed and one seed")
    pairs = [(a, b) for a in range(units) for b in range(a + 1, units)]

    def pooled(figure: Callable[[np.ndarray, np.ndarray], float], part: int) -> np.ndarray:
        return np.array([figure(test[part][a], test[part][b]) for test in tests for a, b in pairs])

    return CartPoleHomogeneity(
        profile=cartpole_fleet_profile(profile).name,
        fleet_seeds=fleets,
        seeds=trial_seeds,
        cart_correlation=pooled(correlation, 0),
        pole_correlation=pooled(correlation, 1),
        cart_difference=pooled(relative_difference, 0),
        pole_difference=pooled(relative_difference, 1),
    )
