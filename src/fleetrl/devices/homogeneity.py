"""The paper's homogeneity test (section 5.3, Table 2) on simulated units. QUBE units get the same seeded
sequence of motor impulses from rest and their arm's and pendulum's encoder changes are correlated (1 for
identical units). CartPole units play the same seeded trials (start state and pushes), each afresh as an
episode is, and pairs compare their cart and pole changes by correlation and by relative difference."""

import csv
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleetrl.devices.cartpole import CartPoleDevice, cartpole_fleet_profile
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import QubeConfig, fleet_profile
from fleetrl.devices.variation import check_unit

START_SPAN = 0.05  # every CartPole start state component is drawn uniformly from ±this (CartPole-v1's reset)


def _check_count(name: str, value: object, least: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        wanted = "a positive integer" if least == 1 else f"an integer of at least {least}"
        raise ValueError(f"{name} must be {wanted}, got {value!r}")


@dataclass(frozen=True)
class HomogeneityResult:
    """Correlation matrices (units × units) and the raw changes (units × impulses, rad)."""

    units: tuple[int, ...]
    fleet_seed: int
    profile: str  # the fleet profile the units were drawn with
    motor: np.ndarray  # Pearson correlation matrix of motor (arm) angle changes
    pendulum: np.ndarray  # Pearson correlation matrix of pendulum angle changes
    motor_changes: np.ndarray
    pendulum_changes: np.ndarray


def homogeneity_test(
    units: int = 3,
    fleet_seed: int = 0,
    impulses: int = 100,
    seed: int = 0,
    *,
    impulse_volts: float = 3.0,
    impulse_seconds: float = 0.03,
    window_seconds: float = 0.5,
    profile: str | None = None,
) -> HomogeneityResult:
    """Run the test on QUBE units 0 … units−1 (at least 2) of fleet ``fleet_seed`` drawn with fleet profile
    ``profile``: ``impulses`` impulses (directions drawn from ``seed``) of ``impulse_volts`` for
    ``impulse_seconds``, each change read after ``window_seconds`` of coasting."""
    _check_count("units", units, 2)
    _check_count("impulses", impulses, 3)
    check_unit(0, fleet_seed)
    chosen = fleet_profile(profile).name
    config = QubeConfig()
    push = max(1, round(impulse_seconds / config.control_period))
    coast = max(1, round(window_seconds / config.control_period))
    directions = np.random.default_rng(seed).choice([-1.0, 1.0], size=impulses)
    motor = np.empty((units, impulses))
    pendulum = np.empty((units, impulses))
    for unit in range(units):
        device = QubeDevice.from_fleet(unit, fleet_seed, config, profile=chosen)
        device.set_state(np.array([0.0, math.pi, 0.0, 0.0]))
        for i, direction in enumerate(directions):
            theta0, alpha0 = device.readings
            for _ in range(push):
                device.step_volts(direction * impulse_volts)
            for _ in range(coast):
                device.step_volts(0.0)
            theta1, alpha1 = device.readings
            motor[unit, i] = theta1 - theta0
            pendulum[unit, i] = alpha1 - alpha0
    return HomogeneityResult(
        units=tuple(range(units)),
        fleet_seed=fleet_seed,
        profile=chosen,
        motor=np.atleast_2d(np.corrcoef(motor)),
        pendulum=np.atleast_2d(np.corrcoef(pendulum)),
        motor_changes=motor,
        pendulum_changes=pendulum,
    )


@dataclass(frozen=True)
class PooledHomogeneity:
    """The off-diagonal correlations of many QUBE tests, pooled (one entry per pair of units)."""

    profile: str
    fleet_seeds: tuple[int, ...]
    impulse_seeds: tuple[int, ...]
    motor: np.ndarray  # motor-angle correlations of every unit pair of every (fleet seed, impulse seed)
    pendulum: np.ndarray  # pendulum-angle correlations, in the same order
    results: tuple[HomogeneityResult, ...] = ()  # every test, fleet seed major

    @property
    def motor_median(self) -> float:
        """Median motor-angle correlation over all pairs."""
        return float(np.median(self.motor))

    @property
    def pendulum_median(self) -> float:
        """Median pendulum-angle correlation over all pairs."""
        return float(np.median(self.pendulum))


def pooled_homogeneity(
    fleet_seeds: Iterable[int],
    impulse_seeds: Iterable[int],
    *,
    units: int = 3,
    impulses: int = 100,
    profile: str | None = None,
) -> PooledHomogeneity:
    """Run ``homogeneity_test`` for every (fleet seed, impulse seed) and pool the off-diagonal pairs."""
    fleets, seeds = tuple(fleet_seeds), tuple(impulse_seeds)
    pairs = np.triu_indices(units, 1)
    results = tuple(
        homogeneity_test(units, fleet_seed, impulses, seed, profile=profile)
        for fleet_seed in fleets
        for seed in seeds
    )
    if not results:
        raise ValueError("give at least one fleet seed and one impulse seed")
    return PooledHomogeneity(
        profile=fleet_profile(profile).name,
        fleet_seeds=fleets,
        impulse_seeds=seeds,
        motor=np.concatenate([r.motor[pairs] for r in results]),
        pendulum=np.concatenate([r.pendulum[pairs] for r in results]),
        results=results,
    )


def _names(result: HomogeneityResult) -> list[str]:
    return [f"unit {u}" for u in result.units]


def write_csv(result: HomogeneityResult, out_dir: Path) -> list[Path]:
    """Write ``motor_correlation.csv`` and ``pendulum_correlation.csv`` into ``out_dir``; return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, matrix in (("motor", result.motor), ("pendulum", result.pendulum)):
        path = out_dir / f"{name}_correlation.csv"
        with path.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["", *_names(result)])
            for label, row in zip(_names(result), matrix, strict=True):
                writer.writerow([label, *(f"{v:.4f}" for v in row)])
        paths.append(path)
    return paths


def format_tables(result: HomogeneityResult) -> str:
    """The two matrices as plain-text tables, like the paper's Table 2 (a) and (b)."""
    names = _names(result)
    width = max(len(n) for n in names) + 2
    blocks = []
    for title, matrix in (
        ("(a) Pearson correlation of motor angle changes", result.motor),
        ("(b) Pearson correlation of pendulum angle changes", result.pendulum),
    ):
        lines = [title, " " * width + "".join(n.rjust(width) for n in names)]
        for label, row in zip(names, matrix, strict=True):
            lines.append(label.ljust(width) + "".join(f"{v:.2f}".rjust(width) for v in row))
        blocks.append("\n".join(lines))
    return (
        f"Homogeneity test, fleet seed {result.fleet_seed} (profile {result.profile}), "
        f"{result.motor_changes.shape[1]} impulses per unit\n\n" + "\n\n".join(blocks)
    )


def cartpole_changes(
    units: int = 3,
    fleet_seed: int = 0,
    trials: int = 100,
    seed: int = 0,
    *,
    pushes: int = 10,
    profile: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The changes (units × trials) of cart position (m) and pole angle (rad) of CartPole units 0 … units−1
    of fleet ``fleet_seed`` over ``trials`` trials of ``pushes`` steps each; ``seed`` draws the trials'
    start states and pushes, the same for every unit."""
    _check_count("units", units, 2)
    _check_count("trials", trials, 3)
    _check_count("pushes", pushes, 1)
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
    """The Pearson correlation of ``a`` and ``b`` (blind to a change's size)."""
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
    cart_difference: np.ndarray  # relative differences (:func:`relative_difference`)
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
    """Run :func:`cartpole_changes` for every (fleet seed, seed) and pool every pair of units' figures."""
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
