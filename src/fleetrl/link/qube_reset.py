"""The QUBE's device-side reset run step by step through any ``DeviceDriver`` (wait still → swing up →
catch → settle): the simulator's phase logic (``controllers.reset_phase_step``) fed with the driver's
readings and Quanser's velocity filter, on the driver's clock (a simulated clock runs it without sleeping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.qube.controllers import ResetPhases
from fleetrl.devices.qube.device import SETTLE_SECONDS, DeviceResetError
from fleetrl.devices.qube.dynamics import filtered_rate, wrap_angle
from fleetrl.link.driver import DeviceDriver

ALPHA, THETA = 0, 2
"""places of the pendulum and arm angles in a QUBE sensor vector [alpha, alpha_dot, theta, theta_dot]"""


@dataclass(frozen=True)
class ResetSettings:
    """How a reset through a driver runs (defaults: the simulator's device-side reset)."""

    period: float = 0.002
    """seconds between readings (the simulator's device period: 500 Hz)"""
    still_rate: float = 1.0
    """the arm counts as at rest while its filtered velocity is below this (rad/s; a swinging pendulum
    rocks it a little)…"""
    still_swing: float = math.radians(5.0)
    """…and the pendulum as hanging while it stays within this of straight down (rad): a lightly damped
    pendulum swings for minutes, and the swing-up starts from a small swing as well as from rest"""
    still_seconds: float = 0.5
    """how long both must hold, motor off, before the swing-up starts (0: start at once)"""
    still_timeout: float = 30.0
    """seconds to wait for that before giving up"""
    kick_volts: float = 3.0
    """a pendulum hanging at rest gives the energy law nothing to pump (its sign(α̇) is 0): the arm is
    pushed with this many volts first (the simulated reset starts from a seeded perturbation instead)"""
    kick_seconds: float = 0.05
    """how long the push lasts (0: none)"""
    timeout: float = 20.0
    """seconds the swing-up, catch and settle may take before giving up"""
    settle_seconds: float = SETTLE_SECONDS
    """the readings stay inside the hand-off windows this long before the reset ends"""
    arm_limit: float = math.radians(150.0)
    """past this |arm angle| (rad) the reset stops the motor and fails (the simulated swing-up travels up
    to ~120°, docs/devices.md; the bridge's own ±90° stop is not active during a reset)"""
    velocity_cutoff: float = 50.0
    """cut-off of the velocity filter (rad/s), Quanser's"""


class AngleRates:
    """Velocity estimates of the arm and pendulum angles through a first-order filter at ``cutoff``."""

    def __init__(self, cutoff: float) -> None:
        self.cutoff = cutoff
        self.theta_dot = 0.0
        self.alpha_dot = 0.0
        self._last: tuple[float, float, float] | None = None

    def update(self, time: float, theta: float, alpha: float) -> tuple[float, float]:
        """Feed the readings taken at ``time``; return (theta_dot, alpha_dot)."""
        if self._last is not None and time > self._last[0]:
            dt = time - self._last[0]
            coeff = 1.0 - math.exp(-self.cutoff * dt)
            self.theta_dot = filtered_rate(self.theta_dot, theta - self._last[1], dt, coeff)
            # the pendulum reading wraps at ±π (hanging): differentiate the shortest way round
            self.alpha_dot = filtered_rate(self.alpha_dot, wrap_angle(alpha - self._last[2]), dt, coeff)
        self._last = (time, theta, alpha)
        return self.theta_dot, self.alpha_dot


def reset_through_driver(
    driver: DeviceDriver, settings: ResetSettings | None = None, constants: np.ndarray | None = None
) -> np.ndarray:
    """Run the device-side reset on ``driver``'s QUBE and return the last sensor vector, its velocities the
    filtered ones the reset judged by (the balance law's last command is left held, as the simulator's
    reset leaves it, until the bridge's first step).

    Phases: hold the arm at centre (the swing-up law's arm spring-damper, no pumping) until it is at rest
    and the pendulum hangs; push; swing up, catch and settle (``ResetPhases``). Raises ``DeviceResetError``
    with the motor off when the unit does not come to rest, does not settle in time, or the arm passes
    ``arm_limit``; any driver fault propagates (the driver switches itself off).

    :param constants: the controllers' constants (default: ``controller_constants()``, nominal)
    """
    if driver.spec.kind != "qube":
        raise ValueError(f"the QUBE reset needs a qube driver, got a {driver.spec.kind} one")
    s = settings or ResetSettings()
    phases = ResetPhases(s.period, max(1, round(s.settle_seconds / s.period)), constants)
    reader = _Reader(driver, AngleRates(s.velocity_cutoff), s)
    try:
        still_since = start = driver.time()
        while driver.time() - still_since < s.still_seconds:
            theta, alpha, theta_dot, alpha_dot = reader.next()
            if abs(theta_dot) > s.still_rate or abs(wrap_angle(alpha - math.pi)) > s.still_swing:
                still_since = driver.time()
            if driver.time() - start > s.still_timeout:
                raise DeviceResetError(f"the unit did not come to rest within {s.still_timeout} s")
            driver.write_command(np.array([phases.hold_volts(theta, alpha, theta_dot, alpha_dot)]))
        start = driver.time()
        while driver.time() - start < s.kick_seconds:
            reader.next()
            driver.write_command(np.array([s.kick_volts]))
        start = driver.time()
        started = False
        while driver.time() - start < s.timeout:
            theta, alpha, theta_dot, alpha_dot = reader.next()
            if not started:  # the swing-up judges its first amplitude by this reading
                phases.start(alpha)
                started = True
            volts, settled = phases.step(theta, alpha, theta_dot, alpha_dot)
            driver.write_command(np.array([volts]))  # settled: these volts hold until the agent's first step
            if settled:  # with the velocities the reset judged by (as the simulator's reset reports them)
                return np.array([alpha, alpha_dot, theta, theta_dot], dtype=np.float32)
        raise DeviceResetError(f"swing-up did not settle within {s.timeout} s; check the unit and its gains")
    except BaseException:
        driver.motor_off()
        raise


class _Reader:
    """Paces a reset at ``period`` on the driver's clock: each ``next`` waits for the next tick (the first
    reads at once), reads the angles, filters the velocities and enforces the arm limit."""

    def __init__(self, driver: DeviceDriver, rates: AngleRates, settings: ResetSettings) -> None:
        self.driver = driver
        self.rates = rates
        self.settings = settings
        self._tick: float | None = None

    def next(self) -> tuple[float, float, float, float]:
        """(theta, alpha, theta_dot, alpha_dot) at the next tick."""
        driver, s = self.driver, self.settings
        if self._tick is not None:
            self._tick += s.period
            driver.wait_until(self._tick)
        else:
            self._tick = driver.time()
        obs = driver.read_sensors()
        theta, alpha = float(obs[THETA]), float(obs[ALPHA])
        if abs(theta) > s.arm_limit:
            raise DeviceResetError(
                f"reset stopped: the arm reached {math.degrees(theta):.0f}° (limit "
                f"±{math.degrees(s.arm_limit):.0f}°); centre it and retry"
            )
        theta_dot, alpha_dot = self.rates.update(driver.time(), theta, alpha)
        return theta, alpha, theta_dot, alpha_dot
