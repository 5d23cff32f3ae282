"""The Gaussian actor head for a box of actions: log-probabilities, entropy, acting, memory, model files."""

import dataclasses
import math
from pathlib import Path

import gymnasium
import numpy as np
import pytest
import torch

from fleetrl.agent.action_space import ActionSpace, UnsupportedActionSpace
from fleetrl.agent.checkpoint import CheckpointError
from fleetrl.agent.config import PPOConfig, get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.memory import TrajectoryMemory
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.ppo import PPOAgent
from fleetrl.agent.state import learner_state, load_learner_state
from fleetrl.agent.statestore import StateStore

BOX = ActionSpace.box([-2.0, 0.0], [2.0, 10.0])  # centre (0, 5), half range (2, 5)
OBS_DIM = 3


def small_config() -> PPOConfig:
    return dataclasses.replace(get_preset("standard"), hidden=(16, 16), memory_size=64, batch_size=32)


def net(space: ActionSpace = BOX) -> ActorCritic:
    return ActorCritic(OBS_DIM, space, (8, 8), "tanh", torch.Generator().manual_seed(0))


def test_hand_computed_log_prob_and_entropy_of_a_zero_head() -> None:
    # head output 0: mean = centre (0, 5); log σ = log(half range) + 0, σ = (2, 5)
    model = net()
    head = torch.zeros(1, 2)
    action = torch.tensor([[1.0, 10.0]])
    log_prob, entropy = model.log_probs_and_entropies(head, action)
    half_log_2pi = 0.5 * math.log(2 * math.pi)
    by_hand = (-0.5 * 0.5**2 - math.log(2) - half_log_2pi) + (-0.5 * 1.0**2 - math.log(5) - half_log_2pi)
    assert log_prob.item() == pytest.approx(by_hand, abs=1e-5)
    assert entropy.item() == pytest.approx(2 * (0.5 + half_log_2pi) + math.log(2) + math.log(5), abs=1e-5)


def test_log_prob_and_entropy_match_torch_distributions() -> None:
    model = net()
    assert model.policy_log_std is not None
    with torch.no_grad():
        model.policy_log_std.copy_(torch.tensor([-0.7, 0.3]))
    obs = torch.randn(5, OBS_DIM, generator=torch.Generator().manual_seed(1))
    actions = torch.randn(5, 2, generator=torch.Generator().manual_seed(2)) * 3.0
    head, _ = model(obs)
    log_probs, entropy = model.log_probs_and_entropies(head, actions)
    mean, log_std = model.gaussian(head)
    normal = torch.distributions.Normal(mean, log_std.exp().expand_as(mean))
    assert torch.allclose(log_probs, normal.log_prob(actions).sum(-1), atol=1e-5)
    assert entropy.item() == pytest.approx(normal.entropy().sum(-1).mean().item(), abs=1e-5)


def test_fast_path_mean_sigma_sample_and_greedy_match_the_network() -> None:
    agent = PPOAgent(OBS_DIM, BOX, small_config(), seed=3)
    with torch.no_grad():
        agent.net.policy.bias.copy_(torch.tensor([5.0, -0.2]))  # mean beyond the box in component 0
    agent.refresh_policy()
    obs = np.array([0.1, -0.4, 0.3], dtype=np.float32)
    mean, log_std = agent.net.gaussian(agent.net(torch.from_numpy(obs)[None])[0])
    fast_mean, fast_sigma = agent._policy.gaussian(obs)
    assert np.allclose(fast_mean, mean.detach().numpy()[0], atol=1e-5)
    assert np.allclose(fast_sigma, log_std.exp().detach().numpy(), atol=1e-6)
    z = np.array([1.5, -0.5])
    sample = agent._policy.act_continuous(obs, z)
    assert sample.dtype == np.float32 and sample.shape == (2,)
    assert np.allclose(sample, fast_mean + fast_sigma * z, atol=1e-5)  # not clipped: what the memory keeps
    greedy = agent.act_greedy(obs)
    assert greedy[0] == 2.0 and greedy[1] == pytest.approx(np.clip(fast_mean[1], 0.0, 10.0), abs=1e-5)
    assert np.array_equal(agent.env_action(np.array([9.0, -1.0], dtype=np.float32)), [2.0, 0.0])


def test_sampled_actions_have_the_policy_mean_and_sigma_and_repeat_with_the_seed() -> None:
    draws = [PPOAgent(OBS_DIM, BOX, small_config(), seed=4) for _ in range(2)]
    obs = np.zeros(OBS_DIM, dtype=np.float32)
    samples = np.array([draws[0].act(obs) for _ in range(20000)])
    assert np.array_equal(samples[:50], np.array([draws[1].act(obs) for _ in range(50)]))
    mean, sigma = draws[0]._policy.gaussian(obs)
    assert np.allclose(samples.mean(0), mean, atol=4 * sigma / math.sqrt(20000))
    assert np.allclose(samples.std(0), sigma, rtol=0.03)


def test_memory_stores_float32_action_vectors_and_keeps_its_shapes() -> None:
    memory = TrajectoryMemory(3, obs_dim=2, grows=True, action_dim=2)
    obs = np.zeros(2, dtype=np.float32)
    for i in range(5):
        memory.add(obs, np.array([i, -i], dtype=np.float32), 1.0, obs, False, False)
    data = memory.transitions()
    assert data.actions.dtype == np.float32 and data.actions.shape == (5, 2)
    assert data.actions[:, 0].tolist() == [0, 1, 2, 3, 4]
    copy = TrajectoryMemory(3, obs_dim=2, grows=True, action_dim=2)
    copy.load_state_arrays(memory.state_arrays())
    assert np.array_equal(copy.transitions().actions, data.actions)
    assert TrajectoryMemory(3, obs_dim=2).transitions().actions.dtype == np.int64


def test_update_moves_the_log_std_and_the_federation_sees_it_in_the_actor_layout() -> None:
    agent = PPOAgent(OBS_DIM, BOX, small_config(), seed=0)
    assert agent.actor_layout()[-1] == ("policy_log_std", (2,))
    assert agent.actor_layout()[-3:-1] == [("policy.weight", (2, 16)), ("policy.bias", (2,))]
    assert agent.n_actions == 0 and agent.memory.transitions().actions.shape == (0, 2)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=OBS_DIM).astype(np.float32)
    for i in range(80):
        action = agent.act(obs)
        reward = -float(np.abs(agent.env_action(action) - [1.0, 5.0]).sum())
        nxt = rng.normal(size=OBS_DIM).astype(np.float32)
        agent.remember(obs, action, reward, nxt, terminated=False, truncated=i % 20 == 19)
        obs = nxt
    before = agent.actor_parameters()
    stats = agent.update()
    assert math.isfinite(stats.actor_loss) and stats.entropy > 0
    gradient = agent.actor_gradient()
    assert gradient.shape == before.shape and np.all(gradient[-2:] != 0.0)  # log-std has a gradient
    assert not np.array_equal(agent.actor_parameters()[-2:], before[-2:])


def test_a_continuous_agent_round_trips_through_its_model_file(tmp_path: Path) -> None:
    agent = PPOAgent(OBS_DIM, BOX, small_config(), seed=5)
    agent.apply_actor_gradient(np.ones(agent.actor_parameters().size, dtype=np.float32))
    path = tmp_path / "box.safetensors"
    agent.save(path)
    loaded = PPOAgent.load(path, obs_dim=OBS_DIM, action_space=BOX)
    assert loaded.action_space == BOX and loaded.architecture() == agent.architecture()
    assert agent.architecture()["action_space"] == {"kind": "box", "low": [-2.0, 0.0], "high": [2.0, 10.0]}
    assert np.array_equal(loaded.model_parameters(), agent.model_parameters())
    obs = np.array([0.3, 0.1, -0.2], dtype=np.float32)
    assert np.array_equal(loaded.act_greedy(obs), agent.act_greedy(obs))
    with pytest.raises(CheckpointError, match="needed here"):
        PPOAgent.load(path, action_space=ActionSpace.box([-1.0], [1.0]))
    with pytest.raises(CheckpointError, match="n_actions=0, but 3"):
        PPOAgent.load(path, n_actions=3)


def test_a_discrete_model_file_records_no_action_space_and_loads_as_before(tmp_path: Path) -> None:
    agent = PPOAgent(OBS_DIM, 3, small_config(), seed=5)
    assert set(agent.architecture()) == {"obs_dim", "n_actions", "hidden", "activation"}
    agent.save(tmp_path / "d.safetensors")
    loaded = PPOAgent.load(tmp_path / "d.safetensors", action_space=ActionSpace.discrete(3))
    assert loaded.action_space.is_discrete and loaded.n_actions == 3


@pytest.mark.parametrize(
    ("space", "message"),
    [
        (gymnasium.spaces.MultiDiscrete([2, 3]), "is not supported"),
        (gymnasium.spaces.Box(-1.0, 1.0, (2, 2)), "is not supported"),
        (gymnasium.spaces.Box(-np.inf, np.inf, (1,)), "finite bounds"),
        (gymnasium.spaces.Box(-1, 1, (1,), dtype=np.int64), "is not supported"),
        (gymnasium.spaces.Discrete(1), "at least 2"),
        (gymnasium.spaces.Discrete(3, start=1), "start at 0"),
    ],
)
def test_unsupported_action_spaces_are_named_with_what_is_supported(
    space: gymnasium.spaces.Space[object], message: str
) -> None:
    with pytest.raises(UnsupportedActionSpace, match=message):
        ActionSpace.of(space)


def test_action_space_round_trips_through_its_dict_and_rejects_others() -> None:
    assert ActionSpace.from_dict(BOX.to_dict()) == BOX
    assert ActionSpace.of(gymnasium.spaces.Discrete(3)) == ActionSpace.discrete(3)
    with pytest.raises(ValueError, match="unknown action space"):
        ActionSpace.from_dict({"kind": "tuple"})


def test_a_continuous_learner_resumed_from_its_state_plays_the_same_rounds(tmp_path: Path) -> None:
    def pendulum_learner() -> Learner:
        env = gymnasium.make("Pendulum-v1", max_episode_steps=50)
        agent = PPOAgent(3, ActionSpace.of(env.action_space), small_config(), seed=9)
        return Learner(env, agent, CompletionCriterion(1e9), seed=9)

    def fingerprint(learner: Learner) -> list[tuple[float, float]]:
        return [(learner.play_round().score, float(learner.agent.actor_parameters().sum())) for _ in range(2)]

    original = pendulum_learner()
    fingerprint(original)
    StateStore(tmp_path, "worker").save(*learner_state(original))
    expected = fingerprint(original)
    resumed = pendulum_learner()
    load_learner_state(resumed, *StateStore(tmp_path, "worker").load())
    assert fingerprint(resumed) == expected
