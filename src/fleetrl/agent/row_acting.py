"""Acting for many rows at once (a unit host's units): matrix products for speed, the per-row kernel's
actions.

The per-row kernel (:meth:`NumpyPolicy.act_rows <fleetrl.agent.policy_numpy.NumpyPolicy.act_rows>`) streams
the whole actor and calls the C library's ``tanh`` 384 times per row of a 3 x 128 trunk: about 12 µs a row.
Here one float64 pass of matrix products over every row (torch, on the same float64 weights) gives each
row's logits in about 2 µs, and from them the action by the kernel's own rule (inverse CDF of the softmax
with the row's draw ``u``). The two passes sum in different orders and their ``tanh`` differ in the last
bits, so the logits may differ by a few units in the 16th digit; the action can differ only where ``u`` lies
that close to a boundary of the cumulative distribution. So a row whose draw lies within :data:`MARGIN` of a
boundary (or whose logits are not finite) is decided by the per-row kernel itself: every row's action is the
kernel's, provided the two passes' logits differ by less than 2 x :data:`MARGIN` — nine orders of magnitude
above what float64 sums over layers of 128 give (``tests/agent/test_row_acting.py`` checks random and trained
weights, and draws placed on the boundaries).
"""

from __future__ import annotations

import numpy as np
import torch

from fleetrl.agent.policy_numpy import NumpyPolicy

__all__ = ["MARGIN", "RowActing"]

MARGIN = 1e-7
"""how close (as a probability) a draw may come to a boundary of the cumulative distribution before the row
goes to the per-row kernel; a boundary moves by at most half the largest logit difference"""
FEW_ROWS = 16
"""below this many rows the per-row kernel alone is as fast"""


class RowActing:
    """Discrete actions for rows of observations, each the per-row kernel's (see the module's docstring).

    :param policy: the acting copy of π_θ (discrete); its weights are read at every call, so this follows
        the policy's refreshes
    """

    def __init__(self, policy: NumpyPolicy) -> None:
        if not policy.discrete:
            raise TypeError("row acting is for a discrete policy")
        self._policy = policy
        self._layers = [(torch.from_numpy(w), torch.from_numpy(b)) for w, b in policy.layers()]
        self._tanh = policy.activation == "tanh"
        self.kernel_rows = 0
        """rows decided by the per-row kernel so far (few rows, or a draw near a boundary)"""

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Actions (int64, n) for the rows of ``obs`` (n, obs_dim), row i with the uniform draw ``u[i]``:
        row i's action is :meth:`NumpyPolicy.act` ``(obs[i], u[i])``."""
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
        if logits.shape[1] > 1:
            gap = np.abs(threshold[:, None] - cumulative[:, :-1]).min(axis=1)
            doubtful = ~(gap > MARGIN * total) | (draws < 0.0)  # NaN gaps are doubtful too
        else:
            doubtful = draws < 0.0
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
        """The actor's head for every row, float64 (n, head size), by matrix products."""
        activations = torch.from_numpy(rows)
        last = len(self._layers) - 1
        with torch.no_grad():
            for i, (weight, bias) in enumerate(self._layers):
                activations = torch.addmm(bias, activations, weight.t())
                if i < last:
                    activations = torch.tanh_(activations) if self._tanh else torch.relu_(activations)
        return activations.numpy()
