"""Greedy episodes on one unit's env: the loop ``fleetrl evaluate`` and ``fleetrl control`` share."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np


def greedy_scores(
    env: gymnasium.Env[Any, Any],
    act: Callable[[np.ndarray], Any],
    episodes: int,
    seed: int = 0,
    report: Callable[[int, float], None] | None = None,
) -> list[float]:
    """The scores (summed rewards) of ``episodes`` episodes of ``env`` acting with ``act``; episode ``k``
    resets with seed ``seed + k``; ``report(k, score)`` is called as each one ends."""
    scores = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        score, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs))
            score += float(reward)
            done = terminated or truncated
        scores.append(score)
        if report is not None:
            report(episode, score)
    return scores
