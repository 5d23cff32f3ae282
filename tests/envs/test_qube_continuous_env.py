"""fleetrl/QubeBalanceContinuous-v0: the discrete task's units, reward and cap, the voltage as the action."""

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.envs.qube_balance import ACTION_VOLTS, QubeBalanceContinuousEnv, QubeBalanceEnv
from fleetrl.envs.registration import QUBE_BALANCE_CONTINUOUS_ID, QUBE_EPISODE_CAP
from fleetrl.link.inprocess import InProcessLink

K = np.array([-2.0, 35.0, -1.5, 3.0])
"""Quanser's balance gains on [theta, alpha, theta_dot, alpha_dot]"""


def volts(value: float) -> np.ndarray:
    return np.array([value], dtype=np.float32)


def test_the_env_checkers_of_gymnasium_and_sb3_pass() -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    check_env(QubeBalanceContinuousEnv(unit=1, fleet_seed=3), skip_render_check=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check_env(gymnasium.make(QUBE_BALANCE_CONTINUOUS_ID, unit=1))
    # the one remark: SB3 recommends a [-1, 1] box; this one is in volts (docs/devices.md, "Environments")
    assert all("normalized" in str(w.message) for w in caught), [str(w.message) for w in caught]


def test_action_space_is_the_voltage_within_the_safe_range() -> None:
    env = QubeBalanceContinuousEnv()
    assert env.action_space == gymnasium.spaces.Box(-3.0, 3.0, (1,), np.float32) and ACTION_VOLTS == 3.0
    assert env.observation_space == QubeBalanceEnv().observation_space
    wider = QubeBalanceContinuousEnv(action_volts=10.0)
    assert isinstance(wider.action_space, gymnasium.spaces.Box) and wider.action_space.high[0] == 10.0


def test_quanser_balance_law_in_volts_holds_to_the_cap() -> None:
    env = gymnasium.make(QUBE_BALANCE_CONTINUOUS_ID, unit=2)
    assert env.spec is not None and env.spec.max_episode_steps == QUBE_EPISODE_CAP
    obs, _ = env.reset(seed=0)
    steps, score = 0, 0.0
    while True:
        alpha, alpha_dot, theta, theta_dot = obs
        command = volts(-float(K @ np.array([theta, alpha, theta_dot, alpha_dot])))
        obs, reward, terminated, truncated, _ = env.step(command)
        steps, score = steps + 1, score + float(reward)
        if terminated or truncated:
            break
    assert (steps, score, terminated, truncated) == (2500, 2500.0, False, True)


def test_same_unit_and_trajectory_as_the_discrete_task_for_the_same_voltages() -> None:
    continuous, discrete = (
        QubeBalanceContinuousEnv(unit=1, fleet_seed=2),
        QubeBalanceEnv(unit=1, fleet_seed=2),
    )
    a, _ = continuous.reset(seed=7)
    b, _ = discrete.reset(seed=7)
    assert np.array_equal(a, b)
    for index in (1, 1, 2, 0, 2, 2, 1, 0):  # 0 V exactly; ±1.44 V up to float32 rounding of the command
        a, ra, ta, _, _ = continuous.step(volts((-1.44, 0.0, 1.44)[index]))
        b, rb, tb, _, _ = discrete.step(index)
        assert np.allclose(a, b, atol=1e-4) and (ra, ta) == (rb, tb)


def test_commands_beyond_the_box_are_clipped_like_the_bound() -> None:
    clipped, bound = QubeBalanceContinuousEnv(), QubeBalanceContinuousEnv()
    clipped.reset(seed=1)
    bound.reset(seed=1)
    for _ in range(3):
        a = clipped.step(volts(50.0))[0]
        b = bound.step(volts(3.0))[0]
    assert np.array_equal(a, b)
    clipped.step(2.5)  # a plain number for the one component is accepted


@pytest.mark.parametrize("action", [np.array([0.1, 0.2]), np.array([np.nan]), "1", [np.inf], None])
def test_bad_actions_are_clear_errors(action: object) -> None:
    env = QubeBalanceContinuousEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"give 1 finite numbers, each within \[-3.0\] .. \[3.0\]"):
        env.step(action)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"action_volts": 12.0}, r"action_volts must be a number in \(0, 10.0\]"),
        ({"action_volts": 0.0}, "action_volts must be"),
        ({"action_volts": 5.0, "max_volts": 4.0}, r"in \(0, 4.0\]"),
        ({"link": InProcessLink(QubeBalanceEnv().link), "quantise": True}, "not with link="),  # type: ignore[arg-type]
    ],
)
def test_bad_arguments_are_clear_errors(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        QubeBalanceContinuousEnv(**kwargs)  # type: ignore[arg-type]


def test_stable_baselines3_ppo_trains_it_unchanged() -> None:
    from stable_baselines3 import PPO

    env = gymnasium.make(QUBE_BALANCE_CONTINUOUS_ID)
    model = PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0)
    model.learn(total_timesteps=256)
    action, _ = model.predict(np.zeros(4, dtype=np.float32), deterministic=True)
    assert action.shape == (1,) and -3.0 <= float(action[0]) <= 3.0
