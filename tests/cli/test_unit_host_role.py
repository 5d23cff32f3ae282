"""Unit hosts as standalone roles (docs/deploy.md, "Unit hosts on several machines"): ``fleetrl chief
--units-per-host U`` waits for the hosts host-0, host-U, …, each a ``fleetrl worker --units U`` process; two
such hosts on a real broker play the rows of ``fleetrl train`` with the same hosts; what cannot be a host is
refused in one line before anything starts."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.transport.broker import EmbeddedBroker

RUN = ["--env", "cartpole", "--preset", "standard", "--seed", "3", "--max-rounds", "3"]
"""what the chief, the hosts and the in-process run share"""
EVERY_EXCHANGE = ("--quorum", "1")
"""the chief's and the in-process run's: every exchange waits for both hosts"""


def played(*outs: Path) -> set[tuple[str, str, str, str]]:
    """Every (unit, round, score, event) the run directories' metrics.csv hold."""
    rows: set[tuple[str, str, str, str]] = set()
    for out in outs:
        with (out / "metrics.csv").open(newline="") as f:
            rows |= {(r["worker"], r["round"], r["score"], r["event"]) for r in csv.DictReader(f)}
    return rows


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_two_standalone_hosts_play_the_rows_of_the_train_command_s_hosts(tmp_path: Path) -> None:
    base = [sys.executable, "-m", "fleetrl.cli.main"]
    with EmbeddedBroker("mosquitto") as broker:
        url = ["--broker", broker.url, "--run-id", "hosts", *RUN]
        roles = [[*base, "chief", *url, *EVERY_EXCHANGE, "--workers", "4", "--units-per-host", "2"]]
        for k in ("0", "2"):
            roles.append(
                [*base, "worker", *url, "--worker-id", k, "--units", "2", "--out", str(tmp_path / k)]
            )
        procs = [subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE) for argv in roles]
        codes = [p.wait(timeout=600) for p in procs]
        outs = [p.communicate() for p in procs]
    assert codes == [0, 0, 0], [err[-800:] for _, err in outs]
    ended = json.loads(outs[0][0].decode().strip().splitlines()[-1])
    assert ended["rounds"] == 3 and not ended["rejections"] and not ended["dropouts"]
    assert "W={host-0,host-2}" in outs[0][1].decode()  # two members, four units
    in_process = tmp_path / "train"
    train = ["train", *RUN, *EVERY_EXCHANGE, "--units", "4", "--units-per-host", "2", "--mode", "federated"]
    assert main([*train, "--transport", "local", "--no-live", "--out", str(in_process)]) == 0
    mine = played(tmp_path / "0", tmp_path / "2")
    assert {(w, r) for w, r, _, _ in mine} == {(str(u), str(r)) for u in range(4) for r in (1, 2, 3)}
    assert mine == played(in_process)
    for k, units in (("0", (0, 1)), ("2", (2, 3))):
        host = tmp_path / k
        assert sorted(json.loads((host / "summary.json").read_text())["workers"]) == [str(u) for u in units]
        assert all((host / "models" / f"worker-{u}.safetensors").exists() for u in units)


@pytest.mark.parametrize(
    ("role", "extra", "words"),
    [
        ("worker", ("--units", "0"), "--units = 0: must be at least 1"),
        ("worker", ("--units", "2", "--scheme", "fedavg"), "--units = 2: a unit host is one policy"),
        ("worker", ("--units", "2", "--resume"), "--units = 2: a unit host keeps no checkpoints"),
        ("worker", ("--units", "2", "--unit", "5"), "--units = 2: a unit host's units are its ids"),
        ("worker", ("--units", "2", "--device-link", "mqtt"), "--units = 2: a standalone unit host runs"),
        ("chief", ("--units-per-host", "2", "--scheme", "fedavg"), "--units-per-host = 2: a unit host is"),
        ("chief", ("--units-per-host", "0"), "--units-per-host = 0: must be at least 1"),
    ],
)
def test_what_cannot_be_a_unit_host_is_refused_in_one_line_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], role: str, extra: tuple[str, ...], words: str
) -> None:
    out = tmp_path / "out"
    ids = ("--workers", "4") if role == "chief" else ("--worker-id", "0")
    argv = [role, "--broker", "mqtt://127.0.0.1:9", "--run-id", "r", "--env", "cartpole", *ids]
    argv += ["--out", str(out)]
    assert main([*argv, *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err) and words in err[-1], err
    assert not out.exists()
