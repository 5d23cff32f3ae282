"""A fleet whose units each keep an own part (``--set own_part=…``), per step and per round: the shared part
stays what the scheme makes it (one policy under pergrad), each unit's own offsets are its own, in its model
file, and survive a restart from its checkpoint."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from cli_helpers import Fleetrl
from safetensors.numpy import load_file

from fleetrl.agent.state import learner_state, load_learner_state
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.factory import make_learner
from fleetrl.runs.spec import WorkerSpec

RUN = ["train", "--env", "cartpole", "--units", "2", "--transport", "local", "--no-live", "--max-rounds", "3"]


def _models(out: Path) -> list[dict[str, np.ndarray]]:
    return [load_file(str(out / "models" / f"worker-{k}.safetensors")) for k in (0, 1)]


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["pergrad", "fedavg"])
def test_each_unit_keeps_its_own_offsets_beside_the_shared_part(
    tmp_path: Path, fleetrl: Fleetrl, scheme: str
) -> None:
    out = tmp_path / scheme
    done = fleetrl(*RUN, "--scheme", scheme, "--set", "own_part=biases", "--out", str(out))
    assert done.returncode == 0, done.stderr
    first, second = _models(out)
    own = [name for name in first if name.startswith("own.")]
    assert sorted(own) == ["own.policy_bias", "own.trunk_0_bias", "own.trunk_1_bias", "own.trunk_2_bias",
                           "own.value_bias"]  # fmt: skip
    assert all(np.any(first[name]) for name in own)
    assert not all(np.array_equal(first[name], second[name]) for name in own)  # each unit's own
    if scheme == "pergrad":  # one shared policy: every shared tensor equal
        assert all(np.array_equal(first[name], second[name]) for name in first if name not in own)


def test_the_own_part_survives_a_restart_from_the_checkpoint(tmp_path: Path) -> None:
    learning = LearningSettings(
        env="cartpole",
        seed=3,
        max_rounds=50,
        scheme="fedavg",
        overrides={"memory_size": 64, "batch_size": 16, "own_part": "heads"},
    )
    spec = WorkerSpec(worker=1, unit=1, out=str(tmp_path), learning=learning)
    original = make_learner(spec)
    for _ in range(3):
        original.play_round()
    assert any(torch.count_nonzero(v) for v in original.agent.net.own.values())
    fields, tensors = learner_state(original)
    resumed = make_learner(spec)
    load_learner_state(resumed, fields, tensors)
    for key, offset in original.agent.net.own.items():
        assert torch.equal(resumed.agent.net.own[key], offset)
    assert [original.play_round().score for _ in range(2)] == [resumed.play_round().score for _ in range(2)]
    for key, offset in original.agent.net.own.items():
        assert torch.equal(resumed.agent.net.own[key], offset)  # its own Adam state came back too
