"""The learning loop of one unit or of U units of one agent, without the federation: each unit's env and
completion criterion, the units stepped together (:class:`~fleetrl.envs.host_envs.HostEnvs`)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from fleetrl.agent.criterion import CompletionCriterion, Episodes, RoundResult
from fleetrl.agent.ppo import PPOAgent, UpdateStats
from fleetrl.envs.host_envs import HostEnvs

__all__ = ["Learner", "PlayedEpisodes"]


@dataclass(frozen=True)
class PlayedEpisodes:
    """The first half of a round: each unit's episodes, whether an update follows, and when it began."""

    units: tuple[Episodes, ...]
    updates: bool
    started: float


class Learner:
    """Plays rounds of the agent's units, each on its own env; used alone and inside a federated worker.

    :param env: each unit's Gymnasium env (one env: one unit)
    :param criterion: each unit's completion criterion (one for one unit)
    :param seed: seeds each unit's env at its first reset (one per unit); None: unseeded
    :param keep_learning: update every round, also once every unit's criterion holds
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any] | Sequence[gymnasium.Env[Any, Any]],
        agent: PPOAgent,
        criterion: CompletionCriterion | Sequence[CompletionCriterion],
        seed: int | Sequence[int] | None = None,
        keep_learning: bool = False,
    ) -> None:
        self.envs = list(env) if isinstance(env, Sequence) else [env]
        self.criteria = list(criterion) if isinstance(criterion, Sequence) else [criterion]
        if not len(self.envs) == len(self.criteria) == agent.units:
            raise ValueError(
                f"a learner needs one env, criterion and agent seed per unit: got {len(self.envs)} envs, "
                f"{len(self.criteria)} criteria, {agent.units} seeds"
            )
        self.seeds = [seed] * agent.units if seed is None or isinstance(seed, int) else list(seed)
        self._envs = HostEnvs(self.envs)
        self.agent = agent
        self.keep_learning = keep_learning
        self.rounds = 0
        self.unit_episodes = [0] * agent.units  # learning episodes, not :meth:`evaluate`'s
        self.completed_once = [False] * agent.units  # each unit's criterion has held at some round
        self.unit_rounds: tuple[RoundResult, ...] = ()  # each unit's result of the latest round
        self.last_round: RoundResult | None = None  # the latest round's: its units' summary

    @property
    def env(self) -> gymnasium.Env[Any, Any]:
        """Unit 0's env."""
        return self.envs[0]

    @property
    def criterion(self) -> CompletionCriterion:
        """Unit 0's completion criterion."""
        return self.criteria[0]

    @property
    def episodes(self) -> int:
        """Learning episodes played by all units in all rounds."""
        return sum(self.unit_episodes)

    @property
    def completed(self) -> bool:
        """Every unit has completed: its criterion held at some round, not necessarily this one."""
        return all(self.completed_once)

    def plays_greedy(self, unit: int = 0) -> bool:
        """Whether the unit's round is played by π_θ's arg-max and stored nowhere: the criterion is
        ``argmax``, the unit has not completed yet, and its last round's score reached the target."""
        if self.agent.config.criterion != "argmax" or self.completed_once[unit]:
            return False
        history = self.criteria[unit].history()
        return bool(history) and history[-1] >= self.criteria[unit].threshold

    def play_units(self, greedy: np.ndarray, learn: bool = True) -> list[list[tuple[float, int]]]:
        """Each unit's episodes of a round (Algorithm 2, lines 2-6), the units stepped together: one, or
        whole episodes until a ``per_round`` memory is filled. A ``greedy`` unit plays one episode by the
        arg-max; it, and every unit when not ``learn``, stores nothing."""
        agent, envs, n = self.agent, self._envs, self.agent.units
        to_env = None if agent.action_space.is_discrete else agent.env_action
        obs = np.stack([self._reset(u) for u in range(n)])
        score, steps = np.zeros(n), np.zeros(n, dtype=np.int64)
        played: list[list[tuple[float, int]]] = [[] for _ in range(n)]
        playing, units = np.ones(n, dtype=bool), np.arange(n)
        at: slice | np.ndarray = slice(None)  # the units playing: every unit, or those still playing
        stores = ~greedy if learn else np.zeros(n, dtype=bool)
        any_greedy = bool(greedy.any())
        while units.size:
            before = obs[at]
            actions = self._act(before, units, greedy[at])  # line 3, for every unit still playing
            sent = actions if to_env is None else [to_env(a) for a in actions]
            step = envs.step(units, sent)  # line 4
            stored = (before, actions, step.rewards, step.obs, step.terminated, step.truncated)
            if learn:  # line 5, for the units that learn from their episode
                rows = stores[at] if any_greedy else slice(None)
                agent.remember_units(units[rows], *(a[rows] for a in stored))
            score[at] += step.rewards
            steps[at] += 1
            ended = step.terminated | step.truncated
            if not ended.any():
                obs[at] = step.obs
                continue
            obs[units[~ended]] = step.obs[~ended]
            for u in units[ended].tolist():
                played[u].append((float(score[u]), int(steps[u])))
                self.unit_episodes[u] += int(learn)
                score[u], steps[u] = 0.0, 0
                if stores[u] and agent.needs_more_episodes(u):
                    obs[u] = self._reset(u)
                else:
                    playing[u] = False
            units = np.flatnonzero(playing)
            at = slice(None) if units.size == n else units
        agent.store_pending()
        return played

    def _act(self, obs: np.ndarray, units: np.ndarray, greedy: np.ndarray) -> np.ndarray:
        if not greedy.any():
            return self.agent.act_units(obs, units)
        actions = [self.agent.act_greedy(row) for row in obs]
        return np.asarray(actions, dtype=np.int64 if self.agent.action_space.is_discrete else np.float32)

    def _reset(self, unit: int) -> np.ndarray:
        seed = self.seeds[unit] if self.unit_episodes[unit] == 0 else None
        return self._envs.reset(unit, seed)

    def play_episodes(self) -> tuple[Episodes, ...]:
        """Every unit's episodes of the round; each criterion sees its unit's mean score."""
        greedy = np.array([self.plays_greedy(u) for u in range(self.agent.units)])
        played = self.play_units(greedy)
        self.rounds += 1
        episodes = []
        for u, (criterion, unit_played) in enumerate(zip(self.criteria, played, strict=True)):
            scores, lengths = zip(*unit_played, strict=True)
            episodes.append(Episodes(scores, lengths))
            criterion.add(episodes[-1].score)
            self.completed_once[u] = self.completed_once[u] or criterion.done
        return tuple(episodes)

    def wants_update(self) -> bool:
        """Line 7: update unless every unit's criterion holds (the worker then sends θ); always if
        keep_learning."""
        return self.keep_learning or not all(c.done for c in self.criteria)

    def play_round(self) -> RoundResult:
        """A whole round alone (Algorithm 2, lines 2-24 without messaging)."""
        played = self.begin_round()
        return self.end_round(played, self.agent.update() if played.updates else None)

    def begin_round(self) -> PlayedEpisodes:
        """:meth:`play_episodes` and line 7's decision; the caller then updates the agent, or not, and hands
        its statistics to :meth:`end_round`."""
        started = time.perf_counter()
        units = self.play_episodes()
        return PlayedEpisodes(units, self.wants_update(), started)

    def end_round(self, played: PlayedEpisodes, stats: UpdateStats | None) -> RoundResult:
        """Each unit's result (:attr:`unit_rounds`) and the round's (returned): their means (steps and
        episodes: sums)."""
        seconds = time.perf_counter() - played.started
        per_unit = self.agent.unit_stats if stats is not None else None
        self.unit_rounds = units = tuple(
            _result(
                self.rounds,
                (episodes.score, sum(episodes.steps), len(episodes.scores), criterion.wma, criterion.done),
                None if per_unit is None else per_unit[u],
                seconds,
            )
            for u, (episodes, criterion) in enumerate(zip(played.units, self.criteria, strict=True))
        )
        score, wma = float(np.mean([r.score for r in units])), float(np.mean([r.wma for r in units]))
        steps, episodes = sum(r.steps for r in units), sum(r.episodes for r in units)
        figures = (score, steps, episodes, wma, all(r.completed for r in units))
        self.last_round = _result(self.rounds, figures, stats, seconds)
        return self.last_round

    def evaluate(self, episodes: int) -> float:
        """Mean score of ``episodes`` greedy episodes of every unit, storing nothing."""
        greedy = np.ones(self.agent.units, dtype=bool)
        scores = [
            s for _ in range(episodes) for unit in self.play_units(greedy, learn=False) for s, _ in unit
        ]
        return float(np.mean(scores))


def _result(
    round_: int, figures: tuple[float, int, int, float, bool], stats: UpdateStats | None, seconds: float
) -> RoundResult:
    """A round's result from its (score, steps, episodes, WMA, completed) and its update's statistics."""
    losses = (math.nan,) * 5 if stats is None else dataclasses.astuple(stats)
    actor_loss, critic_loss, entropy, approx_kl, clip_fraction = losses
    return RoundResult(round_, *figures, actor_loss, critic_loss, entropy, seconds, approx_kl, clip_fraction)
