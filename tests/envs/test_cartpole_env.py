"""fleetrl/CartPoleUnit-v0: API conformance, CartPole-v1 semantics, errors, SB3 compatibility."""

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.registration import CARTPOLE_EPISODE_CAP, CARTPOLE_UNIT_ID


def test_env_checker_passes() -> None:
    check_env(CartPoleUnitEnv(unit=2, fleet_seed=1), skip_render_check=True)


def test_cap_is_500_and_episodes_end_like_cartpole_v1() -> None:
    env = gymnasium.make(CARTPOLE_UNIT_ID, unit=1)
    assert env.spec is not None and env.spec.max_episode_steps == CARTPOLE_EPISODE_CAP == 500
    env.reset(seed=0)
    rewards = []
    while True:
        obs, reward, terminated, truncated, _ = env.step(1)  # always push right: falls quickly
        rewards.append(reward)
        if terminated or truncated:
            break
    assert terminated and not truncated and all(r == 1.0 for r in rewards) and len(rewards) < 100
    assert abs(obs[0]) > 2.4 or abs(obs[2]) > 12 * 2 * np.pi / 360


def test_units_differ_and_seeds_reproduce() -> None:
    def run(unit: int, seed: int) -> np.ndarray:
        env = CartPoleUnitEnv(unit=unit)
        env.reset(seed=seed)
        return np.array([env.step(a)[0] for a in (1, 0, 1, 1, 0, 1, 0, 0)])

    np.testing.assert_array_equal(run(0, 5), run(0, 5))
    assert not np.array_equal(run(0, 5), run(1, 5))


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="unit must be a non-negative integer"):
        CartPoleUnitEnv(unit=-1)
    env = CartPoleUnitEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"out of range \(choose an integer 0 to 1\)"):
        env.step(2)


def test_stable_baselines3_ppo_trains_unchanged() -> None:
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", gymnasium.make(CARTPOLE_UNIT_ID), n_steps=128, batch_size=64, n_epochs=1, seed=0)
    model.learn(total_timesteps=256)
    assert model.num_timesteps >= 256
