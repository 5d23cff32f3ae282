"""Per-unit QUBE parameters: nominal values times deviations drawn from (fleet_seed, unit)."""

from dataclasses import dataclass

from fleetrl.devices.qube.params import NOMINAL, QubeParams
from fleetrl.devices.variation import QUBE_FAMILY, log_uniform, scaled, unit_generator


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
