"""Discrete actions for many rows at once: one float64 pass of matrix products gives each row's logits, the
action by the per-row kernel's inverse-CDF rule; a row whose draw lies within :data:`MARGIN` of a boundary
of the cumulative distribution (or whose logits are not finite) goes to the per-row kernel, so every action
is the kernel's (``tests/agent/test_acting_units.py``)."""

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
