"""The ``last_step`` observation: each observation carries the one before it and the action between them,
for a discrete and a continuous unit, through the one path every run builds its units by."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.envs.wrappers import LastStep


def test_an_observation_holds_the_last_observation_and_the_one_hot_action_that_followed_it() -> None:
    env, description = get_env_spec("qube").make(0, 0, last_step=True)
    try:
        assert description.obs_dim == 11 and description.sensor_dim == 4  # the link still reads 4 numbers
        first, _ = env.reset(seed=0)
        np.testing.assert_array_equal(first[:4], first[4:8])  # at a reset the last observation is the first
        np.testing.assert_array_equal(first[8:], 0.0)  # and no action yet
        second, *_ = env.step(2)
        np.testing.assert_array_equal(second[4:8], first[:4])
        np.testing.assert_array_equal(second[8:], [0.0, 0.0, 1.0])
        third, *_ = env.step(0)
        np.testing.assert_array_equal(third[4:8], second[:4])
        np.testing.assert_array_equal(third[8:], [1.0, 0.0, 0.0])
        again, _ = env.reset(seed=0)
        np.testing.assert_array_equal(again, first)  # a reset forgets the last episode's step
    finally:
        env.close()


def test_a_continuous_command_is_held_clipped_to_its_box() -> None:
    env, description = get_env_spec("qube-continuous").make(0, 0, last_step=True)
    try:
        assert description.obs_dim == 9
        high = float(env.action_space.high[0])
        env.reset(seed=0)
        obs, *_ = env.step(np.array([0.5], np.float32))
        assert obs[8] == pytest.approx(0.5)
        obs, *_ = env.step(np.array([10 * high], np.float32))
        assert obs[8] == pytest.approx(high)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_the_plain_observation_is_the_unit_s_own() -> None:
    assert describe_env("qube").obs_dim == 4
    assert describe_env("qube", True).obs_dim == 11


def test_a_space_it_cannot_hold_is_refused_by_name() -> None:
    env = gymnasium.make("FrozenLake-v1")
    with pytest.raises(ValueError, match="1-D Box observation"):
        LastStep(env)
    env.close()


class ReusedBuffer(gymnasium.Env[np.ndarray, int]):
    """A unit that hands out one float32 buffer, rewritten in place at every step (as a device may)."""

    observation_space = gymnasium.spaces.Box(-10.0, 10.0, (2,), np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def __init__(self) -> None:
        self.buffer = np.zeros(2, np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.buffer[:] = 0.0
        return self.buffer, {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.buffer += 1.0 + action
        return self.buffer, 0.0, False, False, {}


def test_the_last_observation_is_kept_when_the_unit_reuses_its_buffer() -> None:
    env = LastStep(ReusedBuffer())
    env.reset(seed=0)
    first, *_ = env.step(0)
    second, *_ = env.step(1)
    np.testing.assert_array_equal(first[:2], [1.0, 1.0])
    np.testing.assert_array_equal(second[:2], [3.0, 3.0])
    np.testing.assert_array_equal(second[2:4], [1.0, 1.0])  # the step before, not the buffer as it is now
    np.testing.assert_array_equal(second[4:], [0.0, 1.0])
