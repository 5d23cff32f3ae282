"""Many CartPole units stepped together: one compiled call per time step, each unit a row of two arrays, bit
for bit the states :class:`~fleetrl.devices.cartpole.CartPoleDevice` steps alone to."""

from __future__ import annotations

import ctypes
import ctypes.util
from collections.abc import Sequence
from typing import Any

import numba
import numpy as np

from fleetrl.devices.cartpole import CartPoleDevice


# A batch step is CartPoleDevice.step's arithmetic, the same IEEE operations in the same order, with the C
# library's cos, sin and pow (what math and ** call) reached through ctypes: the compiler can then neither
# fuse nor replace them (LLVM makes pow(x, 2) x * x, which differs in the last bit about once in 1,000).
def _libm_functions() -> tuple[Any, Any, Any] | None:
    """The C library's ``cos``, ``sin`` and ``pow`` (those Python calls), or None where not found."""
    name = ctypes.util.find_library("m")
    if name is None:
        return None
    try:
        libm = ctypes.CDLL(name)
        cos, sin, pow_ = libm.cos, libm.sin, libm.pow
    except (OSError, AttributeError):
        return None
    for function, arguments in ((cos, 1), (sin, 1), (pow_, 2)):
        function.argtypes = [ctypes.c_double] * arguments
        function.restype = ctypes.c_double
    return cos, sin, pow_


_FUNCTIONS = _libm_functions()
AVAILABLE = _FUNCTIONS is not None
"""whether CartPoles can be stepped in a batch in this process (the C library's functions were found)"""
_NOT_FOUND: tuple[Any, Any, Any] = (None, None, None)
_COS, _SIN, _POW = _FUNCTIONS or _NOT_FOUND

# parameter columns
_MASSCART, _MASSPOLE, _LENGTH, _FORCE_MAG, _TAU, _GRAVITY = range(6)


@numba.njit  # no cache: the C functions' addresses differ from process to process
def _step_rows(
    params: np.ndarray, state: np.ndarray, rows: np.ndarray, actions: np.ndarray, obs: np.ndarray
) -> None:  # pragma: no cover - compiled (its Python twin is CartPoleDevice.step; the tests compare both)
    for j in range(rows.shape[0]):
        i = rows[j]
        masscart = params[i, _MASSCART]
        masspole = params[i, _MASSPOLE]
        length = params[i, _LENGTH]
        force_mag = params[i, _FORCE_MAG]
        tau = params[i, _TAU]
        gravity = params[i, _GRAVITY]
        x = state[i, 0]
        x_dot = state[i, 1]
        theta = state[i, 2]
        theta_dot = state[i, 3]
        force = force_mag if actions[j] == 1 else -force_mag
        cos_t = _COS(theta)
        sin_t = _SIN(theta)
        total_mass = masspole + masscart
        pole_mass_length = masspole * length
        temp = (force + pole_mass_length * _POW(theta_dot, 2.0) * sin_t) / total_mass
        theta_acc = (gravity * sin_t - cos_t * temp) / (
            length * (4.0 / 3.0 - masspole * _POW(cos_t, 2.0) / total_mass)
        )
        x_acc = temp - pole_mass_length * theta_acc * cos_t / total_mass
        x += tau * x_dot
        x_dot += tau * x_acc
        theta += tau * theta_dot
        theta_dot += tau * theta_acc
        state[i, 0] = x
        state[i, 1] = x_dot
        state[i, 2] = theta
        state[i, 3] = theta_dot
        for k in range(4):
            obs[j, k] = np.float32(state[i, k])


class CartPoleBatch:
    """The devices ``devices`` stepped together, row i ``devices[i]``, each state held while it steps."""

    def __init__(self, devices: Sequence[CartPoleDevice]) -> None:
        self.devices = list(devices)
        self._params = np.array(
            [[d.params.masscart, d.params.masspole, d.params.length, d.params.force_mag, d.params.tau,
              d.params.gravity] for d in self.devices],
            dtype=np.float64,
        ).reshape(len(self.devices), 6)  # fmt: skip
        self._state = np.zeros((len(self.devices), 4), dtype=np.float64)

    def load(self, row: int) -> None:
        """Take unit ``row``'s state from its device."""
        self._state[row] = self.devices[row].state

    def store(self, row: int) -> None:
        """Hand unit ``row``'s state back to its device."""
        self.devices[row].set_state(self._state[row])

    def state(self, row: int) -> np.ndarray:
        """A copy of unit ``row``'s state as the batch holds it (float64)."""
        return self._state[row].copy()

    def step(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Push the units ``rows`` left (0) or right (1) as ``actions`` say; their new observations."""
        moves = np.asarray(actions, dtype=np.int64)
        if moves.size and not bool(np.all((moves == 0) | (moves == 1))):
            bad = int(moves[(moves != 0) & (moves != 1)][0])
            raise ValueError(f"action {bad!r} is out of range (choose 0: push left, or 1: push right)")
        obs = np.empty((len(rows), 4), dtype=np.float32)
        _step_rows(self._params, self._state, np.asarray(rows, dtype=np.int64), moves, obs)
        return obs
