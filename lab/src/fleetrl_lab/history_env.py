"""A QUBE unit whose observation also holds its last observation and last action (an RMA-like history), as
``--env fleetrl_lab.history_env:qube_wide`` for the lab's question: does a shared policy that can infer each
unit's dynamics from one step of history serve a wide fleet's units better? Not a product feature."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from fleetrl.envs.registration import QUBE_BALANCE_ID, register_envs


class LastStep(gymnasium.ObservationWrapper):
    """Observation ``(obs_t, obs_{t-1}, one-hot a_{t-1})``, ``a_{t-1}`` the action that led to ``obs_t``;
    at a reset the last observation is the first and the last action none (zeros)."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        actions, box = env.action_space, env.observation_space
        assert isinstance(actions, gymnasium.spaces.Discrete) and isinstance(box, gymnasium.spaces.Box)
        self.actions = int(actions.n)
        low = np.concatenate([box.low, box.low, np.zeros(self.actions, np.float32)])
        high = np.concatenate([box.high, box.high, np.ones(self.actions, np.float32)])
        self.observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        self._last_obs = np.zeros(box.low.shape, np.float32)
        self._last_action = np.zeros(self.actions, np.float32)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(**kwargs)
        self._last_obs = np.asarray(obs, np.float32)
        self._last_action = np.zeros(self.actions, np.float32)
        return self.observation(obs), info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._last_action = np.zeros(self.actions, np.float32)
        self._last_action[int(action)] = 1.0  # the action that led from the last observation to this one
        out = self.observation(obs)
        self._last_obs = np.asarray(obs, np.float32)
        return out, float(reward), terminated, truncated, info

    def observation(self, observation: Any) -> np.ndarray:
        return np.concatenate([np.asarray(observation, np.float32), self._last_obs, self._last_action])


def qube_wide(unit: int, fleet_seed: int) -> gymnasium.Env:
    """QUBE unit ``unit`` of the ``wide`` fleet ``fleet_seed``, its observation with the last step."""
    return _qube(unit, fleet_seed, "wide")


def qube_table2(unit: int, fleet_seed: int) -> gymnasium.Env:
    """QUBE unit ``unit`` of the ``table2`` fleet ``fleet_seed`` (the default), with the last step."""
    return _qube(unit, fleet_seed, "table2")


def _qube(unit: int, fleet_seed: int, profile: str) -> gymnasium.Env:
    register_envs()
    return LastStep(gymnasium.make(QUBE_BALANCE_ID, unit=unit, fleet_seed=fleet_seed, fleet_profile=profile))
