"""Acting for many units at once: each unit's uniform draw in one compiled call (:class:`UniformDraws`), and
discrete actions for many rows by one float64 pass of matrix products (:class:`RowActing`), every action
the per-row kernel's."""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable, Sequence

import numba
import numpy as np
import torch

from fleetrl.agent.policy_numpy import NumpyPolicy

__all__ = ["MARGIN", "RowActing", "UniformDraws"]

MARGIN = 1e-7  # how close a draw may come to a boundary of the cumulative distribution (a probability)
FEW_ROWS = 16  # below this many rows the per-row kernel alone is as fast


class RowActing:
    """Discrete actions for rows of observations by the per-row kernel's inverse-CDF rule; a row whose draw
    lies within :data:`MARGIN` of a boundary of the cumulative distribution (or whose logits are not
    finite) goes to the kernel itself. ``policy``'s weights are read at every call (its refreshes count)."""

    def __init__(self, policy: NumpyPolicy) -> None:
        if not policy.discrete:
            raise TypeError("row acting is for a discrete policy")
        self._policy = policy
        self._layers = [(torch.from_numpy(w), torch.from_numpy(b)) for w, b in policy.layers()]
        self._tanh = policy.activation == "tanh"
        self.kernel_rows = 0  # rows decided by the per-row kernel so far

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Actions (int64) for the rows of ``obs``: row i's is :meth:`NumpyPolicy.act` ``(obs[i], u[i])``."""
        rows = np.ascontiguousarray(obs, dtype=np.float64)
        draws = np.ascontiguousarray(u, dtype=np.float64)
        out = np.empty(rows.shape[0], dtype=np.int64)
        if rows.shape[0] < FEW_ROWS:
            self._policy.act_rows_exact(rows, draws, out)
            self.kernel_rows += rows.shape[0]
            return out
        logits = self._logits(rows)
        weights = np.exp(logits - logits.max(axis=1, keepdims=True))
        cumulative = np.cumsum(weights, axis=1)
        total = cumulative[:, -1]
        threshold = draws * total
        # the kernel's rule: the first k with threshold < cumulative[k], else the last action
        out[:] = np.minimum((threshold[:, None] >= cumulative).sum(axis=1), logits.shape[1] - 1)
        gap = np.abs(threshold[:, None] - cumulative[:, :-1]).min(axis=1)  # n >= 2 actions: one boundary
        doubtful = ~(gap > MARGIN * total) | (draws < 0.0)  # NaN gaps are doubtful too
        if doubtful.any():
            which = np.flatnonzero(doubtful)
            exact = np.empty(which.size, dtype=np.int64)
            self._policy.act_rows_exact(
                np.ascontiguousarray(rows[which]), np.ascontiguousarray(draws[which]), exact
            )
            out[which] = exact
            self.kernel_rows += int(which.size)
        return out

    def _logits(self, rows: np.ndarray) -> np.ndarray:
        activations = torch.from_numpy(rows)
        last = len(self._layers) - 1
        with torch.no_grad():
            for i, (weight, bias) in enumerate(self._layers):
                activations = torch.addmm(bias, activations, weight.t())
                if i < last:
                    activations = torch.tanh_(activations) if self._tanh else torch.relu_(activations)
        return activations.numpy()


DrawKernel = Callable[[np.ndarray, np.ndarray, np.ndarray], None]


@functools.cache
def _kernel(next_double: int) -> DrawKernel:
    function = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_size_t)(next_double)

    @numba.njit  # no cache: the address differs from process to process
    def draw(states: np.ndarray, units: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
        for j in range(units.shape[0]):
            out[j] = function(states[units[j]])

    return draw


class UniformDraws:
    """Uniform draws in [0, 1) from each unit's own Generator (unit u's is ``generators[u]``; they must
    outlive this object): one compiled loop calls numpy's ``next_double``, the C function behind
    ``Generator.random()``, on each unit's PCG64 state; other bit generators are drawn from in Python."""

    def __init__(self, generators: Sequence[np.random.Generator]) -> None:
        self.generators = list(generators)
        self._draw: DrawKernel | None = None
        if len(self.generators) > 1 and all(
            type(g.bit_generator) is np.random.PCG64 for g in self.generators
        ):
            interfaces = [g.bit_generator.ctypes for g in self.generators]
            functions = {ctypes.cast(i.next_double, ctypes.c_void_p).value for i in interfaces}
            if len(functions) == 1:  # one C function for every PCG64 (numpy's)
                (address,) = functions
                self._states = np.array([i.state_address for i in interfaces], dtype=np.uint64)
                self._draw = _kernel(int(address or 0))

    @property
    def compiled(self) -> bool:
        return self._draw is not None

    def draw(self, units: np.ndarray) -> np.ndarray:
        """``generators[u].random()`` for each u of ``units`` in order (float64, one per unit)."""
        if self._draw is None:
            return np.array([self.generators[u].random() for u in units.tolist()], dtype=np.float64)
        out = np.empty(len(units), dtype=np.float64)
        self._draw(self._states, np.asarray(units, dtype=np.int64), out)
        return out
