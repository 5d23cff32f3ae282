"""Helpers shared by the link tests: a seeded trajectory of an env and an exact comparison."""

from __future__ import annotations

import numpy as np

from fleetrl.envs.link_env import LinkEnv


def run_episodes(env: LinkEnv, episodes: int, steps: int, seed: int) -> list[tuple[np.ndarray, float, bool]]:
    """A trajectory under a fixed pseudo-random action sequence: (obs, reward, terminated) per step."""
    rng = np.random.default_rng(seed)
    n_actions = int(env.action_space.n)
    out: list[tuple[np.ndarray, float, bool]] = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        out.append((obs, 0.0, False))
        for _ in range(steps):
            obs, reward, terminated, _, _ = env.step(int(rng.integers(n_actions)))
            out.append((obs, reward, terminated))
            if terminated:
                break
    return out


def assert_same(a: list[tuple[np.ndarray, float, bool]], b: list[tuple[np.ndarray, float, bool]]) -> None:
    """The two trajectories are equal to the bit."""
    assert len(a) == len(b)
    for (obs_a, r_a, t_a), (obs_b, r_b, t_b) in zip(a, b, strict=True):
        assert np.array_equal(obs_a, obs_b) and r_a == r_b and t_a == t_b
