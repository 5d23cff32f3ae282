"""The device bridge's hardware seam: ``DeviceDriver``, its ``DriverSpec``, the simulated units' driver, and
a unit type's driver function (docs/devices.md, "Putting your unit behind a device bridge")."""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from fleetrl.devices.cartpole import X_LIMIT, CartPoleDevice, CartPoleForceUnit
from fleetrl.devices.factory import DEVICE_TYPES, make_device
from fleetrl.devices.qube.device import ACTION_VOLTS, QubeDevice, QubeVoltageUnit
from fleetrl.link.base import Device
from fleetrl.link.realtime import precise_sleep_until
from fleetrl.link.wire import MAX_VECTOR

QUBE_SAFE_VOLTS = 10.0  # Quanser's recommended amplifier range (±15 V is the absolute maximum)
QUBE_ARM_LIMIT = math.pi / 2.0  # the rig's protective stop: |arm angle| past this ends the episode
QUBE_ARM_INDEX = 2  # the arm angle in the QUBE observation [alpha, alpha_dot, theta, theta_dot]


@dataclass(frozen=True)
class DriverSpec:
    """What the bridge must know about a unit type.

    :param kind: the unit type's name (for logs and errors)
    :param command_low: lower bound of each actuator command component (its length is the command size)
    :param discrete_commands: the command vector of each discrete action index (empty: none)
    :param limit: the protective stop trips when ``abs(sensors[limit_index]) > limit``
    """

    kind: str
    command_low: tuple[float, ...]
    command_high: tuple[float, ...]
    discrete_commands: tuple[tuple[float, ...], ...]
    control_period: float
    limit_index: int
    limit: float
    sensor_size: int = 4
    command_dtype: str = "float64"

    def __post_init__(self) -> None:
        size = len(self.command_low)
        if size < 1 or len(self.command_high) != size:
            raise ValueError(f"command bounds must be two equal non-empty tuples, got {self!r}")
        if size > MAX_VECTOR or not 1 <= self.sensor_size <= MAX_VECTOR:
            raise ValueError(
                f"a command of {size} and a sensor vector of {self.sensor_size} values: the wire carries "
                f"1 to {MAX_VECTOR} values each way"
            )
        if not all(lo < hi for lo, hi in zip(self.command_low, self.command_high, strict=True)):
            raise ValueError(f"each command_low must be below its command_high, got {self!r}")
        for command in self.discrete_commands:
            if len(command) != size or not np.array_equal(self.clamp(np.asarray(command)), command):
                raise ValueError(f"discrete command {command} is not a command of size {size} in bounds")
        if not 0 <= self.limit_index < self.sensor_size:
            last = self.sensor_size - 1
            raise ValueError(f"limit_index {self.limit_index} is not a sensor index (0..{last})")

    @property
    def command_size(self) -> int:
        return len(self.command_low)

    @property
    def n_actions(self) -> int:
        """How many discrete action indices a command may use (0: none)."""
        return len(self.discrete_commands)

    def command_of(self, action: int) -> np.ndarray:
        """The command vector of discrete action index ``action``."""
        return np.array(self.discrete_commands[action], dtype=self.command_dtype)

    def off_command(self) -> np.ndarray:
        return np.zeros(self.command_size, dtype=self.command_dtype)

    def clamp(self, command: np.ndarray) -> np.ndarray:
        """``command`` clipped to the bounds; ValueError for a wrong size or a value that is not finite."""
        vector = np.asarray(command, dtype=self.command_dtype).reshape(-1)
        if vector.size != self.command_size:
            raise ValueError(f"a {self.kind} command holds {self.command_size} values, got {vector.size}")
        if not all(map(math.isfinite, vector.tolist())):  # a few µs faster than numpy on a short vector
            raise ValueError(f"a {self.kind} command must be finite, got {vector.tolist()}")
        low, high = self._bounds
        return np.minimum(np.maximum(vector, low), high)

    @functools.cached_property
    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.command_low), np.array(self.command_high)


def cartpole_spec(tau: float) -> DriverSpec:
    """A simulated CartPole: command ``[force fraction]`` within ±1, actions left / right, the track's end
    (past the env's own termination band) as the limit on x."""
    return DriverSpec("cartpole", (-1.0,), (1.0,), ((-1.0,), (1.0,)), tau, 0, 2.0 * X_LIMIT)


def qube_spec(control_period: float, max_volts: float = QUBE_SAFE_VOLTS) -> DriverSpec:
    """A QUBE-Servo 2: command ``[volts]`` within ±``max_volts``, the paper's three actions, the arm limit."""
    actions = tuple((volts,) for volts in ACTION_VOLTS)
    return DriverSpec(
        "qube", (-max_volts,), (max_volts,), actions, control_period, QUBE_ARM_INDEX, QUBE_ARM_LIMIT
    )


@runtime_checkable
class DeviceDriver(Protocol):
    """One unit's I/O as the bridge sees it (from the bridge's one thread): a monotonic clock, the sensor
    vector (float32, may be reused), an actuator command held until the next (clamped; ValueError for a
    wrong size or a value not finite), the zero command, waiting under the held command, the device-side
    reset returning the first sensor vector, and close (motor off, hardware released)."""

    spec: DriverSpec

    def time(self) -> float: ...
    def read_sensors(self) -> np.ndarray: ...
    def write_command(self, command: np.ndarray) -> None: ...
    def motor_off(self) -> None: ...
    def wait_until(self, deadline: float) -> None: ...
    def home(self, seed: int | None) -> np.ndarray: ...
    def close(self) -> None: ...


class SimulatedDriver:
    """A simulated unit behind the driver interface, bit-identical to stepping the device in-process. In
    lockstep time is simulated; in real time ``wait_until`` sleeps, then simulates the periods that elapsed.

    :param device: a ``QubeDevice`` or ``CartPoleDevice``, or any ``Device`` whose ``step`` takes a command
        vector of ``spec`` (required then)
    """

    def __init__(self, device: Device, spec: DriverSpec | None = None, *, realtime: bool = False) -> None:
        self.device = device
        self.realtime = realtime
        unit: Device = device
        if isinstance(device, QubeDevice):
            spec = spec or qube_spec(device.config.control_period, device.config.max_volts)
            unit = QubeVoltageUnit(device)
        elif isinstance(device, CartPoleDevice):
            spec = spec or cartpole_spec(device.params.tau)
            unit = CartPoleForceUnit(device)
        elif spec is None:
            raise ValueError(
                f"a simulated {type(device).__name__} needs its DriverSpec (the command and sensor vectors "
                "it takes and returns): SimulatedDriver(device, spec)"
            )
        self.spec = spec
        self.command = self.spec.off_command()  # the command the motor holds
        self.periods = 0  # control periods simulated since the last reset
        self._unit = unit
        self._step = unit.step
        self._origin = time.perf_counter()
        self._obs = np.zeros(spec.sensor_size, dtype=np.float32)

    def time(self) -> float:
        """Wall seconds since the last reset in real time; simulated seconds in lockstep."""
        if self.realtime:
            return time.perf_counter() - self._origin
        return self.periods * self.spec.control_period

    def read_sensors(self) -> np.ndarray:
        return self._obs

    def write_command(self, command: np.ndarray) -> None:
        self.command = self.spec.clamp(command)

    def motor_off(self) -> None:
        self.command = self.spec.off_command()

    def wait_until(self, deadline: float) -> None:
        """Simulate every control period that ends by ``deadline`` (real time: sleep until then first)."""
        period = self.spec.control_period
        if self.realtime:
            precise_sleep_until(self._origin + deadline)
        due = math.floor(deadline / period + 1e-6)
        for _ in range(due - self.periods):
            self._period()

    def _period(self) -> None:
        self._obs[:] = self._step(self.command)
        self.periods += 1

    def home(self, seed: int | None) -> np.ndarray:
        """The device's own reset; the lockstep clock restarts at 0, the real-time one runs on."""
        self._obs[:] = self._unit.reset(seed)
        self.motor_off()
        self.periods = math.floor(self.time() / self.spec.control_period) if self.realtime else 0
        return self._obs

    def close(self) -> None:
        self.motor_off()
        self._unit.close()


def simulated_driver(
    env: str,
    unit: int,
    fleet_seed: int = 0,
    *,
    fleet_profile: str | None = None,
    period: float | None = None,
    realtime: bool = False,
) -> SimulatedDriver:
    """A driver over unit ``unit`` of fleet ``fleet_seed`` of type ``env`` (``qube`` or ``cartpole``);
    ``period``: the control period in seconds (QUBE only)."""
    if env not in DEVICE_TYPES:
        raise ValueError(f"unknown env {env!r} (choose {' or '.join(DEVICE_TYPES)})")
    # in real time the bridge itself delays the command one period (as the rig): the simulation must not
    options: dict[str, object] = {"actuation_delay": False} if realtime and env == "qube" else {}
    if period is not None:
        if env != "qube":
            raise ValueError(f"a {env} unit has a fixed control period; --period-ms applies to qube only")
        options["control_period"] = period
    device = make_device(env, unit, fleet_seed, fleet_profile=fleet_profile, **options)
    return SimulatedDriver(device, realtime=realtime)


DriverFunction = Callable[..., DeviceDriver]
"""``driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver``: a unit type's device side"""


def driver_of(
    function: DriverFunction, unit: int, fleet_seed: int, *, realtime: bool = False
) -> DeviceDriver:
    """What ``function(unit, fleet_seed, realtime=realtime)`` returns, checked; ValueError if not a driver."""
    name = getattr(function, "__qualname__", repr(function))
    try:
        driver = function(unit, fleet_seed, realtime=realtime)
    except Exception as err:
        raise ValueError(f"driver function {name}: unit {unit}: {type(err).__name__}: {err}") from None
    if not isinstance(driver, DeviceDriver) or not isinstance(getattr(driver, "spec", None), DriverSpec):
        raise ValueError(
            f"driver function {name} returned a {type(driver).__name__} for unit {unit}, not a DeviceDriver "
            "(spec: DriverSpec, time, read_sensors, write_command, motor_off, wait_until, home, close)"
        )
    return driver
