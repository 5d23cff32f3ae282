"""Helpers shared by the link tests: a seeded trajectory of an env and an exact comparison."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from fleetrl.envs.link_env import LinkEnv


def run_episodes(env: LinkEnv, episodes: int, steps: int, seed: int) -> list[tuple[np.ndarray, float, bool]]:
    """A trajectory under a fixed pseudo-random action sequence: (obs, reward, terminated) per step. A box
    action is drawn from 1.5 times its bounds (the values beyond are clipped)."""
    rng = np.random.default_rng(seed)
    out: list[tuple[np.ndarray, float, bool]] = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        out.append((obs, 0.0, False))
        for _ in range(steps):
            obs, reward, terminated, _, _ = env.step(random_action(env.action_space, rng))
            out.append((obs, reward, terminated))
            if terminated:
                break
    return out


def assert_same(a: list[tuple[np.ndarray, float, bool]], b: list[tuple[np.ndarray, float, bool]]) -> None:
    """The two trajectories are equal to the bit."""
    assert len(a) == len(b)
    for (obs_a, r_a, t_a), (obs_b, r_b, t_b) in zip(a, b, strict=True):
        assert np.array_equal(obs_a, obs_b) and r_a == r_b and t_a == t_b


def random_action(space: gymnasium.Space[Any], rng: np.random.Generator) -> Any:
    """An index of a Discrete space, or a float32 vector from 1.5 times a Box's bounds."""
    if isinstance(space, gymnasium.spaces.Discrete):
        return int(rng.integers(int(space.n)))
    assert isinstance(space, gymnasium.spaces.Box)
    return (1.5 * rng.uniform(space.low, space.high)).astype(np.float32)
