"""fleetrl/QubeBalance-v0: API conformance, the paper's reward, seeding, errors, SB3 compatibility."""

import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.envs.registration import QUBE_BALANCE_ID, QUBE_EPISODE_CAP

K = np.array([-2.0, 35.0, -1.5, 3.0])


def _bang_bang_balance(obs: np.ndarray) -> int:
    """Quanser's law squeezed into the three actions: power +60 / 0 / −60."""
    alpha, alpha_dot, theta, theta_dot = obs
    volts = -float(K @ np.array([theta, alpha, theta_dot, alpha_dot]))
    return 2 if volts > 0.7 else (0 if volts < -0.7 else 1)


def test_env_checker_passes() -> None:
    check_env(QubeBalanceEnv(unit=1, fleet_seed=3), skip_render_check=True)


def test_registered_with_the_episode_cap_as_truncation() -> None:
    env = gymnasium.make(QUBE_BALANCE_ID, unit=2)
    assert env.spec is not None and env.spec.max_episode_steps == QUBE_EPISODE_CAP == 2500
    obs, _ = env.reset(seed=0)
    steps, score = 0, 0.0
    while True:
        obs, reward, terminated, truncated, _ = env.step(_bang_bang_balance(obs))
        steps += 1
        score += float(reward)
        if terminated or truncated:
            break
    assert (steps, score, terminated, truncated) == (2500, 2500.0, False, True)


def test_falling_pendulum_scores_zero_and_terminates() -> None:
    env = QubeBalanceEnv()
    obs, _ = env.reset(seed=1)
    rewards = []
    terminated = False
    for _ in range(2000):
        obs, reward, terminated, truncated, _ = env.step(2)  # full power one way: it must fall
        rewards.append(reward)
        assert not truncated
        if terminated:
            break
    assert terminated and rewards[-1] == 0.0 and all(r == 1.0 for r in rewards[:-1])
    assert abs(obs[0]) > math.radians(7.5) or abs(obs[2]) > math.pi / 2


def test_arm_limit_terminates() -> None:
    env = QubeBalanceEnv(actuation_delay=False)
    env.reset(seed=0)
    device = env.link.device  # type: ignore[attr-defined]
    device.set_state(np.array([math.pi / 2 - 0.001, 0.0, 5.0, 0.0]))
    _, reward, terminated, _, _ = env.step(1)
    assert terminated and reward == 0.0


def test_seeding_reproduces_episodes() -> None:
    def run(seed: int) -> list[np.ndarray]:
        env = QubeBalanceEnv(unit=4, fleet_seed=2)
        first, _ = env.reset(seed=seed)
        return [first] + [env.step(a)[0] for a in (0, 2, 1, 2, 0, 0, 1)]

    np.testing.assert_array_equal(np.array(run(9)), np.array(run(9)))
    assert not np.array_equal(run(9)[0], run(10)[0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"unit": -1}, "unit must be a non-negative integer"),
        ({"fleet_seed": -3}, "fleet_seed must be a non-negative integer"),
        ({"unit": "two"}, "unit must be a non-negative integer"),
        ({"control_perod": 0.01}, "unknown QUBE option"),
        ({"velocity_estimate": "kalman"}, "unknown velocity_estimate 'kalman'"),
        ({"control_period": -0.006}, "control_period must be a positive number"),
    ],
)
def test_bad_arguments_are_clear_errors(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        QubeBalanceEnv(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("action", [3, -1, 1.5, "1", np.array([0, 1])])
def test_action_out_of_range_is_a_clear_error(action: object) -> None:
    env = QubeBalanceEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"out of range \(choose an integer 0 to 2\)"):
        env.step(action)


def test_numpy_actions_are_accepted() -> None:
    env = QubeBalanceEnv()
    env.reset(seed=0)
    for action in (np.int64(2), np.array(1), np.array([0])):
        env.step(action)


def test_stable_baselines3_ppo_trains_unchanged() -> None:
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", gymnasium.make(QUBE_BALANCE_ID), n_steps=128, batch_size=64, n_epochs=1, seed=0)
    model.learn(total_timesteps=256)
    action, _ = model.predict(np.zeros(4, dtype=np.float32))
    assert 0 <= int(action) <= 2
