"""What a round produced, as values: its episodes and its result (score, steps, WMA, the update's figures).

Kept apart from the learner (and torch) so the federation's pure parts can build a round's record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Episodes:
    """The episodes of one round (Algorithm 2, lines 2-6), in the order played."""

    scores: tuple[float, ...]
    """each episode's return (sum of its rewards)"""
    steps: tuple[int, ...]
    """each episode's number of steps"""

    @property
    def score(self) -> float:
        """The round's score: the mean return of its episodes (the one episode's return for a ring memory)."""
        return float(np.mean(self.scores))


@dataclass(frozen=True)
class RoundResult:
    """What one round (its episodes, then maybe the update) produced.

    A round is one episode, or with ``trajectory_memory='per_round'`` (the ``paper-code`` preset) the whole
    episodes that fill the memory; it always ends with at most one update, so the federation's round
    numbers count updates either way.
    """

    round: int
    """1-based index of the round"""
    score: float
    """the mean return of the round's episodes (with one episode: its return)"""
    steps: int
    """number of steps in the round (all its episodes)"""
    episodes: int
    """number of episodes in the round"""
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
    approx_kl: float = math.nan
    """the update's estimate of KL(π_θold ‖ π_θ), averaged over the K optimisations (NaN without an update)"""
    clip_fraction: float = math.nan
    """share of the update's samples whose ratio R_t lay outside [1 − ε, 1 + ε] (NaN without an update)"""


def interrupted_round(number: int) -> RoundResult:
    """The result of round ``number`` of a worker that went down while playing it and came back after its
    fleet had gone on: what it played is lost (no episodes, NaN figures), the round stays in its books."""
    nan = math.nan
    return RoundResult(number, nan, 0, 0, nan, False, nan, nan, nan, 0.0)
