"""Every field of the QUBE's SPI command and reply frames, pinned to literal bytes from
reference/qube-spi-protocol.md: the driver's encoders, and the emulator's decoder the other tests rely on."""

from __future__ import annotations

import math

import pytest
from qube_emulator import EmulatedQube

from fleetrl.link.qube_spi import (
    RESET_MASK,
    SPI_MODE,
    SPI_SPEED_HZ,
    STEP_MASK,
    arm_angle,
    command_frame,
    decode_reply,
    duty_of_volts,
    motor_word,
    pendulum_angle,
    volts_of_duty,
)


def hex_bytes(text: str) -> list[int]:
    return list(bytes.fromhex(text))


def test_bus_settings_are_mode_2_at_1_mhz() -> None:
    assert (SPI_MODE, SPI_SPEED_HZ) == (2, 1_000_000)


@pytest.mark.parametrize(
    ("duty", "enabled", "bytes_15_16"),
    [
        (60, True, "80 3C"),  # the sheet's worked examples
        (-60, True, "FF C4"),
        (0, True, "80 00"),
        (0, False, "00 00"),  # amplifier disabled
        (-60, False, "7F C4"),  # −60 masked to 15 bits, before the amplifier bit
        (625, True, "82 71"),  # 625 ≈ 15 V
        (-1, True, "FF FF"),
        (-1023, True, "FC 01"),  # sign bit 0x0400 extended into bits 11-14
        (1023, True, "83 FF"),
    ],
)
def test_motor_word_bytes(duty: int, enabled: bool, bytes_15_16: str) -> None:
    assert list(motor_word(duty, enabled=enabled).to_bytes(2, "big")) == hex_bytes(bytes_15_16)


def test_a_duty_outside_11_bits_is_refused() -> None:
    with pytest.raises(ValueError, match="11-bit"):
        motor_word(1024, enabled=True)


def test_duty_units_are_625_per_15_volts() -> None:
    assert duty_of_volts(1.44) == 60 and duty_of_volts(-1.44) == -60  # the paper's actions
    assert volts_of_duty(625) == 15.0 and volts_of_duty(280) == pytest.approx(6.72)


def test_a_step_frame_writes_motor_enable_and_leds() -> None:
    frame = command_frame(motor_word(60, enabled=True), led=(0, 999, 0))
    assert frame == hex_bytes("01 00 1F 0000 03E7 0000 000000 000000 803C")
    assert STEP_MASK == 0b0001_1111


def test_every_led_field_is_big_endian_0_to_999() -> None:
    frame = command_frame(0, led=(999, 500, 1))
    assert frame[3:9] == hex_bytes("03E7 01F4 0001")
    with pytest.raises(ValueError, match="LED levels"):
        command_frame(0, led=(1000, 0, 0))


def test_the_reset_frame_presets_both_encoders() -> None:
    frame = command_frame(0, mask=RESET_MASK)
    assert frame == hex_bytes("01 00 7F 0000 0000 0000 000000 000000 0000")
    presets = command_frame(0, mask=RESET_MASK, presets=(-1, 0x123456))
    assert presets[9:15] == hex_bytes("FFFFFF 123456")  # 24-bit big-endian, two's complement


def test_reply_fields() -> None:
    reply = decode_reply(hex_bytes("0309 FFFFFF 000400") + [0xAA] * 9)  # bytes 8-16 are not used
    assert (reply.device_id, reply.arm_counts, reply.pendulum_counts) == (0x0309, -1, 1024)
    extremes = decode_reply(hex_bytes("FFFF 800000 7FFFFF") + [0] * 9)
    assert (extremes.device_id, extremes.arm_counts, extremes.pendulum_counts) == (
        0xFFFF,
        -(2**23),
        2**23 - 1,
    )
    with pytest.raises(ValueError, match="17 bytes"):
        decode_reply([0] * 16)


def test_counts_to_radians() -> None:
    count = 2 * math.pi / 2048
    assert arm_angle(-1) == pytest.approx(count)  # negated: positive is counter-clockwise
    assert arm_angle(512) == pytest.approx(-math.pi / 2)
    assert pendulum_angle(0) == pytest.approx(-math.pi)  # zeroed hanging
    assert pendulum_angle(1024) == pytest.approx(0.0)  # upright
    assert pendulum_angle(1024 + 2048) == pytest.approx(0.0)  # modulo one revolution
    assert pendulum_angle(-512) == pytest.approx(math.pi / 2)


def test_the_emulator_decodes_the_sheets_literal_frames() -> None:
    qube = EmulatedQube()
    qube.transfer(hex_bytes("01 00 1F 0000 03E7 0000 000000 000000 FFC4"))
    assert (qube.duty, qube.amplifier, qube.frames[-1].led) == (-60, True, (0, 999, 0))
    assert qube.volts == pytest.approx(-1.44)
    qube.transfer(hex_bytes("01 00 1F 0000 0000 0000 000000 000000 803C"))
    assert qube.volts == pytest.approx(1.44)
    qube.transfer(hex_bytes("01 00 1F 0000 0000 0000 000000 000000 003C"))  # duty kept, amplifier off
    assert (qube.duty, qube.amplifier, qube.volts) == (60, False, 0.0)
    qube.transfer(hex_bytes("00 00 1F 0000 0000 0000 000000 000000 80C4"))  # read only: nothing written
    assert (qube.duty, qube.amplifier) == (60, False)


def test_the_emulator_replies_with_24_bit_counts_and_honours_presets() -> None:
    qube = EmulatedQube()
    qube.device.set_state([-3 * 2 * math.pi / 2048 - 1e-9, math.pi + 1e-9, 0.0, 0.0])
    reply = qube.transfer(hex_bytes("00 00 00 0000 0000 0000 000000 000000 0000"))
    assert reply[:8] == hex_bytes("0309 000003 000000")
    reply = qube.transfer(hex_bytes("01 00 60 0000 0000 0000 FFFFFF 000400 0000"))  # preset: −1, 1024
    reply = qube.transfer(hex_bytes("00 00 00 0000 0000 0000 000000 000000 0000"))
    assert reply[:8] == hex_bytes("0309 FFFFFF 000400")
