"""``QubeSpiDriver`` against an emulated QUBE on a fake bus (no hardware, simulated clock): bus set-up,
the frames it sends, counts to angles, the ±10 V clamp, and the faults that disable the amplifier."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from qube_emulator import QUBE_ID, EmulatedQube, FakeSpiDev

from fleetrl.devices.qube.device import DeviceResetError, QubeDevice
from fleetrl.link.driver import DeviceDriver
from fleetrl.link.qube_reset import ResetSettings
from fleetrl.link.qube_spi import QubeFault, QubeSpiDriver

COUNT = 2 * math.pi / 2048


def rig(**options: object) -> tuple[QubeSpiDriver, EmulatedQube, FakeSpiDev]:
    """A driver on bus 0, device 1, wired to an emulated unit of the default fleet."""
    qube = EmulatedQube(QubeDevice.from_fleet(1, 0).params)
    bus = FakeSpiDev(qube)
    driver = QubeSpiDriver(
        0, 1, spi_factory=lambda: bus, clock=qube.clock, sleep_until=qube.sleep_until, **options
    )
    return driver, qube, bus


def test_the_bus_is_opened_in_mode_2_at_1_mhz_and_the_encoders_zeroed_amplifier_off() -> None:
    driver, qube, bus = rig()
    assert isinstance(driver, DeviceDriver)
    assert bus.opened == (0, 1) and bus.settings_at_transfer == {(0b10, 1_000_000)}
    first = qube.frames[0]
    assert (first.mode, first.mask, first.presets, first.word) == (0x01, 0x7F, (0, 0), 0x0000)
    assert driver.expected_id == QUBE_ID


def test_a_command_becomes_the_duty_word_and_is_clamped_to_10_volts() -> None:
    driver, qube, _ = rig()
    driver.write_command(driver.spec.command_of(2))  # the paper's +60
    assert (qube.frames[-1].word, qube.frames[-1].mask) == (0x803C, 0x1F)
    driver.write_command(np.array([-1.44]))
    assert qube.frames[-1].word == 0xFFC4
    driver.write_command(np.array([12.0]))  # past Quanser's ±10 V
    assert qube.duty == 416 and qube.volts == pytest.approx(9.984)
    driver.write_command(np.array([-50.0]))
    assert qube.duty == -416
    with pytest.raises(ValueError, match="finite"):
        driver.write_command(np.array([math.nan]))
    driver.read_sensors()  # a read resends the held command
    assert qube.frames[-1].word == motor_word_of(-416)


def motor_word_of(duty: int) -> int:
    return (duty & 0x7FFF) | 0x8000


def test_counts_become_angles_and_velocities_are_finite_differences() -> None:
    driver, qube, _ = rig()
    qube.device.set_state(np.array([0.3, 0.1, 0.0, 0.0]))  # arm +0.3 rad, pendulum 0.1 rad from upright
    obs = driver.read_sensors().copy()
    assert obs[2] == pytest.approx(0.3, abs=COUNT) and obs[0] == pytest.approx(0.1, abs=COUNT)
    qube.device.set_state(np.array([0.31, -0.1, 0.0, 0.0]))
    qube.sleep_until(0.010)
    later = driver.read_sensors()
    assert later[3] == pytest.approx(1.0, abs=2 * COUNT / 0.01)  # (0.31 − 0.30) / 10 ms
    assert later[1] == pytest.approx(-20.0, abs=2 * COUNT / 0.01)
    qube.device.set_state(np.array([0.0, math.pi - 0.01, 0.0, 0.0]))  # hanging, just short of +π
    qube.sleep_until(0.020)
    driver.read_sensors()
    qube.device.set_state(np.array([0.0, -math.pi + 0.01, 0.0, 0.0]))  # just past it: the reading wraps
    qube.sleep_until(0.030)
    wrapped = driver.read_sensors()
    assert wrapped[1] == pytest.approx(2.0, abs=2 * COUNT / 0.01)  # +0.02 rad in 10 ms, not −2π


def test_the_held_duty_drives_the_plant_for_the_elapsed_time() -> None:
    driver, qube, _ = rig()
    driver.write_command(np.array([3.0]))
    driver.wait_until(0.2)
    obs = driver.read_sensors()
    assert obs[2] > 0.05  # the arm turned the positive way under +3 V
    assert qube.device.state[0] == pytest.approx(obs[2], abs=COUNT)


def test_a_wrong_device_id_disables_the_amplifier_and_stops_the_driver() -> None:
    driver, qube, _ = rig()
    driver.write_command(np.array([2.0]))
    qube.device_id = 0x1234
    with pytest.raises(QubeFault, match="device id 0x1234, expected 0x0309"):
        driver.read_sensors()
    assert not qube.amplifier and qube.frames[-1].word == 0x0000 and qube.frames[-1].led == (999, 0, 0)
    with pytest.raises(QubeFault, match="stopped after a fault"):
        driver.write_command(np.array([1.0]))
    assert not qube.amplifier


@pytest.mark.parametrize("empty_bus_id", [0x0000, 0xFFFF])
def test_an_empty_bus_is_a_fault_when_opening(empty_bus_id: int) -> None:
    qube = EmulatedQube(device_id=empty_bus_id)
    bus = FakeSpiDev(qube)
    with pytest.raises(QubeFault, match=f"device id 0x{empty_bus_id:04x}, expected a QUBE's"):
        QubeSpiDriver(spi_factory=lambda: bus, clock=qube.clock, sleep_until=qube.sleep_until)
    assert bus.closed and not qube.amplifier


def test_an_expected_id_is_checked_from_the_first_reply() -> None:
    qube = EmulatedQube()
    with pytest.raises(QubeFault, match="expected 0x0777"):
        QubeSpiDriver(spi_factory=lambda: FakeSpiDev(qube), clock=qube.clock, expected_id=0x0777)


def test_a_stuck_arm_encoder_under_a_large_command_is_a_fault() -> None:
    driver, qube, _ = rig()
    qube.stuck_arm = True
    driver.write_command(np.array([3.0]))
    with pytest.raises(QubeFault, match="arm encoder stuck"):
        for tick in range(1, 200):
            driver.wait_until(tick * 0.006)
            driver.read_sensors()
    assert 0.3 < driver.time() < 0.32 and not qube.amplifier


def test_a_small_command_on_a_still_arm_is_no_fault() -> None:
    driver, qube, _ = rig()
    qube.stuck_arm = True
    driver.write_command(np.array([0.5]))  # below the stuck-detection threshold
    for tick in range(1, 200):
        driver.wait_until(tick * 0.006)
        driver.read_sensors()
    assert driver.faulted is None and qube.amplifier


def test_close_and_leaving_with_disable_the_amplifier() -> None:
    driver, qube, bus = rig()
    driver.write_command(np.array([1.0]))
    driver.close()
    assert not qube.amplifier and qube.frames[-1].word == 0x0000 and bus.closed
    with pytest.raises(RuntimeError, match="boom"), rig()[0] as inside:
        inside.write_command(np.array([1.0]))
        raise RuntimeError("boom")
    assert not inside.amplifier


def test_a_stuck_pendulum_encoder_makes_the_reset_fail_with_the_motor_off() -> None:
    settings = ResetSettings(still_seconds=0.1, timeout=2.0)
    driver, qube, _ = rig(reset=settings)
    original = qube.raw_counts
    qube.raw_counts = lambda: (original()[0], 0)  # the pendulum never moves
    with pytest.raises(DeviceResetError, match=r"did not settle within 2\.0 s"):
        driver.home(None)
    assert not qube.amplifier


def test_without_spidev_the_error_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "spidev", None)  # as if not installed
    with pytest.raises(QubeFault, match=r"pip install 'fleetrl\[pi\]'"):
        QubeSpiDriver()
