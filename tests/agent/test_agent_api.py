"""What the federation uses: actor layout, last gradient, gradient through Adam, get/set parameters."""

import dataclasses
from typing import Any

import numpy as np
import pytest
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent

OBS_DIM, N_ACTIONS = 4, 3


def agent_with_memory(preset: str = "paper", seed: int = 0, n: int = 100, **overrides: Any) -> PPOAgent:
    config = dataclasses.replace(get_preset(preset), **overrides)
    agent = PPOAgent(OBS_DIM, N_ACTIONS, config, seed=seed)
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=OBS_DIM).astype(np.float32)
    for i in range(n):
        nxt = rng.normal(size=OBS_DIM).astype(np.float32)
        agent.remember(obs, agent.act(obs), 1.0, nxt, terminated=(i % 30 == 29), truncated=False)
        obs = nxt
    return agent


def test_layout_is_trunk_then_policy_head() -> None:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0)
    layout = agent.actor_layout()
    assert [name for name, _ in layout] == [
        "trunk.0.weight", "trunk.0.bias", "trunk.1.weight", "trunk.1.bias",
        "trunk.2.weight", "trunk.2.bias", "policy.weight", "policy.bias",
    ]  # fmt: skip
    assert layout[0][1] == (128, OBS_DIM) and layout[-2][1] == (N_ACTIONS, 128)
    size = sum(int(np.prod(shape)) for _, shape in layout)
    assert size == agent.actor_parameters().shape[0]
    assert agent.actor_parameters().dtype == np.float32


def test_actor_gradient_before_update_is_an_error() -> None:
    with pytest.raises(RuntimeError, match="update"):
        PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0).actor_gradient()


@pytest.mark.parametrize("preset", ["paper", "standard"])
def test_update_returns_finite_stats_and_a_flat_gradient(preset: str) -> None:
    agent = agent_with_memory(preset)
    before = agent.actor_parameters()
    stats = agent.update()
    assert all(np.isfinite([stats.actor_loss, stats.critic_loss, stats.entropy]))
    grad = agent.actor_gradient()
    assert grad.dtype == np.float32 and grad.shape == (agent.actor_parameters().size,)
    assert np.any(grad != 0.0)
    assert not np.array_equal(before, agent.actor_parameters())


def test_apply_gradient_steps_through_adam() -> None:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0)
    theta = agent.actor_parameters()
    g = np.random.default_rng(1).normal(size=theta.shape).astype(np.float32)
    agent.apply_actor_gradient(g)
    # Adam's first step moves every parameter by lr·g/(|g| + eps) ≈ lr·sign(g)
    expected = theta - agent.config.actor_lr * g / (np.abs(g) + 1e-8)
    assert np.allclose(agent.actor_parameters(), expected, atol=1e-6)
    # the second step of the same gradient also moves by ≈ lr·sign(g): Adam keeps its moments
    agent.apply_actor_gradient(g)
    assert np.allclose(agent.actor_parameters(), theta - 2 * agent.config.actor_lr * np.sign(g), atol=1e-5)


def test_apply_gradient_leaves_the_critic_head_alone_and_refreshes_acting() -> None:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0)
    value_before = agent.net.value.weight.detach().clone()
    obs = np.ones(OBS_DIM, dtype=np.float32)
    probs_before = agent._policy.probabilities(obs)
    agent.apply_actor_gradient(np.full(agent.actor_parameters().size, 0.5, dtype=np.float32))
    assert torch.equal(agent.net.value.weight, value_before)
    assert not np.allclose(agent._policy.probabilities(obs), probs_before)


def test_set_parameters_round_trip_and_acting_follows() -> None:
    source = agent_with_memory(seed=1)
    source.update()
    target = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=2)
    target.set_actor_parameters(source.actor_parameters())
    assert np.array_equal(target.actor_parameters(), source.actor_parameters())
    obs = np.array([0.1, -0.2, 0.3, 0.0], dtype=np.float32)
    assert np.allclose(target._policy.probabilities(obs), source._policy.probabilities(obs))
    assert target.act_greedy(obs) == source.act_greedy(obs)


def test_gradient_round_trip_between_agents() -> None:
    # what the chief does with one worker (the average of one gradient is that gradient): the receiver takes
    # one step of its actor Adam with g. Adam's first step, by hand: m̂ = g, v̂ = g², so
    # θ₁ = θ₀ − η · g / (|g| + ε), with ε = 1e-8: each weight moves by η against the sign of its gradient.
    worker = agent_with_memory(seed=3)
    worker.update()
    g = worker.actor_gradient().astype(np.float64)
    twin = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=4)
    before = twin.actor_parameters().astype(np.float64)
    twin.apply_actor_gradient(worker.actor_gradient())
    moved = twin.actor_parameters().astype(np.float64) - before
    lr = get_preset("paper").actor_lr
    assert np.count_nonzero(g) > 0.9 * g.size  # a real gradient, not zeros
    assert np.allclose(moved, -lr * g / (np.abs(g) + 1e-8), rtol=1e-3, atol=1e-6)


def test_model_vector_is_the_actor_then_the_value_head() -> None:
    agent = agent_with_memory(seed=5)
    layout = agent.model_layout()
    assert layout[: len(agent.actor_layout())] == agent.actor_layout()
    assert layout[-2:] == [("value.weight", (1, 128)), ("value.bias", (1,))]
    assert sum(p.numel() for p in agent.net.parameters()) == agent.model_parameters().shape[0]
    assert np.array_equal(agent.model_parameters()[: agent.actor_parameters().size], agent.actor_parameters())


def test_set_model_parameters_moves_both_heads_and_keeps_each_adam() -> None:
    source = agent_with_memory(seed=1)
    source.update()
    target = agent_with_memory(seed=2)
    target.update()
    adam_steps = [s["step"].item() for s in target.actor_optimizer.state.values()]
    target.set_model_parameters(source.model_parameters())
    assert np.array_equal(target.model_parameters(), source.model_parameters())
    obs = np.array([0.1, -0.2, 0.3, 0.0], dtype=np.float32)
    with torch.no_grad():
        values = [a.net.value_of(torch.from_numpy(obs[None]))[0].item() for a in (source, target)]
    assert values[0] == values[1]
    assert target.act_greedy(obs) == source.act_greedy(obs)
    assert [s["step"].item() for s in target.actor_optimizer.state.values()] == adam_steps
    with pytest.raises(ValueError, match="model parameter vector must be flat with"):
        target.set_model_parameters(source.actor_parameters())


@pytest.mark.parametrize("bad", [np.zeros(5, np.float32), np.zeros((2, 2), np.float32)])
def test_wrong_vectors_are_rejected(bad: np.ndarray) -> None:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0)
    with pytest.raises(ValueError, match="flat with"):
        agent.set_actor_parameters(bad)
    with pytest.raises(ValueError, match="flat with"):
        agent.apply_actor_gradient(bad)
    nan = np.full(agent.actor_parameters().size, np.nan, dtype=np.float32)
    with pytest.raises(ValueError, match="non-finite"):
        agent.apply_actor_gradient(nan)


def test_each_optimiser_steps_the_trunk_with_its_own_loss() -> None:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, get_preset("paper"), seed=0)
    trunk = {id(p) for _, p in agent.net.trunk_parameters()}
    actor_of = {id(p) for g in agent.actor_optimizer.param_groups for p in g["params"]}
    critic_of = {id(p) for g in agent.critic_optimizer.param_groups for p in g["params"]}
    assert trunk <= actor_of and trunk <= critic_of
    assert id(agent.net.value.weight) in critic_of and id(agent.net.value.weight) not in actor_of


@pytest.mark.parametrize(
    "overrides",
    [
        {"gae_scope": "memory", "critic_target": "gae"},
        {"old_policy": "behaviour", "normalise_advantages": True, "entropy_coef": 0.01},
        {"critic_loss": "huber", "activation": "relu"},
    ],
)
def test_every_option_updates(overrides: dict[str, Any]) -> None:
    agent = agent_with_memory(**overrides)
    stats = agent.update()
    assert np.isfinite(stats.actor_loss) and np.isfinite(agent.actor_gradient()).all()
