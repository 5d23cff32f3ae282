"""A round's outcome: the completion criterion (WMA of the last 10 scores, section 5.2), the round's episodes
and its result (kept free of torch so the federation's pure parts can build a round's record)."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np


class CompletionCriterion:
    """Learning is complete once the WMA of the last ``window`` scores reaches ``threshold``: the oldest
    score weighs 1, the newest ``window``; with fewer than ``window`` scores the criterion cannot hold."""

    def __init__(self, threshold: float, window: int = 10) -> None:
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window}")
        self.threshold = float(threshold)
        self.window = window
        self._scores: deque[float] = deque(maxlen=window)

    def add(self, score: float) -> None:
        """Record the score of the episode just finished."""
        self._scores.append(float(score))

    @property
    def wma(self) -> float:
        """Weighted moving average of the recorded scores (newest heaviest); 0.0 before any score."""
        if not self._scores:
            return 0.0
        weights = np.arange(1, len(self._scores) + 1, dtype=np.float64)
        return float(np.dot(weights, np.asarray(self._scores, dtype=np.float64)) / weights.sum())

    @property
    def done(self) -> bool:
        """True once ``window`` scores are recorded and their WMA is at least the threshold."""
        return len(self._scores) == self.window and self.wma >= self.threshold

    def history(self) -> list[float]:
        """The recorded scores in the window, oldest first (for a checkpoint)."""
        return list(self._scores)

    def load_history(self, scores: list[float]) -> None:
        """Replace the recorded scores with ``scores`` (oldest first; only the last ``window`` count)."""
        self._scores.clear()
        self._scores.extend(float(s) for s in scores)


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
    """What one round (an episode, or a ``per_round`` memory's episodes, then at most one update) produced."""

    round: int
    """1-based index of the round"""
    score: float
    """the mean return of the round's episodes"""
    steps: int
    episodes: int
    wma: float
    """weighted moving average of the last scores after this one"""
    completed: bool
    """the criterion holds after this round; then no update was made (line 7) unless learning goes on"""
    actor_loss: float
    """−L^CLIP averaged over the update's K optimisations; this and the next NaN without an update"""
    critic_loss: float
    entropy: float
    seconds: float
    """wall time of the round (episodes and update)"""
    approx_kl: float = math.nan
    clip_fraction: float = math.nan


def interrupted_round(number: int) -> RoundResult:
    """Round ``number`` of a worker that went down while playing it: nothing played, NaN figures."""
    nan = math.nan
    return RoundResult(number, nan, 0, 0, nan, False, nan, nan, nan, 0.0)
