"""Deterministic per-unit deviations: unit ``u`` of fleet ``s`` always gets the same parameters.

Each draw uses its own ``numpy.random.Generator`` seeded by ``SeedSequence(fleet_seed, spawn_key=(family,
unit))``, so units are independent of one another and of how many units a fleet has. The ranges are
documented, with their sources, in docs/devices.md.
"""

import math
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.qube.params import NOMINAL, QubeParams

QUBE_FAMILY = 1
CARTPOLE_FAMILY = 2


@dataclass(frozen=True)
class QubeVariation:
    """How far a QUBE unit may deviate from nominal."""

    mass_length: float = 0.03
    """uniform relative deviation of mr, Lr, mp, Lp (±3 %)"""
    motor: float = 0.10
    """uniform relative deviation of Rm and km (±10 %)"""
    Dr_range: tuple[float, float] = (5e-6, 1e-3)
    """log-uniform span of the arm damping (N·m·s/rad): the published span up to the newer Quanser value"""
    Dp_range: tuple[float, float] = (1e-6, 5e-5)
    """log-uniform span of the pendulum damping (N·m·s/rad): published span up to the newer Quanser value"""
    encoder_offset_counts: int = 2
    """encoder zero offsets are whole counts in [−2, 2]"""


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


def qube_unit_params(fleet_seed: int, unit: int, variation: QubeVariation | None = None) -> QubeParams:
    """The physical parameters of QUBE unit ``unit`` of fleet ``fleet_seed``."""
    v = variation or QubeVariation()
    rng = unit_generator(fleet_seed, unit, QUBE_FAMILY)
    n = NOMINAL
    return QubeParams(
        Rm=scaled(rng, n.Rm, v.motor),
        km=scaled(rng, n.km, v.motor),
        mr=scaled(rng, n.mr, v.mass_length),
        Lr=scaled(rng, n.Lr, v.mass_length),
        mp=scaled(rng, n.mp, v.mass_length),
        Lp=scaled(rng, n.Lp, v.mass_length),
        Dr=log_uniform(rng, v.Dr_range),
        Dp=log_uniform(rng, v.Dp_range),
        g=n.g,
        theta_offset_counts=int(rng.integers(-v.encoder_offset_counts, v.encoder_offset_counts + 1)),
        alpha_offset_counts=int(rng.integers(-v.encoder_offset_counts, v.encoder_offset_counts + 1)),
    )
