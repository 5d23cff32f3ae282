"""Continuous units behind MQTT device bridges, end to end: ``fleetrl train --device-link mqtt`` of the
continuous QUBE task and of a user's unit type (slider_units.py, its bridges serving ``--device-driver``),
federated and in worker processes, every worker's rounds recorded and every bridge closed cleanly; and
``fleetrl device --driver package.module:function`` serving the user's unit to a link in another process."""

from __future__ import annotations

import csv
import json
import re
import threading
from pathlib import Path

import numpy as np
import pytest
from device_process import device_process
from slider_units import DRIVER, FACTORY, SliderEnv

from fleetrl.cli.main import main
from fleetrl.link.mqtt import open_mqtt_link
from fleetrl.transport.broker import EmbeddedBroker

pytestmark = [pytest.mark.slow, pytest.mark.mqtt]

REPO = Path(__file__).resolve().parents[2]
SLIDER = ["--env", FACTORY, "--device-driver", DRIVER, "--target-score", "95"]
CLOSED = re.compile(r"bridge for unit (\d+) closed \(BridgeStats\(commands=(\d+), rejected=(\d+)")


@pytest.fixture(autouse=True)
def _from_the_repository(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # the slider's modules are imported from the current directory


def train(out: Path, mode: str, rounds: int, *argv: str) -> list[tuple[int, int, float]]:
    """Train 2 units; every worker's (worker, round, score), sorted."""
    argv = ("train", "--units", "2", "--mode", mode, "--preset", "standard", "--max-rounds", str(rounds),
            "--no-live", "--out", str(out), *argv)  # fmt: skip
    assert main(list(argv)) == 0
    with (out / "metrics.csv").open(newline="") as f:
        return sorted((int(r["worker"]), int(r["round"]), float(r["score"])) for r in csv.DictReader(f))


def train_over_bridges(out: Path, mode: str, rounds: int, *argv: str) -> list[tuple[int, int, float]]:
    """Train 2 units, each behind a device bridge; check the rounds and the bridges' clean shutdown."""
    scores = train(out, mode, rounds, "--device-link", "mqtt", *argv)
    assert [(w, r) for w, r, _ in scores] == [(w, r) for w in (0, 1) for r in range(1, rounds + 1)]
    closed = {int(unit): (int(n), int(rejected)) for unit, n, rejected in CLOSED.findall(
        (out / "logs" / "run.log").read_text())}  # fmt: skip
    assert sorted(closed) == [0, 1] and all(n > rounds and rejected == 0 for n, rejected in closed.values())
    assert not [t.name for t in threading.enumerate() if t.name.startswith("fleetrl-bridge")]
    assert json.loads((out / "config.json").read_text())["device_link"] == "mqtt"
    return scores


def test_the_continuous_qube_task_trains_federated_behind_bridges(tmp_path: Path) -> None:
    argv = ("--env", "qube-continuous", "--transport", "local")
    over_bridges = train_over_bridges(tmp_path / "run", "federated", 3, *argv)
    assert over_bridges == train(tmp_path / "in-process", "federated", 3, *argv)  # lockstep: the same units


def test_a_user_unit_type_trains_federated_behind_bridges(tmp_path: Path) -> None:
    over_bridges = train_over_bridges(tmp_path / "run", "federated", 3, *SLIDER, "--transport", "local")
    in_process = train(
        tmp_path / "in-process", "federated", 3, *SLIDER[:2], *SLIDER[4:], "--transport", "local"
    )
    assert over_bridges == in_process
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["result_settings"]["device_driver"] == DRIVER


def test_a_user_unit_type_trains_in_worker_processes_behind_bridges(tmp_path: Path) -> None:
    train_over_bridges(tmp_path / "run", "individual", 2, *SLIDER)


def test_fleetrl_device_serves_a_user_driver(tmp_path: Path) -> None:
    with EmbeddedBroker() as broker, device_process(broker.url, "own", DRIVER, 1, 4, REPO):
        env = SliderEnv(1, 4, link=open_mqtt_link(broker.url, "own", 1, obs_size=2, online_timeout=30.0))
        in_process = SliderEnv(1, 4)
        for over in (env, in_process):
            over.reset(seed=3)
        for force in (1.0, -0.5, 0.25):
            action = np.array([force], dtype=np.float32)
            assert np.array_equal(env.step(action)[0], in_process.step(action)[0])
        env.close()
