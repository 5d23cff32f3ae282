"""One worker's learning loop without the federation: env + agent + completion criterion, round by round."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.ppo import PPOAgent


@dataclass(frozen=True)
class RoundResult:
    """What one round (one episode, then maybe the update) produced."""

    round: int
    """1-based index of the round"""
    score: float
    """sum of the episode's rewards"""
    steps: int
    """number of steps in the episode"""
    wma: float
    """weighted moving average of the last scores after this one (see CompletionCriterion)"""
    completed: bool
    """the criterion holds after this episode; then no update was made (Algorithm 2, line 7) unless the
    learner keeps learning"""
    actor_loss: float
    """−L^CLIP averaged over the round's K optimisations (NaN when no update was made)"""
    critic_loss: float
    """L^V averaged over the K optimisations (NaN when no update was made)"""
    entropy: float
    """mean policy entropy over the windows (NaN when no update was made)"""
    seconds: float
    """wall time of the round (episode and update)"""


class Learner:
    """Plays rounds on one env; used by individual mode and inside the federated worker.

    :param env: a Gymnasium env with a flat Box observation and a Discrete action space
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
        self.completed = False

    def play_episode(self, greedy: bool = False, learn: bool = True) -> tuple[float, int]:
        """One episode (Algorithm 2, lines 2-6), storing transitions if ``learn``; returns (score, steps)."""
        seed = self.seed if self.rounds == 0 else None
        obs, _ = self.env.reset(seed=seed)
        act = self.agent.act_greedy if greedy else self.agent.act
        score, steps = 0.0, 0
        while True:
            action = act(obs)  # line 3
            next_obs, reward, terminated, truncated, _ = self.env.step(action)  # line 4
            if learn:
                self.agent.remember(obs, action, float(reward), next_obs, terminated, truncated)  # line 5
            score += float(reward)
            steps += 1
            if terminated or truncated:
                return score, steps
            obs = next_obs

    def play_round(self) -> RoundResult:
        """One episode, then the update unless the criterion now holds (lines 2-24 without messaging)."""
        started = time.perf_counter()
        score, steps = self.play_episode()
        self.rounds += 1
        self.criterion.add(score)
        nan = math.nan
        losses = (nan, nan, nan)
        done = self.criterion.done
        if done:
            self.completed = True
        if not done or self.keep_learning:  # line 7: once learning is finished the worker sends θ instead
            stats = self.agent.update()  # lines 11-24
            losses = (stats.actor_loss, stats.critic_loss, stats.entropy)
        return RoundResult(
            self.rounds,
            score,
            steps,
            self.criterion.wma,
            done,
            *losses,
            time.perf_counter() - started,
        )

    def evaluate(self, episodes: int) -> float:
        """Mean score of ``episodes`` greedy episodes, storing nothing."""
        scores = [self.play_episode(greedy=True, learn=False)[0] for _ in range(episodes)]
        return float(np.mean(scores))
