"""The update as single steps (begin_update, step_gradients, apply_step, end_update), the sequential
critic-then-actor steps of one Adam, and the memory that empties after the update."""

import dataclasses
from typing import Any

import numpy as np
import pytest
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent
from fleetrl.agent.update import gae

OBS_DIM, N_ACTIONS = 4, 3
PRESETS = ["paper", "standard", "paper-code"]


def agent_with_memory(
    preset: str, seed: int = 0, data_seed: int = 0, n: int = 250, **overrides: Any
) -> PPOAgent:
    config = dataclasses.replace(get_preset(preset), **overrides)
    agent = PPOAgent(OBS_DIM, N_ACTIONS, config, seed=seed)
    rng = np.random.default_rng(data_seed)
    obs = rng.normal(size=OBS_DIM).astype(np.float32)
    for i in range(n):
        nxt = rng.normal(size=OBS_DIM).astype(np.float32)
        reward = float(rng.random() < 0.8)
        agent.remember(obs, agent.act(obs), reward, nxt, terminated=(i % 40 == 39), truncated=False)
        obs = nxt
    return agent


def step_by_step(agent: PPOAgent) -> list[np.ndarray]:
    """The update through the step API, returning each step's gradient."""
    gradients = []
    for k in range(agent.begin_update()):
        gradients.append(agent.step_gradients(k))
        agent.apply_step(gradients[-1])
    agent.end_update()
    return gradients


@pytest.mark.parametrize("preset", PRESETS)
def test_update_and_the_step_api_give_bit_identical_parameters(preset: str) -> None:
    torch.set_num_threads(1)
    whole, stepped = agent_with_memory(preset), agent_with_memory(preset)
    for _ in range(3):  # three rounds: Adam states and window draws carry over
        stats = whole.update()
        step_by_step(stepped)
        assert np.isfinite(stats.actor_loss) and np.isfinite(stats.critic_loss)
        assert np.array_equal(whole.model_parameters(), stepped.model_parameters())
        assert np.array_equal(whole.actor_gradient(), stepped.actor_gradient())
        for agent in (whole, stepped):  # refill (a per_round memory was emptied)
            rng = np.random.default_rng(len(agent.memory))
            for _ in range(200):
                obs = rng.normal(size=OBS_DIM).astype(np.float32)
                agent.remember(obs, agent.act(obs), 1.0, obs, terminated=False, truncated=False)
    assert not np.array_equal(whole.model_parameters(), agent_with_memory(preset).model_parameters())


@pytest.mark.parametrize("preset", PRESETS)
def test_averaged_step_gradients_keep_two_agents_identical(preset: str) -> None:
    torch.set_num_threads(1)
    # Same initial weights (seed), different experience: their own gradients differ at every step.
    first, second = agent_with_memory(preset, data_seed=1), agent_with_memory(preset, data_seed=2)
    n_steps = first.begin_update()
    assert second.begin_update() == n_steps
    for k in range(n_steps):
        assert first.step_layout(k) == second.step_layout(k)
        g1, g2 = first.step_gradients(k), second.step_gradients(k)
        assert not np.array_equal(g1, g2)
        average = (g1 + g2) / 2
        first.apply_step(average)
        second.apply_step(average)
        assert np.array_equal(first.model_parameters(), second.model_parameters())
    first.end_update()
    second.end_update()
    assert np.array_equal(first.actor_gradient(), second.actor_gradient())


@pytest.mark.parametrize(("preset", "steps"), [("paper", 10), ("paper-code", 20)])
def test_step_layouts_name_what_each_step_moves(preset: str, steps: int) -> None:
    agent = agent_with_memory(preset)
    before = agent.step_layout(0)  # known before the update starts (a scheme can set up its buffers)
    assert agent.begin_update() == steps
    assert agent.step_layout(0) == before
    first = [name for name, _ in agent.step_layout(0)]
    if preset == "paper":  # both models at once, critic first (the order their steps are applied)
        assert first[0] == "critic:trunk.0.weight" and first[-1] == "actor:policy.bias"
        assert "critic:value.bias" in first and "actor:trunk.0.weight" in first
    else:  # the critic alone, then the actor alone
        assert first == ["critic:" + name for name, _ in agent.net.trunk_parameters()] + [
            "critic:value.weight",
            "critic:value.bias",
        ]
        assert [name for name, _ in agent.step_layout(1)] == [
            "actor:" + name for name, _ in agent.actor_layout()
        ]
    gradient = agent.step_gradients(0)
    assert gradient.dtype == np.float32
    assert gradient.size == sum(int(np.prod(shape)) for _, shape in agent.step_layout(0))


def test_steps_must_go_in_order() -> None:
    agent = agent_with_memory("paper")
    with pytest.raises(RuntimeError, match="no update under way"):
        agent.step_gradients(0)
    n_steps = agent.begin_update()
    with pytest.raises(RuntimeError, match="already under way"):
        agent.begin_update()
    with pytest.raises(RuntimeError, match="no step gradient to apply"):
        agent.apply_step(np.zeros(3, dtype=np.float32))
    with pytest.raises(RuntimeError, match="step 1 requested, but step 0"):
        agent.step_gradients(1)
    gradient = agent.step_gradients(0)
    with pytest.raises(RuntimeError, match="not applied yet"):
        agent.step_gradients(0)
    with pytest.raises(ValueError, match="flat with"):
        agent.apply_step(gradient[:-1])
    agent.apply_step(gradient)
    with pytest.raises(RuntimeError, match=f"after 1 of {n_steps} steps"):
        agent.end_update()


def test_one_adam_steps_the_critic_then_the_actor_at_the_stepped_parameters() -> None:
    torch.set_num_threads(1)
    agent = agent_with_memory("paper-code")
    assert list(agent.optimisers()) == ["shared"]
    adam = agent.optimisers()["shared"]
    assert {id(p) for g in adam.param_groups for p in g["params"]} == {id(p) for p in agent.net.parameters()}
    twin = agent_with_memory("paper-code")
    agent.begin_update()
    twin.begin_update()
    policy0, value0 = agent.net.policy.weight.detach().clone(), agent.net.value.weight.detach().clone()

    critic_gradient = agent.step_gradients(0)
    assert np.array_equal(critic_gradient, twin.step_gradients(0))
    agent.apply_step(critic_gradient)
    twin.apply_step(np.zeros_like(critic_gradient))  # Adam from rest with g = 0 leaves the weights
    # The critic's step moved the value head and not the policy head, nor gave the policy head an Adam
    # state: no zero-gradient step (the authors' code made one, and its momentum moved the other model).
    assert not torch.equal(agent.net.value.weight, value0)
    assert torch.equal(agent.net.policy.weight, policy0)
    assert agent.net.policy.weight not in adam.state

    # The actor's gradient is taken where the critic's step left the (shared) trunk.
    actor_gradient = agent.step_gradients(1)
    assert not np.array_equal(actor_gradient, twin.step_gradients(1))
    agent.apply_step(actor_gradient)
    assert not torch.equal(agent.net.policy.weight, policy0)
    assert agent.net.value.weight in adam.state and agent.net.policy.weight in adam.state
    trunk_steps = adam.state[agent.net.trunk_layers[0].weight]["step"].item()
    assert trunk_steps == 2 and adam.state[agent.net.policy.weight]["step"].item() == 1
    for k in range(2, agent.update_step_count()):
        gradient = agent.step_gradients(k)
        agent.apply_step(gradient)
    agent.end_update()
    assert np.array_equal(agent.actor_gradient(), gradient)  # line 25: the last actor gradient applied


@pytest.mark.parametrize(("memory", "left"), [("ring", 200), ("per_round", 0)])
def test_a_per_round_memory_is_emptied_by_the_update(memory: str, left: int) -> None:
    agent = agent_with_memory("standard", n=300, trajectory_memory=memory, memory_size=200)
    assert len(agent.memory) == 300 if memory == "per_round" else 200  # a per_round memory keeps all
    agent.update()
    assert len(agent.memory) == left
    assert agent.needs_more_episodes() == (memory == "per_round")


@pytest.mark.parametrize(("memory", "left"), [("ring", 200), ("per_round", 0)])
def test_an_abandoned_update_keeps_the_steps_applied_and_the_next_update_runs(memory: str, left: int) -> None:
    agent = agent_with_memory("standard", n=300, trajectory_memory=memory, memory_size=200)
    before = agent.model_parameters().copy()
    agent.begin_update()
    agent.apply_step(agent.step_gradients(0))
    stepped = agent.model_parameters().copy()
    agent.abandon_update()
    assert not np.array_equal(stepped, before) and np.array_equal(agent.model_parameters(), stepped)
    assert len(agent.memory) == left
    with pytest.raises(RuntimeError, match="no update under way"):
        agent.end_update()
    agent.abandon_update()  # a round dropped before its update began: nothing under way, nothing changes
    assert np.array_equal(agent.model_parameters(), stepped) and len(agent.memory) == left
    rng = np.random.default_rng(1)
    for i in range(200):  # the next round's play, then a whole update through the step API
        obs = rng.normal(size=OBS_DIM).astype(np.float32)
        agent.remember(obs, agent.act(obs), 1.0, obs, terminated=(i % 40 == 39), truncated=False)
    assert len(step_by_step(agent)) == agent.update_step_count()


def test_the_critic_weight_scales_the_critic_gradient_only() -> None:
    torch.set_num_threads(1)
    unit = agent_with_memory("paper", critic_coef=1.0)
    half = agent_with_memory("paper", critic_coef=0.5)
    unit.begin_update()
    half.begin_update()
    sizes = [int(np.prod(shape)) for name, shape in unit.step_layout(0) if name.startswith("critic:")]
    g_unit, g_half = unit.step_gradients(0), half.step_gradients(0)
    n_critic = sum(sizes)
    np.testing.assert_allclose(g_half[:n_critic], 0.5 * g_unit[:n_critic], rtol=1e-6, atol=1e-9)
    assert np.array_equal(g_half[n_critic:], g_unit[n_critic:])


def test_the_memory_scope_critic_chases_the_targets_fixed_at_the_rounds_start() -> None:
    """With Â computed once over the memory (``gae_scope='memory'``, the standard preset), the λ-return target
    is Â + V(s) of line 11 for all K steps: the first step's critic loss is Ê[|Â|], and as the critic learns,
    its loss against those fixed targets falls."""
    torch.set_num_threads(1)
    agent = agent_with_memory("standard", batch_size=250, n=250)
    data = agent.memory.transitions()
    obs, next_obs = torch.from_numpy(data.obs), torch.from_numpy(data.next_obs)
    with torch.no_grad():
        values, next_values = agent.net.value_of(obs), agent.net.value_of(next_obs)
    cfg = agent.config
    rewards, terminated, ends = (torch.from_numpy(data.rewards), torch.from_numpy(data.terminated),
                                 torch.from_numpy(data.episode_end))  # fmt: skip
    advantages = gae(rewards, values, next_values, terminated, ends, cfg.gamma, cfg.gae_lambda)
    fixed_targets = advantages + values
    # the same network and memory, one optimisation: its loss is the first step's
    first = agent_with_memory("standard", batch_size=250, n=250, n_optimisations=1)
    assert first.update().critic_loss == pytest.approx(float(advantages.abs().mean()), rel=1e-5)
    agent.update()
    with torch.no_grad():
        after = float((agent.net.value_of(obs) - fixed_targets).abs().mean())
    assert after < 0.9 * float(advantages.abs().mean())  # the critic moved towards the fixed targets
