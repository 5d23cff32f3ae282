"""Must show (issue 7): kill -9 of a role, then ``--resume``: the run completes, no round lost or doubled."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import pytest

from fleetrl.federation.worker import FederatedWorker, RoundRecord, WorkerSummary
from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

HERE = Path(__file__).resolve().parent
needs_mosquitto = pytest.mark.skipif(find_mosquitto() is None, reason="mosquitto not installed")


class ChiefProcess:
    """tests/federation/fake_chief_process.py, its printed lines read on a thread."""

    def __init__(
        self, url: str, run_id: str, workers: str, rounds: int, directory: Path, *extra: str
    ) -> None:
        argv = [sys.executable, str(HERE / "fake_chief_process.py"), url, run_id, workers, str(rounds)]
        self.proc = subprocess.Popen(
            [*argv, str(directory), *extra],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
        )  # fmt: skip
        self.lines: list[str] = []
        assert self.proc.stdout is not None
        threading.Thread(target=self._read, args=(self.proc.stdout,), daemon=True).start()

    def _read(self, stdout: IO[str]) -> None:
        for line in stdout:
            self.lines.append(line.strip())

    def closed(self) -> list[int]:
        return [int(line.split()[1]) for line in self.lines if line.startswith("closed ")]

    def kill_after_round(self, rnd: int, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while max(self.closed(), default=0) < rnd:
            assert time.monotonic() < deadline, f"chief stuck: {self.lines[-3:]}"
            time.sleep(0.01)
        os.kill(self.proc.pid, signal.SIGKILL)
        assert self.proc.wait(30) == -signal.SIGKILL

    def summary(self) -> dict[str, Any]:
        assert self.proc.wait(60) == 0
        (line,) = [line for line in self.lines if line.startswith("summary ")]
        result: dict[str, Any] = json.loads(line.removeprefix("summary "))
        return result


def run_workers(
    make_transport: Callable[[], Any], learners: dict[str, Any], run_id: str, rounds: int
) -> tuple[dict[str, list[RoundRecord]], dict[str, WorkerSummary], list[threading.Thread]]:
    records: dict[str, list[RoundRecord]] = {w: [] for w in learners}
    summaries: dict[str, WorkerSummary] = {}

    def body(w: str) -> None:
        worker = FederatedWorker(
            learners[w], make_transport(), run_id=run_id, worker_id=w, max_rounds=rounds,
            on_record=records[w].append, reply_timeout=90.0, resend_interval=0.5,
        )  # fmt: skip
        summaries[w] = worker.run()

    threads = [threading.Thread(target=body, args=(w,), daemon=True) for w in learners]
    for thread in threads:
        thread.start()
    return records, summaries, threads


@pytest.mark.mqtt
@pytest.mark.timeout(240)
@needs_mosquitto
def test_kill_9_of_the_chief_twice_then_resume_loses_and_doubles_no_round(
    fleet_runner: Callable[..., Any], fake_fleet: Callable[..., dict[str, Any]], tmp_path: Path
) -> None:
    """Killed before and after the transfer of round 4, the chief resumes from its checkpoint each time; the
    workers' rounds, scores and events are exactly those of an uninterrupted run on the local bus."""
    rounds = 10
    local = fleet_runner(LocalBus().client, fake_fleet(), max_rounds=rounds)
    run_id, workers = "resume", "1,2,3"
    with EmbeddedBroker("mosquitto") as broker:
        url = broker.url
        chief = ChiefProcess(url, run_id, workers, rounds, tmp_path)
        records, summaries, threads = run_workers(
            lambda: MqttTransport(url, reconnect_delay=(1, 2), clean_session=False),
            fake_fleet(pause=0.15), run_id, rounds,
        )  # fmt: skip
        try:
            chief.kill_after_round(2)
            chief = ChiefProcess(url, run_id, workers, rounds, tmp_path, "--resume")
            chief.kill_after_round(5)
            chief = ChiefProcess(url, run_id, workers, rounds, tmp_path, "--resume")
            summary = chief.summary()
            for thread in threads:
                thread.join(60)
        finally:
            if chief.proc.poll() is None:
                chief.proc.kill()
    assert not any(t.is_alive() for t in threads), "a worker hung"
    assert records == local.records  # every round once, with the same numbers
    assert summaries["2"].reason == "transfer_out" and summaries["1"].reason == "transfer_out"
    assert summaries["3"].reason in ("run ended", f"reached M={rounds}")  # `done` may come before or after M
    assert summary["rounds"] == rounds and summary["end_reason"] == f"reached M={rounds} rounds"
    assert [(t["round"], t["from"]) for t in summary["transfers"]] == [(4, "2"), (7, "1")]
    assert summary["dropouts"] == [] and min(chief.closed()) > 5
