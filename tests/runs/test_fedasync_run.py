"""`fleetrl train --scheme fedasync` end to end: in-process and over the embedded broker, a short budget (the
pipeline, not the science)."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.transport.broker import EmbeddedBroker

pytestmark = pytest.mark.slow  # whole `fleetrl train` runs

ROUNDS = 5


def train(out: Path, *extra: str) -> dict:
    argv = ["train", "--env", "cartpole", "--units", "3", "--preset", "standard", "--seed", "3",
            "--max-rounds", str(ROUNDS), "--out", str(out), "--no-live", "--mode", "federated",
            "--scheme", "fedasync", *extra]  # fmt: skip
    assert main(argv) == 0
    return json.loads((out / "summary.json").read_text())


def check_run(out: Path, summary: dict) -> None:
    """Every unit played its M rounds, each recorded once; the chief took each contribution once."""
    rows = list(csv.DictReader((out / "metrics.csv").open()))
    assert sorted((int(r["worker"]), int(r["round"])) for r in rows) == [
        (w, r) for w in range(3) for r in range(1, ROUNDS + 1)
    ]
    assert {r["event"] for r in rows} == {"async_model"}
    chief = json.loads((out / "chief.json").read_text())
    assert chief["scheme"] == "fedasync" and chief["end_reason"] == f"reached M={ROUNDS} rounds"
    counts = chief["contributions"]
    assert {w: (c["applied"], c["last_round"]) for w, c in counts.items()} == {
        w: (ROUNDS, ROUNDS) for w in ("0", "1", "2")
    }
    assert all(0 <= c["staleness_max"] <= 2 * ROUNDS for c in counts.values())
    assert summary["rig_seconds"]["rule"] == "nobody waits"


def test_an_in_process_fedasync_run_ends_properly(tmp_path: Path) -> None:
    out = tmp_path / "run"
    check_run(out, train(out, "--transport", "local"))


@pytest.mark.mqtt
def test_a_fedasync_run_over_the_embedded_broker_ends_properly(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with EmbeddedBroker() as broker:
        check_run(out, train(out, "--broker", broker.url))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--round-timeout", "5"), "no round barrier"),
        (("--scheme-param", "alpha=0"), "must be in (0, 1]"),
        (("--aggregation", "median"), "does not apply"),
    ],
)
def test_bad_settings_are_refused_before_the_run_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], message: str
) -> None:
    argv = ["train", "--env", "cartpole", "--units", "2", "--max-rounds", "2", "--out", str(tmp_path / "x"),
            "--no-live", "--mode", "federated", "--scheme", "fedasync", *extra]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def role(name: str, url: str, out: Path, *extra: str) -> subprocess.Popen[bytes]:
    argv = [sys.executable, "-m", "fleetrl.cli.main", name, "--broker", url, "--run-id", "async",
            "--env", "cartpole", "--preset", "standard", "--max-rounds", str(ROUNDS), "--scheme", "fedasync",
            "--out", str(out), *extra]  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    log = (out.parent / f"{out.name}.{name}.log").open("ab")
    return subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def rounds(out: Path) -> list[int]:
    path = out / "metrics.csv"
    return [int(r["round"]) for r in csv.DictReader(path.open())] if path.exists() else []


@pytest.mark.mqtt
@pytest.mark.mosquitto
@pytest.mark.timeout(420)
def test_chief_and_worker_processes_with_the_chief_killed_and_resumed(tmp_path: Path) -> None:
    chief_out = tmp_path / "chief"
    procs: list[subprocess.Popen[bytes]] = []
    with EmbeddedBroker("mosquitto") as broker:
        try:
            chief = ["--workers", "2", "--dropout-grace", "120"]
            procs.append(role("chief", broker.url, chief_out, *chief))
            procs += [role("worker", broker.url, tmp_path / f"w{k}", "--worker-id", str(k)) for k in (0, 1)]
            deadline = time.monotonic() + 150
            while len(rounds(tmp_path / "w0")) < 2:
                assert time.monotonic() < deadline and procs[0].poll() is None, "no round 2 of worker 0"
                time.sleep(0.05)
            os.kill(procs[0].pid, signal.SIGKILL)
            assert procs[0].wait(30) == -signal.SIGKILL
            procs.append(role("chief", broker.url, chief_out, *chief, "--resume"))
            codes = [p.wait(240) for p in procs[1:]]
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
    assert codes == [0, 0, 0]
    for k in (0, 1):  # every round of each worker recorded once, and taken once by the chief
        assert rounds(tmp_path / f"w{k}") == list(range(1, ROUNDS + 1))
    counts = json.loads((chief_out / "chief.json").read_text())["contributions"]
    assert {w: (c["applied"], c["last_round"]) for w, c in counts.items()} == {
        "0": (ROUNDS, ROUNDS),
        "1": (ROUNDS, ROUNDS),
    }
