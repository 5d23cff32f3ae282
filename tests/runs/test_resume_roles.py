"""``fleetrl chief/worker --resume`` end to end: a killed worker and a killed chief continue the run exactly.

Two runs of the same seeds share one mosquitto broker: run A undisturbed; in run B worker 1 is killed with
SIGKILL after its round 3 and the chief after round 5, and each is restarted with ``--resume``. B's
metrics.csv must equal A's row for row (every round once; same scores, steps, losses and events).
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from fleetrl.transport.broker import EmbeddedBroker

pytestmark = pytest.mark.slow  # chief and worker processes training CartPole

ROUNDS = 8
# The default scheme, pergrad: K exchanges per round, so a kill usually lands inside a round, whose closed
# steps the resumed worker replays against the chief's answers (docs/protocol.md, "Checkpoints and resume").
RUN = ["--env", "cartpole", "--preset", "standard", "--max-rounds", str(ROUNDS)]


def start(role: str, url: str, run_id: str, out: Path, *extra: str) -> subprocess.Popen[bytes]:
    argv = [sys.executable, "-m", "fleetrl.cli.main", role, "--broker", url, "--run-id", run_id, *RUN]
    out.parent.mkdir(parents=True, exist_ok=True)
    log = (out.parent / f"{out.name}.{role}.log").open("ab")
    return subprocess.Popen(
        [*argv, "--out", str(out), *extra], stdout=log, stderr=subprocess.STDOUT, start_new_session=True
    )


def chief(url: str, run_id: str, out: Path, *extra: str) -> subprocess.Popen[bytes]:
    return start("chief", url, run_id, out, "--workers", "2", "--dropout-grace", "120", *extra)


def worker(url: str, run_id: str, out: Path, k: int, *extra: str) -> subprocess.Popen[bytes]:
    return start("worker", url, run_id, out / f"w{k}", "--worker-id", str(k), "--seed", "5", *extra)


def rows(out: Path) -> list[dict[str, str]]:
    path = out / "metrics.csv"
    if not path.exists():
        return []
    with path.open(newline="") as f:
        return [{k: v for k, v in r.items() if k != "wall_time"} for r in csv.DictReader(f)]


def wait_until(
    done: Callable[[], bool], what: str, procs: list[subprocess.Popen[bytes]], timeout: float = 150.0
) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        failed = [p.args for p in procs if p.poll() not in (None, 0, -signal.SIGKILL)]
        assert not failed, f"a role failed while waiting for {what}: {failed}"
        time.sleep(0.05)


def kill9(proc: subprocess.Popen[bytes]) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    assert proc.wait(30) == -signal.SIGKILL


@pytest.mark.mqtt
@pytest.mark.timeout(420)
@pytest.mark.mosquitto
def test_kill_9_of_a_worker_and_of_the_chief_then_resume_gives_the_undisturbed_run(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    procs: list[subprocess.Popen[bytes]] = []
    with EmbeddedBroker("mosquitto") as broker:
        url = broker.url
        try:
            procs += [chief(url, "A", a / "chief"), worker(url, "A", a, 0), worker(url, "A", a, 1)]
            procs += [chief(url, "B", b / "chief"), worker(url, "B", b, 0), worker(url, "B", b, 1)]
            wait_until(lambda: len(rows(b / "w1")) >= 3, "round 3 of worker 1 in run B", procs)
            kill9(procs[5])
            procs.append(worker(url, "B", b, 1, "--resume"))
            log = b / "chief" / "chief.log"
            wait_until(
                lambda: log.exists() and "round 5: answered" in log.read_text(), "round 5 in run B", procs
            )
            kill9(procs[3])
            procs.append(chief(url, "B", b / "chief", "--resume"))
            codes = [p.wait(240) for p in procs if p.returncode is None]
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
    assert codes == [0] * len(codes)
    for k in (0, 1):
        expected = rows(a / f"w{k}")
        assert [int(r["round"]) for r in expected] == list(range(1, ROUNDS + 1))
        assert rows(b / f"w{k}") == expected, f"worker {k}"
    assert "after resume" in (b / "chief" / "chief.log").read_text()
