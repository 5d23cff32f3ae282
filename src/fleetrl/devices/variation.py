"""Deterministic per-unit deviations: unit ``u`` of fleet ``s`` always gets the same parameters, drawn from
its own generator (``SeedSequence(fleet_seed, spawn_key=(family, unit))``), independent of the other units
and of the fleet's size. docs/devices.md lists the ranges with their sources.
"""

import math

import numpy as np

QUBE_FAMILY = 1
CARTPOLE_FAMILY = 2


def check_unit(unit: object, fleet_seed: object) -> tuple[int, int]:
    """Validate a (unit, fleet_seed) pair: both non-negative integers."""
    for name, value in (("unit", unit), ("fleet_seed", fleet_seed)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
        if value < 0:
            raise ValueError(f"{name} must be a non-negative integer (0, 1, 2, …), got {value}")
    return int(unit), int(fleet_seed)  # type: ignore[call-overload]


def unit_generator(fleet_seed: int, unit: int, family: int) -> np.random.Generator:
    """The random generator that decides unit ``unit`` of fleet ``fleet_seed`` for one device family."""
    unit, fleet_seed = check_unit(unit, fleet_seed)
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(fleet_seed, spawn_key=(family, unit))))


def scaled(rng: np.random.Generator, value: float, relative: float) -> float:
    """``value`` times a factor drawn uniformly from [1 − relative, 1 + relative]."""
    return float(value * rng.uniform(1.0 - relative, 1.0 + relative))


def log_uniform(rng: np.random.Generator, span: tuple[float, float]) -> float:
    """A value drawn log-uniformly from ``span``."""
    return float(math.exp(rng.uniform(math.log(span[0]), math.log(span[1]))))
