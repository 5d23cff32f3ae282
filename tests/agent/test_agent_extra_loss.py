"""The hook into local training (``PPOAgent.set_extra_loss``): a scalar of the network added to each
minibatch's loss, checked on terms whose gradient is known by hand."""

import dataclasses
from typing import Any

import numpy as np
import pytest
import torch
from torch import nn

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent

OBS_DIM, N_ACTIONS = 4, 3


def agent_with_memory(preset: str = "paper", **overrides: Any) -> PPOAgent:
    agent = PPOAgent(OBS_DIM, N_ACTIONS, dataclasses.replace(get_preset(preset), **overrides), seed=0)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=OBS_DIM).astype(np.float32)
    for i in range(250):
        nxt = rng.normal(size=OBS_DIM).astype(np.float32)
        agent.remember(obs, agent.act(obs), float(rng.random() < 0.8), nxt, i % 40 == 39, False)
        obs = nxt
    return agent


def sum_of_parameters(weight: float) -> Any:
    """weight·Σθ: its gradient is ``weight`` in every entry of every parameter."""
    return lambda model: weight * sum(p.sum() for p in model.parameters())


@pytest.mark.parametrize("preset", ["paper", "standard", "paper-code"])
def test_every_step_gradient_gains_the_terms_gradient(preset: str) -> None:
    torch.set_num_threads(1)
    plain, hooked = agent_with_memory(preset), agent_with_memory(preset)
    hooked.set_extra_loss(sum_of_parameters(0.25))
    plain.begin_update()
    hooked.begin_update()
    difference = hooked.step_gradients(0) - plain.step_gradients(0)  # the same parameters at step 0
    np.testing.assert_allclose(difference, 0.25, atol=1e-5)


def test_a_dominant_term_moves_its_parameters_by_adams_first_step() -> None:
    """−c·Σ(policy bias) with c huge: its gradient −c swamps the PPO loss's, and Adam's first step moves each
    entry by lr·sign(−g) = +lr; the value head, which the term does not touch, moves as without it."""
    torch.set_num_threads(1)
    plain, hooked = agent_with_memory(n_optimisations=1), agent_with_memory(n_optimisations=1)
    bias = hooked.net.policy.bias.detach().clone()

    def pull(model: nn.Module) -> torch.Tensor:
        return -1e6 * model.get_parameter("policy.bias").sum()

    hooked.set_extra_loss(pull)
    plain.update()
    hooked.update()
    lr = hooked.config.actor_lr
    np.testing.assert_allclose((hooked.net.policy.bias.detach() - bias).numpy(), lr, rtol=1e-4)
    assert torch.equal(hooked.net.value.weight, plain.net.value.weight)


def test_without_a_term_every_number_is_unchanged() -> None:
    torch.set_num_threads(1)
    plain, cleared = agent_with_memory("standard"), agent_with_memory("standard")
    cleared.set_extra_loss(sum_of_parameters(1.0))
    cleared.set_extra_loss(None)
    assert plain.update() == cleared.update()
    assert np.array_equal(plain.model_parameters(), cleared.model_parameters())
    assert np.array_equal(plain.actor_gradient(), cleared.actor_gradient())
