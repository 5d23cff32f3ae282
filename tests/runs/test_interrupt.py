"""Ctrl-C (SIGINT) in the middle of `fleetrl train` leaves a valid, partial run directory."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleetrl.runs.records import read_metrics

pytestmark = [pytest.mark.slow, pytest.mark.mqtt]  # `fleetrl train` processes, federated over MQTT


@pytest.mark.timeout(180)
@pytest.mark.parametrize("mode", ["individual", "federated"])
def test_sigint_leaves_a_valid_partial_run(tmp_path: Path, mode: str) -> None:
    out = tmp_path / "run"
    argv = [
        sys.executable,
        "-m",
        "fleetrl.cli.main",
        "train",
        "--env",
        "cartpole",
        "--units",
        "2",
        "--mode",
        mode,
        "--preset",
        "standard",
        "--max-rounds",
        "100000",
        "--out",
        str(out),
        "--no-live",
    ]
    child = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        metrics = out / "metrics.csv"
        if metrics.exists() and {r.worker for r in read_metrics(metrics)} == {0, 1}:
            break  # both workers have reported a round
        time.sleep(0.2)
    assert child.poll() is None, child.communicate()
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["rounds"] >= 1
    records = read_metrics(out / "metrics.csv")
    assert {r.worker for r in records} == {0, 1}
    assert (out / "scores.png").is_file() and "run directory" in stdout
    for k in (0, 1):
        assert (out / "models" / f"worker-{k}.safetensors").stat().st_size > 1000
