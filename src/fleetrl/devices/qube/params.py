"""QUBE-Servo 2 parameters: a unit's physical constants, the simulator's configuration, per-unit deviations
drawn from (fleet_seed, unit) and the named fleet profiles. Nominal values are from
``reference/qube-servo2-model.md``; docs/devices.md lists every value with its source and deviation."""

import math
from dataclasses import dataclass, fields

import numpy as np

from fleetrl.devices.variation import (
    QUBE_FAMILY,
    FleetProfile,
    log_uniform,
    named_profile,
    scaled,
    unit_generator,
)

ENCODER_RESOLUTION = 2.0 * math.pi / 2048  # radians per count of both 2048-count quadrature encoders
POWER_TO_VOLTS = 15.0 / 625.0  # the rig's motor power units to volts: 625 units ≈ 15 V, so power 60 ≈ 1.44 V
ACTION_POWERS = (-60.0, 0.0, 60.0)  # motor power of action index 0, 1, 2 (the paper's actions)


@dataclass(frozen=True)
class QubeParams:
    """Physical parameters of one unit (SI units). Inertias follow the workbook form m·L²/12."""

    Rm: float = 8.4  # motor terminal resistance (ohm)
    km: float = 0.042  # torque constant = back-EMF constant (N·m/A = V·s/rad)
    mr: float = 0.095  # rotary arm mass (kg)
    Lr: float = 0.085  # rotary arm length, pivot to end (m)
    mp: float = 0.024  # pendulum mass (kg)
    Lp: float = 0.129  # pendulum length (m); centre of mass at Lp/2
    Dr: float = 1.5e-3  # arm viscous damping (N·m·s/rad); workbook value
    Dp: float = 5e-4  # pendulum viscous damping (N·m·s/rad); workbook value
    g: float = 9.81  # gravity (m/s²)
    theta_offset_counts: int = 0  # zero offset of the arm encoder (counts)
    alpha_offset_counts: int = 0  # zero offset of the pendulum encoder (counts)
    cable_stiffness: float = 0.0  # of the cable torque on the arm, −Kc·θ (N·m/rad); not in the reference
    deadband_volts: float = 0.0  # the amplifier's dead zone (V): ±this gives 0 V, beyond it lose this much

    @property
    def Jr(self) -> float:
        """Arm moment of inertia about its centre of mass (kg·m²)."""
        return self.mr * self.Lr**2 / 12.0

    @property
    def Jp(self) -> float:
        """Pendulum moment of inertia about its centre of mass (kg·m²)."""
        return self.mp * self.Lp**2 / 12.0

    def coefficients(self) -> np.ndarray:
        """The constants the compiled dynamics use, in the order ``dynamics.C_*`` names them."""
        return np.array(
            [
                self.Jr + self.mp * self.Lr**2,  # C_M11: M11 at alpha = 0
                0.25 * self.mp * self.Lp**2,  # C_QUARTER: ¼·mp·Lp²
                0.5 * self.mp * self.Lp * self.Lr,  # C_HALF: ½·mp·Lp·Lr
                self.Jp + 0.25 * self.mp * self.Lp**2,  # C_M22
                0.5 * self.mp * self.Lp * self.g,  # C_GRAV: ½·mp·Lp·g
                self.km,
                self.Rm,
                self.Dr,
                self.Dp,
                self.theta_offset_counts * ENCODER_RESOLUTION,
                self.alpha_offset_counts * ENCODER_RESOLUTION,
                self.cable_stiffness,  # C_CABLE
                self.deadband_volts,  # C_DEADBAND
            ],
            dtype=np.float64,
        )


NOMINAL = QubeParams()  # the workbook unit: nominal values, workbook damping, no encoder offset


@dataclass(frozen=True)
class QubeConfig:
    """How a unit is simulated and sensed (the same for every unit of a fleet)."""

    control_period: float = 0.006  # seconds per agent step (the paper's rig: 6 ms ≈ 166 Hz)
    max_substep: float = 0.001  # largest RK4 step (s); a period is split into equal steps no longer
    quantise: bool = True  # read angles through 2048-count encoders (with the unit's zero offsets)
    velocity_estimate: str = "difference"
    """the agent's velocities: ``difference`` of the readings over a period (the rig's code), or ``filter``,
    a derivative through a low-pass at ``velocity_cutoff`` every substep (the device-side controllers')"""
    velocity_cutoff: float = 50.0  # cut-off of the velocity filter (rad/s)
    actuation_delay: bool = True  # a command takes effect one period after it is sent, as on the rig
    max_volts: float = 10.0  # amplifier saturation (V); Quanser recommends ±10 V
    device_period: float = 0.002  # period of the device-side controllers during a reset (500 Hz)
    reset_timeout: float = 20.0  # simulated seconds the device-side reset may take before it fails

    def __post_init__(self) -> None:
        for name in ("control_period", "max_substep", "device_period", "max_volts", "reset_timeout"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of its unit, got {value!r}")
        if self.max_substep > 0.001:
            raise ValueError(f"max_substep must be at most 0.001 s (1 ms RK4), got {self.max_substep!r}")
        if self.velocity_estimate not in ("filter", "difference"):
            raise ValueError(
                f"unknown velocity_estimate {self.velocity_estimate!r} (choose filter or difference)"
            )
        if not self.velocity_cutoff > 0:
            raise ValueError(f"velocity_cutoff must be positive (rad/s), got {self.velocity_cutoff!r}")


def qube_config(**options: object) -> QubeConfig:
    """A ``QubeConfig`` from keyword options, with a clear error for an unknown option."""
    known = {f.name for f in fields(QubeConfig)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise ValueError(f"unknown QUBE option(s) {unknown} (choose from {sorted(known)})")
    return QubeConfig(**options)  # type: ignore[arg-type]


@dataclass(frozen=True)
class QubeVariation:
    """How far a QUBE unit may deviate from nominal (the defaults are fleet profile ``v1``): relative spreads
    drawn uniformly, each parameter on its own; spans drawn log-uniformly (damping in N·m·s/rad, cable in
    N·m/rad), the dead zone's uniformly (V); a span (0, 0) leaves that effect out."""

    arm_mass_length: float = 0.03  # mr and Lr
    pendulum_mass_length: float = 0.03  # mp and Lp
    resistance: float = 0.10  # Rm
    torque_constant: float = 0.10  # km, independent of Rm
    Dr_range: tuple[float, float] = (5e-6, 1e-3)  # the published span up to the newer Quanser value
    Dp_range: tuple[float, float] = (1e-6, 5e-5)  # the published span up to the newer Quanser value
    encoder_offset_counts: int = 2  # encoder zero offsets are whole counts in [−2, 2]
    cable_stiffness_range: tuple[float, float] = (0.0, 0.0)
    deadband_range: tuple[float, float] = (0.0, 0.0)


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


V1 = FleetProfile(
    "v1",
    QubeVariation(),
    "the first fleet: masses, lengths ±3 %, motor ±10 %, published damping spans; no cable, no dead zone",
)
TABLE2 = FleetProfile(
    "table2",
    QubeVariation(Dr_range=(5e-5, 1e-3), Dp_range=(1e-5, 5e-5), cable_stiffness_range=(5e-4, 6e-3)),
    "calibrated to the paper's Table 2: v1 plus a cable torque on the arm, damping raised at the bottom",
)
WIDE = FleetProfile(
    "wide",
    QubeVariation(
        arm_mass_length=0.20,
        pendulum_mass_length=0.20,
        resistance=0.25,
        torque_constant=0.25,
        Dr_range=TABLE2.variation.Dr_range,
        Dp_range=TABLE2.variation.Dp_range,
        cable_stiffness_range=TABLE2.variation.cable_stiffness_range,
        deadband_range=(0.0, 0.2),
    ),
    "mixed revisions and wear: table2 with masses, lengths ±20 %, motor ±25 %, a dead zone to 0.2 V",
)

FLEET_PROFILES: dict[str, FleetProfile[QubeVariation]] = {p.name: p for p in (V1, TABLE2, WIDE)}
DEFAULT_FLEET_PROFILE = TABLE2.name
"""the profile a fleet is drawn with unless another is named (``table2`` matches the paper's Table 2)"""


def fleet_profile(name: str | None = None) -> FleetProfile[QubeVariation]:
    """The QUBE profile called ``name`` (None: the default); an unknown name is a ValueError."""
    return named_profile(FLEET_PROFILES, name, DEFAULT_FLEET_PROFILE, "fleet profile")
