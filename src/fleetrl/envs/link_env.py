"""What the cyber environments share: a device link, seeded resets, action checking, and small
``rgb_array`` frames drawn with numpy alone."""

import math
from abc import abstractmethod
from typing import Any

import gymnasium
import numpy as np

from fleetrl.link.base import DeviceLink

FRAME = 200  # frame height and width in pixels
ARM, PENDULUM, CART, TRACK = (40, 90, 160), (200, 60, 40), (60, 60, 60), (170, 170, 170)


def action_index(action: object, n_actions: int) -> int:
    """``action`` as a plain int in [0, n_actions), or a ValueError that says what is allowed."""
    if isinstance(action, int | np.integer) and not isinstance(action, bool):
        index = int(action)
    elif isinstance(action, np.ndarray) and action.size == 1 and np.issubdtype(action.dtype, np.integer):
        index = int(action.reshape(()))
    else:
        index = -1
    if not 0 <= index < n_actions:
        raise ValueError(f"action {action!r} is out of range (choose an integer 0 to {n_actions - 1})")
    return index


def box_action(action: object, space: gymnasium.spaces.Box) -> np.ndarray:
    """``action`` as a float32 vector of the box's shape, clipped to its bounds, or a ValueError."""
    if type(action) is np.ndarray and action.dtype == np.float32 and action.shape == space.shape:
        vector = action  # the common case (an agent's action), checked in a few µs
    else:
        raw = np.asarray(action) if action is not None else np.asarray(np.nan)
        numeric = np.issubdtype(raw.dtype, np.integer) or np.issubdtype(raw.dtype, np.floating)
        vector = raw.astype(np.float32) if numeric else np.full(1, np.nan, dtype=np.float32)
        if vector.shape == () and space.shape == (1,):
            vector = vector.reshape(1)
    if vector.shape != space.shape or not all(map(math.isfinite, vector.tolist())):
        raise ValueError(
            f"action {action!r} is not allowed (give {space.shape[0]} finite numbers, "
            f"each within {space.low.tolist()} .. {space.high.tolist()}; values beyond are clipped)"
        )
    return np.minimum(np.maximum(vector, space.low), space.high)


def blank() -> np.ndarray:
    """A white frame."""
    return np.full((FRAME, FRAME, 3), 255, dtype=np.uint8)


def line(
    img: np.ndarray,
    start: tuple[float, float],
    end: tuple[float, float],
    color: tuple[int, ...],
    width: int = 3,
) -> None:
    """Draw a thick segment between two (x, y) pixel points (y down), clipped to the frame."""
    n = int(max(abs(end[0] - start[0]), abs(end[1] - start[1]))) + 1
    xs = np.rint(np.linspace(start[0], end[0], n)).astype(int)
    ys = np.rint(np.linspace(start[1], end[1], n)).astype(int)
    half = width // 2
    for dx in range(-half, half + 1):
        for dy in range(-half, half + 1):
            x, y = xs + dx, ys + dy
            keep = (x >= 0) & (x < img.shape[1]) & (y >= 0) & (y < img.shape[0])
            img[y[keep], x[keep]] = color


class LinkEnv(gymnasium.Env[np.ndarray, Any]):
    """A Gymnasium env whose device sits behind a ``DeviceLink``; subclasses judge each observation."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 50}  # noqa: RUF012 (gymnasium's convention)

    def __init__(self, link: DeviceLink, n_actions: int, render_mode: str | None = None) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode {render_mode!r} is not supported (use None or 'rgb_array')")
        self.render_mode = render_mode
        self._link = link
        self._n_actions = n_actions
        self._link_step = link.step
        self._last_obs: np.ndarray | None = None

    @property
    def link(self) -> DeviceLink:
        """The link this env reaches its device through."""
        return self._link

    @abstractmethod
    def judge(self, obs: np.ndarray) -> tuple[float, bool]:
        """Reward and termination for an observation; subclasses define the task."""

    @abstractmethod
    def frame(self, obs: np.ndarray) -> np.ndarray:
        """An ``rgb_array`` picture of an observation; subclasses draw their unit."""

    def link_action(self, action: object) -> Any:
        """The action as the link takes it: a plain index in [0, n_actions), or a ValueError."""
        return action_index(action, self._n_actions)

    def render(self) -> np.ndarray | None:
        """The last observation as an RGB frame with ``render_mode="rgb_array"``; None otherwise."""
        if self.render_mode != "rgb_array" or self._last_obs is None:
            return None
        return self.frame(self._last_obs)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Seed and reset the device; the info holds ``reset_seconds`` where the link knows it."""
        super().reset(seed=seed)
        device_seed = int(self.np_random.integers(0, 2**63 - 1))
        self._last_obs = self._link.reset(device_seed).copy()
        seconds = getattr(self._link, "last_reset_seconds", None)
        return self._last_obs, {} if seconds is None else {"reset_seconds": seconds}

    def step(self, action: object) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Send the action, judge the new observation. Truncation is left to gymnasium's TimeLimit."""
        index = action if type(action) is int and 0 <= action < self._n_actions else None
        obs, extra = self._link_step(self.link_action(action) if index is None else index)
        reward, terminated = self.judge(obs)
        self._last_obs = obs = obs.copy()
        return obs, reward, terminated, False, dict(extra) if extra else {}

    def close(self) -> None:
        """Close the link."""
        self._link.close()
