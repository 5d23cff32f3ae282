"""Learner rounds: determinism, no update on completion, and an honest learning test on CartPole."""

import math
from typing import Any

import gymnasium
import numpy as np
import pytest
import torch

import fleetrl  # noqa: F401  (registers the fleetrl envs)
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent

CARTPOLE_UNIT = "fleetrl/CartPoleUnit-v0"


def make_env() -> gymnasium.Env[Any, Any]:
    if CARTPOLE_UNIT in gymnasium.envs.registration.registry:
        try:
            return gymnasium.make(CARTPOLE_UNIT, unit=0, fleet_seed=0)
        except ImportError:  # the unit env's module is not there in this checkout
            pass
    return gymnasium.make("CartPole-v1")


def make_learner(preset: str, seed: int, threshold: float = 475.0) -> Learner:
    env = make_env()
    assert env.observation_space.shape is not None
    assert isinstance(env.action_space, gymnasium.spaces.Discrete)
    n_actions = int(env.action_space.n)
    agent = PPOAgent(env.observation_space.shape[0], n_actions, get_preset(preset), seed=seed)
    return Learner(env, agent, CompletionCriterion(threshold), seed=seed)


@pytest.mark.parametrize("preset", ["paper", "standard"])
def test_same_seed_same_first_20_scores(preset: str) -> None:
    torch.set_num_threads(1)
    runs = []
    for _ in range(2):
        learner = make_learner(preset, seed=7)
        runs.append([learner.play_round().score for _ in range(20)])
    assert runs[0] == runs[1]
    other = make_learner(preset, seed=8)
    assert [other.play_round().score for _ in range(20)] != runs[0]


def test_completed_round_makes_no_update() -> None:
    learner = make_learner("standard", seed=0, threshold=0.0)
    results = [learner.play_round() for _ in range(10)]
    assert not any(r.completed for r in results[:9])
    assert all(np.isfinite(r.actor_loss) for r in results[:9])
    theta = learner.agent.actor_parameters()
    last = results[-1]
    assert last.completed and learner.completed and last.round == 10
    assert math.isnan(last.actor_loss) and math.isnan(last.critic_loss) and math.isnan(last.entropy)
    assert np.array_equal(theta, learner.agent.actor_parameters())
    assert last.steps == last.score  # CartPole: +1 per step


def test_a_learner_that_keeps_learning_updates_after_completion() -> None:
    learner = make_learner("standard", seed=0, threshold=0.0)
    learner.keep_learning = True
    results = [learner.play_round() for _ in range(10)]
    theta = learner.agent.actor_parameters()
    last = learner.play_round()
    assert results[-1].completed and last.completed and learner.completed
    assert all(np.isfinite(r.actor_loss) for r in [*results, last])
    assert not np.array_equal(theta, learner.agent.actor_parameters())


STANDARD_SEED = 0
STANDARD_MAX_ROUNDS = 150  # seed 0 completes at round 79 (docs/algorithm.md)


@pytest.mark.slow
def test_standard_preset_learns_cartpole() -> None:
    torch.set_num_threads(1)
    learner = make_learner("standard", seed=STANDARD_SEED)
    for _ in range(STANDARD_MAX_ROUNDS):
        result = learner.play_round()
        if result.completed:
            break
    assert result.completed, f"no completion in {STANDARD_MAX_ROUNDS} rounds (WMA {result.wma:.0f})"
    assert result.wma >= 475.0
    assert learner.evaluate(3) >= 400.0
