"""Issue 14 ("idle means idle"): every long-running role, once it is waiting, uses at most 1 % of a core.

Each role runs as its own process (``python -m fleetrl.cli.main ROLE``, no wrapper); the test waits until the
role announced itself on the broker (it is then waiting), then reads the role process's own CPU time (utime +
stime in /proc/<pid>/stat) over MEASURE seconds.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleetrl.federation.topics import status_topic
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


def cpu_share(pids: list[int], seconds: float = MEASURE) -> float:
    """The share of one core the processes used together over the next ``seconds``."""
    before, started = sum(cpu_seconds(p) for p in pids), time.monotonic()
    time.sleep(seconds)
    return (sum(cpu_seconds(p) for p in pids) - before) / (time.monotonic() - started)


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


def measure(
    role: subprocess.Popen[str], ready: Callable[[], None], name: str, children: bool = False
) -> float:
    try:
        ready()
        time.sleep(1.5)  # past the chief's 1 s round deadline, into plain waiting
        pids = [role.pid, *(_children(role.pid) if children else [])]
        share = cpu_share(pids)
        assert role.poll() is None, "the role stopped while it was measured"
    finally:
        role.terminate()
        role.wait(30)
    print(f"idle CPU of {name}: {100 * share:.2f} % of a core over {MEASURE:g} s")
    return share


def _children(pid: int) -> list[int]:
    found = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return [int(p) for p in found]


def test_a_chief_waiting_for_workers_after_its_round_deadline_is_idle(broker: EmbeddedBroker) -> None:
    role = start_role(
        "chief", "--broker", broker.url, "--run-id", "idle-chief", "--workers", "2", "--env", "cartpole",
        "--round-timeout", "1", "--idle-timeout", "100",
    )  # fmt: skip
    ready = lambda: wait_for_retained(broker.url, status_topic("idle-chief", "chief"), role)  # noqa: E731
    assert measure(role, ready, "chief (waiting for workers, round deadline passed)") <= MAX_SHARE


def test_a_worker_waiting_for_the_chief_is_idle(broker: EmbeddedBroker, tmp_path: Path) -> None:
    role = start_role(
        "worker", "--broker", broker.url, "--run-id", "idle-worker", "--worker-id", "0", "--env", "cartpole",
        "--out", str(tmp_path / "w0"), "--reply-timeout", "100",
    )  # fmt: skip
    ready = lambda: wait_for_retained(broker.url, status_topic("idle-worker", "0"), role)  # noqa: E731
    assert measure(role, ready, "worker (waiting for the chief's welcome)") <= MAX_SHARE


def test_a_device_bridge_in_lockstep_waiting_for_commands_is_idle(broker: EmbeddedBroker) -> None:
    role = start_role(
        "device", "--broker", broker.url, "--run-id", "idle-dev", "--unit", "0", "--env", "cartpole"
    )
    ready = lambda: wait_for_retained(broker.url, device_topic("idle-dev", 0, "status"), role)  # noqa: E731
    assert measure(role, ready, "device bridge (lockstep, no commands)") <= MAX_SHARE


@pytest.mark.parametrize("prefer", ["mosquitto", "amqtt"])
def test_fleetrl_broker_with_nobody_connected_is_idle(prefer: str) -> None:
    role = start_role("broker", "--prefer", prefer)

    def ready() -> None:
        assert role.stdout is not None
        line = role.stdout.readline()
        assert "broker listening" in line, line

    name = (
        f"fleetrl broker --prefer {prefer} (with its mosquitto child)"
        if prefer == "mosquitto"
        else ("fleetrl broker --prefer amqtt (in-process broker)")
    )
    assert measure(role, ready, name, children=prefer == "mosquitto") <= MAX_SHARE
