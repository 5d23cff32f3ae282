"""``MqttLink``: a ``DeviceLink`` to a unit served by a device bridge, over any ``Transport``; only the state
carrying a command's (session id, sequence number) answers it."""

from __future__ import annotations

import logging
import secrets
import time
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from fleetrl.link.base import NO_INFO, Action
from fleetrl.link.wire import (
    FLAG_PROTECTIVE_STOP,
    FLAG_WATCHDOG,
    OFFLINE,
    ONLINE,
    Command,
    State,
    WireError,
    decode_state,
    device_topic,
    encode_command,
)
from fleetrl.transport.base import Transport
from fleetrl.transport.mqtt import MqttTransport

log = logging.getLogger(__name__)

STEP_TIMEOUT = 1.0  # default seconds to wait for the state answering a step
RESET_TIMEOUT = 60.0  # … for a device-side reset (a real swing-up takes seconds)
ONLINE_TIMEOUT = 10.0  # … for the bridge's retained ``online`` when the link opens

_EXTRAS = {
    FLAG_PROTECTIVE_STOP: MappingProxyType({"protective_stop": 1.0}),
    FLAG_WATCHDOG: MappingProxyType({"watchdog": 1.0}),
    FLAG_PROTECTIVE_STOP | FLAG_WATCHDOG: MappingProxyType({"protective_stop": 1.0, "watchdog": 1.0}),
}


class DeviceLinkError(ConnectionError):
    """The bridge refused a command, or went away (an ``OSError``: a command meeting it exits 1)."""


class DeviceTimeoutError(DeviceLinkError, TimeoutError):
    """No fresh state arrived in time."""


class MqttLink:
    """A ``DeviceLink`` over ``transport`` (unconnected; closed by :meth:`close`) to the bridge serving
    ``unit`` of run ``run_id``; an observation of another size than ``obs_size`` is a ``DeviceLinkError``."""

    def __init__(
        self,
        transport: Transport,
        run_id: str,
        unit: int,
        *,
        step_timeout: float = STEP_TIMEOUT,
        reset_timeout: float = RESET_TIMEOUT,
        online_timeout: float = ONLINE_TIMEOUT,
        obs_size: int | None = None,
    ) -> None:
        self.unit = unit
        self.obs_size = obs_size
        self.cmd_topic = device_topic(run_id, unit, "cmd")
        self.state_topic = device_topic(run_id, unit, "state")
        self.status_topic = device_topic(run_id, unit, "status")
        self.step_timeout = step_timeout
        self.reset_timeout = reset_timeout
        self.session = secrets.randbits(32)  # echoed in every state meant for this link
        self.seq = 0  # of the last command sent
        self.stale = 0  # states dropped as not answering the command waited for
        self.last_state: State | None = None
        self._transport = transport
        transport.connect(f"fleetrl-link-{run_id}-{unit}-{self.session:08x}")
        transport.subscribe(self.status_topic, qos=1)
        transport.subscribe(self.state_topic, qos=0)
        self._online = False
        self._wait_online(online_timeout)

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Ask the bridge for a device-side reset with ``seed``; return the first observation."""
        state = self._call(Command(self.session, self.seq + 1, "reset", seed=seed), self.reset_timeout)
        return state.obs

    def step(self, action: Action) -> tuple[np.ndarray, Mapping[str, float]]:
        """Send ``action`` (an index or a command vector); return the observation and extras
        (``protective_stop``, ``watchdog`` = 1.0 when the bridge's safety acted)."""
        state = self._call(Command.step(self.session, self.seq + 1, action), self.step_timeout)
        return state.obs, _EXTRAS.get(state.flags, NO_INFO)

    def close(self) -> None:
        """Disconnect (the bridge's watchdog switches the motor off)."""
        self._transport.close()

    def __deepcopy__(self, memo: dict[int, object]) -> MqttLink:
        """The link itself: a connection's handle, not a value (gymnasium deep-copies an env's spec)."""
        return self

    def _call(self, command: Command, timeout: float) -> State:
        self.seq = command.seq
        self._transport.publish(self.cmd_topic, encode_command(command), qos=0)
        state = self._await(command.seq, timeout)
        if state.error is not None:
            raise DeviceLinkError(f"unit {self.unit} refused {command.op} seq {command.seq}: {state.error}")
        if self.obs_size is not None and state.obs.size != self.obs_size:
            raise DeviceLinkError(
                f"unit {self.unit}'s bridge sent {state.obs.size} observation values, the env declares "
                f"{self.obs_size} (is the bridge serving this unit type?)"
            )
        self.last_state = state
        return state

    def _await(self, seq: int, timeout: float) -> State:
        deadline = time.monotonic() + timeout
        transport = self._transport
        while True:
            message = transport.receive(max(0.0, deadline - time.monotonic()))
            if message is None:
                raise DeviceTimeoutError(
                    f"no state from unit {self.unit} within {timeout:g} s for seq {seq} "
                    f"(is a bridge serving {self.cmd_topic}? start one with `fleetrl device`)"
                )
            if message.topic == self.status_topic:
                self._note_status(message.payload)
                continue
            try:
                state = decode_state(message.payload)
            except WireError as err:
                self.stale += 1
                log.warning("unit %d: dropped a malformed state: %s", self.unit, err)
                continue
            if state.sid == self.session and state.seq == seq:
                return state
            self.stale += 1
            log.debug("unit %d: dropped state seq %d (waiting for %d)", self.unit, state.seq, seq)

    def _note_status(self, payload: bytes) -> None:
        if payload == ONLINE:
            self._online = True
        elif payload == OFFLINE and self._online:
            raise DeviceLinkError(f"the bridge of unit {self.unit} went offline")

    def _wait_online(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not self._online:
            message = self._transport.receive(max(0.0, deadline - time.monotonic()))
            if message is None:
                self._transport.close()
                raise DeviceTimeoutError(
                    f"no bridge online for unit {self.unit} within {timeout:g} s "
                    f"(start one: fleetrl device --unit {self.unit} …; it announces on {self.status_topic})"
                )
            if message.topic == self.status_topic:
                self._note_status(message.payload)


def open_mqtt_link(
    url: str, run_id: str, unit: int, *, obs_size: int | None = None, **timeouts: float
) -> MqttLink:
    """An ``MqttLink`` over a new ``MqttTransport`` to the broker at ``url``."""
    return MqttLink(MqttTransport(url), run_id, unit, obs_size=obs_size, **timeouts)
