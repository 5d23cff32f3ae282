"""A worker's checkpoint is refused by a worker built with other settings (the scheme and its parameters
included), naming what differs; with the same settings it restores the learner."""

from dataclasses import replace
from pathlib import Path

import pytest
import torch

from fleetrl.runs.checkpoints import WorkerCheckpoint
from fleetrl.runs.factory import make_learner
from fleetrl.runs.settings import LearningSettings
from fleetrl.runs.spec import WorkerSpec


def spec(tmp_path: Path, **changes: object) -> WorkerSpec:
    learning = LearningSettings(
        env="cartpole", preset="standard", seed=3, fleet_seed=0, max_rounds=5, scheme="fedavgm",
        scheme_params={"momentum": 0.5, "server_lr": 1.0},
    )  # fmt: skip
    return WorkerSpec(worker=0, unit=0, learning=replace(learning, **changes), out=str(tmp_path))  # type: ignore[arg-type]


def test_a_checkpoint_loads_into_the_same_worker_and_is_refused_by_another_scheme(tmp_path: Path) -> None:
    saved_spec = spec(tmp_path)
    learner = make_learner(saved_spec)
    WorkerCheckpoint(tmp_path / "ckpt", saved_spec, "run").save(learner, next_round=4)

    again = make_learner(saved_spec)
    with torch.no_grad():
        for p in again.agent.net.parameters():
            p.zero_()
    assert WorkerCheckpoint(tmp_path / "ckpt", saved_spec, "run").load(again).next_round == 4
    for a, b in zip(learner.agent.net.parameters(), again.agent.net.parameters(), strict=True):
        assert torch.equal(a, b)

    for changes, named in (
        ({"scheme": "fedavg", "scheme_params": {}}, "scheme: checkpoint 'fedavgm', now 'fedavg'"),
        ({"scheme_params": {"momentum": 0.9, "server_lr": 1.0}}, "scheme_params: checkpoint"),
        ({"preset": "paper"}, "preset: checkpoint 'standard', now 'paper'"),
    ):
        other = spec(tmp_path, **changes)
        with pytest.raises(ValueError, match="checkpoint was written with other settings") as caught:
            WorkerCheckpoint(tmp_path / "ckpt", other, "run").load(make_learner(other))
        assert named in str(caught.value)
