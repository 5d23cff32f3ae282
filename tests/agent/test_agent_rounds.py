"""A round of several episodes (the paper-code preset): whole episodes until the memory holds ≥ 200
transitions, the mean return as the round's score, one update, then an empty memory."""

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


def make_learner(preset: str, seed: int = 0, threshold: float = 475.0) -> Learner:
    env: gymnasium.Env[Any, Any] = gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0)
    agent = PPOAgent(4, 2, get_preset(preset), seed=seed)
    return Learner(env, agent, CompletionCriterion(threshold), seed=seed)


def test_a_paper_code_round_plays_whole_episodes_until_200_transitions() -> None:
    torch.set_num_threads(1)
    learner = make_learner("paper-code")
    (episodes,) = learner.play_episodes()
    memory = learner.agent.memory
    assert len(episodes.scores) > 1  # a new CartPole policy falls within ~20 steps
    assert sum(episodes.steps) >= 200 and sum(episodes.steps[:-1]) < 200  # stopped once filled
    assert len(memory) == sum(episodes.steps)  # every step of every episode, none overwritten
    ends = np.flatnonzero(memory.transitions().episode_end)
    assert (ends + 1).tolist() == np.cumsum(episodes.steps).tolist()  # whole episodes
    assert episodes.score == pytest.approx(np.mean(episodes.scores))
    assert learner.criterion.history() == [episodes.score] and learner.rounds == 1
    assert learner.episodes == len(episodes.scores)
    learner.agent.update()
    assert len(memory) == 0  # cleared after the update: nothing is kept across rounds


def test_a_paper_code_round_result_counts_its_episodes_and_steps() -> None:
    torch.set_num_threads(1)
    learner = make_learner("paper-code", seed=1)
    results = [learner.play_round() for _ in range(3)]
    assert [r.round for r in results] == [1, 2, 3]
    for result in results:
        assert result.episodes > 1 and result.steps >= 200
        assert result.score == pytest.approx(result.steps / result.episodes)  # CartPole: +1 per step
        assert np.isfinite(result.actor_loss) and np.isfinite(result.critic_loss)
    assert learner.episodes == sum(r.episodes for r in results)
    assert learner.last_round is results[-1]
    assert learner.criterion.history() == pytest.approx([r.score for r in results])


@pytest.mark.parametrize("preset", ["paper", "standard"])
def test_a_ring_memory_round_is_one_episode(preset: str) -> None:
    torch.set_num_threads(1)
    learner = make_learner(preset)
    result = learner.play_round()
    assert result.episodes == 1 and result.score == result.steps == len(learner.agent.memory)


def test_a_completed_paper_code_round_makes_no_update_and_keeps_its_memory() -> None:
    learner = make_learner("paper-code", threshold=0.0)
    results = [learner.play_round() for _ in range(10)]
    assert not any(r.completed for r in results[:9]) and results[-1].completed
    assert np.isnan(results[-1].actor_loss)
    assert len(learner.agent.memory) == results[-1].steps  # no update, so nothing was cleared


def test_the_first_episode_alone_is_seeded() -> None:
    torch.set_num_threads(1)
    learner = make_learner("paper-code", seed=5)
    starts = []
    env_reset = learner.env.reset

    def reset(**kwargs: Any) -> Any:
        starts.append(kwargs.get("seed"))
        return env_reset(**kwargs)

    learner.env.reset = reset  # type: ignore[method-assign]
    learner.play_round()
    assert starts[0] == 5 and all(s is None for s in starts[1:]) and len(starts) > 1
