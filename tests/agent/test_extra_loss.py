"""The hook a federation scheme uses to add a term to local training (``PPOAgent.set_extra_loss``)."""

from __future__ import annotations

import numpy as np

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent


def agent_with_memory() -> PPOAgent:
    agent = PPOAgent(4, ActionSpace.discrete(2), get_preset("standard"), seed=3)
    rng = np.random.default_rng(0)
    for t in range(80):
        obs = rng.standard_normal(4).astype(np.float32)
        agent.remember(obs, int(agent.act(obs)), 1.0, obs, False, t == 79)
    return agent


def test_the_extra_term_s_gradient_joins_every_step_s_gradient() -> None:
    plain, extra = agent_with_memory(), agent_with_memory()
    extra.set_extra_loss(lambda net: 0.5 * sum(p.sum() for p in net.parameters()))  # ∂/∂p = 0.5 everywhere
    plain.begin_update(), extra.begin_update()
    without, with_term = plain.step_gradients(0), extra.step_gradients(0)
    np.testing.assert_allclose(with_term - without, 0.5, atol=1e-6)
    extra.set_extra_loss(None)
    plain.apply_step(without), extra.apply_step(without)
    np.testing.assert_array_equal(extra.step_gradients(1), plain.step_gradients(1))


def test_no_extra_term_changes_nothing() -> None:
    first, second = agent_with_memory(), agent_with_memory()
    second.set_extra_loss(None)
    first.update(), second.update()
    assert first.model_parameters().tobytes() == second.model_parameters().tobytes()
