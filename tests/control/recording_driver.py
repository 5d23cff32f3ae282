"""A user's driver for the command-line tests (``--driver recording_driver:driver``, from this directory): a
simulated QUBE that writes each call that moves the motor (``write``, ``off``, ``close``) as a line to the
file ``FLEETRL_TEST_DRIVER_LOG`` names, so a test can see what a process did to its unit before it ended."""

from __future__ import annotations

import os

import numpy as np

from fleetrl.link.driver import SimulatedDriver, simulated_driver

LOG = "FLEETRL_TEST_DRIVER_LOG"


class RecordingDriver:
    """``SimulatedDriver``'s interface, each motor call noted."""

    def __init__(self, inner: SimulatedDriver, log: str) -> None:
        self.inner = inner
        self.spec = inner.spec
        self._log = open(log, "a", buffering=1)  # noqa: SIM115 (open for the driver's life)

    def time(self) -> float:
        return self.inner.time()

    def read_sensors(self) -> np.ndarray:
        return self.inner.read_sensors()

    def write_command(self, command: np.ndarray) -> None:
        self.inner.write_command(command)
        self._log.write(f"write {float(command[0]):g}\n")

    def motor_off(self) -> None:
        self.inner.motor_off()
        self._log.write("off\n")

    def wait_until(self, deadline: float) -> None:
        self.inner.wait_until(deadline)

    def home(self, seed: int | None) -> np.ndarray:
        return self.inner.home(seed)

    def close(self) -> None:
        self.inner.close()
        self._log.write("close\n")
        self._log.close()


def driver(unit: int, fleet_seed: int, *, realtime: bool) -> RecordingDriver:
    """Unit ``unit`` of the simulated QUBE fleet ``fleet_seed``, recorded."""
    return RecordingDriver(simulated_driver("qube", unit, fleet_seed, realtime=realtime), os.environ[LOG])
