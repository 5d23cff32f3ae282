"""The numba acting copy agrees with the torch actor, samples from π, and is fast."""

import numpy as np
import pytest
import torch

from fleetrl.agent.config import Activation, PPOConfig, get_preset
from fleetrl.agent.ppo import PPOAgent


@pytest.mark.parametrize("activation", ["tanh", "relu"])
def test_numba_policy_matches_torch(activation: Activation) -> None:
    config = PPOConfig(activation=activation)
    agent = PPOAgent(5, 3, config, seed=0)
    agent.apply_actor_gradient(
        np.random.default_rng(0).normal(size=agent.actor_parameters().size).astype(np.float32)
    )
    rng = np.random.default_rng(1)
    for _ in range(20):
        obs = rng.normal(size=5).astype(np.float32)
        with torch.no_grad():
            logits, _ = agent.net(torch.from_numpy(obs)[None])
        expected = torch.softmax(logits, -1)[0].numpy()
        assert np.allclose(agent._policy.probabilities(obs), expected, atol=1e-5)
        assert agent.act_greedy(obs) == int(np.argmax(expected))


def test_sampling_follows_the_policy() -> None:
    agent = PPOAgent(4, 3, get_preset("paper"), seed=0)
    agent.apply_actor_gradient(np.linspace(-1, 1, agent.actor_parameters().size).astype(np.float32))
    obs = np.array([0.5, -0.5, 1.0, 0.0], dtype=np.float32)
    probs = agent._policy.probabilities(obs)
    counts = np.bincount([agent.act(obs) for _ in range(20000)], minlength=3) / 20000
    assert np.allclose(counts, probs, atol=0.015)


def test_wrong_observation_length_is_rejected() -> None:
    agent = PPOAgent(4, 2, get_preset("paper"), seed=0)
    with pytest.raises(ValueError, match="expects 4"):
        agent.act(np.zeros(3, dtype=np.float32))
