"""rgb_array frames, and Stable-Baselines3's make_vec_env (which asks for rgb_array) on both envs."""

import gymnasium
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_ID


@pytest.mark.parametrize("env_id", [QUBE_BALANCE_ID, CARTPOLE_UNIT_ID])
def test_rgb_array_frames_follow_the_state(env_id: str) -> None:
    env = gymnasium.make(env_id, unit=1, fleet_seed=0, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray) and first.shape == (200, 200, 3) and first.dtype == np.uint8
    assert (first < 255).any()
    for _ in range(8):
        env.step(2 if env_id == QUBE_BALANCE_ID else 1)
    later = env.render()
    assert later is not None and not np.array_equal(first, later)


@pytest.mark.parametrize("env_id", [QUBE_BALANCE_ID, CARTPOLE_UNIT_ID])
def test_no_frames_without_render_mode_and_bad_modes_are_refused(env_id: str) -> None:
    env = gymnasium.make(env_id)
    env.reset(seed=0)
    assert env.render() is None
    entry_point = gymnasium.spec(env_id).entry_point
    assert isinstance(entry_point, str) and entry_point.startswith("fleetrl.envs.")  # loads lazily
    with pytest.raises(ValueError, match="render_mode 'human' is not supported"):
        gymnasium.envs.registration.load_env_creator(entry_point)(render_mode="human")


@pytest.mark.parametrize("env_id", [QUBE_BALANCE_ID, CARTPOLE_UNIT_ID])
def test_sb3_make_vec_env_builds_the_envs_unchanged(env_id: str) -> None:
    vec_env = make_vec_env(env_id, n_envs=2, seed=0, env_kwargs={"unit": 2, "fleet_seed": 1})
    obs = vec_env.reset()
    assert obs.shape == (2, 4)
    obs, rewards, dones, _ = vec_env.step(np.array([0, 1]))
    assert obs.shape == (2, 4) and rewards.shape == (2,) and dones.shape == (2,)
    vec_env.close()
