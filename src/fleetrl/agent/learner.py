"""One worker's learning loop without the federation: env + agent + completion criterion, round by round."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.ppo import PPOAgent, UpdateStats
from fleetrl.agent.round_result import Episodes, RoundResult


@dataclass(frozen=True)
class PlayedEpisodes:
    """The first half of a round: its episodes, and whether the round goes on with an update (line 7)."""

    episodes: Episodes
    updates: bool
    started: float
    """``time.perf_counter()`` as the round began"""


class Learner:
    """Plays rounds on one env; used by individual mode and inside the federated worker.

    :param env: a Gymnasium env with a flat Box observation and a Discrete or 1-D Box action space
    :param agent: the PPO agent that acts and learns
    :param criterion: decides when learning is complete
    :param seed: seeds the env at its first reset (later resets continue its random stream)
    :param keep_learning: update after every episode, also once the criterion holds (the ``fedavg``
        federation scheme, where a completed worker keeps learning with the fleet)
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        agent: PPOAgent,
        criterion: CompletionCriterion,
        seed: int | None = None,
        keep_learning: bool = False,
    ) -> None:
        self.env = env
        self.agent = agent
        self.criterion = criterion
        self.seed = seed
        self.keep_learning = keep_learning
        self.rounds = 0
        self.episodes = 0
        """episodes played in all rounds (not :meth:`evaluate`'s)"""
        self.completed = False
        self.last_round: RoundResult | None = None
        """the result of the latest :meth:`play_round`"""

    def unit_progress(self) -> list[float]:
        """The unit's progress towards its criterion (:attr:`CompletionCriterion.progress`), as a list of
        one (a unit host's has one per unit)."""
        return [self.criterion.progress]

    def units_completed(self) -> list[bool]:
        """Whether the unit has completed (its criterion held at some round), as a list of one."""
        return [self.completed]

    def play_episode(self, greedy: bool = False, learn: bool = True) -> tuple[float, int]:
        """One episode (Algorithm 2, lines 2-6), storing transitions if ``learn``; returns (score, steps)."""
        seed = self.seed if self.episodes == 0 else None
        obs, _ = self.env.reset(seed=seed)
        act = self.agent.act_greedy if greedy else self.agent.act
        # a box's sample goes to the env clipped, to the memory as drawn (PPOAgent.env_action)
        to_env = None if self.agent.action_space.is_discrete else self.agent.env_action
        score, steps = 0.0, 0
        while True:
            action = act(obs)  # line 3
            sent = action if to_env is None else to_env(action)
            next_obs, reward, terminated, truncated, _ = self.env.step(sent)  # line 4
            if learn:
                self.agent.remember(obs, action, float(reward), next_obs, terminated, truncated)  # line 5
            score += float(reward)
            steps += 1
            if terminated or truncated:
                if learn:
                    self.episodes += 1
                return score, steps
            obs = next_obs

    def play_episodes(self) -> Episodes:
        """The first half of a round: one episode, or whole episodes until the agent's trajectory memory
        holds what its update needs (``trajectory_memory='per_round'``); the criterion sees the mean. With
        the ``argmax`` criterion, a round after one whose score reached the target plays its episode by the
        arg-max and stores nothing (:meth:`plays_greedy`)."""
        if self.plays_greedy():
            played = [self.play_episode(greedy=True, learn=False)]
            self.episodes += 1
        else:
            played = [self.play_episode()]
            while self.agent.needs_more_episodes():
                played.append(self.play_episode())
        scores, steps = zip(*played, strict=True)
        episodes = Episodes(scores, steps)
        self.rounds += 1
        self.criterion.add(episodes.score)
        if self.criterion.done:
            self.completed = True
        return episodes

    def plays_greedy(self) -> bool:
        """Whether this round's episode is played by π_θ's arg-max: the criterion is ``argmax``, the unit has
        not completed yet, and the last round's score (the criterion's newest) reached the target. Read from
        the criterion, so a resumed unit plays as it would have. A completed unit that stays with its fleet
        samples again: the fleet learns from its fresh episodes, not from a memory the proof left stale."""
        if self.agent.config.criterion != "argmax" or self.completed:
            return False
        history = self.criterion.history()
        return bool(history) and history[-1] >= self.criterion.threshold

    def wants_update(self) -> bool:
        """Line 7: update unless learning is finished (the worker then sends θ); always if keep_learning."""
        return not self.criterion.done or self.keep_learning

    def play_round(self) -> RoundResult:
        """A whole round alone (Algorithm 2, lines 2-24 without messaging): :meth:`begin_round`, the agent's
        update unless the criterion now holds, :meth:`end_round`."""
        played = self.begin_round()
        return self.end_round(played, self.agent.update() if played.updates else None)

    def begin_round(self) -> PlayedEpisodes:
        """:meth:`play_episodes` and line 7's decision; the caller then updates the agent, or not (a
        per-step scheme's worker drives the update through the fleet), and hands its statistics to
        :meth:`end_round`."""
        started = time.perf_counter()
        episodes = self.play_episodes()
        return PlayedEpisodes(episodes, self.wants_update(), started)

    def end_round(self, played: PlayedEpisodes, stats: UpdateStats | None) -> RoundResult:
        """The round's result from its episodes and its update's statistics (None: no update was made)."""
        episodes, nan = played.episodes, math.nan
        losses = (nan,) * 5 if stats is None else dataclasses.astuple(stats)
        actor_loss, critic_loss, entropy, approx_kl, clip_fraction = losses
        self.last_round = RoundResult(
            self.rounds,
            episodes.score,
            sum(episodes.steps),
            len(episodes.scores),
            self.criterion.wma,
            self.criterion.done,
            actor_loss,
            critic_loss,
            entropy,
            time.perf_counter() - played.started,
            approx_kl,
            clip_fraction,
        )
        return self.last_round

    def evaluate(self, episodes: int) -> float:
        """Mean score of ``episodes`` greedy episodes, storing nothing."""
        scores = [self.play_episode(greedy=True, learn=False)[0] for _ in range(episodes)]
        return float(np.mean(scores))
