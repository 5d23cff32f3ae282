"""A unit's observation with its last step in it: ``(o_t, o_{t-1}, a_{t-1})``, so one shared policy can tell
units apart by how they answered its last action (the ``last_step`` setting; docs/algorithm.md, "The last
step in the observation")."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np


class LastStep(gymnasium.ObservationWrapper[np.ndarray, Any, Any]):
    """Observation ``(o_t, o_{t-1}, a_{t-1})``: ``a_{t-1}`` the action that led to ``o_t``, one-hot for a
    discrete action, the command clipped to its box for a continuous one. At a reset the last observation is
    the first one and the last action none (zeros)."""

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        super().__init__(env)
        box, actions = env.observation_space, env.action_space
        if not isinstance(box, gymnasium.spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"the last step needs a 1-D Box observation, got {box}")
        if isinstance(actions, gymnasium.spaces.Discrete):
            self._discrete, size = True, int(actions.n)
            act_low, act_high = np.zeros(size, np.float32), np.ones(size, np.float32)
        elif isinstance(actions, gymnasium.spaces.Box) and len(actions.shape) == 1:
            self._discrete, size = False, int(actions.shape[0])
            act_low = np.minimum(actions.low, 0.0).astype(np.float32)
            act_high = np.maximum(actions.high, 0.0).astype(np.float32)
        else:
            raise ValueError(f"the last step needs a Discrete or 1-D Box action, got {actions}")
        self._actions = actions
        low = np.concatenate([box.low, box.low, act_low]).astype(np.float32)
        high = np.concatenate([box.high, box.high, act_high]).astype(np.float32)
        self.observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        self._last_obs = np.zeros(box.shape, np.float32)
        self._last_action = np.zeros(size, np.float32)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._last_obs = np.array(obs, np.float32)  # a copy: a unit may reuse its observation buffer
        self._last_action[:] = 0.0
        return self.observation(obs), info

    def step(self, action: Any) -> tuple[np.ndarray, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._last_action = self._encode(action)
        out = self.observation(obs)
        self._last_obs = np.array(obs, np.float32)  # a copy: a unit may reuse its observation buffer
        return out, reward, terminated, truncated, info

    def observation(self, observation: Any) -> np.ndarray:
        return np.concatenate([np.asarray(observation, np.float32), self._last_obs, self._last_action])

    def _encode(self, action: Any) -> np.ndarray:
        """The action as the observation holds it."""
        if self._discrete:
            encoded = np.zeros_like(self._last_action)
            encoded[int(action)] = 1.0
            return encoded
        box: Any = self._actions
        return np.clip(np.asarray(action, np.float32).reshape(-1), box.low, box.high).astype(np.float32)
