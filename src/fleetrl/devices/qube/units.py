"""Per-unit QUBE parameters: nominal values times deviations drawn from (fleet_seed, unit).

How far units deviate is a ``QubeVariation``; the named fleet profiles (``fleet_profiles``) are the
variations a fleet can be drawn with. The draws come in a fixed order, the newer parameters last, so a
variation that leaves them at zero reproduces the older fleets bit for bit.
"""

from dataclasses import dataclass

import numpy as np

from fleetrl.devices.qube.params import NOMINAL, QubeParams
from fleetrl.devices.variation import QUBE_FAMILY, log_uniform, scaled, unit_generator


@dataclass(frozen=True)
class QubeVariation:
    """How far a QUBE unit may deviate from nominal. The defaults are fleet profile ``v1``."""

    arm_mass_length: float = 0.03
    """uniform relative deviation of the arm's mr and Lr, each drawn on its own (±3 %)"""
    pendulum_mass_length: float = 0.03
    """uniform relative deviation of the pendulum's mp and Lp, each drawn on its own (±3 %)"""
    resistance: float = 0.10
    """uniform relative deviation of Rm (±10 %)"""
    torque_constant: float = 0.10
    """uniform relative deviation of km, independent of Rm (±10 %)"""
    Dr_range: tuple[float, float] = (5e-6, 1e-3)
    """log-uniform span of the arm damping (N·m·s/rad): the published span up to the newer Quanser value"""
    Dp_range: tuple[float, float] = (1e-6, 5e-5)
    """log-uniform span of the pendulum damping (N·m·s/rad): published span up to the newer Quanser value"""
    encoder_offset_counts: int = 2
    """encoder zero offsets are whole counts in [−2, 2]"""
    cable_stiffness_range: tuple[float, float] = (0.0, 0.0)
    """log-uniform span of the cable torque's stiffness on the arm (N·m/rad); (0, 0): no cable torque"""
    deadband_range: tuple[float, float] = (0.0, 0.0)
    """uniform span of the amplifier's dead zone (V); (0, 0): no dead zone"""


def _spread(rng: np.random.Generator, span: tuple[float, float], *, log: bool) -> float:
    """A draw from ``span`` (log-uniform or uniform); a span of one value gives that value exactly."""
    low, high = span
    if low == high:
        rng.uniform()  # keep the number of draws per unit the same for every variation
        return float(low)
    return log_uniform(rng, span) if log else float(rng.uniform(low, high))


def qube_unit_params(fleet_seed: int, unit: int, variation: QubeVariation | None = None) -> QubeParams:
    """The physical parameters of QUBE unit ``unit`` of fleet ``fleet_seed``."""
    v = variation or QubeVariation()
    rng = unit_generator(fleet_seed, unit, QUBE_FAMILY)
    n = NOMINAL
    return QubeParams(
        Rm=scaled(rng, n.Rm, v.resistance),
        km=scaled(rng, n.km, v.torque_constant),
        mr=scaled(rng, n.mr, v.arm_mass_length),
        Lr=scaled(rng, n.Lr, v.arm_mass_length),
        mp=scaled(rng, n.mp, v.pendulum_mass_length),
        Lp=scaled(rng, n.Lp, v.pendulum_mass_length),
        Dr=log_uniform(rng, v.Dr_range),
        Dp=log_uniform(rng, v.Dp_range),
        g=n.g,
        theta_offset_counts=int(rng.integers(-v.encoder_offset_counts, v.encoder_offset_counts + 1)),
        alpha_offset_counts=int(rng.integers(-v.encoder_offset_counts, v.encoder_offset_counts + 1)),
        cable_stiffness=_spread(rng, v.cable_stiffness_range, log=True),
        deadband_volts=_spread(rng, v.deadband_range, log=False),
    )
