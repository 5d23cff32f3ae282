"""The device bridge and MqttLink on the in-process bus: same trajectories as in-process, rejections,
stale states, watchdog, protective stop, real-time mode (broker tests: test_device_link_mqtt.py)."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from trajectory_helpers import assert_same, run_episodes

from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.bridge import DeviceBridge
from fleetrl.link.driver import SimulatedDriver, simulated_driver
from fleetrl.link.mqtt import DeviceLinkError, DeviceTimeoutError, MqttLink
from fleetrl.link.wire import (
    Command,
    State,
    decode_command,
    device_topic,
    encode_command,
    encode_state,
)
from fleetrl.transport.local import LocalBus, LocalTransport

RUN = "t"


@pytest.fixture
def bus() -> LocalBus:
    return LocalBus()


def serve(bus: LocalBus, env: str = "qube", unit: int = 0, **options: object) -> DeviceBridge:
    realtime = bool(options.pop("realtime", False))
    driver = simulated_driver(env, unit, 3, realtime=realtime)
    return DeviceBridge(bus.client(), driver, RUN, unit, realtime=realtime, **options).start()


@pytest.fixture
def bridge(bus: LocalBus) -> Iterator[DeviceBridge]:
    running = serve(bus)
    yield running
    running.close()


@pytest.mark.parametrize(("env_cls", "kind"), [(QubeBalanceEnv, "qube"), (CartPoleUnitEnv, "cartpole")])
def test_lockstep_link_gives_the_in_process_trajectory(bus: LocalBus, env_cls: type, kind: str) -> None:
    bridge = serve(bus, kind, unit=2)
    try:
        over_link = env_cls(2, 3, link=MqttLink(bus.client(), RUN, 2))
        assert_same(run_episodes(over_link, 3, 150, seed=11), run_episodes(env_cls(2, 3), 3, 150, seed=11))
        over_link.close()
    finally:
        bridge.close()
    assert bridge.stats.rejected == 0


def raw_command(bus: LocalBus, payload: bytes) -> LocalTransport:
    sender = bus.client()
    sender.connect("raw")
    sender.publish(device_topic(RUN, 0, "cmd"), payload)
    return sender


def test_malformed_and_out_of_range_commands_are_rejected_logged_and_answered(
    bus: LocalBus, bridge: DeviceBridge, caplog: pytest.LogCaptureFixture
) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    link.reset(1)
    with caplog.at_level(logging.WARNING, logger="fleetrl.link.bridge"):
        raw_command(bus, b"\xc1 not msgpack")
        with pytest.raises(DeviceLinkError, match="out of range"):
            link.step(7)
        with pytest.raises(DeviceLinkError, match="out of range"):
            link.step(-1)
        time.sleep(0.05)
    assert "not msgpack" in caplog.text and "out of range" in caplog.text
    assert bridge.stats.rejected == 3
    link.step(1)  # the bridge carries on
    assert bridge.stats.commands == 2


def test_a_replayed_command_is_ignored_as_stale(bus: LocalBus, bridge: DeviceBridge) -> None:
    link = MqttLink(bus.client(), RUN, 0, step_timeout=0.2)
    link.reset(1)
    link.step(1)
    raw_command(bus, encode_command(Command(link.session, link.seq, "step", action=2)))
    time.sleep(0.05)
    assert bridge.stats.rejected == 1 and bridge.stats.commands == 2


class FakeBridge:
    """Answers each command with stale states first (old seq, another session), then the right one.

    With ``late=True`` the first answer is withheld until the next command (a late answer)."""

    def __init__(self, bus: LocalBus, late: bool = False) -> None:
        self.transport = bus.client()
        self.transport.connect("fake")
        self.transport.subscribe(device_topic(RUN, 0, "cmd"))
        self.transport.publish(device_topic(RUN, 0, "status"), b"online", retain=True)
        self.late = late
        self.withheld: State | None = None
        self.thread = threading.Thread(target=self.loop, daemon=True)
        self.thread.start()

    def loop(self) -> None:
        while (message := self.transport.receive(1.0)) is not None:
            cmd = decode_command(message.payload, 3, 1)
            fresh = State(cmd.sid, cmd.seq, 0.0, np.full(4, cmd.seq, dtype=np.float32))
            stale = [
                State(cmd.sid, cmd.seq - 1, 0.0, np.full(4, -1.0, dtype=np.float32)),
                State(cmd.sid ^ 1, cmd.seq, 0.0, np.full(4, -2.0, dtype=np.float32)),
            ]
            if self.withheld is not None:
                stale.insert(0, self.withheld)
            for state in stale:
                self.transport.publish(device_topic(RUN, 0, "state"), encode_state(state))
            if self.late and self.withheld is None:
                self.withheld = fresh
                continue
            self.transport.publish(device_topic(RUN, 0, "state"), encode_state(fresh))


def test_a_stale_state_is_never_used_as_fresh(bus: LocalBus) -> None:
    FakeBridge(bus)
    link = MqttLink(bus.client(), RUN, 0)
    for expected in (1, 2, 3):
        obs, _ = link.step(0)
        assert np.all(obs == expected)
    assert link.stale == 6


def test_a_late_answer_to_a_timed_out_step_is_dropped(bus: LocalBus) -> None:
    FakeBridge(bus, late=True)
    link = MqttLink(bus.client(), RUN, 0, step_timeout=0.2)
    with pytest.raises(DeviceTimeoutError, match="no state from unit 0"):
        link.step(0)
    obs, _ = link.step(0)  # the late answer to seq 1 arrives first and is dropped
    assert np.all(obs == 2)
    assert link.stale == 5


def test_no_bridge_is_a_clear_timeout(bus: LocalBus) -> None:
    with pytest.raises(DeviceTimeoutError, match="no bridge online for unit 0"):
        MqttLink(bus.client(), RUN, 0, online_timeout=0.1)


def test_protective_stop_when_the_arm_passes_its_limit(bus: LocalBus, bridge: DeviceBridge) -> None:
    link = MqttLink(bus.client(), RUN, 0)
    link.reset(5)
    extras: object = {}
    for _ in range(400):  # full power one way: the arm runs past pi/2
        obs, extras = link.step(2)
        if extras:
            break
    assert extras == {"protective_stop": 1.0} and abs(obs[2]) > np.pi / 2
    assert isinstance(bridge.driver, SimulatedDriver) and not bridge.driver.command.any()
    with pytest.raises(DeviceLinkError, match="protective stop"):
        link.step(2)
    link.reset(6)
    assert link.step(1)[1] == {}
    assert bridge.stats.protective_stops == 1


def test_in_real_time_the_step_that_meets_the_stop_gets_the_reading_that_tripped_it(bus: LocalBus) -> None:
    """The tripping reading may come at a tick with no command waiting (a loaded machine): the next step is
    still answered with it, flagged, so the env ends its episode instead of meeting a refusal."""
    bridge = serve(bus, realtime=True, watchdog=30.0)
    try:
        link = MqttLink(bus.client(), RUN, 0)
        link.reset(5)
        extras: object = {}
        for _ in range(2000):  # full power one way: the arm runs past pi/2
            obs, extras = link.step(2)
            if extras:
                break
        assert extras == {"protective_stop": 1.0} and abs(obs[2]) > np.pi / 2
        with pytest.raises(DeviceLinkError, match="protective stop"):
            link.step(2)
        assert bridge.stats.protective_stops == 1 and not bridge.motor_on
    finally:
        bridge.close()


def test_realtime_bridge_paces_steps(bus: LocalBus) -> None:
    # 0 V steps: a test process descheduled for half a second while full power is held drives the real-time
    # plant past its arm limit (0.53 s from rest), which is the plant's doing, not the pacing's
    bridge = serve(bus, realtime=True, watchdog=5.0)
    try:
        link = MqttLink(bus.client(), RUN, 0)
        link.reset(2)
        started = time.perf_counter()
        for _ in range(30):
            link.step(1)
        elapsed = time.perf_counter() - started
        assert elapsed > 30 * 0.006 * 0.8  # paced by the 6 ms period (slower under load is fine)
        assert bridge.motor_on and bridge.stats.protective_stops == 0
    finally:
        bridge.close()


@pytest.mark.parametrize(("realtime", "action"), [(False, 2), (True, 1)])
def test_the_watchdog_stops_the_motor_of_a_dead_worker(bus: LocalBus, realtime: bool, action: int) -> None:
    # lockstep holds full power (the plant moves only on commands, so nothing but the watchdog can stop it);
    # real time holds 0 V (full power would reach the arm limit within 0.53 s of a stalled bridge thread)
    bridge = serve(bus, realtime=realtime, watchdog=0.2)
    try:
        worker = bus.client()
        link = MqttLink(worker, RUN, 0)
        link.reset(2)
        link.step(action)
        driver = bridge.driver
        assert isinstance(driver, SimulatedDriver) and bridge.motor_on
        assert driver.command.any() == (action != 1)
        died = time.perf_counter()
        worker.abort()  # the worker dies without a goodbye
        while bridge.motor_on and time.perf_counter() - died < 2.0:
            time.sleep(0.001)
        assert not bridge.motor_on and not driver.command.any()
        assert time.perf_counter() - died < 0.2 + 1.0  # the watchdog's doing (precise figures: benchmarks)
        assert bridge.stats.watchdog_trips == 1 and bridge.stats.protective_stops == 0
    finally:
        bridge.close()
