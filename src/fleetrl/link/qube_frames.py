"""The QUBE-Servo 2's SPI frames (Raspberry Pi variant): the 17-byte command and reply, as pure functions.
Every constant is a fact of ``reference/qube-spi-protocol.md``; check it against your unit's data sheet."""

from __future__ import annotations

import math
from dataclasses import dataclass

SPI_MODE = 0b10  # SPI mode 2 (CPOL = 1, CPHA = 0), not mode 0
SPI_SPEED_HZ = 1_000_000
FRAME_BYTES = 17  # one full-duplex transfer writes the command and returns the reply

MODE_WRITE = 0x01  # command byte 0: write what the mask selects
MASK_MOTOR = 1 << 0  # write mask bit 0: write the motor command
MASK_ENABLE = 1 << 1  # write mask bit 1: write the motor (amplifier) enable
MASK_RED, MASK_GREEN, MASK_BLUE = 1 << 2, 1 << 3, 1 << 4  # write mask bits 2-4: the LEDs
MASK_PRESET_ARM, MASK_PRESET_PENDULUM = 1 << 5, 1 << 6  # bits 5-6: preset encoder 0 (arm), 1 (pendulum)
STEP_MASK = MASK_MOTOR | MASK_ENABLE | MASK_RED | MASK_GREEN | MASK_BLUE  # written every control step
RESET_MASK = STEP_MASK | MASK_PRESET_ARM | MASK_PRESET_PENDULUM  # written once at reset: zeroes both encoders
LED_FULL = 999  # an LED's full brightness (0x03E7), big-endian in two bytes

AMPLIFIER_ENABLE = 0x8000  # motor command word bit 15: amplifier enabled
DUTY_MASK = 0x7FFF  # an 11-bit two's-complement duty, sign-extended into bits 11-14
DUTY_LIMIT = 1023  # the largest magnitude an 11-bit two's-complement duty holds
VOLTS_PER_DUTY = 15.0 / 625.0  # 625 duty units ≈ 15 V

COUNTS_PER_REV = 2048  # counts per revolution of both encoders
RADIANS_PER_COUNT = 2.0 * math.pi / COUNTS_PER_REV
COUNTS_MODULUS = 1 << 24  # encoder counts are 24-bit two's complement (sign bit 0x800000)


@dataclass(frozen=True)
class Reply:
    """The fields of a reply frame the driver uses."""

    device_id: int  # bytes 0-1, big-endian
    arm_counts: int  # bytes 2-4, encoder 0, signed
    pendulum_counts: int  # bytes 5-7, encoder 1, signed


def duty_of_volts(volts: float) -> int:
    """The nearest duty value to ``volts`` (625 ≈ 15 V); ValueError beyond the 11-bit range."""
    duty = round(volts / VOLTS_PER_DUTY)
    if not -DUTY_LIMIT <= duty <= DUTY_LIMIT:
        raise ValueError(f"{volts} V is duty {duty}, outside the 11-bit range ±{DUTY_LIMIT}")
    return duty


def volts_of_duty(duty: int) -> float:
    """The volts a duty value commands."""
    return duty * VOLTS_PER_DUTY


def motor_word(duty: int, *, enabled: bool) -> int:
    """The 16-bit motor command word: ``duty`` masked to 15 bits, bit 15 set when the amplifier is on."""
    if not -DUTY_LIMIT <= duty <= DUTY_LIMIT:
        raise ValueError(f"duty {duty} is outside the 11-bit range ±{DUTY_LIMIT}")
    return (duty & DUTY_MASK) | (AMPLIFIER_ENABLE if enabled else 0)


def command_frame(
    word: int,
    *,
    mask: int = STEP_MASK,
    led: tuple[int, int, int] = (0, 0, 0),
    presets: tuple[int, int] = (0, 0),
) -> list[int]:
    """The 17 command bytes: write ``mask``'s fields, motor command ``word``, LED levels (0-999, red,
    green, blue), encoder presets (arm, pendulum; 24-bit, used only where ``mask`` selects them)."""
    if not all(0 <= level <= LED_FULL for level in led):
        raise ValueError(f"LED levels must be 0 to {LED_FULL}, got {led}")
    frame = bytearray(FRAME_BYTES)
    frame[0] = MODE_WRITE
    frame[2] = mask
    for field, level in enumerate(led):
        frame[3 + 2 * field : 5 + 2 * field] = level.to_bytes(2, "big")
    frame[9:12] = (presets[0] % COUNTS_MODULUS).to_bytes(3, "big")
    frame[12:15] = (presets[1] % COUNTS_MODULUS).to_bytes(3, "big")
    frame[15:17] = word.to_bytes(2, "big")
    return list(frame)


def decode_reply(reply: list[int] | bytes) -> Reply:
    """The device id and both encoder counts of a reply frame; ValueError for a frame of the wrong size."""
    data = bytes(reply)
    if len(data) != FRAME_BYTES:
        raise ValueError(f"a reply frame has {FRAME_BYTES} bytes, got {len(data)}")
    return Reply(
        int.from_bytes(data[0:2], "big"),
        int.from_bytes(data[2:5], "big", signed=True),
        int.from_bytes(data[5:8], "big", signed=True),
    )


def arm_angle(counts: int) -> float:
    """Arm angle (rad) of encoder 0's counts, negated so that positive is counter-clockwise."""
    return -counts * RADIANS_PER_COUNT


def pendulum_angle(counts: int) -> float:
    """Pendulum angle (rad, 0 upright, −π hanging) of encoder 1's counts, zeroed hanging still."""
    return (counts % COUNTS_PER_REV) * RADIANS_PER_COUNT - math.pi
