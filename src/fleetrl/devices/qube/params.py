"""Physical parameters of one QUBE-Servo 2 unit and the simulator's configuration.

Nominal values are from ``reference/qube-servo2-model.md`` (Quanser workbook); docs/devices.md lists every
value with its source and the per-unit deviation drawn for it.
"""

import math
from dataclasses import dataclass, fields

import numpy as np

ENCODER_COUNTS = 2048
"""counts per revolution of both quadrature encoders"""
ENCODER_RESOLUTION = 2.0 * math.pi / ENCODER_COUNTS
"""radians per encoder count (0.00307 rad)"""
POWER_TO_VOLTS = 15.0 / 625.0
"""the rig's motor power units to volts: 625 units ≈ 15 V, so power 60 ≈ 1.44 V"""
ACTION_POWERS = (-60.0, 0.0, 60.0)
"""motor power of action index 0, 1, 2 (the paper's actions)"""


@dataclass(frozen=True)
class QubeParams:
    """Physical parameters of one unit (SI units). Inertias follow the workbook form m·L²/12."""

    Rm: float = 8.4
    """motor terminal resistance (ohm)"""
    km: float = 0.042
    """torque constant = back-EMF constant (N·m/A = V·s/rad)"""
    mr: float = 0.095
    """rotary arm mass (kg)"""
    Lr: float = 0.085
    """rotary arm length, pivot to end (m)"""
    mp: float = 0.024
    """pendulum mass (kg)"""
    Lp: float = 0.129
    """pendulum length (m); centre of mass at Lp/2"""
    Dr: float = 1.5e-3
    """arm viscous damping (N·m·s/rad); workbook value"""
    Dp: float = 5e-4
    """pendulum viscous damping (N·m·s/rad); workbook value"""
    g: float = 9.81
    """gravity (m/s²)"""
    theta_offset_counts: int = 0
    """zero offset of the arm encoder (counts)"""
    alpha_offset_counts: int = 0
    """zero offset of the pendulum encoder (counts)"""
    cable_stiffness: float = 0.0
    """stiffness of the cable torque on the arm, −Kc·θ (N·m/rad); not in the reference's model, so 0"""
    deadband_volts: float = 0.0
    """width of the amplifier's dead zone (V): commands inside ±this give 0 V, beyond it lose this much;
    the QUBE-Servo manual gives ~0.65 V, the reference's model has none, so 0"""

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


NOMINAL = QubeParams()
"""the workbook unit: nominal values, workbook damping, no encoder offset"""

VELOCITY_ESTIMATES = ("filter", "difference")


@dataclass(frozen=True)
class QubeConfig:
    """How a unit is simulated and sensed (the same for every unit of a fleet)."""

    control_period: float = 0.006
    """seconds per agent step (the paper's rig: 6 ms ≈ 166 Hz)"""
    max_substep: float = 0.001
    """largest RK4 step (s); each period is split into equal steps no longer than this"""
    quantise: bool = True
    """read angles through 2048-count encoders (with the unit's zero offsets)"""
    velocity_estimate: str = "difference"
    """how the agent's velocities are estimated: ``difference``, the finite difference of the readings over
    one control period (the rig's code); ``filter``, a derivative through a first-order low-pass at
    ``velocity_cutoff`` updated every substep (Quanser's 50 rad/s filter). The device-side controllers
    always use the filter."""
    velocity_cutoff: float = 50.0
    """cut-off of the velocity filter (rad/s)"""
    actuation_delay: bool = True
    """a command takes effect one period after it is sent (the rig answers before the new voltage acts)"""
    max_volts: float = 10.0
    """amplifier saturation (V); Quanser recommends ±10 V"""
    device_period: float = 0.002
    """period of the device-side controllers during a reset (swing-up, balance): 500 Hz"""
    reset_timeout: float = 20.0
    """simulated seconds the device-side reset may take before it reports a failure"""

    def __post_init__(self) -> None:
        for name in ("control_period", "max_substep", "device_period", "max_volts", "reset_timeout"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of its unit, got {value!r}")
        if self.max_substep > 0.001:
            raise ValueError(f"max_substep must be at most 0.001 s (1 ms RK4), got {self.max_substep!r}")
        if self.velocity_estimate not in VELOCITY_ESTIMATES:
            raise ValueError(
                f"unknown velocity_estimate {self.velocity_estimate!r} (choose filter or difference)"
            )
        if not self.velocity_cutoff > 0:
            raise ValueError(f"velocity_cutoff must be positive (rad/s), got {self.velocity_cutoff!r}")

    @staticmethod
    def substeps(period: float, max_substep: float) -> tuple[int, float]:
        """Split ``period`` into the fewest equal RK4 steps no longer than ``max_substep``."""
        n = max(1, math.ceil(period / max_substep - 1e-9))
        return n, period / n


def qube_config(**options: object) -> QubeConfig:
    """A ``QubeConfig`` from keyword options, with a clear error for an unknown option."""
    known = {f.name for f in fields(QubeConfig)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise ValueError(f"unknown QUBE option(s) {unknown} (choose from {sorted(known)})")
    return QubeConfig(**options)  # type: ignore[arg-type]
