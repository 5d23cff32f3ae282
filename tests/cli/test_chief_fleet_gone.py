"""A ``fleetrl chief`` whose every worker dropped out (here its one worker, killed with -9: its last will says
it went offline) has no fleet left to train: it ends the run at once, says so in one line and exits 1 (a
command that could not do its job), its chief.json kept."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleetrl.transport.broker import EmbeddedBroker


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_a_chief_whose_every_worker_dropped_out_exits_1(tmp_path: Path) -> None:
    def start(*argv: str) -> subprocess.Popen[str]:
        return subprocess.Popen(
            [sys.executable, "-m", "fleetrl.cli.main", *argv],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip

    with EmbeddedBroker("mosquitto") as broker:
        common = ("--broker", broker.url, "--run-id", "gone", "--env", "cartpole", "--max-rounds", "400")
        chief = start(
            "chief", *common, "--workers", "1", "--dropout-grace", "0.5", "--out", str(tmp_path / "c")
        )
        worker = start("worker", *common, "--worker-id", "0", "--out", str(tmp_path / "w0"))
        try:
            rows = tmp_path / "w0" / "metrics.csv"
            deadline = time.monotonic() + 60
            while (
                time.monotonic() < deadline
                and len(rows.read_text().splitlines() if rows.exists() else []) < 3
            ):
                time.sleep(0.1)  # two rounds played: the worker is in the fleet
            worker.send_signal(signal.SIGKILL)
            worker.wait(10)
            _, err = chief.communicate(timeout=60)
        finally:
            for process in (worker, chief):
                if process.poll() is None:
                    process.kill()
    assert chief.returncode == 1, err
    assert err.strip().splitlines()[-1] == "fleetrl chief: error: run 'gone': every worker dropped out"
    record = json.loads((tmp_path / "c" / "chief.json").read_text())
    assert record["end_reason"] == "every worker dropped out" and record["dropouts"][0]["worker"] == "0"
