"""Issue 14 ("idle means idle"): every long-running role, once it is waiting, uses at most 1 % of a core.

Each role runs as its own process (``python -m fleetrl.cli.main ROLE``, no wrapper); the test waits until the
role announced itself on the broker (it is then waiting), then reads the role process's own CPU time (utime +
stime in /proc/<pid>/stat) over MEASURE seconds. All roles wait side by side and are measured over the same
window (one wait for the whole module instead of one per role).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from fleetrl.federation.wire.topics import status_topic
from fleetrl.link.wire import device_topic
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.mqtt import MqttTransport

pytestmark = [
    pytest.mark.slow,
    pytest.mark.mqtt,
    pytest.mark.timeout(120),
    pytest.mark.mosquitto,
]
MEASURE = 10.0
"""seconds of waiting measured"""
MAX_SHARE = 0.01
"""the bound: 1 % of one core"""
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far (its threads included, its children not)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS  # fields 14 and 15 of proc(5)


@pytest.fixture(scope="module")
def broker() -> Iterator[EmbeddedBroker]:
    with EmbeddedBroker("mosquitto") as running:
        yield running


def start_role(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "fleetrl.cli.main", *argv],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
    )  # fmt: skip


def wait_for_retained(url: str, topic: str, role: subprocess.Popen[str], timeout: float = 60.0) -> None:
    """Return once ``topic`` holds an ``online`` status: the role is up and waiting."""
    probe = MqttTransport(url)
    probe.connect(f"idle-probe-{time.monotonic_ns()}")
    try:
        probe.subscribe(topic)
        deadline = time.monotonic() + timeout
        while True:
            assert role.poll() is None, f"the role exited with {role.returncode}"
            assert time.monotonic() < deadline, f"nothing on {topic}"
            message = probe.receive(0.5)
            if message is not None and message.payload.startswith(b"online"):
                return
    finally:
        probe.close()


@dataclass
class Role:
    """One long-running role under measurement: its process and how to tell it is up and waiting."""

    name: str
    process: subprocess.Popen[str]
    ready: Callable[[], None]
    children: bool = False

    def pids(self) -> list[int]:
        return [self.process.pid, *(_children(self.process.pid) if self.children else [])]


def _children(pid: int) -> list[int]:
    found = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return [int(p) for p in found]


def _broker_line(role: subprocess.Popen[str]) -> Callable[[], None]:
    def ready() -> None:
        assert role.stdout is not None
        line = role.stdout.readline()
        assert "broker listening" in line, line

    return ready


def _roles(broker: EmbeddedBroker, tmp: Path) -> list[Role]:
    chief = start_role(
        "chief", "--broker", broker.url, "--run-id", "idle-chief", "--workers", "2", "--env", "cartpole",
        "--round-timeout", "1", "--idle-timeout", "100",
    )  # fmt: skip
    worker = start_role(
        "worker", "--broker", broker.url, "--run-id", "idle-worker", "--worker-id", "0", "--env", "cartpole",
        "--out", str(tmp / "w0"), "--reply-timeout", "100",
    )  # fmt: skip
    device = start_role(
        "device", "--broker", broker.url, "--run-id", "idle-dev", "--unit", "0", "--env", "cartpole"
    )
    roles = [
        Role(
            "chief (waiting for workers, round deadline passed)",
            chief,
            lambda: wait_for_retained(broker.url, status_topic("idle-chief", "chief"), chief),
        ),
        Role(
            "worker (waiting for the chief's welcome)",
            worker,
            lambda: wait_for_retained(broker.url, status_topic("idle-worker", "0"), worker),
        ),
        Role(
            "device bridge (lockstep, no commands)",
            device,
            lambda: wait_for_retained(broker.url, device_topic("idle-dev", 0, "status"), device),
        ),
    ]
    for prefer in ("mosquitto", "amqtt"):
        process = start_role("broker", "--prefer", prefer)
        name = (
            "fleetrl broker --prefer mosquitto (with its mosquitto child)"
            if prefer == "mosquitto"
            else "fleetrl broker --prefer amqtt (in-process broker)"
        )
        roles.append(Role(name, process, _broker_line(process), children=prefer == "mosquitto"))
    return roles


@pytest.fixture(scope="module")
def idle_shares(
    broker: EmbeddedBroker, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[dict[str, float]]:
    """Every role started at once and measured over the same window (each process's own CPU time, so the
    roles do not count against each other): role name → share of a core."""
    roles = _roles(broker, tmp_path_factory.mktemp("idle"))
    try:
        for role in roles:
            role.ready()
        time.sleep(1.5)  # past the chief's 1 s round deadline, into plain waiting
        pids = {role.name: role.pids() for role in roles}
        before = {name: sum(cpu_seconds(p) for p in ps) for name, ps in pids.items()}
        started = time.monotonic()
        time.sleep(MEASURE)
        elapsed = time.monotonic() - started
        shares = {
            name: (sum(cpu_seconds(p) for p in ps) - before[name]) / elapsed for name, ps in pids.items()
        }
        for role in roles:
            assert role.process.poll() is None, f"{role.name} stopped while it was measured"
    finally:
        for role in roles:
            role.process.terminate()
        for role in roles:
            role.process.wait(30)
    for name, share in shares.items():
        print(f"idle CPU of {name}: {100 * share:.2f} % of a core over {MEASURE:g} s")
    yield shares


def _share(shares: dict[str, float], starts: str) -> float:
    (share,) = [value for name, value in shares.items() if name.startswith(starts)]
    return share


def test_a_chief_waiting_for_workers_after_its_round_deadline_is_idle(idle_shares: dict[str, float]) -> None:
    assert _share(idle_shares, "chief") <= MAX_SHARE


def test_a_worker_waiting_for_the_chief_is_idle(idle_shares: dict[str, float]) -> None:
    assert _share(idle_shares, "worker") <= MAX_SHARE


def test_a_device_bridge_in_lockstep_waiting_for_commands_is_idle(idle_shares: dict[str, float]) -> None:
    assert _share(idle_shares, "device bridge") <= MAX_SHARE


@pytest.mark.parametrize("prefer", ["mosquitto", "amqtt"])
def test_fleetrl_broker_with_nobody_connected_is_idle(idle_shares: dict[str, float], prefer: str) -> None:
    assert _share(idle_shares, f"fleetrl broker --prefer {prefer}") <= MAX_SHARE
