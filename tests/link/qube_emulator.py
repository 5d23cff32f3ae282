"""An emulated QUBE-Servo 2 on the far side of a fake ``spidev``: the simulator's physics behind the frames.

Written from reference/qube-spi-protocol.md alone, never from the driver's encoders: it decodes each
command frame byte by byte (mode, mask, LEDs, presets, the duty word and its amplifier bit), integrates the
plant for the time elapsed on its simulated clock under the volts held, and answers with a reply frame built
from the true angles quantised to 2048 counts. Faults to inject: a wrong device id, a stuck arm encoder.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import QubeConfig, QubeParams
from fleetrl.link.driver import precise_sleep_until

QUBE_ID = 0x0309
"""the id this emulated unit answers with (the sheet gives no value: any id the driver then expects)"""
STEP = 0.001
"""the emulator integrates the plant in steps of this many seconds"""


def signed_24(word: int) -> int:
    """A 24-bit two's-complement word as an int (sign bit 0x800000)."""
    return word - (1 << 24) if word & 0x800000 else word


@dataclass
class Received:
    """One command frame as the emulator understood it."""

    mode: int
    mask: int
    led: tuple[int, int, int]
    presets: tuple[int, int]
    word: int


@dataclass
class EmulatedQube:
    """A simulated unit answering 17-byte frames, with a clock the driver under test reads and sleeps on."""

    params: QubeParams = field(default_factory=QubeParams)
    device_id: int = QUBE_ID
    stuck_arm: bool = False
    wall_clock: bool = False
    """run on the wall clock (for a real-time bridge) instead of the simulated one"""
    now: float = 0.0
    duty: int = 0
    amplifier: bool = False
    frames: list[Received] = field(default_factory=list)

    def __post_init__(self) -> None:
        config = QubeConfig(control_period=STEP, actuation_delay=False, quantise=False)
        self.device = QubeDevice(self.params, config)
        self.device.set_state(np.array([0.0, math.pi, 0.0, 0.0]))  # hanging still, arm centred
        self._integrated = 0.0
        self._started = time.perf_counter()
        self._zero = [0, 0]
        self._stuck_counts = 0

    def go_wall_clock(self) -> None:
        """From now on run on the wall clock, going on from the simulated time reached so far."""
        self._started = time.perf_counter() - self.now
        self.wall_clock = True

    # the injected clock
    def clock(self) -> float:
        """Simulated seconds (or wall seconds since the emulator was made)."""
        return time.perf_counter() - self._started if self.wall_clock else self.now

    def sleep_until(self, deadline: float) -> None:
        """Sleeping on the simulated clock: time jumps (on the wall clock: a real sleep)."""
        if self.wall_clock:
            precise_sleep_until(self._started + deadline)
        self.now = max(self.now, deadline)

    @property
    def volts(self) -> float:
        """What the amplifier drives now: duty × 15 / 625 while enabled, else nothing."""
        return self.duty * 15.0 / 625.0 if self.amplifier else 0.0

    def raw_counts(self) -> tuple[int, int]:
        """The encoders' own counts: arm negative counter-clockwise (the driver negates), pendulum counting
        from hanging."""
        theta, alpha = self.device.state[0], self.device.state[1]
        return math.floor(-theta / (2 * math.pi / 2048)), math.floor((alpha - math.pi) / (2 * math.pi / 2048))

    def transfer(self, frame: list[int]) -> list[int]:
        """One full-duplex transfer: run the plant up to now, act on the command, answer."""
        assert len(frame) == 17 and all(0 <= b <= 255 for b in frame), frame
        self._integrate()
        received = Received(
            mode=frame[0],
            mask=frame[2],
            led=(frame[3] << 8 | frame[4], frame[5] << 8 | frame[6], frame[7] << 8 | frame[8]),
            presets=(
                signed_24(frame[9] << 16 | frame[10] << 8 | frame[11]),
                signed_24(frame[12] << 16 | frame[13] << 8 | frame[14]),
            ),
            word=frame[15] << 8 | frame[16],
        )
        assert frame[1] == 0x00, "byte 1 is padding"
        self.frames.append(received)
        arm, pendulum = self.raw_counts()
        if received.mode == 0x01:
            if received.mask & 0x20:
                self._zero[0] = arm - received.presets[0]
            if received.mask & 0x40:
                self._zero[1] = pendulum - received.presets[1]
            if received.mask & 0x01:
                duty = received.word & 0x07FF
                if duty & 0x0400:
                    duty -= 0x0800
                sign_bits = (received.word >> 11) & 0x0F
                assert sign_bits == (0x0F if duty < 0 else 0), f"bits 11-14 must extend the sign: {frame}"
                self.duty = duty
            if received.mask & 0x02:
                self.amplifier = bool(received.word & 0x8000)
        arm_counts = self._stuck_counts if self.stuck_arm else arm - self._zero[0]
        self._stuck_counts = arm_counts
        pendulum_counts = pendulum - self._zero[1]
        reply = [self.device_id >> 8, self.device_id & 0xFF]
        for counts in (arm_counts, pendulum_counts):
            word = counts & 0xFFFFFF
            reply += [word >> 16, (word >> 8) & 0xFF, word & 0xFF]
        return reply + [0] * 9

    def _integrate(self) -> None:
        steps = math.floor((self.clock() - self._integrated) / STEP + 1e-6)
        for _ in range(steps):
            self.device.step_volts(self.volts)
        self._integrated += steps * STEP


class FakeSpiDev:
    """Stands in for ``spidev.SpiDev``: records how it was set up and hands transfers to the emulator."""

    def __init__(self, qube: EmulatedQube) -> None:
        self.qube = qube
        self.mode = 0
        self.max_speed_hz = 0
        self.opened: tuple[int, int] | None = None
        self.closed = False
        self.settings_at_transfer: set[tuple[int, int]] = set()

    def open(self, bus: int, device: int) -> None:
        self.opened = (bus, device)

    def xfer2(self, data: list[int]) -> list[int]:
        assert self.opened is not None and not self.closed, "transfer on a bus not open"
        self.settings_at_transfer.add((self.mode, self.max_speed_hz))
        return self.qube.transfer(list(data))

    def close(self) -> None:
        self.closed = True
