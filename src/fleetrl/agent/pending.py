"""Transitions of many units written in one assignment per field and time step, moved into each unit's
:class:`~fleetrl.agent.memory.TrajectoryMemory` later (what one ``add`` per transition stores)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleetrl.agent.memory import TrajectoryMemory

__all__ = ["PendingTransitions"]

ROWS = 256
"""transitions a unit may have pending before every unit's are moved into its memory"""


class PendingTransitions:
    """Up to :data:`ROWS` transitions per unit, unit u's i-th pending one in row i of column u.

    :param units: U
    :param obs_dim: length of an observation
    :param action_dim: 0 for discrete action indices, else the length of a continuous action
    """

    def __init__(self, units: int, obs_dim: int, action_dim: int = 0) -> None:
        self.counts = np.zeros(units, dtype=np.int64)
        """each unit's pending transitions"""
        self._obs = np.zeros((ROWS, units, obs_dim), dtype=np.float32)
        self._next_obs = np.zeros((ROWS, units, obs_dim), dtype=np.float32)
        if action_dim == 0:
            self._actions = np.zeros((ROWS, units), dtype=np.int64)
        else:
            self._actions = np.zeros((ROWS, units, action_dim), dtype=np.float32)
        self._rewards = np.zeros((ROWS, units), dtype=np.float32)
        self._terminated = np.zeros((ROWS, units), dtype=bool)
        self._truncated = np.zeros((ROWS, units), dtype=bool)
        self._any = False

    def add(
        self,
        memories: Sequence[TrajectoryMemory],
        units: np.ndarray,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
    ) -> None:
        """One transition for each unit of ``units`` (distinct; row j of each array is ``units[j]``'s),
        after its pending ones; first every unit's pending ones move into ``memories`` if a unit's are full.
        """
        if len(units) == 0:
            return
        rows = self.counts[units]
        if int(rows.max()) >= ROWS:
            self.drain(memories)
            rows = self.counts[units]
        self._obs[rows, units] = obs
        self._actions[rows, units] = actions
        self._rewards[rows, units] = rewards
        self._next_obs[rows, units] = next_obs
        self._terminated[rows, units] = terminated
        self._truncated[rows, units] = truncated
        self.counts[units] = rows + 1
        self._any = True

    def drain(self, memories: Sequence[TrajectoryMemory]) -> None:
        """Move every unit's pending transitions into its memory (unit u's into ``memories[u]``), in order."""
        if not self._any:
            return
        for u in np.flatnonzero(self.counts).tolist():
            n = int(self.counts[u])
            memories[u].extend(
                self._obs[:n, u],
                self._actions[:n, u],
                self._rewards[:n, u],
                self._next_obs[:n, u],
                self._terminated[:n, u],
                self._truncated[:n, u],
            )
        self.counts[:] = 0
        self._any = False
