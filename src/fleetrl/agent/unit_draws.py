"""Each unit's uniform draw, for many units in one call: one compiled loop calls numpy's ``next_double``
(the C function behind ``Generator.random()``) on each unit's bit-generator state, the same numbers in
order (other bit generators than PCG64, or a single generator, are drawn from in Python)."""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable, Sequence

import numba
import numpy as np

__all__ = ["UniformDraws"]

DrawKernel = Callable[[np.ndarray, np.ndarray, np.ndarray], None]


@functools.cache
def _kernel(next_double: int) -> DrawKernel:
    """A compiled loop over units that calls the C function at address ``next_double`` (one per process)."""
    function = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_size_t)(next_double)

    @numba.njit  # no cache: the address differs from process to process
    def draw(states: np.ndarray, units: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
        for j in range(units.shape[0]):
            out[j] = function(states[units[j]])

    return draw


class UniformDraws:
    """Uniform draws in [0, 1) from each unit's own Generator.

    :param generators: unit u's is ``generators[u]``; they must outlive this object
    """

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
        """Whether the draws take the compiled path (every Generator a PCG64)."""
        return self._draw is not None

    def draw(self, units: np.ndarray) -> np.ndarray:
        """``generators[u].random()`` for each u of ``units`` in order (float64, one per unit)."""
        if self._draw is None:
            return np.array([self.generators[u].random() for u in units.tolist()], dtype=np.float64)
        out = np.empty(len(units), dtype=np.float64)
        self._draw(self._states, np.asarray(units, dtype=np.int64), out)
        return out
