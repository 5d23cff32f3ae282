"""``QubeSpiDriver``: a QUBE-Servo 2 (Raspberry Pi variant) on the Pi's SPI bus, behind ``DeviceDriver``
(docs/hardware.md), and its 17-byte command and reply frames as pure functions: every frame constant is a
fact of ``reference/qube-spi-protocol.md``; check it against your unit's data sheet. ``spidev`` is the
``pi`` extra."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Protocol

import numpy as np

from fleetrl.link.driver import QUBE_SAFE_VOLTS, precise_sleep_until, qube_spec
from fleetrl.link.qube_reset import ResetSettings, reset_through_driver

log = logging.getLogger(__name__)

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


STUCK_VOLTS = 2.0  # a held command at least this large must move the arm…
STUCK_SECONDS = 0.3  # …by a count within this long, or the arm encoder (or the motor) is stuck
STUCK_DUTY = duty_of_volts(STUCK_VOLTS)
SAFE_DUTY = math.floor(QUBE_SAFE_VOLTS / VOLTS_PER_DUTY)  # the largest duty inside ±10 V
NO_DEVICE_IDS = (0x0000, 0xFFFF)  # what a bus with nothing on it reads back
INSTALL_HINT = "pip install 'fleetrl[pi]'"


class QubeFault(OSError):
    """The QUBE or its bus misbehaved (or cannot be reached); the amplifier has been disabled."""


class SpiDevice(Protocol):
    """The part of ``spidev.SpiDev`` the driver uses."""

    mode: int
    max_speed_hz: int

    def open(self, bus: int, device: int) -> None: ...
    def xfer2(self, data: list[int]) -> list[int]: ...
    def close(self) -> None: ...


def spidev_factory() -> Callable[[], SpiDevice]:
    """``spidev.SpiDev``, imported now; a clear error naming the extra when it is not installed."""
    try:
        import spidev
    except ImportError:
        raise QubeFault(f"the qube-spi driver needs the spidev package: {INSTALL_HINT}") from None
    factory: Callable[[], SpiDevice] = spidev.SpiDev
    return factory


class QubeSpiDriver:
    """A QUBE-Servo 2 on ``/dev/spidev<bus>.<device>`` as a ``DeviceDriver``: the command clamped to ±10 V,
    every reply's device id checked (``expected_id``, default the first reply's), a stuck arm encoder a
    fault, the amplifier disabled on any fault. Opening zeroes both encoders: start it with the pendulum
    hanging still and the arm centred."""

    def __init__(
        self,
        bus: int = 0,
        device: int = 0,
        *,
        control_period: float = 0.006,
        expected_id: int | None = None,
        spi_factory: Callable[[], SpiDevice] | None = None,
        clock: Callable[[], float] = time.perf_counter,
        sleep_until: Callable[[float], None] = precise_sleep_until,
        reset: ResetSettings | None = None,
    ) -> None:
        self.spec = qube_spec(control_period, QUBE_SAFE_VOLTS)
        self.expected_id = expected_id
        self.reset_settings = reset or ResetSettings()
        self.faulted: str | None = None  # why the driver stopped
        self.duty = 0  # the duty value held
        self.amplifier = False  # whether the amplifier is enabled
        self._clock = clock
        self._sleep_until = sleep_until
        self._obs = np.zeros(4, dtype=np.float32)
        self._last_read: tuple[float, float, float] | None = None
        self._arm_counts: int | None = None
        self._arm_still_since = 0.0
        self._spi = (spi_factory or spidev_factory())()
        try:
            self._spi.open(bus, device)
        except OSError as err:
            raise QubeFault(
                f"cannot open /dev/spidev{bus}.{device} ({err}): enable SPI (raspi-config, Interface "
                "Options) and run as a user in the spi group"
            ) from None
        self._spi.mode = SPI_MODE
        self._spi.max_speed_hz = SPI_SPEED_HZ
        self._origin = clock()
        try:
            self._transfer(RESET_MASK)  # amplifier off, both encoders zeroed
        except BaseException:
            self._spi.close()
            raise
        log.info("QUBE on /dev/spidev%d.%d, device id 0x%04x", bus, device, self.expected_id)

    def time(self) -> float:
        """Seconds on the clock since the driver opened."""
        return self._clock() - self._origin

    def read_sensors(self) -> np.ndarray:
        """One transfer (the held command resent); [alpha, alpha_dot, theta, theta_dot], the velocities by
        finite difference since the previous read (as the rig)."""
        self._refuse_if_faulted()
        reply = self._transfer()
        now = self.time()
        theta, alpha = arm_angle(reply.arm_counts), pendulum_angle(reply.pendulum_counts)
        self._check_arm_moves(reply.arm_counts, now)
        theta_dot = alpha_dot = 0.0
        if self._last_read is not None and now > self._last_read[0]:
            dt = now - self._last_read[0]
            theta_dot = (theta - self._last_read[1]) / dt
            alpha_dot = math.remainder(alpha - self._last_read[2], 2.0 * math.pi) / dt
        self._last_read = (now, theta, alpha)
        self._obs[:] = (alpha, alpha_dot, theta, theta_dot)
        return self._obs

    def write_command(self, command: np.ndarray) -> None:
        """Clamp ``[volts]`` to ±10 V, enable the amplifier and send the duty word."""
        self._refuse_if_faulted()
        volts = float(self.spec.clamp(command)[0])
        self.duty = min(max(duty_of_volts(volts), -SAFE_DUTY), SAFE_DUTY)
        self.amplifier = True
        self._transfer()

    def motor_off(self) -> None:
        """Duty 0 and the amplifier disabled (also after a fault; never raises for the bus's sake)."""
        self.duty, self.amplifier = 0, False
        try:
            self._transfer(check=False)
        except Exception as err:  # the bus itself failed: nothing more can be sent
            log.error("QUBE: could not send amplifier-off: %s", err)

    def wait_until(self, deadline: float) -> None:
        """Sleep until ``time() >= deadline`` (the amplifier holds the duty meanwhile)."""
        self._sleep_until(self._origin + deadline)

    def home(self, seed: int | None) -> np.ndarray:
        """The device-side reset through this driver (``fleetrl.link.qube_reset``); ``seed`` is ignored."""
        self._refuse_if_faulted()
        return reset_through_driver(self, self.reset_settings)

    def close(self) -> None:
        """Disable the amplifier and release the bus."""
        self.motor_off()
        self._spi.close()

    def __enter__(self) -> QubeSpiDriver:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def _transfer(self, mask: int | None = None, *, check: bool = True) -> Reply:
        """Send the held duty word (LEDs: green running, red faulted, blue amplifier off); the reply."""
        led = (LED_FULL, 0, 0) if self.faulted else (0, LED_FULL, 0) if self.amplifier else (0, 0, LED_FULL)
        word = motor_word(self.duty, enabled=self.amplifier)
        frame = command_frame(word, led=led) if mask is None else command_frame(word, mask=mask, led=led)
        reply = decode_reply(self._spi.xfer2(frame))
        if check:
            self._check_id(reply.device_id)
        return reply

    def _check_id(self, device_id: int) -> None:
        if self.expected_id is None and device_id not in NO_DEVICE_IDS:
            self.expected_id = device_id
        if device_id != self.expected_id:
            expected = "a QUBE's" if self.expected_id is None else f"0x{self.expected_id:04x}"
            self._fault(f"reply carries device id 0x{device_id:04x}, expected {expected}: check the wiring")

    def _check_arm_moves(self, counts: int, now: float) -> None:
        if counts != self._arm_counts or not self.amplifier or abs(self.duty) < STUCK_DUTY:
            self._arm_counts = counts
            self._arm_still_since = now
        elif now - self._arm_still_since > STUCK_SECONDS:
            self._fault(
                f"arm encoder stuck at {counts} counts for {now - self._arm_still_since:.2f} s under "
                f"{volts_of_duty(self.duty):.1f} V: check the encoder cable and that the arm is free"
            )

    def _fault(self, reason: str) -> None:
        self.faulted = reason
        self.motor_off()
        log.error("QUBE fault, amplifier disabled: %s", reason)
        raise QubeFault(f"{reason} (amplifier disabled)")

    def _refuse_if_faulted(self) -> None:
        if self.faulted is not None:
            raise QubeFault(f"the QUBE driver stopped after a fault: {self.faulted}")
