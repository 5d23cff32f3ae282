"""The envs of a unit host's units, stepped together where they can be.

A unit simulated in-process as a built-in CartPole (``fleetrl/CartPoleUnit-v0`` as ``gymnasium.make`` builds
it: its env over an :class:`~fleetrl.link.inprocess.InProcessLink` to a
:class:`~fleetrl.devices.cartpole.CartPoleDevice`, under gymnasium's ``TimeLimit``, ``OrderEnforcing`` and
``PassiveEnvChecker`` only, no rendering) is stepped with every other such unit of the host in a
:class:`~fleetrl.devices.cartpole_batch.CartPoleBatch`: one compiled call per time step, judged by
:meth:`~fleetrl.envs.cartpole_unit.CartPoleUnitEnv.judge_rows` and truncated at its ``TimeLimit``, each
unit's numbers those its own env would give. Every other unit (behind a device bridge, paced, a QUBE, a
user's unit type) is stepped through its own env, one call each.

Resets always go through the unit's own env (its seeding is the env's); the batch then takes the device's
state. While the batch steps a unit, its env's own wrappers do not see the steps (its ``TimeLimit`` count
stays at 0); the device's state is handed back at every episode's end.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

from fleetrl.devices import cartpole_batch
from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.cartpole_batch import CartPoleBatch
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.link.inprocess import InProcessLink

__all__ = ["HostEnvs", "StepRows", "batched_cartpole"]

_TRANSPARENT = (OrderEnforcing, PassiveEnvChecker)
"""wrappers that change no number of a step"""


@dataclass(frozen=True)
class StepRows:
    """One time step of some units: row j is unit ``units[j]``'s."""

    obs: np.ndarray
    """s_{t+1}, one row per unit"""
    rewards: np.ndarray
    """r_{t+1}, float64"""
    terminated: np.ndarray
    """bool"""
    truncated: np.ndarray
    """bool"""


def batched_cartpole(env: gymnasium.Env[Any, Any]) -> tuple[CartPoleDevice, int | None] | None:
    """The in-process CartPole device and episode cap (None: none) of an env a batch can step, or None if
    ``env`` is anything else (another unit type, a link, another wrapper, rendering), or no batch can
    step CartPoles in this process (:data:`~fleetrl.devices.cartpole_batch.AVAILABLE`)."""
    if not cartpole_batch.AVAILABLE:
        return None
    cap: int | None = None
    inner: Any = env
    while isinstance(inner, gymnasium.Wrapper):
        if type(inner) is TimeLimit and cap is None:
            cap = int(inner._max_episode_steps)
        elif type(inner) not in _TRANSPARENT:
            return None
        inner = inner.env
    if type(inner) is not CartPoleUnitEnv or inner.render_mode is not None:
        return None
    link = inner.link
    if type(link) is not InProcessLink or type(link.device) is not CartPoleDevice:
        return None
    return link.device, cap


class HostEnvs:
    """The units' envs (unit u's is ``envs[u]``): :meth:`reset` one, :meth:`step` many.

    :param envs: one Gymnasium env per unit
    """

    def __init__(self, envs: Sequence[gymnasium.Env[Any, Any]]) -> None:
        self.envs = list(envs)
        found = [batched_cartpole(env) for env in self.envs]
        batched = [u for u, f in enumerate(found) if f is not None]
        self._row = np.full(len(self.envs), -1, dtype=np.int64)
        """unit → its row in the batch (-1: stepped through its own env)"""
        self._row[batched] = np.arange(len(batched))
        self._batch = CartPoleBatch([found[u][0] for u in batched])  # type: ignore[index]
        self._cap = np.array([found[u][1] or np.iinfo(np.int64).max for u in batched], dtype=np.int64)  # type: ignore[index]
        self._elapsed = np.zeros(len(batched), dtype=np.int64)
        self._obs_dtype: np.dtype[Any] | None = None

    @property
    def batched(self) -> np.ndarray:
        """The units stepped in the batch."""
        return np.flatnonzero(self._row >= 0)

    def reset(self, unit: int, seed: int | None) -> np.ndarray:
        """Reset unit ``unit``'s env (with ``seed``, if given); its first observation."""
        obs, _ = self.envs[unit].reset(seed=seed)
        row = int(self._row[unit])
        if row >= 0:
            self._batch.load(row)
            self._elapsed[row] = 0
        first = np.asarray(obs)
        self._obs_dtype = first.dtype if self._obs_dtype is None else np.result_type(self._obs_dtype, first)
        return first

    def step(self, units: np.ndarray, actions: Sequence[Any] | np.ndarray) -> StepRows:
        """Step every unit of ``units`` with its action (row j: ``actions[j]``, as its env takes it), all
        reset before; the batched units in one call, the others one by one."""
        n = len(units)
        rows = self._row[units]
        in_batch = rows >= 0
        dtype = self._obs_dtype if self._obs_dtype is not None else np.float32
        obs = np.empty((n, *self._obs_shape(units)), dtype=dtype)
        rewards = np.empty(n, dtype=np.float64)
        terminated = np.empty(n, dtype=bool)
        truncated = np.empty(n, dtype=bool)
        if in_batch.any():
            batch_rows = rows[in_batch]
            stepped = self._batch.step(batch_rows, np.asarray(actions)[in_batch])
            obs[in_batch] = stepped
            rewards[in_batch], terminated[in_batch] = CartPoleUnitEnv.judge_rows(stepped)
            self._elapsed[batch_rows] += 1
            truncated[in_batch] = self._elapsed[batch_rows] >= self._cap[batch_rows]
            for row in batch_rows[terminated[in_batch] | truncated[in_batch]].tolist():
                self._batch.store(row)  # the episode ends: the device holds its last state again
        for j in np.flatnonzero(~in_batch).tolist():
            action = actions[j]
            if isinstance(action, np.integer):  # an env stepped alone is sent a plain index, as before
                action = int(action)
            next_obs, reward, term, trunc, _ = self.envs[int(units[j])].step(action)
            obs[j] = next_obs
            rewards[j], terminated[j], truncated[j] = float(reward), term, trunc
        return StepRows(obs, rewards, terminated, truncated)

    def _obs_shape(self, units: np.ndarray) -> tuple[int, ...]:
        space = self.envs[int(units[0])].observation_space if len(units) else None
        return tuple(space.shape) if space is not None and space.shape is not None else (4,)
