"""``fleetrl control`` on the emulated SPI bus (``tests/link/qube_emulator.py``): a saved policy holds the
pendulum on the QUBE through ``QubeSpiDriver``; the arm limit's protective stop and a driver fault each
leave the amplifier off, and the controller always ends with the amplifier off and the bus closed."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from qube_emulator import QUBE_ID, EmulatedQube, FakeSpiDev

from fleetrl.agent.action_space import ActionSpace
from fleetrl.control.controller import run_on_unit
from fleetrl.control.export import export_policy
from fleetrl.control.policies import load_policy
from fleetrl.devices.qube.controllers import balance_volts, controller_constants
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.link.qube_spi import QubeFault, QubeSpiDriver

PERIOD = 0.006
OFF = 0x0000
"""the motor word with the amplifier disabled and duty 0"""


@pytest.fixture
def qube() -> Iterator[EmulatedQube]:
    unit = EmulatedQube(QubeDevice.from_fleet(2, 0).params)
    yield unit
    assert not unit.amplifier and unit.frames[-1].word == OFF  # whatever happened, the amplifier is off


def spi_driver(qube: EmulatedQube) -> tuple[QubeSpiDriver, FakeSpiDev]:
    spi = FakeSpiDev(qube)
    driver = QubeSpiDriver(spi_factory=lambda: spi, clock=qube.clock, sleep_until=qube.sleep_until)
    return driver, spi


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["model file", "onnx"])
def test_a_saved_policy_holds_the_pendulum_on_the_emulated_qube(
    models: dict[str, Path], tmp_path: Path, qube: EmulatedQube, kind: str
) -> None:
    model = models["balancing"]
    if kind == "onnx":
        model = tmp_path / "policy.onnx"
        assert export_policy(models["balancing"], model, "qube").passed
    driver, spi = spi_driver(qube)
    scores = run_on_unit(load_policy(model), "qube", driver, 2)
    assert scores == [2500.0, 2500.0]
    assert qube.now > 2 * 2500 * PERIOD  # two whole episodes of the emulator's clock, the resets besides
    assert spi.closed


class ArmRamp:
    """The balance law (through the paper's ±1.44 V actions) with the arm's set point moving at ``rate``
    rad/s: it keeps the pendulum up while it walks the arm to its ±90° limit."""

    obs_dim, action_space, env, last_step = 4, ActionSpace.discrete(3), None, False

    def __init__(self, rate: float, qube: EmulatedQube | None = None) -> None:
        self.rate, self.qube = rate, qube
        self.steps = 0
        self.gains = controller_constants()

    def act(self, obs: np.ndarray) -> Any:
        alpha, alpha_dot, theta, theta_dot = (float(v) for v in obs)
        target = self.rate * self.steps * PERIOD
        self.steps += 1
        return 2 if balance_volts(theta - target, alpha, theta_dot, alpha_dot, self.gains) > 0.0 else 0


def test_the_arm_limit_switches_the_amplifier_off(qube: EmulatedQube) -> None:
    driver, spi = spi_driver(qube)
    at_end: list[tuple[bool, int]] = []

    def report(episode: int, score: float) -> None:  # as the episode ends, before the controller closes
        at_end.append((qube.amplifier, qube.frames[-1].word))

    # a watchdog longer than the test: only the protective stop can switch the amplifier off here
    scores = run_on_unit(ArmRamp(0.6), "qube", driver, 1, watchdog=30.0, report=report)
    assert 100 < scores[0] < 2500  # the arm, not the pendulum, ended it: the ramp's ~90° in ~2.6 s
    assert at_end == [(False, OFF)]
    assert spi.closed


class FaultAt(ArmRamp):
    """Holds the pendulum, then makes the emulated QUBE answer with another device id at step ``at``."""

    def __init__(self, qube: EmulatedQube, at: int) -> None:
        super().__init__(0.0, qube)
        self.at = at

    def act(self, obs: np.ndarray) -> Any:
        if self.steps == self.at and self.qube is not None:
            self.qube.device_id = 0x0001
        return super().act(obs)


def test_a_driver_fault_ends_the_run_with_its_reason_and_the_amplifier_off(qube: EmulatedQube) -> None:
    driver, spi = spi_driver(qube)
    with pytest.raises(QubeFault, match=f"device id 0x0001, expected 0x{QUBE_ID:04x}.*amplifier disabled"):
        run_on_unit(FaultAt(qube, at=200), "qube", driver, 3)
    assert driver.faulted is not None and spi.closed


@pytest.mark.slow
def test_in_real_time_the_controller_ticks_the_spi_driver_on_the_wall_clock(qube: EmulatedQube) -> None:
    """The rig's mode: the emulator's clock is the wall clock once the swing-up has settled, so the episode
    really waits (the swing-up itself on the simulated clock: a test process starved by the rest of the suite
    held a pumping command for as long and threw the arm off its limits)."""
    driver, spi = spi_driver(qube)
    home = driver.home

    def home_then_wall_clock(seed: int | None) -> np.ndarray:
        state = home(seed)
        qube.go_wall_clock()
        return state

    driver.home = home_then_wall_clock
    policy = ArmRamp(1.0)
    started = time.perf_counter()
    scores = run_on_unit(policy, "qube", driver, 1, realtime=True, watchdog=30.0)
    assert scores[0] > 0 and policy.steps >= scores[0]
    assert time.perf_counter() - started > policy.steps * PERIOD * 0.8  # paced by the 6 ms ticks
    assert spi.closed


def test_ctrl_c_during_the_device_side_reset_leaves_the_amplifier_off(
    models: dict[str, Path], qube: EmulatedQube
) -> None:
    """Ctrl-C reaches the bridge's thread (the main one) wherever it is: here mid swing-up, amplifier on."""
    driver, spi = spi_driver(qube)
    sleep_until = qube.sleep_until

    def interrupted_mid_reset(deadline: float) -> None:
        sleep_until(deadline)
        if qube.now > 1.0 and qube.amplifier:  # the swing-up is pumping
            raise KeyboardInterrupt

    driver._sleep_until = interrupted_mid_reset
    with pytest.raises(KeyboardInterrupt):
        run_on_unit(load_policy(models["balancing"]), "qube", driver, 1)
    assert spi.closed  # and the fixture: the amplifier off, the last word sent 0x0000
