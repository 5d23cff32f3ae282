"""Completion criterion: weighted moving average (WMA) of the last 10 episode scores (section 5.2)."""

from __future__ import annotations

from collections import deque

import numpy as np


class CompletionCriterion:
    """Learning is complete once the WMA of the last ``window`` scores reaches ``threshold``.

    Weights are linear in recency: the oldest score of the window weighs 1, the newest weighs
    ``window`` (the standard WMA), normalised by their sum (55 for a window of 10). Until ``window``
    scores exist the WMA is taken over what there is (same linear weights) but the criterion cannot
    hold: one lucky early episode must not finish a worker.

    :param threshold: WMA at which learning is complete (QUBE 2450 of 2500; CartPole 475 of 500)
    :param window: number of most recent scores in the average (the paper: 10)
    """

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

    def reset(self) -> None:
        """Forget all scores."""
        self._scores.clear()
