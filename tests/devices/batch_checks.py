"""What every batch of simulated units must do: step each unit as the unit steps alone, bit for bit."""

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np


def steps_match_alone(
    batch: Any, alone: Sequence[Any], rng: np.random.Generator, n_actions: int, steps: int
) -> Iterator[tuple[int, np.ndarray]]:
    """Step random units of ``batch`` (about 70 % of them each step, with random actions) and the same units
    of ``alone``; assert equal observations and states; yield each stepped unit's row and observation."""
    for _ in range(steps):
        rows = np.flatnonzero(rng.random(len(alone)) < 0.7)  # some units rest this step
        actions = rng.integers(0, n_actions, size=rows.size)
        obs = batch.step(rows, actions)
        assert obs.dtype == np.float32 and obs.shape == (rows.size, 4)
        for j, (row, action) in enumerate(zip(rows.tolist(), actions.tolist(), strict=True)):
            expected = alone[row].step(action)
            assert np.array_equal(obs[j], expected)
            assert np.array_equal(batch.state(row), alone[row].state)
            yield row, expected
