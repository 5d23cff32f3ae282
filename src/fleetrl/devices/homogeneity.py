"""The paper's homogeneity test (section 5.3, Table 2) on simulated QUBE units: every unit gets the same
seeded sequence of motor impulses from rest, the arm's and pendulum's encoder changes after each are
recorded, and the units' Pearson correlation is the result (1 for identical units).
"""

import csv
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.fleet_profiles import fleet_profile
from fleetrl.devices.qube.params import QubeConfig
from fleetrl.devices.variation import check_unit


@dataclass(frozen=True)
class HomogeneityResult:
    """Correlation matrices (units × units) and the raw changes (units × impulses, rad)."""

    units: tuple[int, ...]
    fleet_seed: int
    profile: str
    """the fleet profile the units were drawn with"""
    motor: np.ndarray
    """Pearson correlation matrix of motor (arm) angle changes"""
    pendulum: np.ndarray
    """Pearson correlation matrix of pendulum angle changes"""
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
    """Run the test on units 0 … units−1 of fleet ``fleet_seed`` drawn with fleet profile ``profile``.

    :param units: how many units (at least 2)
    :param impulses: how many impulses per unit (at least 3)
    :param seed: seed of the impulse directions (the same sequence for every unit)
    :param impulse_volts: voltage of an impulse
    :param impulse_seconds: duration of an impulse
    :param window_seconds: coasting time after each impulse before the change is read
    :param profile: the fleet profile (``fleetrl.devices.qube.fleet_profiles``); None: the default
    """
    if isinstance(units, bool) or not isinstance(units, int) or units < 2:
        raise ValueError(f"units must be an integer of at least 2, got {units!r}")
    if isinstance(impulses, bool) or not isinstance(impulses, int) or impulses < 3:
        raise ValueError(f"impulses must be an integer of at least 3, got {impulses!r}")
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
    """The off-diagonal correlations of many homogeneity tests, pooled (one entry per pair of units)."""

    profile: str
    fleet_seeds: tuple[int, ...]
    impulse_seeds: tuple[int, ...]
    motor: np.ndarray
    """motor-angle correlations of every unit pair of every (fleet seed, impulse seed)"""
    pendulum: np.ndarray
    """pendulum-angle correlations, in the same order"""
    results: tuple[HomogeneityResult, ...] = ()
    """every test, fleet seed major (for its matrices and raw changes)"""

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
    """Run ``homogeneity_test`` for every (fleet seed, impulse seed) and pool the off-diagonal pairs.

    The paper's Table 2 is one such test on three real units; a simulated fleet is judged by the median
    over several fleet and impulse seeds (single pairs scatter widely).
    """
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
