"""The envs of many units, stepped together where they can be: in-process CartPoles and QUBEs as
``gymnasium.make`` builds them in one compiled batch call per type and time step (two or more of a type), each
unit's numbers those its own env gives; every other unit, and every reset, through its own env."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

from fleetrl.devices import cartpole_batch
from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.cartpole_batch import CartPoleBatch
from fleetrl.devices.qube.device import QubeBatch, QubeDevice
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.inprocess import InProcessLink

__all__ = ["HostEnvs", "StepRows", "batched_device"]

_TRANSPARENT = (OrderEnforcing, PassiveEnvChecker)  # wrappers that change no number of a step


@dataclass(frozen=True)
class StepRows:
    """One time step of some units: row j is unit ``units[j]``'s."""

    obs: np.ndarray  # s_{t+1}, one row per unit
    rewards: np.ndarray  # r_{t+1}, float64
    terminated: np.ndarray  # bool
    truncated: np.ndarray  # bool


@dataclass(frozen=True)
class _Kind:
    """A unit type whose in-process units a batch can step."""

    env: type[CartPoleUnitEnv | QubeBalanceEnv]  # its ``judge_rows`` judges a batch's steps
    device: type
    batch: Callable[[list[Any]], Any]  # the batch of a list of such devices
    available: bool = True  # whether such a batch can run in this process


_KINDS = (
    _Kind(CartPoleUnitEnv, CartPoleDevice, CartPoleBatch, cartpole_batch.AVAILABLE),
    _Kind(QubeBalanceEnv, QubeDevice, QubeBatch),
)
"""the unit types stepped in batches, the kind's index its batch's"""


def batched_device(env: gymnasium.Env[Any, Any]) -> tuple[int, Any, int | None] | None:
    """The batch kind, in-process device and episode cap of an env a batch can step, else None."""
    cap: int | None = None
    inner: Any = env
    while isinstance(inner, gymnasium.Wrapper):
        if type(inner) is TimeLimit and cap is None:
            cap = int(inner._max_episode_steps)
        elif type(inner) not in _TRANSPARENT:
            return None
        inner = inner.env
    for index, kind in enumerate(_KINDS):
        if type(inner) is not kind.env:
            continue
        link = getattr(inner, "link", None)
        if not kind.available or inner.render_mode is not None or type(link) is not InProcessLink:
            return None
        return (index, link.device, cap) if type(link.device) is kind.device else None
    return None


@dataclass
class _Batch:
    """One kind's batch in a host, with each of its rows' episode cap and steps so far."""

    kind: _Kind
    stepper: Any
    cap: np.ndarray
    elapsed: np.ndarray


class HostEnvs:
    """The units' envs (unit u's is ``envs[u]``): :meth:`reset` one, :meth:`step` many."""

    def __init__(self, envs: Sequence[gymnasium.Env[Any, Any]]) -> None:
        self.envs = list(envs)
        found = [batched_device(env) for env in self.envs]
        self._kind = np.full(len(self.envs), -1, dtype=np.int64)  # unit → its batch's kind (-1: none)
        self._row = np.full(len(self.envs), -1, dtype=np.int64)  # unit → its row in its batch
        self._batches: dict[int, _Batch] = {}
        for index, kind in enumerate(_KINDS):
            units = [u for u, f in enumerate(found) if f is not None and f[0] == index]
            if len(units) < 2:  # a unit alone is stepped as fast through its own env
                continue
            self._kind[units] = index
            self._row[units] = np.arange(len(units))
            caps = [found[u][2] or np.iinfo(np.int64).max for u in units]  # type: ignore[index]
            stepper = kind.batch([found[u][1] for u in units])  # type: ignore[index]
            self._batches[index] = _Batch(
                kind, stepper, np.array(caps, dtype=np.int64), np.zeros(len(units), dtype=np.int64)
            )
        self._obs_dtype: np.dtype[Any] | None = None
        space = self.envs[0].observation_space if self.envs else None
        self._obs_shape = tuple(space.shape) if space is not None and space.shape is not None else (4,)

    @property
    def batched(self) -> np.ndarray:
        """The units stepped in a batch."""
        return np.flatnonzero(self._kind >= 0)

    def reset(self, unit: int, seed: int | None) -> np.ndarray:
        """Reset unit ``unit``'s env (with ``seed``, if given); its first observation."""
        obs, _ = self.envs[unit].reset(seed=seed)
        kind = int(self._kind[unit])
        if kind >= 0:
            row = int(self._row[unit])
            self._batches[kind].stepper.load(row)
            self._batches[kind].elapsed[row] = 0
        first = np.asarray(obs)
        self._obs_dtype = first.dtype if self._obs_dtype is None else np.result_type(self._obs_dtype, first)
        return first

    def step(self, units: np.ndarray, actions: Sequence[Any] | np.ndarray) -> StepRows:
        """Step every unit of ``units`` with its action (row j: ``actions[j]``), all reset before."""
        n = len(units)
        kinds = self._kind[units]
        dtype = self._obs_dtype if self._obs_dtype is not None else np.float32
        obs = np.empty((n, *self._obs_shape), dtype=dtype)
        rewards = np.empty(n, dtype=np.float64)
        terminated, truncated = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        chosen = np.asarray(actions) if self._batches else np.empty(0)  # once a step, not once a batch
        for index, batch in self._batches.items():
            mine = kinds == index
            if not mine.any():
                continue
            rows = self._row[units[mine]]
            stepped = batch.stepper.step(rows, chosen[mine])
            obs[mine] = stepped
            rewards[mine], terminated[mine] = batch.kind.env.judge_rows(stepped)
            batch.elapsed[rows] += 1
            truncated[mine] = batch.elapsed[rows] >= batch.cap[rows]
            for row in rows[terminated[mine] | truncated[mine]].tolist():
                batch.stepper.store(row)  # the episode ends: the device holds its last state again
        alone = range(n) if not self._batches else np.flatnonzero(kinds < 0).tolist()
        for j in alone:
            action = actions[j]
            if isinstance(action, np.integer):  # an env stepped alone is sent a plain index, as before
                action = int(action)
            next_obs, reward, term, trunc, _ = self.envs[int(units[j])].step(action)
            obs[j] = next_obs
            rewards[j], terminated[j], truncated[j] = float(reward), term, trunc
        return StepRows(obs, rewards, terminated, truncated)
