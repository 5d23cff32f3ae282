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
from fleetrl.envs.registration import CARTPOLE_UNIT_ID

pytestmark = pytest.mark.slow  # every test here trains for rounds


def make_env() -> gymnasium.Env[Any, Any]:
    return gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0)


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


# The learning test is statistical: a seed fixes a run on one CPU only (docs/algorithm.md, "Seeding"), so
# no single seed's round count is asserted. A seed learns if it completes within the cap and its greedy policy
# then holds the pole (a mean of ≥ 400 over 3 episodes); at least 4 of 5 seeds must. The bounds come from
# `python benchmarks/preset_rounds.py --seeds 0-9` (tuning seeds, never the ones below) on a 2-core AMD EPYC
# (AVX2): after the critic-target fix (commit 2ca43f9) seeds 0-9 completed in 43-77 rounds and every greedy
# policy scored 500. Before it, in four settings that give four sets of code paths: the host's kernels
# (rounds 54-108), FLEETRL_PORTABLE=1 (49-120), torch without SIMD (55-141), MKL's compatible path (64-228),
# and an Intel Xeon (AVX-512, seeds 0-6: 71-173). The cap of 300 leaves a margin of 1.3× over the slowest of
# those 57 runs, and one seed of five may still miss (on one of the held-out seeds the completed policy's
# greedy play once averaged 311: stochastic play had met the criterion, greedy play did not hold).
LEARNING_SEEDS = range(100, 105)
LEARNING_MAX_ROUNDS = 300
LEARNING_MIN_COMPLETED = 4


@pytest.mark.timeout(900)  # 5 seeds × 300 rounds: 70 s alone, several times that beside other heavy tests
def test_standard_preset_learns_cartpole() -> None:
    torch.set_num_threads(1)
    learned, outcomes = 0, []
    for seed in LEARNING_SEEDS:
        learner = make_learner("standard", seed=seed)
        for _ in range(LEARNING_MAX_ROUNDS):
            result = learner.play_round()
            if result.completed:
                assert result.wma >= 475.0
                greedy = learner.evaluate(3)  # greedy play of the completed policy should hold the pole
                learned += greedy >= 400.0
                outcomes.append(f"seed {seed}: round {result.round}, greedy {greedy:.0f}")
                break
        else:
            outcomes.append(f"seed {seed}: not completed")
    assert learned >= LEARNING_MIN_COMPLETED, (
        f"{learned} of {len(LEARNING_SEEDS)} seeds completed within {LEARNING_MAX_ROUNDS} rounds with a "
        f"greedy policy that holds the pole ({'; '.join(outcomes)}); at least {LEARNING_MIN_COMPLETED} should"
    )
