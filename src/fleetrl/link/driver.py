"""The hardware seam of the device bridge: ``DeviceDriver`` (read encoders, write voltage, time), with the
simulated units as one implementation.

The bridge (``fleetrl.link.bridge``) knows only this interface, so a driver for a physical QUBE-Servo 2
(SPI from a Raspberry Pi, or Quanser's HIL API; see docs/hardware.md) replaces ``SimulatedDriver`` without
touching the bridge. One agent step on the bridge is::

    driver.write_voltage(spec.action_volts[action])   # held until the next write
    driver.wait_until(driver.time() + period)         # hardware: sleep; simulator: integrate
    obs = driver.read_encoders()
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from fleetrl.devices.cartpole import X_LIMIT, CartPoleDevice
from fleetrl.devices.factory import DEVICE_TYPES, make_device
from fleetrl.devices.qube.device import ACTION_VOLTS, QubeDevice

SPIN_SECONDS = 0.0005
"""``precise_sleep_until`` sleeps in the OS until this close to the deadline, then spins"""


@dataclass(frozen=True)
class DriverSpec:
    """What the bridge must know about a unit type.

    :param kind: the unit type (``qube`` or ``cartpole``)
    :param action_volts: the motor command of each action index (QUBE: volts; CartPole: ±1 = full force)
    :param control_period: seconds of one agent step
    :param limit_index: the observation component the protective stop watches (QUBE: arm angle)
    :param limit: the protective stop trips when ``abs(obs[limit_index]) > limit``
    """

    kind: str
    action_volts: tuple[float, ...]
    control_period: float
    limit_index: int
    limit: float

    @property
    def n_actions(self) -> int:
        """How many action indices a command may use."""
        return len(self.action_volts)


@runtime_checkable
class DeviceDriver(Protocol):
    """One unit's I/O as the bridge sees it; every method is called from the bridge's one thread."""

    spec: DriverSpec

    def time(self) -> float:
        """Seconds on the driver's clock (monotonic; hardware: wall time, lockstep simulation: simulated)."""
        ...

    def read_encoders(self) -> np.ndarray:
        """The observation read now: encoder angles and their velocity estimates (float32, may be reused)."""
        ...

    def write_voltage(self, volts: float) -> None:
        """Command ``volts``; the motor holds it until the next write (0 switches the motor off)."""
        ...

    def wait_until(self, deadline: float) -> None:
        """Let the unit run, under the held command, until ``time() >= deadline``."""
        ...

    def home(self, seed: int | None) -> np.ndarray:
        """Device-side reset (QUBE: swing up from hanging, catch, settle); return the first observation."""
        ...

    def close(self) -> None:
        """Switch the motor off and release the hardware."""
        ...


def precise_sleep_until(deadline: float) -> None:
    """Sleep until ``time.perf_counter() >= deadline``: the OS sleeps most of it, a spin does the last bit."""
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0.0:
            return
        if remaining > SPIN_SECONDS:
            time.sleep(remaining - SPIN_SECONDS)


class SimulatedDriver:
    """A simulated unit behind the driver interface, bit-identical to stepping the device in-process.

    In lockstep (``realtime=False``) time is simulated: ``wait_until`` integrates the physics at once. In
    real time the clock is ``time.perf_counter`` and ``wait_until`` sleeps until the deadline, then
    integrates every control period that elapsed under the held command.

    :param device: the simulated unit (``QubeDevice`` or ``CartPoleDevice``)
    :param realtime: pace the simulation by the wall clock
    """

    def __init__(self, device: QubeDevice | CartPoleDevice, *, realtime: bool = False) -> None:
        self.device = device
        self.realtime = realtime
        if isinstance(device, QubeDevice):
            self.spec = DriverSpec("qube", ACTION_VOLTS, device.config.control_period, 2, math.pi / 2.0)
        else:
            # the track's end: beyond the env's own termination band, so it never cuts an episode short
            self.spec = DriverSpec("cartpole", (-1.0, 1.0), device.params.tau, 0, 2.0 * X_LIMIT)
        self.volts = 0.0
        """the command the motor holds"""
        self.periods = 0
        """control periods simulated since the last reset"""
        self._origin = time.perf_counter()
        self._obs = np.zeros(4, dtype=np.float32)

    def time(self) -> float:
        """Wall seconds since the last reset in real time; simulated seconds in lockstep."""
        if self.realtime:
            return time.perf_counter() - self._origin
        return self.periods * self.spec.control_period

    def read_encoders(self) -> np.ndarray:
        """The observation after the last simulated period."""
        return self._obs

    def write_voltage(self, volts: float) -> None:
        """Hold ``volts`` from the next simulated period on."""
        self.volts = float(volts)

    def wait_until(self, deadline: float) -> None:
        """Simulate every control period that ends by ``deadline`` (real time: sleep until then first)."""
        period = self.spec.control_period
        if self.realtime:
            precise_sleep_until(self._origin + deadline)
        due = math.floor(deadline / period + 1e-6)
        for _ in range(due - self.periods):
            self._period()

    def _period(self) -> None:
        device = self.device
        if isinstance(device, QubeDevice):
            obs = device.step_volts(self.volts)
        elif self.volts != 0.0:
            obs = device.step(1 if self.volts > 0.0 else 0)
        else:  # a CartPole unit has no "off" action: with the motor off the simulated cart is braked
            obs = self._obs
        self._obs[:] = obs
        self.periods += 1

    def home(self, seed: int | None) -> np.ndarray:
        """The device's own reset (QUBE: swing-up and settle, simulated instantly). In lockstep the
        simulated clock restarts at 0; in real time the clock runs on and the period count catches up."""
        self._obs[:] = self.device.reset(seed)
        self.volts = 0.0
        self.periods = math.floor(self.time() / self.spec.control_period) if self.realtime else 0
        return self._obs

    def close(self) -> None:
        """Motor off; close the simulated unit."""
        self.volts = 0.0
        self.device.close()


def simulated_driver(
    env: str,
    unit: int,
    fleet_seed: int = 0,
    *,
    fleet_profile: str | None = None,
    period: float | None = None,
    realtime: bool = False,
) -> SimulatedDriver:
    """A driver over unit ``unit`` of fleet ``fleet_seed`` of type ``env`` (``qube`` or ``cartpole``).

    :param fleet_profile: the QUBE fleet profile (None: the default; a CartPole fleet has none)
    :param period: control period in seconds (QUBE only; default the device's 6 ms; CartPole's is 20 ms)
    :param realtime: pace by the wall clock (see ``SimulatedDriver``)
    """
    if env not in DEVICE_TYPES:
        raise ValueError(f"unknown env {env!r} (choose {' or '.join(DEVICE_TYPES)})")
    # in real time the bridge itself answers before the new command acts (the rig's one-period delay),
    # so the simulated actuator must not add another
    options: dict[str, object] = {"actuation_delay": False} if realtime and env == "qube" else {}
    if period is not None:
        if env != "qube":
            raise ValueError(f"a {env} unit has a fixed control period; --period-ms applies to qube only")
        options["control_period"] = period
    device = make_device(env, unit, fleet_seed, fleet_profile=fleet_profile, **options)
    return SimulatedDriver(device, realtime=realtime)
