"""The device-side reset run step by step through a driver (``fleetrl.link.qube_reset``) against the
compiled one: the same laws and phase logic, so on the same simulated unit both settle alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleetrl.devices.qube.device import RESET_PERTURBATION, DeviceResetError, QubeDevice
from fleetrl.devices.qube.params import QubeConfig
from fleetrl.link.driver import SimulatedDriver, simulated_driver
from fleetrl.link.qube_reset import ResetSettings, reset_through_driver

UNITS = range(6)


def start_state(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    angle, rate = RESET_PERTURBATION
    return np.array([0.0, math.pi + rng.uniform(-angle, angle), 0.0, rng.uniform(-rate, rate)])


@pytest.mark.parametrize("unit", UNITS)
def test_the_reset_through_a_driver_settles_like_the_compiled_reset(unit: int) -> None:
    compiled = QubeDevice.from_fleet(unit, 0)
    first = compiled.reset(seed=unit).copy()
    # the driver's unit reads as the compiled reset's controllers do: 2 ms periods, the same sensors
    device = QubeDevice.from_fleet(unit, 0, QubeConfig(control_period=0.002, velocity_estimate="filter"))
    device.set_state(start_state(unit))
    driver = SimulatedDriver(device)
    obs = reset_through_driver(driver, ResetSettings(still_seconds=0.0, kick_seconds=0.0))
    seconds = driver.time()
    # measured on units 0-9 of fleet 0, profiles table2 and v1: both always settle (1.2-4.1 s), at most
    # 0.25 s apart (the sampling differs, and a pump can end a swing earlier or later)
    assert abs(seconds - compiled.last_reset_seconds) < 0.35, (seconds, compiled.last_reset_seconds)
    for got, expected, tolerance in zip(
        obs, first, (math.radians(3), 1.5, math.radians(20), 1.5), strict=True
    ):
        assert abs(got) <= tolerance and abs(expected) <= tolerance  # both inside the hand-off windows
    assert driver.command[0] != 0.0  # the balance law's volts stay held for the agent's first step


def test_a_reset_that_does_not_settle_fails_with_the_motor_off() -> None:
    device = QubeDevice.from_fleet(0, 0, QubeConfig(control_period=0.002))
    device.set_state(start_state(0))
    driver = SimulatedDriver(device)
    with pytest.raises(DeviceResetError, match=r"did not settle within 0\.3 s"):
        reset_through_driver(driver, ResetSettings(still_seconds=0.0, timeout=0.3))
    assert driver.command.tolist() == [0.0]


def test_an_arm_past_the_reset_limit_stops_the_motor() -> None:
    device = QubeDevice.from_fleet(0, 0, QubeConfig(control_period=0.002))
    device.set_state(np.array([2.0, math.pi, 0.0, 0.0]))
    driver = SimulatedDriver(device)
    with pytest.raises(DeviceResetError, match="the arm reached 114°"):
        reset_through_driver(driver, ResetSettings(still_seconds=0.0, arm_limit=math.radians(100)))
    assert driver.command.tolist() == [0.0]


def test_a_unit_that_keeps_moving_is_not_swung_up() -> None:
    device = QubeDevice.from_fleet(0, 0, QubeConfig(control_period=0.002))
    device.set_state(np.array([0.0, math.pi + 0.5, 0.0, 0.0]))  # swinging ±29°, lightly damped
    driver = SimulatedDriver(device)
    with pytest.raises(DeviceResetError, match=r"did not come to rest within 1\.0 s"):
        reset_through_driver(driver, ResetSettings(still_timeout=1.0))
    assert driver.command.tolist() == [0.0]


def test_only_a_qube_driver_is_reset_this_way() -> None:
    with pytest.raises(ValueError, match="needs a qube driver, got a cartpole one"):
        reset_through_driver(simulated_driver("cartpole", 0, 0))
