"""Wrappers of a unit's env: its observation with its last step in it (``LastStep``, the ``last_step``
setting), a unit paced in real time as on the rig (``PacedEnv``), and one that stalls at times
(``StalledEnv``, ``--stall``). Pacing and stalls change nothing the env computes, only when."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, SupportsFloat

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


class PacedEnv(gymnasium.Wrapper[Any, Any, Any, Any]):
    """``env`` whose steps each last ``period`` seconds of wall time (at least), and its resets their time on
    the rig (reset info ``reset_seconds``) × ``reset_scale``; deadlines are kept (an overshoot does not add
    up). ``clock`` (monotonic seconds) and ``sleep`` are the time source and the wait."""

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        period: float,
        *,
        reset_scale: float = 0.0,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if not period > 0:
            raise ValueError(f"a paced env's period must be > 0 seconds, got {period!r}")
        if not reset_scale >= 0:
            raise ValueError(f"a paced env's reset scale must be >= 0, got {reset_scale!r}")
        super().__init__(env)
        self.period = period
        self.reset_scale = reset_scale
        self._clock = clock
        self._sleep = sleep
        self._due: float | None = None  # when the last step was due to return (None before the first reset)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the unit and wait until its time on the rig, scaled, has passed since the reset began."""
        began = self._clock()
        obs, info = self.env.reset(**kwargs)
        due = began + float(info.get("reset_seconds", 0.0)) * self.reset_scale
        now = self._clock()
        if due > now:
            self._sleep(due - now)
        self._due = max(now, due)
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the unit, then wait until one period after the previous step was due (no wait if late)."""
        result = self.env.step(action)
        now = self._clock()
        due = now if self._due is None else max(now, self._due + self.period)
        if due > now:
            self._sleep(due - now)
        self._due = due
        return result


class StalledEnv(gymnasium.Wrapper[Any, Any, Any, Any]):
    """``env`` whose steps and resets first call ``wait`` (a stalling unit's: returns when not paused)."""

    def __init__(self, env: gymnasium.Env[Any, Any], wait: Callable[[], Any]) -> None:
        super().__init__(env)
        self._wait = wait

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the unit once it is not paused."""
        self._wait()
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the unit once it is not paused."""
        self._wait()
        return self.env.step(action)
