"""The device bridge (the Raspberry Pi's role): one unit, driven through a ``DeviceDriver``, served on its
MQTT device topics, with its own watchdog and protective stop; lockstep or real time (docs/devices.md)."""

from __future__ import annotations

import collections
import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.qube.device import DeviceResetError
from fleetrl.link.driver import DeviceDriver
from fleetrl.link.realtime import SPIN_SECONDS
from fleetrl.link.wire import (
    FLAG_PROTECTIVE_STOP,
    FLAG_WATCHDOG,
    OFFLINE,
    ONLINE,
    Command,
    State,
    WireError,
    decode_command,
    device_topic,
    encode_state,
)
from fleetrl.transport.base import Received, Transport, Will

log = logging.getLogger(__name__)

WATCHDOG_SECONDS = 0.1  # default: motor off after this long without a command
IDLE_POLL = 0.1  # seconds a lockstep bridge waits for a command before checking its watchdog and stop flag
_EMPTY = np.zeros(0, dtype=np.float32)
TICK_HISTORY = 100_000  # real-time tick times kept for jitter measurements


@dataclass
class BridgeStats:
    """Counters of one bridge, for logs, tests and benchmarks."""

    commands: int = 0  # accepted
    rejected: int = 0  # refused as malformed, out of range or stale
    watchdog_trips: int = 0
    protective_stops: int = 0
    overruns: int = 0  # real-time ticks that started more than a period late


class DeviceBridge:
    """Serve one unit over a transport (unconnected: the bridge connects it with its last will).

    :param realtime: real-time mode (fixed control period, last command held); default lockstep
    :param watchdog: seconds without a command after which the motor is switched off
    """

    def __init__(
        self,
        transport: Transport,
        driver: DeviceDriver,
        run_id: str,
        unit: int,
        *,
        realtime: bool = False,
        watchdog: float = WATCHDOG_SECONDS,
    ) -> None:
        if not watchdog > 0:
            raise ValueError(f"watchdog must be a positive number of seconds, got {watchdog!r}")
        self.transport = transport
        self.driver = driver
        self.unit = unit
        self.realtime = realtime
        self.watchdog = watchdog
        self.cmd_topic = device_topic(run_id, unit, "cmd")
        self.state_topic = device_topic(run_id, unit, "state")
        self.status_topic = device_topic(run_id, unit, "status")
        self.stats = BridgeStats()
        self.tick_times: collections.deque[float] = collections.deque(maxlen=TICK_HISTORY)  # driver clock
        self.motor_on = False  # a command is being held (the watchdog's concern)
        self.stopped = False  # protective stop in force (cleared by a reset)
        self._trip_reading: np.ndarray | None = None
        self._spec = driver.spec
        self._commands = [driver.spec.command_of(action) for action in range(driver.spec.n_actions)]
        self._session = -1
        self._last_seq = -1
        self._last_command = time.monotonic()
        self._flags = 0
        self._pending: Command | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._connected = False

    def open(self) -> None:
        """Connect, subscribe to commands, and announce ``online`` (retained)."""
        will = Will(self.status_topic, OFFLINE, qos=1, retain=True)
        self.transport.connect(f"fleetrl-bridge-{self.cmd_topic.split('/')[1]}-{self.unit}", will=will)
        self.transport.subscribe(self.cmd_topic, qos=0)
        self.transport.publish(self.status_topic, ONLINE, qos=1, retain=True)
        self._connected = True
        mode = "real time" if self.realtime else "lockstep"
        log.info(
            "bridge for %s unit %d serving %s (%s, period %.1f ms, watchdog %.0f ms)",
            self._spec.kind,
            self.unit,
            self.cmd_topic,
            mode,
            1e3 * self._spec.control_period,
            1e3 * self.watchdog,
        )

    def serve(self) -> None:
        """Open (if needed) and serve until :meth:`stop`; the motor is off when this returns."""
        if not self._connected:
            self.open()
        try:
            if self.realtime:
                self._serve_realtime()
            else:
                self._serve_lockstep()
        finally:
            self.driver.motor_off()
            self.motor_on = False

    def start(self) -> DeviceBridge:
        """Open, then serve in a daemon thread; returns self."""
        self.open()
        self._thread = threading.Thread(target=self.serve, name=f"fleetrl-bridge-{self.unit}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Ask :meth:`serve` to return (within a control period or ``IDLE_POLL``)."""
        self._stop.set()

    def close(self) -> None:
        """Stop serving, switch the motor off, announce ``offline`` and disconnect; close the driver."""
        self.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._connected:
            self.transport.publish(self.status_topic, OFFLINE, qos=1, retain=True)
            self.transport.close()
            self._connected = False
        self.driver.close()
        log.info("bridge for unit %d closed (%s)", self.unit, self.stats)

    def _serve_lockstep(self) -> None:
        while not self._stop.is_set():
            message = self.transport.receive(self._poll_timeout())
            if message is not None:
                command = self._accept(message)
                if command is not None:
                    self._run_lockstep(command)
            self._check_watchdog()

    def _serve_realtime(self) -> None:
        driver = self.driver
        period = self._spec.control_period
        next_tick = driver.time() + period
        while not self._stop.is_set():
            remaining = next_tick - driver.time()
            if remaining > SPIN_SECONDS:
                message = self.transport.receive(remaining - SPIN_SECONDS)
                if message is not None:
                    command = self._accept(message)
                    if command is not None and command.op == "reset":
                        self._pending = None
                        self._home(command)
                        next_tick = driver.time() + period
                    elif command is not None:
                        self._pending = command  # the newest command wins the next tick
                continue
            driver.wait_until(next_tick)
            self._tick()
            next_tick += period
            late = driver.time() - next_tick
            if late > 0.0:  # a whole period was lost (e.g. the process was descheduled): do not catch up
                self.stats.overruns += 1
                next_tick += period * (1 + int(late // period))

    def _tick(self) -> None:
        driver = self.driver
        self.tick_times.append(driver.time())
        obs = driver.read_sensors()
        self._check_limit(obs)
        self._check_watchdog()
        command, self._pending = self._pending, None
        if command is None:
            return
        if self.stopped:
            self._answer_stopped(command)
            return
        self._answer(command, obs)
        self._actuate(command)

    def _run_lockstep(self, command: Command) -> None:
        driver = self.driver
        if command.op == "reset":
            self._home(command)
            return
        if self.stopped:
            self._answer_stopped(command)
            return
        self._actuate(command)
        driver.wait_until(driver.time() + self._spec.control_period)
        obs = driver.read_sensors()
        self._check_limit(obs)
        self._answer(command, obs)

    def _home(self, command: Command) -> None:
        """Reset the device and answer with its observation, or with why the reset failed (motor off)."""
        try:
            obs = self.driver.home(command.seed)
        except DeviceResetError as err:
            self.motor_on = False
            self._refuse(command, f"reset failed: {err}")
            return
        self._answer(command, obs, reset=True)

    def _actuate(self, command: Command) -> None:
        """Hold ``command``'s action index's command vector, or its own vector clamped to the bounds."""
        if command.action is not None:
            self.driver.write_command(self._commands[command.action])
        else:
            self.driver.write_command(self._spec.clamp(np.array(command.command)))
        self.motor_on = True

    def _accept(self, message: Received) -> Command | None:
        """The command in ``message`` if it is valid and fresh; otherwise log why and (if possible) answer."""
        if message.topic != self.cmd_topic:
            return None
        try:
            command = decode_command(message.payload, self._spec.n_actions, self._spec.command_size)
        except WireError as err:
            self._reject(f"malformed command: {err}")
            if err.sid is not None and err.seq is not None:
                self._publish(State(err.sid, err.seq, self.driver.time(), _EMPTY, error=str(err)))
            return None
        if command.sid != self._session:
            log.info("unit %d: controller session %08x takes over", self.unit, command.sid)
            self._session, self._last_seq = command.sid, -1
        elif command.seq <= self._last_seq:
            self._reject(f"stale command seq {command.seq} (last seen {self._last_seq}): ignored")
            return None
        self._last_seq = command.seq
        self._last_command = time.monotonic()
        self.stats.commands += 1
        return command

    def _reject(self, reason: str) -> None:
        self.stats.rejected += 1
        n = self.stats.rejected
        if n <= 20 or n % 1000 == 0:  # a flood of garbage must not flood the log too
            log.warning("unit %d rejected a command (%d so far): %s", self.unit, n, reason)

    def _refuse(self, command: Command, reason: str) -> None:
        self._reject(f"seq {command.seq}: {reason}")
        self._publish(State(command.sid, command.seq, self.driver.time(), _EMPTY, error=reason))

    def _answer_stopped(self, command: Command) -> None:
        """A step under the protective stop: the first gets the tripping reading (flagged), later ones are
        refused; none is acted on."""
        if self._trip_reading is not None:
            self._answer(command, self._trip_reading)
        else:
            self._refuse(command, "protective stop in force: the arm passed its limit; reset first")

    def _answer(self, command: Command, obs: np.ndarray, *, reset: bool = False) -> None:
        self._trip_reading = None  # an answer carries the stop's flag: later steps are refused
        if obs.size != self._spec.sensor_size:  # a driver fault: never passed on as an observation
            self._refuse(
                command, f"driver read {obs.size} sensor values, its spec declares {self._spec.sensor_size}"
            )
            return
        if reset:
            self.stopped = False
            self.motor_on = False
            self._flags = 0
        flags = self._flags | (FLAG_PROTECTIVE_STOP if self.stopped else 0)
        self._flags = 0
        self._publish(State(command.sid, command.seq, self.driver.time(), obs, flags))

    def _publish(self, state: State) -> None:
        self.transport.publish(self.state_topic, encode_state(state), qos=0)

    def _check_limit(self, obs: np.ndarray) -> None:
        value = abs(float(obs[self._spec.limit_index]))
        if not self.stopped and value > self._spec.limit:
            self.driver.motor_off()
            self.motor_on = False
            self.stopped = True
            self._trip_reading = obs.copy()
            self.stats.protective_stops += 1
            log.warning(
                "unit %d protective stop: |obs[%d]| = %.3f > %.3f; motor off until reset",
                self.unit,
                self._spec.limit_index,
                value,
                self._spec.limit,
            )

    def _check_watchdog(self) -> None:
        if self.motor_on and time.monotonic() - self._last_command > self.watchdog:
            self.driver.motor_off()
            self.motor_on = False
            self._flags |= FLAG_WATCHDOG
            self.stats.watchdog_trips += 1
            # in lockstep every pause between episodes trips it: a warning only in real time
            level = logging.WARNING if self.realtime else logging.DEBUG
            log.log(
                level, "unit %d watchdog: no command for %.0f ms; motor off", self.unit, 1e3 * self.watchdog
            )

    def _poll_timeout(self) -> float:
        if not self.motor_on:
            return IDLE_POLL
        left = self._last_command + self.watchdog - time.monotonic()
        return min(IDLE_POLL, max(left, 0.0) + 1e-4)
