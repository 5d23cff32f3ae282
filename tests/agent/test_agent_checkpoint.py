"""Saving and loading agents: safetensors round trip and clear errors for bad files."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from safetensors.numpy import save_file

from fleetrl.agent.checkpoint import CheckpointError
from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent


def saved(tmp_path: Path, obs_dim: int = 4, n_actions: int = 2) -> tuple[PPOAgent, Path]:
    agent = PPOAgent(obs_dim, n_actions, get_preset("standard"), seed=5)
    agent.apply_actor_gradient(np.ones(agent.actor_parameters().size, dtype=np.float32))
    path = tmp_path / "models" / "worker-0.safetensors"
    agent.save(path)
    return agent, path


def test_round_trip_restores_policy_config_and_critic(tmp_path: Path) -> None:
    agent, path = saved(tmp_path)
    loaded = PPOAgent.load(path, obs_dim=4, n_actions=2)
    assert loaded.config == agent.config and loaded.seed == 5
    assert np.array_equal(loaded.actor_parameters(), agent.actor_parameters())
    assert np.array_equal(loaded.net.value.weight.detach().numpy(), agent.net.value.weight.detach().numpy())
    obs = np.array([0.01, 0.2, -0.03, 0.1], dtype=np.float32)
    assert loaded.act_greedy(obs) == agent.act_greedy(obs)
    assert not list(path.parent.glob("*.partial"))
    assert path.read_bytes()[:8] != b"\x80\x04\x95"  # not a pickle


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no model file"):
        PPOAgent.load(tmp_path / "nope.safetensors")


@pytest.mark.parametrize("damage", ["garbage", "truncated"])
def test_corrupt_file_is_a_clear_error(tmp_path: Path, damage: str) -> None:
    _, path = saved(tmp_path)
    data = path.read_bytes()
    path.write_bytes(b"this is not a model" if damage == "garbage" else data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="not a readable safetensors model file"):
        PPOAgent.load(path)


def test_foreign_safetensors_file(tmp_path: Path) -> None:
    path = tmp_path / "other.safetensors"
    save_file({"w": np.zeros(3, dtype=np.float32)}, str(path))
    with pytest.raises(CheckpointError, match="not a fleetrl agent model"):
        PPOAgent.load(path)


def test_model_for_another_env_is_refused(tmp_path: Path) -> None:
    _, path = saved(tmp_path, obs_dim=4, n_actions=2)
    with pytest.raises(CheckpointError, match="n_actions=2, but 3 is needed"):
        PPOAgent.load(path, obs_dim=4, n_actions=3)
    with pytest.raises(CheckpointError, match="obs_dim=4, but 5 is needed"):
        PPOAgent.load(path, obs_dim=5)


def test_tensors_that_do_not_fit_the_stated_architecture(tmp_path: Path) -> None:
    agent, path = saved(tmp_path)
    small = PPOAgent(4, 2, dataclasses.replace(get_preset("standard"), hidden=(8, 8, 8)), seed=0)
    small_path = tmp_path / "small.safetensors"
    small.save(small_path)
    # graft the small network's tensors under the big model's metadata
    from fleetrl.agent.checkpoint import read_checkpoint, write_checkpoint

    tensors, _ = read_checkpoint(small_path)
    _, metadata = read_checkpoint(path)
    write_checkpoint(path, tensors, metadata)
    with pytest.raises(CheckpointError, match=r"does not fit this architecture: trunk.0.weight has shape"):
        PPOAgent.load(path)
    assert agent.actor_parameters().size > small.actor_parameters().size
