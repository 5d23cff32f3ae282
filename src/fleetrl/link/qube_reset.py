"""The QUBE's device-side reset through any ``DeviceDriver`` (wait still → swing up → catch → settle): the
simulator's phase logic fed the driver's readings and Quanser's velocity filter, on the driver's clock."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.qube.controllers import ResetPhases
from fleetrl.devices.qube.device import SETTLE_SECONDS, DeviceResetError
from fleetrl.devices.qube.dynamics import filtered_rate, wrap_angle
from fleetrl.link.driver import DeviceDriver

ALPHA, THETA = (
    0,
    2,
)  # the pendulum and arm angles in a QUBE sensor vector [alpha, alpha_dot, theta, theta_dot]


@dataclass(frozen=True)
class ResetSettings:
    """How a reset through a driver runs (defaults: the simulator's device-side reset)."""

    period: float = 0.002  # seconds between readings (the simulator's 500 Hz)
    still_rate: float = 1.0  # rad/s: the arm is at rest while its filtered velocity is below this…
    still_swing: float = math.radians(5.0)  # …and the pendulum hangs while within this of straight down
    still_seconds: float = 0.5  # how long both must hold, motor off, before the swing-up (0: at once)
    still_timeout: float = 30.0  # seconds to wait for that
    kick_volts: float = 3.0  # a pendulum at rest gives the energy law nothing to pump: push the arm first
    kick_seconds: float = 0.05  # how long the push lasts (0: none)
    timeout: float = 20.0  # seconds the swing-up, catch and settle may take
    settle_seconds: float = SETTLE_SECONDS  # inside the hand-off windows this long before the reset ends
    arm_limit: float = math.radians(150.0)  # past this |arm angle| the reset fails (swing-up travels ~120°)
    velocity_cutoff: float = 50.0  # of the velocity filter (rad/s), Quanser's


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
    """Run the device-side reset on ``driver``'s QUBE: hold the arm at centre until all is still, push, swing
    up, catch and settle (``ResetPhases``, with ``constants``); return the last sensor vector with the
    filtered velocities, the last command left held. ``DeviceResetError`` (motor off) if the unit does not
    come to rest, does not settle in time or the arm passes ``arm_limit``."""
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
    """Paces a reset on the driver's clock: each ``next`` waits for the next tick (the first reads at once),
    reads the angles, filters the velocities and enforces the arm limit."""

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
