"""What every test directory shares: the brokers to run MQTT tests on, the mosquitto marker, line-reading
child processes, and a closing line that says which tests a missing mosquitto skipped.

Markers (pyproject.toml): ``slow`` (trains, or runs longer than a few seconds), ``mqtt`` (needs a broker),
``mosquitto`` (needs the mosquitto binary: skipped, and counted at the end, where there is none).
``make test-fast`` runs the rest: unit tests with no broker and no training.
``FLEETRL_HIDE_MOSQUITTO=1`` hides an installed mosquitto, to run the suite as on a machine without it.
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import pytest
from module_order import START_FIRST

from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto

MOSQUITTO_MISSING = "mosquitto not installed"
INSTALL_MOSQUITTO = "apt-get install -y mosquitto"

# Every MQTT test that takes a broker runs on both: the real mosquitto a deployment uses, and the embedded
# amqtt broker that carries the tests where mosquitto is missing.
BROKERS = [pytest.param("mosquitto", marks=pytest.mark.mosquitto), "amqtt"]


def start_rank(item: pytest.Item) -> int:
    """Where ``item``'s module stands in :data:`START_FIRST` (after them all if it is not there)."""
    module = item.nodeid.split("::")[0].removeprefix("tests/")
    return START_FIRST.index(module) if module in START_FIRST else len(START_FIRST)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Put the longest modules first (:data:`START_FIRST`; otherwise pytest's order, each module's tests kept
    together), and skip the tests marked ``mosquitto`` where there is no mosquitto binary (or it is
    hidden)."""
    items.sort(key=start_rank)
    if find_mosquitto() is not None:
        return
    skip = pytest.mark.skip(reason=f"{MOSQUITTO_MISSING} ({INSTALL_MOSQUITTO})")
    for item in items:
        if item.get_closest_marker("mosquitto") is not None:
            item.add_marker(skip)


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    """Say plainly how many tests a missing mosquitto skipped, and how to install it."""
    skipped = [
        report
        for report in terminalreporter.stats.get("skipped", [])
        if MOSQUITTO_MISSING in str(getattr(report, "longrepr", ""))
    ]
    if skipped:
        terminalreporter.write_line(
            f"{len(skipped)} tests skipped: {MOSQUITTO_MISSING} on this machine (or hidden by "
            f"FLEETRL_HIDE_MOSQUITTO=1); the embedded amqtt broker carried the other MQTT tests. "
            f"Install mosquitto with: {INSTALL_MOSQUITTO}",
            yellow=True,
            bold=True,
        )


@pytest.fixture(scope="module", params=BROKERS)
def broker(request: pytest.FixtureRequest) -> Iterator[EmbeddedBroker]:
    """A running embedded broker, once mosquitto and once amqtt, shared by a module's tests."""
    with EmbeddedBroker(request.param) as running:
        yield running


class LineProcess:
    """A child process whose printed lines are collected on a thread; killed at the end of the test."""

    def __init__(self, argv: Sequence[str]) -> None:
        self.proc = subprocess.Popen(
            list(argv), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True
        )
        self.lines: list[str] = []
        assert self.proc.stdout is not None
        threading.Thread(target=self._read, args=(self.proc.stdout,), daemon=True).start()

    def _read(self, stdout: IO[str]) -> None:
        for line in stdout:
            self.lines.append(line.strip())

    def numbers(self, prefix: str) -> list[int]:
        """The integers after ``prefix`` on the lines that start with it (e.g. ``"round "`` → rounds)."""
        return [int(line.split()[1]) for line in self.lines if line.startswith(prefix)]

    def wait_for(self, prefix: str, at_least: int, timeout: float = 30.0) -> None:
        """Wait until a line ``prefix N`` with N ≥ ``at_least`` has been printed."""
        deadline = time.monotonic() + timeout
        while max(self.numbers(prefix), default=0) < at_least:
            assert time.monotonic() < deadline, f"{Path(self.proc.args[1]).name} stuck at {self.lines[-3:]}"
            assert self.proc.poll() is None, f"{self.proc.args[1]} exited {self.proc.returncode}"
            time.sleep(0.02)

    def stop(self, timeout: float = 30.0) -> int:
        """Wait for the process to end by itself and return its exit code (killed if it does not)."""
        try:
            return self.proc.wait(timeout=timeout)
        finally:
            self.kill()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


@pytest.fixture
def line_process() -> Iterator[Callable[[Sequence[str]], LineProcess]]:
    """Start :class:`LineProcess` children; every one still running is killed when the test ends."""
    started: list[LineProcess] = []

    def start(argv: Sequence[str]) -> LineProcess:
        started.append(LineProcess(argv))
        return started[-1]

    yield start
    for child in started:
        child.kill()
