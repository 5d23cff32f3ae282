"""The continuous QUBE task through the launcher: a federated run of Gaussian-head workers, each scheme that
shares whole tensors keeping one policy, and a model refused by a discrete env (and the other way round)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import Fleetrl, last_line
from safetensors.numpy import load_file

pytestmark = pytest.mark.slow
RUN = ["train", "--env", "qube-continuous", "--units", "2", "--mode", "federated", "--preset", "standard"]


@pytest.mark.parametrize("scheme", ["pergrad", "fedavg"])
def test_a_continuous_fleet_trains_federated_and_its_policy_is_refused_by_the_discrete_task(
    tmp_path: Path, fleetrl: Fleetrl, scheme: str
) -> None:
    out = tmp_path / scheme
    run = fleetrl(*RUN, "--scheme", scheme, "--transport", "local", "--max-rounds", "3", "--no-live",
                  "--out", str(out))  # fmt: skip
    assert run.returncode == 0, run.stderr
    with (out / "metrics.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 and all(float(r["score"]) >= 1 for r in rows)
    first, second = (load_file(str(out / "models" / f"worker-{k}.safetensors")) for k in (0, 1))
    assert "policy_log_std" in first  # the Gaussian head's σ is part of the shared model
    assert all(np.array_equal(first[name], second[name]) for name in first)  # one fleet policy

    model = str(out / "models" / "worker-0.safetensors")
    fits = fleetrl("evaluate", model, "--env", "qube-continuous", "--unit", "5", "--episodes", "1")
    assert fits.returncode == 0, fits.stderr
    wrong = fleetrl("evaluate", model, "--env", "qube", "--unit", "5", "--episodes", "1")
    assert wrong.returncode == 2
    assert "Box(low=[-3.0], high=[3.0]) actions; env 'qube' has 4 and Discrete(3)" in last_line(wrong)
