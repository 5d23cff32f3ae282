"""The ``argmax`` criterion: after a round that reached the target a unit plays by π_θ's arg-max, stores
nothing, and samples again once an episode falls short."""

import dataclasses
from typing import Any

import gymnasium
import pytest

import fleetrl  # noqa: F401  (registers the fleetrl envs)
from fleetrl.agent.config import Criterion, PPOConfig, get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID


def make_learner(threshold: float, *, criterion: Criterion = "argmax") -> Learner:
    env: gymnasium.Env[Any, Any] = gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0)
    config = dataclasses.replace(get_preset("standard"), criterion=criterion)
    agent = PPOAgent(4, 2, config, seed=3)
    return Learner(env, agent, CompletionCriterion(threshold), seed=3)


class ActionCounts:
    """Counts the agent's sampled and arg-max actions (the real agent acts; only the calls are counted)."""

    def __init__(self, agent: PPOAgent) -> None:
        self.sampled = self.greedy = 0
        act, act_greedy = agent.act_units, agent.act_greedy

        def counted_act(obs: Any, units: Any) -> Any:
            self.sampled += len(units)
            return act(obs, units)

        def counted_greedy(obs: Any) -> Any:
            self.greedy += 1
            return act_greedy(obs)

        agent.act_units, agent.act_greedy = counted_act, counted_greedy  # type: ignore[method-assign]


def test_a_round_after_a_held_one_is_played_by_the_arg_max_and_stored_nowhere() -> None:
    learner = make_learner(threshold=0.0)  # every score reaches it
    counts = ActionCounts(learner.agent)
    first = learner.play_round()
    assert counts.greedy == 0 and counts.sampled == first.steps
    stored = len(learner.agent.memory)
    assert learner.plays_greedy()
    second = learner.play_round()
    assert counts.greedy == second.steps and counts.sampled == first.steps
    assert len(learner.agent.memory) == stored  # the arg-max episode is not learned from
    assert second.episodes == 1 and learner.episodes == 2


def test_an_episode_short_of_the_target_sends_the_unit_back_to_sampling() -> None:
    learner = make_learner(threshold=0.0)
    counts = ActionCounts(learner.agent)
    learner.play_round()
    greedy_round = learner.play_round()
    assert counts.greedy == greedy_round.steps
    learner.criterion.threshold = greedy_round.score + 1  # the arg-max episode fell short of the target
    assert not learner.plays_greedy()
    sampled_before = counts.sampled
    sampled_round = learner.play_round()
    assert counts.sampled == sampled_before + sampled_round.steps and counts.greedy == greedy_round.steps


def test_off_by_default_every_round_is_sampled() -> None:
    assert PPOConfig().criterion == "sampled"
    learner = make_learner(threshold=0.0, criterion="sampled")
    counts = ActionCounts(learner.agent)
    results = [learner.play_round() for _ in range(3)]
    assert counts.greedy == 0 and counts.sampled == sum(r.steps for r in results)
    assert not learner.plays_greedy()


def test_a_resumed_unit_plays_as_its_criterion_says() -> None:
    learner = make_learner(threshold=475.0)
    assert not learner.plays_greedy()
    learner.criterion.load_history([120.0, 500.0])  # a checkpoint's scores: the newest held
    assert learner.plays_greedy()
    learner.criterion.load_history([500.0, 120.0])
    assert not learner.plays_greedy()


def test_settings_it_cannot_run_with_are_refused_before_anything_starts() -> None:
    per_round = dataclasses.replace(get_preset("paper-code"), criterion="argmax")
    with pytest.raises(ValueError, match=r"criterion 'argmax' .* needs trajectory_memory 'ring'"):
        per_round.validate()


def test_a_completed_unit_that_stays_with_its_fleet_samples_again() -> None:
    learner = make_learner(threshold=0.0)
    learner.keep_learning = True  # a scheme whose mature units stay (pergrad, fedavg, fedasync)
    counts = ActionCounts(learner.agent)
    results = [learner.play_round() for _ in range(10)]
    assert results[-1].completed and not results[-2].completed  # ten scores: the criterion holds
    assert counts.greedy == sum(r.steps for r in results[1:])  # rounds 2-10 proved it
    stored = len(learner.agent.memory)
    assert not learner.plays_greedy()
    after = learner.play_round()
    assert counts.sampled == results[0].steps + after.steps  # its episodes feed the fleet again
    assert len(learner.agent.memory) == min(stored + after.steps, learner.agent.config.memory_size)
