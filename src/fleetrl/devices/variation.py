"""Deterministic per-unit deviations: unit ``u`` of fleet ``s`` always gets the same parameters, drawn from
its own generator (``SeedSequence(fleet_seed, spawn_key=(family, unit))``), independent of the other units
and of the fleet's size; and the named fleet profiles they are drawn with. docs/devices.md lists the ranges.
"""

import math
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

QUBE_FAMILY = 1
CARTPOLE_FAMILY = 2

V = TypeVar("V")


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


@dataclass(frozen=True)
class FleetProfile(Generic[V]):
    """A named per-unit variation (how far its units deviate from nominal) and one line on what it is for."""

    name: str
    variation: V
    summary: str


def named_profile(
    profiles: dict[str, FleetProfile[V]], name: str | None, default: str, what: str
) -> FleetProfile[V]:
    """The profile called ``name`` (None: ``default``); an unknown name is a ValueError naming the choices."""
    try:
        return profiles[default if name is None else name]
    except (KeyError, TypeError):
        *others, last = profiles
        raise ValueError(f"unknown {what} {name!r} (choose {', '.join(others)} or {last})") from None
