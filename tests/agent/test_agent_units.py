"""An agent and learner of U units on one policy, each with its own memory, seed and criterion: its gradient
is the mean of its units' gradients, for every preset; an agent of one unit is that unit's own agent."""

import dataclasses

import gymnasium
import numpy as np
import pytest
import torch

from fleetrl.agent.config import PPOConfig, get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID

OBS_DIM, N_ACTIONS = 4, 3
SEEDS = (11, 12, 13)


def small_config(**overrides: object) -> PPOConfig:
    """The standard preset on a hand-sized net and memory (windows of 6 of at most 12 transitions)."""
    base = dict(hidden=(8, 8), memory_size=12, batch_size=6, n_optimisations=3)
    return dataclasses.replace(get_preset("standard"), **(base | overrides))  # type: ignore[arg-type]


def fill(agents: list[PPOAgent], host: PPOAgent, lengths: tuple[int, ...], seed: int) -> None:
    """The same transitions in unit u's own agent and in the host's memory of unit u (lengths[u] of them,
    episodes ending every 5 steps)."""
    rng = np.random.default_rng(seed)
    for u, (agent, n) in enumerate(zip(agents, lengths, strict=True)):
        obs = rng.normal(size=OBS_DIM).astype(np.float32)
        for t in range(n):
            nxt = rng.normal(size=OBS_DIM).astype(np.float32)
            action, reward, end = int(rng.integers(N_ACTIONS)), float(rng.random()), t % 5 == 4
            agent.remember(obs, action, reward, nxt, terminated=end, truncated=False)
            host.memories[u].add(obs, action, reward, nxt, terminated=end, truncated=False)
            obs = nxt


def preset_config(preset: str, **overrides: object) -> PPOConfig:
    """A preset on a hand-sized net and memory (windows of 6 of at most 12 transitions)."""
    base = dict(hidden=(8, 8), memory_size=12, batch_size=6, n_optimisations=3)
    return dataclasses.replace(get_preset(preset), **(base | overrides))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("preset", "overrides"),
    [
        ("standard", {}),
        ("standard", {"normalise_advantages": False, "entropy_coef": 0.01}),
        ("paper", {}),
        ("paper-code", {}),
    ],
)
def test_the_units_gradient_is_the_mean_of_their_own_gradients(preset: str, overrides: dict) -> None:
    torch.set_num_threads(1)
    config = preset_config(preset, **overrides)
    host = PPOAgent(OBS_DIM, N_ACTIONS, config, SEEDS)
    units = [PPOAgent(OBS_DIM, N_ACTIONS, config, seed=s) for s in SEEDS]
    for agent in units:  # one policy: every unit's agent at the host's network
        agent.set_model_parameters(host.model_parameters())
    for round_, lengths in enumerate([(9, 4, 12), (5, 4, 3)]):  # ragged windows: 6, all 4, 6; then 6, 6, 6
        fill(units, host, lengths, seed=round_)
        steps = host.begin_update()
        assert steps == config.n_optimisations * len(host._parts) and all(
            a.begin_update() == steps for a in units
        )
        for k in range(steps):
            own = [agent.step_gradients(k) for agent in units]
            mean = np.mean(own, axis=0)
            assert np.allclose(host.step_gradients(k), mean, rtol=1e-5, atol=1e-7)
            assert not np.allclose(own[0], own[1], rtol=1e-3)  # the units' minibatches differ
            for agent in [host, *units]:
                agent.apply_step(mean)
        stats = host.end_update()
        unit_stats = [agent.end_update() for agent in units]
        assert host.unit_stats is not None
        for mine, theirs in zip(host.unit_stats, unit_stats, strict=True):
            assert np.allclose(dataclasses.astuple(mine), dataclasses.astuple(theirs), rtol=1e-5, atol=1e-6)
        assert np.isclose(stats.critic_loss, np.mean([s.critic_loss for s in unit_stats]), rtol=1e-5)
    assert np.allclose(host.model_parameters(), units[0].model_parameters(), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("memory", ["ring", "per_round"])
def test_unit_0_of_several_plays_and_learns_as_that_unit_alone(memory: str) -> None:
    torch.set_num_threads(1)
    config = dataclasses.replace(get_preset("standard"), hidden=(32, 32), trajectory_memory=memory)
    env = lambda: gymnasium.make(CARTPOLE_UNIT_ID, unit=1, fleet_seed=0)  # noqa: E731
    alone = Learner(
        env(), PPOAgent(4, 2, config, seed=5), CompletionCriterion(60.0), seed=5, keep_learning=True
    )
    host = Learner([env()], PPOAgent(4, 2, config, [5]), [CompletionCriterion(60.0)], [5], keep_learning=True)
    for _ in range(6):
        mine, theirs = host.play_round(), alone.play_round()
        (unit,) = host.unit_rounds
        assert (unit.score, unit.steps, unit.wma, unit.completed) == (
            theirs.score, theirs.steps, theirs.wma, theirs.completed
        )  # fmt: skip
        assert unit.actor_loss == theirs.actor_loss and mine.score == theirs.score
        assert unit.episodes == theirs.episodes >= (2 if memory == "per_round" else 1)
    assert np.array_equal(host.agent.model_parameters(), alone.agent.model_parameters())


def test_each_unit_of_a_learner_keeps_its_own_env_seed_and_criterion() -> None:
    torch.set_num_threads(1)
    config = dataclasses.replace(get_preset("standard"), hidden=(16,))
    envs = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=0) for u in range(3)]
    criteria = [CompletionCriterion(t, window=1) for t in (0.0, 1e9, 0.0)]  # units 0 and 2 complete at once
    host = Learner(envs, PPOAgent(4, 2, config, [7, 8, 7]), criteria, [7, 8, 7], keep_learning=True)
    host.play_round()
    rounds = host.unit_rounds
    assert [r.completed for r in rounds] == [True, False, True] and not host.completed
    assert host.last_round is not None and host.last_round.steps == sum(r.steps for r in rounds)
    assert len(host.agent.memories[1]) == rounds[1].steps  # each unit's transitions in its own memory
    # units 0 and 2 share a seed but not their dynamics: unit 0 and a lone unit 0 of that seed agree
    lone = Learner([gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0)], PPOAgent(4, 2, config, [7]),
                       [CompletionCriterion(0.0)], 7)  # fmt: skip
    lone.play_round()
    assert lone.unit_rounds[0].score == rounds[0].score


class ScriptedCriterion(CompletionCriterion):
    """A criterion that holds in the rounds its script says (the host's bookkeeping, not a unit's scores)."""

    def __init__(self, holds: list[bool]) -> None:
        super().__init__(0.0, window=1)
        self._script, self._holds = iter(holds), False

    def add(self, score: float) -> None:
        super().add(score)
        self._holds = next(self._script)

    @property
    def done(self) -> bool:
        return self._holds


def test_a_learner_completes_once_every_unit_has_completed_not_when_all_hold_in_one_round() -> None:
    config = dataclasses.replace(get_preset("standard"), hidden=(16,))
    envs = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=0) for u in range(2)]
    # unit 0 completes in round 1 and then falls below its target; unit 1 completes in round 3
    criteria = [ScriptedCriterion([True, False, False]), ScriptedCriterion([False, False, True])]
    host = Learner(envs, PPOAgent(4, 2, config, [7, 8]), criteria, keep_learning=True)
    completed, units = [], []
    for _ in range(3):
        host.play_episodes()
        completed.append(host.completed)
        units.append(list(host.completed_once))
    assert completed == [False, False, True]  # as two workers' first completions: rounds 1 and 3
    assert units == [[True, False], [True, False], [True, True]]  # each unit once it has completed
    assert host.wants_update()  # a per-step scheme's units learn on with the fleet


def test_batched_acting_takes_each_rows_own_action() -> None:
    host = PPOAgent(OBS_DIM, N_ACTIONS, small_config(), SEEDS)
    rng = np.random.default_rng(0)
    obs, draws = rng.normal(size=(50, OBS_DIM)), rng.random(50)
    rows = host._policy.act_rows(obs, draws)
    assert [host._policy.act(o, u) for o, u in zip(obs, draws, strict=True)] == rows.tolist()
    assert len(set(rows.tolist())) > 1


def test_an_agent_needs_a_unit() -> None:
    with pytest.raises(ValueError, match="at least one unit"):
        PPOAgent(OBS_DIM, N_ACTIONS, small_config(), [])


def test_each_unit_of_several_plays_the_argmax_criterion_on_its_own_scores() -> None:
    config = dataclasses.replace(get_preset("standard"), hidden=(16,), criterion="argmax")
    envs = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=0) for u in range(2)]
    criteria = [CompletionCriterion(t) for t in (0.0, 1e9)]  # unit 0's every score reaches its target
    learner = Learner(envs, PPOAgent(4, 2, config, [7, 8]), criteria, [7, 8])
    learner.play_round()
    stored = [len(memory) for memory in learner.agent.memories]
    assert [learner.plays_greedy(u) for u in range(2)] == [True, False]
    learner.play_round()
    after = [len(memory) for memory in learner.agent.memories]
    assert after[0] == stored[0] and after[1] > stored[1]  # unit 0's arg-max episode is stored nowhere
