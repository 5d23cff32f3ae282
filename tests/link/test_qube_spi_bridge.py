"""A whole episode through the device bridge over the fake SPI bus: the env's reset runs the device-side
reset through ``QubeSpiDriver``, Quanser's balance law (through the paper's three actions) holds the
pendulum, and full power one way trips the bridge's protective stop at the arm limit (amplifier off)."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from qube_emulator import EmulatedQube, FakeSpiDev

from fleetrl.devices.qube.controllers import balance_volts, controller_constants
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.bridge import DeviceBridge
from fleetrl.link.mqtt import DeviceLinkError, MqttLink
from fleetrl.link.qube_reset import ResetSettings
from fleetrl.link.qube_spi import QubeSpiDriver
from fleetrl.transport.local import LocalBus

RUN = "spi"


@pytest.fixture
def qube() -> EmulatedQube:
    return EmulatedQube(QubeDevice.from_fleet(2, 0).params)


@pytest.fixture
def bridge(qube: EmulatedQube) -> Iterator[tuple[DeviceBridge, LocalBus]]:
    bus = LocalBus()
    spi = FakeSpiDev(qube)
    driver = QubeSpiDriver(spi_factory=lambda: spi, clock=qube.clock, sleep_until=qube.sleep_until)
    # lockstep: each step holds its command for one period of the emulator's simulated clock
    running = DeviceBridge(bus.client(), driver, RUN, 0).start()
    yield running, bus
    running.close()
    assert not qube.amplifier and spi.closed


def bang_bang(obs: np.ndarray, gains: np.ndarray) -> int:
    """Quanser's balance law acting only through the actions −60 / +60."""
    alpha, alpha_dot, theta, theta_dot = (float(v) for v in obs)
    return 2 if balance_volts(theta, alpha, theta_dot, alpha_dot, gains) > 0.0 else 0


def test_an_episode_over_the_fake_spi_bus(qube: EmulatedQube, bridge: tuple[DeviceBridge, LocalBus]) -> None:
    running, bus = bridge
    env = QubeBalanceEnv(0, 0, link=MqttLink(bus.client(), RUN, 0))
    obs, _ = env.reset(seed=1)
    assert abs(obs[0]) <= math.radians(3.0) and abs(obs[2]) <= math.radians(20.0)  # handed over upright
    reset_at = qube.now
    gains = controller_constants()
    for _ in range(300):
        obs, reward, terminated, _, _ = env.step(bang_bang(obs, gains))
        assert reward == 1.0 and not terminated
    assert qube.now - reset_at == pytest.approx(300 * 0.006)  # one 6 ms period of simulated time per step
    assert {frame.word for frame in qube.frames[-600:]} <= {0x803C, 0xFFC4}  # only the paper's ±60 duty
    for _ in range(400):  # full power one way: the arm runs to its limit
        obs, reward, terminated, _, info = env.step(2)
        if info.get("protective_stop"):
            break
    assert info.get("protective_stop") and abs(obs[2]) > math.pi / 2
    assert not qube.amplifier and qube.frames[-1].word == 0x0000  # the stop disabled the amplifier
    with pytest.raises(DeviceLinkError, match="protective stop"):
        env.step(1)
    obs, _ = env.reset(seed=2)  # the next reset swings up again from wherever the arm stopped
    assert abs(obs[0]) <= math.radians(3.0)
    assert running.stats.protective_stops == 1 and running.stats.rejected == 1
    env.close()


def test_a_failed_reset_is_answered_with_its_reason_and_the_bridge_carries_on(
    qube: EmulatedQube, bridge: tuple[DeviceBridge, LocalBus]
) -> None:
    running, bus = bridge
    driver = running.driver
    assert isinstance(driver, QubeSpiDriver)
    driver.reset_settings = ResetSettings(still_seconds=0.1, timeout=1.0)
    original = qube.raw_counts
    qube.raw_counts = lambda: (original()[0], 0)  # a stuck pendulum encoder: the swing-up never sees it move
    link = MqttLink(bus.client(), RUN, 0)
    with pytest.raises(DeviceLinkError, match=r"reset failed: swing-up did not settle within 1\.0 s"):
        link.reset(1)
    assert not qube.amplifier and running.stats.rejected == 1
    qube.raw_counts, driver.reset_settings = original, ResetSettings()
    assert abs(link.reset(2)[0]) <= math.radians(3.0)


def test_a_realtime_bridge_ticks_the_spi_driver_on_the_wall_clock(qube: EmulatedQube) -> None:
    """The rig's mode: the emulator's clock is the wall clock here, so this one test really waits."""
    qube.wall_clock = True
    spi = FakeSpiDev(qube)
    driver = QubeSpiDriver(spi_factory=lambda: spi, clock=qube.clock, sleep_until=qube.sleep_until)
    bus = LocalBus()
    running = DeviceBridge(bus.client(), driver, RUN, 0, realtime=True).start()
    try:
        link = MqttLink(bus.client(), RUN, 0)
        started = time.perf_counter()
        for i in range(30):
            # full power both ways once, then 0 V: a test stalled with full power held on a loaded machine
            # would drive the wall-clock emulator's arm to its limit
            link.step((2, 0)[i] if i < 2 else 1)
        assert {frame.word for frame in qube.frames} >= {0x803C, 0xFFC4}
        assert time.perf_counter() - started > 30 * 0.006 * 0.8  # paced by the 6 ms ticks
        assert len(running.tick_times) >= 30
    finally:
        running.close()
    assert not qube.amplifier and spi.closed
