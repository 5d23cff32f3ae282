"""A learner's state saved between rounds and loaded into a fresh learner continues bit-identically."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fleetrl.agent.learner import Learner
from fleetrl.agent.state import learner_state, load_learner_state
from fleetrl.agent.statestore import StateError, StateStore
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.factory import make_learner
from fleetrl.runs.spec import WorkerSpec

SPEC = WorkerSpec(
    worker=1, unit=1, out="unused",
    learning=LearningSettings(env="cartpole", preset="standard", seed=3, max_rounds=50, scheme="paper",
                              overrides={"memory_size": 64, "batch_size": 16}),
)  # fmt: skip


def fingerprint(learner: Learner, rounds: int) -> list[tuple[float, int, float]]:
    """Scores, steps and actor-parameter checksums of the next ``rounds`` rounds."""
    out = []
    for _ in range(rounds):
        result = learner.play_round()
        out.append((result.score, result.steps, float(learner.agent.actor_parameters().sum())))
    return out


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_learner_resumed_from_its_state_plays_the_same_rounds(tmp_path: Path) -> None:
    original = make_learner(SPEC)
    fingerprint(original, 3)
    original.agent.apply_actor_gradient(np.full(original.agent.actor_parameters().size, 0.01, np.float32))
    store = StateStore(tmp_path, "worker")
    store.save(*learner_state(original))
    expected = fingerprint(original, 4)

    fields, tensors = StateStore(tmp_path, "worker").load()
    json.dumps(fields)  # the fields really are JSON
    resumed = make_learner(SPEC)
    load_learner_state(resumed, fields, tensors)
    assert resumed.rounds == 3 and resumed.criterion.history() == original.criterion.history()[:3]
    assert fingerprint(resumed, 4) == expected


@pytest.mark.timeout(60)
def test_the_store_commits_atomically_and_rejects_a_corrupt_blob(tmp_path: Path) -> None:
    store = StateStore(tmp_path, "chief")
    store.save({"round": 1}, {"a": np.arange(3, dtype=np.float32)})
    store.save({"round": 2}, {"a": np.arange(3, dtype=np.float32)})  # same tensors: same blob
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chief-1.safetensors", "chief.json"]
    store.save({"round": 3}, {"a": np.ones(3, dtype=np.float32)})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chief-2.safetensors", "chief.json"]
    (tmp_path / "chief-3.safetensors").write_bytes(b"left by a save killed before its commit")
    fields, tensors = StateStore(tmp_path, "chief").load()
    assert fields == {"round": 3} and tensors["a"].tolist() == [1.0, 1.0, 1.0]
    assert not (tmp_path / "chief-3.safetensors").exists()
    (tmp_path / "chief-2.safetensors").write_bytes(b"corrupt")
    with pytest.raises(StateError, match="does not match"):
        StateStore(tmp_path, "chief").load()
    with pytest.raises(FileNotFoundError):
        StateStore(tmp_path / "nowhere", "chief").load()
