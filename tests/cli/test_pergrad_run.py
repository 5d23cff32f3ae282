"""The per-step scheme end to end: the same seeded run gives the same scores over the in-process bus and
over a real broker, every worker ends with the same policy, and settings that cannot work are refused
first."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import Fleetrl, last_line
from safetensors.numpy import load_file

pytestmark = pytest.mark.slow
RUN = ["train", "--env", "cartpole", "--units", "2", "--scheme", "pergrad", "--preset", "standard"]


def scores(out: Path) -> list[tuple[str, str, str, str]]:
    with (out / "metrics.csv").open(newline="") as f:
        return sorted((r["worker"], r["round"], r["score"], r["actor_loss"]) for r in csv.DictReader(f))


@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_pergrad_over_mosquitto_plays_the_in_process_run_and_keeps_one_policy(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    local, mqtt = tmp_path / "local", tmp_path / "mqtt"
    for out, transport in ((local, "local"), (mqtt, "mqtt")):
        done = fleetrl(*RUN, "--max-rounds", "4", "--transport", transport, "--no-live", "--out", str(out))
        assert done.returncode == 0, done.stderr
    assert len(scores(local)) == 8 and scores(local) == scores(mqtt)
    first, second = (load_file(str(local / "models" / f"worker-{k}.safetensors")) for k in (0, 1))
    assert all(np.array_equal(first[name], second[name]) for name in first)  # one policy, two units


def test_pergrad_refuses_a_preset_whose_steps_differ_before_anything_starts(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    out = tmp_path / "run"
    preset = fleetrl(*RUN[:-1], "paper-code", "--out", str(out))
    assert preset.returncode == 2 and "optimisers = 'per_model'" in last_line(preset), preset.stderr
    assert "--scheme fedavg or paper" in last_line(preset)  # what to do instead
    assert not out.exists()
