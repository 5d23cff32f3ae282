"""Must show (issue 7): kill -9 of a role, then ``--resume``: the run completes, no round lost or doubled."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from conftest import worker_of

from fleetrl.federation.worker.runner import FederatedRound, WorkerSummary
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

HERE = Path(__file__).resolve().parent
FAKE_CHIEF = [sys.executable, str(HERE / "fake_chief_process.py")]


def kill_after_round(chief: Any, rnd: int) -> None:
    """kill -9 the chief process once it has printed ``closed N`` with N ≥ ``rnd``."""
    chief.wait_for("closed ", rnd, timeout=60.0)
    os.kill(chief.proc.pid, signal.SIGKILL)
    assert chief.proc.wait(30) == -signal.SIGKILL


def summary_of(chief: Any) -> dict[str, Any]:
    """The JSON the chief process printed after ``summary`` once it exited 0."""
    assert chief.stop(60) == 0
    (line,) = [line for line in chief.lines if line.startswith("summary ")]
    result: dict[str, Any] = json.loads(line.removeprefix("summary "))
    return result


def run_workers(
    make_transport: Callable[[], Any], learners: dict[str, Any], run_id: str, rounds: int
) -> tuple[dict[str, list[FederatedRound]], dict[str, WorkerSummary], list[threading.Thread]]:
    records: dict[str, list[FederatedRound]] = {w: [] for w in learners}
    summaries: dict[str, WorkerSummary] = {}

    def body(w: str) -> None:
        worker = worker_of(
            learners[w], make_transport(), run_id=run_id, worker_id=w, max_rounds=rounds,
            on_record=records[w].append, reply_timeout=90.0, resend_interval=0.5, scheme="paper",
        )  # fmt: skip
        summaries[w] = worker.run()

    threads = [threading.Thread(target=body, args=(w,), daemon=True) for w in learners]
    for thread in threads:
        thread.start()
    return records, summaries, threads


@pytest.mark.mqtt
@pytest.mark.timeout(240)
@pytest.mark.mosquitto
def test_kill_9_of_the_chief_twice_then_resume_loses_and_doubles_no_round(
    fleet_runner: Callable[..., Any],
    fake_fleet: Callable[..., dict[str, Any]],
    tmp_path: Path,
    line_process: Callable[[list[str]], Any],
) -> None:
    """Killed before and after the transfer of round 4, the chief resumes from its checkpoint each time; the
    workers' rounds, scores and events are exactly those of an uninterrupted run on the local bus."""
    rounds = 10
    local = fleet_runner(LocalBus().client, fake_fleet(), max_rounds=rounds)
    run_id, workers = "resume", "1,2,3"
    with EmbeddedBroker("mosquitto") as broker:
        url = broker.url
        argv = [*FAKE_CHIEF, url, run_id, workers, str(rounds), str(tmp_path)]
        chief = line_process(argv)
        records, summaries, threads = run_workers(
            lambda: MqttTransport(url, reconnect_delay=(1, 2), clean_session=False),
            fake_fleet(pause=0.15), run_id, rounds,
        )  # fmt: skip
        try:
            kill_after_round(chief, 2)
            chief = line_process([*argv, "--resume"])
            kill_after_round(chief, 5)
            chief = line_process([*argv, "--resume"])
            summary = summary_of(chief)
            for thread in threads:
                thread.join(60)
        finally:
            chief.kill()
    assert not any(t.is_alive() for t in threads), "a worker hung"
    assert records == local.records  # every round once, with the same numbers
    assert summaries["2"].reason == "transfer_out" and summaries["1"].reason == "transfer_out"
    assert summaries["3"].reason in ("run ended", f"reached M={rounds}")  # `done` may come before or after M
    assert summary["rounds"] == rounds and summary["end_reason"] == f"reached M={rounds} rounds"
    assert [(t["round"], t["from"]) for t in summary["transfers"]] == [(4, "2"), (7, "1")]
    assert summary["dropouts"] == [] and min(chief.numbers("closed ")) > 5
