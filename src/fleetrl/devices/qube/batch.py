"""Many QUBE units stepped together: one compiled call per time step, each unit a row of arrays run through
the very control period a lone ``QubeDevice`` runs (``agent_step``), so the states are equal bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from fleetrl.devices.qube.device import ACTION_VOLTS, QubeDevice
from fleetrl.devices.qube.dynamics import agent_step

_VOLTS = np.array(ACTION_VOLTS, dtype=np.float64)  # volts of action index 0, 1, 2


@njit(cache=True)
def _step_rows(
    states: np.ndarray,
    coefficients: np.ndarray,
    sensors: np.ndarray,
    settings: np.ndarray,
    rows: np.ndarray,
    volts: np.ndarray,
    obs: np.ndarray,
) -> None:  # pragma: no cover - compiled (each row is QubeDevice.step's own call; the tests compare both)
    for j in range(rows.shape[0]):
        i = rows[j]
        agent_step(states[i], coefficients[i], sensors[i], settings[i], volts[j], obs[j])


class QubeBatch:
    """The devices ``devices`` (row i: ``devices[i]``) stepped together; the batch holds each unit's state and
    sensor pipeline while it steps it (:meth:`load` takes them from its device, :meth:`store` hands back)."""

    def __init__(self, devices: Sequence[QubeDevice]) -> None:
        if not devices:
            raise ValueError("a batch of QUBE units needs at least one unit")
        self.devices = list(devices)
        self._coefficients = np.array([d._coefficients for d in self.devices], dtype=np.float64)
        self._settings = np.array([d._agent_settings for d in self.devices], dtype=np.float64)
        self._state = np.array([d._state for d in self.devices], dtype=np.float64)
        self._sensor = np.array([d._sensor for d in self.devices], dtype=np.float64)

    def load(self, row: int) -> None:
        """Take unit ``row``'s state and sensor pipeline from its device."""
        device = self.devices[row]
        self._state[row] = device._state
        self._sensor[row] = device._sensor

    def store(self, row: int) -> None:
        """Hand unit ``row``'s state and sensor pipeline back to its device."""
        device = self.devices[row]
        device._state[:] = self._state[row]
        device._sensor[:] = self._sensor[row]

    def state(self, row: int) -> np.ndarray:
        """A copy of unit ``row``'s true state as the batch holds it (float64)."""
        return self._state[row].copy()

    def sensor(self, row: int) -> np.ndarray:
        """A copy of unit ``row``'s sensor pipeline as the batch holds it (float64)."""
        return self._sensor[row].copy()

    def step(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """One control period for the units ``rows`` with action indices ``actions`` (0, 1, 2); their new
        observations (float32, one row per unit of ``rows``)."""
        indices = np.asarray(actions, dtype=np.int64)
        if indices.size and not bool(np.all((indices >= 0) & (indices <= 2))):
            bad = int(indices[(indices < 0) | (indices > 2)][0])
            raise ValueError(f"action {bad!r} is out of range (choose 0, 1 or 2: power -60, 0, +60)")
        obs = np.empty((len(rows), 4), dtype=np.float32)
        _step_rows(
            self._state,
            self._coefficients,
            self._sensor,
            self._settings,
            np.asarray(rows, dtype=np.int64),
            _VOLTS[indices],
            obs,
        )
        return obs
