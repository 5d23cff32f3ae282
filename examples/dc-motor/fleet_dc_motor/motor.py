"""The physics of one DC motor unit, knowing nothing of rewards or learning: the device, which the env reaches
through a link (in-process, or a device bridge serving it: :func:`fleet_dc_motor.units.driver`).

A permanent-magnet DC motor driving a flywheel from an H-bridge. The armature inductance is neglected (its
time constant, ~0.25 ms, is far below the 10 ms control period), so the current follows the voltage at once:

    i = (V − k·ω) / R                                   (armature current, A)
    J·dω/dt = k·i − b·ω − τc·tanh(ω / ω_c)              (ω in rad/s; tanh: Coulomb friction, smoothed)

with V = duty × supply voltage. The speed is measured as an encoder would: the counts that passed during
the control period, times the angle of one count, over the period.

Each unit of a fleet has its own R, k, J, b and τc, drawn from ``(unit, fleet_seed)`` by
:func:`unit_params`: the same seeds give the same unit on every machine.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MotorParams:
    """One motor unit's constants (SI units)."""

    resistance: float = 2.0
    """armature resistance R (Ω)"""
    torque_constant: float = 0.05
    """torque constant k (N·m/A), equal to the back-EMF constant (V·s/rad)"""
    inertia: float = 1.0e-4
    """rotor and flywheel inertia J (kg·m²)"""
    viscous_friction: float = 5.0e-5
    """viscous friction b (N·m·s/rad)"""
    coulomb_friction: float = 5.0e-3
    """Coulomb friction torque τc (N·m)"""
    supply_volts: float = 12.0
    """the H-bridge's supply: a duty cycle of ±1 applies ±this voltage (V)"""

    @property
    def no_load_speed(self) -> float:
        """The steady speed at full voltage without Coulomb friction (rad/s)."""
        k, r = self.torque_constant, self.resistance
        return self.supply_volts * k / (k * k + self.viscous_friction * r)

    @property
    def time_constant(self) -> float:
        """The mechanical time constant J·R / (k² + b·R) (s)."""
        k, r = self.torque_constant, self.resistance
        return self.inertia * r / (k * k + self.viscous_friction * r)


CONTROL_PERIOD = 0.01
"""seconds of one control period: the duty cycle is held this long, and the encoder counted over it"""

NOMINAL = MotorParams()
"""the datasheet motor every unit deviates from"""

COULOMB_SMOOTHING = 1.0
"""ω_c (rad/s): below about this speed the Coulomb friction fades out smoothly (no chattering at rest)"""

SPREAD: dict[str, float] = {
    "resistance": 0.10,
    "torque_constant": 0.05,
    "inertia": 0.20,
    "viscous_friction": 0.30,
    "coulomb_friction": 0.30,
}
"""each varying constant's relative spread s: a unit's value is nominal × U(1 − s, 1 + s), drawn in this
order"""


def unit_params(unit: int, fleet_seed: int) -> MotorParams:
    """Unit ``unit`` of fleet ``fleet_seed``: the nominal motor with each constant of :data:`SPREAD` scaled by
    its own uniform factor from ``numpy.random.default_rng([fleet_seed, unit])``.

    :raises ValueError: a negative unit or fleet seed
    """
    for name, value in (("unit", unit), ("fleet_seed", fleet_seed)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
    rng = np.random.default_rng([int(fleet_seed), int(unit)])
    scaled = {name: getattr(NOMINAL, name) * rng.uniform(1 - s, 1 + s) for name, s in SPREAD.items()}
    return dataclasses.replace(NOMINAL, **{k: float(v) for k, v in scaled.items()})


class DCMotor:
    """One simulated DC motor, a ``fleetrl.link.base.Device``: ``reset(seed)`` → measurement,
    ``step(command)`` → measurement, ``close()``.

    A command is the vector ``[duty]`` (the zero command: no voltage, the motor coasts); a measurement is the
    sensor vector ``[speed, current]`` (rad/s, A; float32, as a device bridge carries it). ``step`` holds
    the duty cycle for one control period (zero-order hold) and integrates with ``substeps`` classical RK4
    steps.

    :param params: the unit's constants
    :param period: the control period (s)
    :param substeps: RK4 steps per period
    :param counts_per_rev: the encoder's resolution
    :param start_speed: a reset draws the initial speed from U(−start_speed, +start_speed) (rad/s): the motor
        may still be coasting from before
    """

    def __init__(
        self,
        params: MotorParams = NOMINAL,
        *,
        period: float = CONTROL_PERIOD,
        substeps: int = 10,
        counts_per_rev: int = 1024,
        start_speed: float = 10.0,
    ) -> None:
        if not (period > 0 and substeps >= 1 and counts_per_rev >= 1 and start_speed >= 0):
            raise ValueError(
                "period must be > 0, substeps and counts_per_rev >= 1, start_speed >= 0; got "
                f"{period}, {substeps}, {counts_per_rev}, {start_speed}"
            )
        self.params = params
        self.period = period
        self.substeps = substeps
        self.count_angle = 2.0 * math.pi / counts_per_rev
        """the angle of one encoder count (rad)"""
        self.start_speed = start_speed
        self.speed = 0.0
        """the true speed ω (rad/s)"""
        self.angle = 0.0
        """the true shaft angle (rad)"""
        self.volts = 0.0
        """the voltage applied during the last period (V)"""

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start again: the initial speed and encoder angle drawn from ``seed``; the first measurement (its
        speed the true one: no period has passed)."""
        rng = np.random.default_rng(seed)
        self.speed = float(rng.uniform(-self.start_speed, self.start_speed))
        self.angle = float(rng.uniform(0.0, self.count_angle))
        self.volts = 0.0
        return self._measure(self.speed)

    def step(self, command: np.ndarray) -> np.ndarray:
        """Apply ``command[0]`` (the duty cycle) × the supply voltage for one period (beyond ±1 the H-bridge
        saturates); the measurement at the period's end.

        :raises ValueError: a command that is not one finite duty cycle
        """
        vector = np.asarray(command, dtype=np.float64).reshape(-1)
        if vector.shape != (1,) or not math.isfinite(vector[0]):
            raise ValueError(f"a motor command is one finite duty cycle [duty], got {command!r}")
        duty = float(vector[0])
        self.volts = min(1.0, max(-1.0, duty)) * self.params.supply_volts
        counts_before = math.floor(self.angle / self.count_angle)
        h = self.period / self.substeps
        for _ in range(self.substeps):
            self._rk4(h)
        counts = math.floor(self.angle / self.count_angle) - counts_before
        return self._measure(counts * self.count_angle / self.period)

    def close(self) -> None:
        """Nothing to release for a simulated motor (a real one would stop its bridge here)."""
        self.volts = 0.0

    def current(self, speed: float) -> float:
        """The armature current at ``speed`` under the applied voltage (A)."""
        return (self.volts - self.params.torque_constant * speed) / self.params.resistance

    def _acceleration(self, speed: float) -> float:
        p = self.params
        torque = p.torque_constant * self.current(speed)
        friction = p.viscous_friction * speed + p.coulomb_friction * math.tanh(speed / COULOMB_SMOOTHING)
        return (torque - friction) / p.inertia

    def _rk4(self, h: float) -> None:
        w = self.speed
        k1 = self._acceleration(w)
        k2 = self._acceleration(w + 0.5 * h * k1)
        k3 = self._acceleration(w + 0.5 * h * k2)
        k4 = self._acceleration(w + h * k3)
        # the angle is the speed's integral: RK4's weights on the four stages' speeds, summed
        self.angle += h * (w + (h / 6) * (k1 + k2 + k3))
        self.speed = w + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)

    def _measure(self, speed: float) -> np.ndarray:
        return np.array([speed, self.current(self.speed)], dtype=np.float32)
