"""``fleetrl train --env cartpole --fleet-profile wide`` end to end: two rounds, the profile recorded, the
same rows with the units in one unit host (stepped in its batch), other rows than the standard fleet's; and
``fleetrl evaluate`` runs the model on a wide unit."""

import csv
import json
from pathlib import Path

import pytest

from fleetrl.cli.main import main


def train(out: Path, *extra: str) -> list[tuple[str, str, str]]:
    """(round, worker, score) of a 2-unit federated CartPole run of 2 rounds on the in-process bus."""
    argv = ["train", "--env", "cartpole", "--units", "2", "--preset", "standard", "--seed", "3",
            "--max-rounds", "2", "--mode", "federated", "--transport", "local", "--no-live",
            "--out", str(out), *extra]  # fmt: skip
    assert main(argv) == 0
    return sorted((r["round"], r["worker"], r["score"]) for r in csv.DictReader((out / "metrics.csv").open()))


@pytest.mark.slow
def test_a_wide_cartpole_fleet_trains_two_rounds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wide = train(tmp_path / "wide", "--fleet-profile", "wide")
    assert [(r, w) for r, w, _ in wide] == [("1", "0"), ("1", "1"), ("2", "0"), ("2", "1")]
    config = json.loads((tmp_path / "wide" / "config.json").read_text())
    assert config["fleet_profile"] == config["result_settings"]["fleet_profile"] == "wide"
    assert train(tmp_path / "host", "--fleet-profile", "wide", "--units-per-host", "2") == wide
    assert train(tmp_path / "standard")[:2] != wide[:2]  # the first round, before any update: other units
    capsys.readouterr()
    model = str(tmp_path / "wide" / "models" / "worker-1.safetensors")
    evaluate = ["evaluate", model, "--env", "cartpole", "--unit", "1", "--fleet-profile", "wide"]
    assert main([*evaluate, "--episodes", "2"]) == 0
    assert len(json.loads(capsys.readouterr().out)["scores"]) == 2
