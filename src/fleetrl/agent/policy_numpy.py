"""Fast acting: a numba copy of the actor (trunk + policy head), refreshed after every change of θ, so a
rollout step never touches torch. This module imports no torch (a policy read from a file runs without it)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numba
import numpy as np

from fleetrl import portable
from fleetrl.agent.action_space import ActionSpace

if TYPE_CHECKING:
    from fleetrl.agent.network import ActorCritic

Layer = tuple[np.ndarray, np.ndarray]  # weight (out, in), bias (out,)

_TANH = 0
_RELU = 1
# fastmath lets LLVM reorder and fuse the sums per CPU; the portable mode gives that speed up
_FASTMATH = not portable.enabled()


@numba.njit(cache=True, fastmath=_FASTMATH)
def _logits_kernel(
    weights: np.ndarray,
    biases: np.ndarray,
    dims: np.ndarray,
    activation: int,
    obs: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
) -> np.ndarray:
    """Forward pass of the actor: layer l maps dims[l] → dims[l+1] with weights[l] (zero-padded)."""
    n_layers = dims.shape[0] - 1
    for i in range(dims[0]):
        a[i] = obs[i]
    for layer in range(n_layers):
        n_in = dims[layer]
        n_out = dims[layer + 1]
        last = layer == n_layers - 1
        w = weights[layer]
        for o in range(n_out):
            s = biases[layer, o]
            row = w[o]
            for i in range(n_in):
                s += row[i] * a[i]
            if last:
                b[o] = s
            elif activation == _TANH:
                b[o] = np.tanh(s)
            else:
                b[o] = s if s > 0.0 else 0.0
        for o in range(n_out):
            a[o] = b[o]
    return a[: dims[n_layers]]


@numba.njit(cache=True, fastmath=_FASTMATH)
def _act_kernel(
    weights: np.ndarray,
    biases: np.ndarray,
    dims: np.ndarray,
    activation: int,
    obs: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    u: float,
) -> int:
    """Sample an action by inverse CDF with uniform ``u`` in [0, 1); ``u < 0`` means argmax (greedy)."""
    logits = _logits_kernel(weights, biases, dims, activation, obs, a, b)
    n = logits.shape[0]
    best = 0
    for k in range(1, n):
        if logits[k] > logits[best]:
            best = k
    if u < 0.0:
        return best
    total = 0.0
    for k in range(n):
        b[k] = np.exp(logits[k] - logits[best])
        total += b[k]
    threshold = u * total
    cumulative = 0.0
    for k in range(n):
        cumulative += b[k]
        if threshold < cumulative:
            return k
    return n - 1


@numba.njit(cache=True, fastmath=_FASTMATH)
def _act_rows_kernel(
    weights: np.ndarray,
    biases: np.ndarray,
    dims: np.ndarray,
    activation: int,
    obs: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    u: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`_act_kernel` for every row of ``obs`` with its draw ``u[row]``, into ``out``."""
    for row in range(obs.shape[0]):
        out[row] = _act_kernel(weights, biases, dims, activation, obs[row], a, b, u[row])


@numba.njit(cache=True, fastmath=_FASTMATH)
def _gaussian_kernel(
    weights: np.ndarray,
    biases: np.ndarray,
    dims: np.ndarray,
    activation: int,
    obs: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    centre: np.ndarray,
    half: np.ndarray,
    std: np.ndarray,
    z: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    out: np.ndarray,
) -> None:
    """A Gaussian action into ``out``: mean + σ·z for standard normal draws ``z`` (unclipped: what the
    memory stores); with an empty ``z`` the mean clipped to [low, high] (greedy)."""
    head = _logits_kernel(weights, biases, dims, activation, obs, a, b)
    greedy = z.shape[0] == 0
    for d in range(out.shape[0]):
        mean = centre[d] + half[d] * head[d]
        if greedy:
            out[d] = min(max(mean, low[d]), high[d])
        else:
            out[d] = mean + std[d] * z[d]


class NumpyPolicy:
    """A frozen float64 copy of π_θ (trunk, policy head, a Gaussian's log-std) for acting; call
    :meth:`refresh` after θ changes."""

    def __init__(self, net: ActorCritic) -> None:
        widths = [net.obs_dim, *(layer.out_features for layer in net.trunk_layers)]
        self._setup([*widths, net.action_space.head_size], net.activation, net.action_space)
        self.refresh(net)

    @classmethod
    def from_layers(
        cls,
        layers: Sequence[Layer],
        activation: str,
        space: ActionSpace,
        log_std: np.ndarray | None = None,
    ) -> NumpyPolicy:
        """A policy from plain arrays: the trunk's layers then the policy head's."""
        policy = cls.__new__(cls)
        widths = [int(layers[0][0].shape[1])] + [int(weight.shape[0]) for weight, _ in layers]
        policy._setup(widths, activation, space)
        policy._load(layers, log_std)
        return policy

    def _setup(self, widths: list[int], activation: str, space: ActionSpace) -> None:
        self._activation = _TANH if activation == "tanh" else _RELU
        self.discrete = space.is_discrete
        self._centre = space.centre()
        self._half = space.half_range()
        self._low = np.asarray(space.low, dtype=np.float64)
        self._high = np.asarray(space.high, dtype=np.float64)
        self._std = np.ones(space.dim, dtype=np.float64)
        self._no_draw = np.zeros(0, dtype=np.float64)
        self._dims = np.asarray(widths, dtype=np.int64)
        self._a = np.zeros(max(widths), dtype=np.float64)
        self._b = np.zeros(max(widths), dtype=np.float64)
        self._obs = np.zeros(widths[0], dtype=np.float64)
        n_layers, width = len(widths) - 1, max(widths)
        self._weights = np.zeros((n_layers, width, width), dtype=np.float64)
        self._biases = np.zeros((n_layers, width), dtype=np.float64)

    def refresh(self, net: ActorCritic) -> None:
        """Copy the current trunk and policy-head weights out of ``net`` (with the unit's own offsets)."""
        names = [*(f"trunk.{i}" for i in range(len(net.trunk_layers))), "policy"]
        effective = [net.effective(name) for name in names]
        arrays = [(w.detach().cpu().numpy(), b.detach().cpu().numpy()) for w, b in effective]
        log_std = None if net.policy_log_std is None else net.policy_log_std.detach().cpu().numpy()
        self._load(arrays, log_std)

    def _load(self, layers: Sequence[Layer], log_std: np.ndarray | None) -> None:
        for i, (w, bias) in enumerate(layers):
            self._weights[i, : w.shape[0], : w.shape[1]] = w
            self._biases[i, : w.shape[0]] = bias
        if log_std is not None:
            self._std = self._half * np.exp(np.asarray(log_std).astype(np.float64))

    def _net(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        return self._weights, self._biases, self._dims, self._activation

    def _load_obs(self, obs: np.ndarray) -> np.ndarray:
        flat = np.asarray(obs, dtype=np.float64).reshape(-1)
        if flat.shape[0] != self._dims[0]:
            raise ValueError(f"observation has {flat.shape[0]} values, the policy expects {self._dims[0]}")
        return flat

    def act(self, obs: np.ndarray, u: float) -> int:
        """Action sampled from π_θ(·|obs) using the uniform draw ``u`` in [0, 1) (discrete)."""
        if not self.discrete:
            raise TypeError("a Gaussian policy acts with act_continuous(obs, z)")
        return int(_act_kernel(*self._net(), self._load_obs(obs), self._a, self._b, u))

    def act_rows(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Actions (int64, n) for the rows of ``obs``: row i's is :meth:`act` ``(obs[i], u[i])``."""
        if not self.discrete:
            raise TypeError("a Gaussian policy acts with act_continuous(obs, z)")
        rows = np.ascontiguousarray(obs, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != self._dims[0]:
            raise ValueError(f"observations have shape {rows.shape}, the policy expects (n, {self._dims[0]})")
        out = np.empty(rows.shape[0], dtype=np.int64)
        self.act_rows_exact(rows, np.ascontiguousarray(u, dtype=np.float64), out)
        return out

    def act_rows_exact(self, rows: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:
        """:meth:`act_rows` without its checks (``rows`` and ``u`` float64, C-contiguous) into ``out``."""
        _act_rows_kernel(*self._net(), rows, self._a, self._b, u, out)

    def layers(self) -> list[Layer]:
        """The trunk's layers then the policy head's as float64 views of the arrays the kernels read (they
        follow every :meth:`refresh`)."""
        return [
            (self._weights[i, : self._dims[i + 1], : self._dims[i]], self._biases[i, : self._dims[i + 1]])
            for i in range(len(self._dims) - 1)
        ]

    @property
    def activation(self) -> str:
        """The trunk's activation: ``tanh`` or ``relu``."""
        return "tanh" if self._activation == _TANH else "relu"

    def act_greedy(self, obs: np.ndarray) -> int:
        """The most probable action under π_θ(·|obs) (discrete)."""
        return self.act(obs, -1.0)  # the kernel takes a negative draw as "the arg-max, no sampling"

    def act_continuous(self, obs: np.ndarray, z: np.ndarray | None) -> np.ndarray:
        """A Gaussian action (float32): mean + σ·``z`` for standard normal draws ``z`` (not clipped), or for
        ``z=None`` the mean clipped to the box (greedy)."""
        if self.discrete:
            raise TypeError("a discrete policy acts with act(obs, u)")
        draws = self._no_draw if z is None else np.asarray(z, dtype=np.float64)
        if z is not None and draws.shape != self._std.shape:
            raise ValueError(f"need {self._std.shape[0]} normal draws, got shape {draws.shape}")
        out = np.empty(self._std.shape[0], dtype=np.float64)
        gaussian = (self._centre, self._half, self._std, draws, self._low, self._high)
        _gaussian_kernel(*self._net(), self._load_obs(obs), self._a, self._b, *gaussian, out)
        return out.astype(np.float32)

    def gaussian(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and σ of π_θ(·|obs) in the env's units, float64 (for tests and inspection)."""
        head = _logits_kernel(*self._net(), self._load_obs(obs), self._a, self._b)
        return self._centre + self._half * head, self._std.copy()

    def probabilities(self, obs: np.ndarray) -> np.ndarray:
        """π_θ(·|obs) as a float64 vector (for tests and inspection; discrete)."""
        if not self.discrete:
            raise TypeError("a Gaussian policy has no probability vector: see gaussian(obs)")
        logits = _logits_kernel(*self._net(), self._load_obs(obs), self._a, self._b).copy()
        z = np.exp(logits - logits.max())
        return np.asarray(z / z.sum())
