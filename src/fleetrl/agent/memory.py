"""Trajectory memory (the last N transitions across episodes, or one round's), its windows, and the pending
transitions of many units, moved into their memories in bulk."""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, fields

import numpy as np
import torch


@dataclass(frozen=True)
class Transitions:
    """A chronological run of transitions ⟨s_t, a_t, r_{t+1}, s_{t+1}⟩ (Algorithm 2, line 5), oldest first:
    float32 arrays, but int64 discrete actions (a continuous action as sampled, before clipping)."""

    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_obs: np.ndarray
    terminated: np.ndarray
    """1 where s_{t+1} is terminal (no bootstrap from V(s_{t+1}))"""
    episode_end: np.ndarray
    """1 where the episode ended at this step (terminated or truncated): GAE stops here"""
    behaviour_log_probs: np.ndarray
    """log π(a_t|s_t) under the policy that acted (filled in by the agent)"""

    def __len__(self) -> int:
        return int(self.actions.shape[0])


class TrajectoryMemory:
    """A ring buffer of the last ``capacity`` transitions (``ring``, Table 1: 200), or with ``grows``
    (``per_round``) a buffer that doubles when full, emptied by the agent after each update.

    :param action_dim: 0 for discrete action indices (int64), else the length of a continuous action
    """

    def __init__(self, capacity: int, obs_dim: int, grows: bool = False, action_dim: int = 0) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        if action_dim < 0:
            raise ValueError(f"action_dim must be >= 0 (0: discrete actions), got {action_dim}")
        self.capacity = capacity
        self.grows = grows
        self._obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self._next_obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        if action_dim == 0:
            self._actions = np.zeros(capacity, dtype=np.int64)
        else:
            self._actions = np.zeros((capacity, action_dim), dtype=np.float32)
        self._rewards = np.zeros(capacity, dtype=np.float32)
        self._terminated = np.zeros(capacity, dtype=np.float32)
        self._episode_end = np.zeros(capacity, dtype=np.float32)
        self._log_probs = np.zeros(capacity, dtype=np.float32)
        self._scored = np.zeros(capacity, dtype=bool)
        self._next = 0
        self._size = 0

    def __len__(self) -> int:
        return self._size

    def add(
        self,
        obs: np.ndarray,
        action: int | np.ndarray,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        truncated: bool,
    ) -> None:
        """Store one transition; when full, overwrite the oldest (ring) or double the buffer (``grows``)."""
        if self.grows and self._size == self._buffer_size:
            self._resize(2 * self._buffer_size)
        i = self._next
        self._obs[i] = obs
        self._actions[i] = action
        self._rewards[i] = reward
        self._next_obs[i] = next_obs
        self._terminated[i] = 1.0 if terminated else 0.0
        self._episode_end[i] = 1.0 if (terminated or truncated) else 0.0
        self._scored[i] = False
        self._next = (i + 1) % self._buffer_size
        self._size = min(self._size + 1, self._buffer_size)

    def extend(
        self,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
    ) -> None:
        """Store n transitions in order (row i of each array is the i-th), as n calls of :meth:`add` do."""
        n = len(rewards)
        if n == 0:
            return
        if self.grows:
            while self._size + n > self._buffer_size:
                self._resize(2 * self._buffer_size)
        size = self._buffer_size
        first = max(0, n - size)  # a ring keeps only the last `size` of them
        start = (self._next + first) % size
        slots: slice | np.ndarray = slice(start, start + n - first)
        if start + n - first > size:  # the run wraps round the ring's end
            slots = (start + np.arange(n - first)) % size
        kept = slice(first, n)
        self._obs[slots] = obs[kept]
        self._actions[slots] = actions[kept]
        self._rewards[slots] = rewards[kept]
        self._next_obs[slots] = next_obs[kept]
        ends = np.asarray(terminated[kept], dtype=bool)
        self._terminated[slots] = ends
        self._episode_end[slots] = ends | np.asarray(truncated[kept], dtype=bool)
        self._scored[slots] = False
        self._next = (self._next + n) % size
        self._size = min(self._size + n, size)

    def clear(self) -> None:
        """Forget every transition."""
        self._next = 0
        self._size = 0

    @property
    def _buffer_size(self) -> int:
        return int(self._actions.shape[0])

    def _resize(self, size: int) -> None:
        keep = min(size, self._buffer_size)
        for name in _STATE:
            old = getattr(self, name)
            new = np.zeros((size, *old.shape[1:]), dtype=old.dtype)
            new[:keep] = old[:keep]
            setattr(self, name, new)
        self._size = min(self._size, size)
        self._next = self._size % size  # the write position wrapped to 0 when the old buffer filled

    def transitions(self) -> Transitions:
        """All stored transitions in chronological order (a copy)."""
        if self._size < self._buffer_size:
            order = np.arange(self._size)
        else:
            order = (np.arange(self._buffer_size) + self._next) % self._buffer_size
        return Transitions(
            self._obs[order],
            self._actions[order],
            self._rewards[order],
            self._next_obs[order],
            self._terminated[order],
            self._episode_end[order],
            self._log_probs[order],
        )

    def unscored(self) -> np.ndarray:
        """Slots of transitions whose behaviour log-probability is not yet recorded (the agent scores them
        right before the policy changes, so with the policy that acted)."""
        return np.flatnonzero(~self._scored[: self._size])

    def score(self, slots: np.ndarray, log_probs: np.ndarray) -> None:
        """Record behaviour log-probabilities for ``slots`` (from :meth:`unscored`)."""
        self._log_probs[slots] = log_probs
        self._scored[slots] = True

    def slots(self, slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Observations and actions stored at ``slots``."""
        return self._obs[slots], self._actions[slots]

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The whole buffer as named arrays (copies), ring position included, for a checkpoint."""
        arrays = {name.lstrip("_"): getattr(self, name).copy() for name in _STATE}
        arrays["position"] = np.array([self._next, self._size], dtype=np.int64)
        return arrays

    def load_state_arrays(self, arrays: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state_arrays` returned (a growing memory first takes the saved length)."""
        saved = np.asarray(arrays["actions"]).shape[0]
        if self.grows and saved >= self.capacity and saved != self._buffer_size:
            self._resize(saved)
        for name in _STATE:
            current = getattr(self, name)
            key = name.lstrip("_")
            value = np.asarray(arrays[key])
            if value.shape != current.shape:
                raise ValueError(f"memory {key} has shape {value.shape}, expected {current.shape}")
            current[...] = value
        self._next, self._size = (int(v) for v in arrays["position"])


_STATE = ("_obs", "_next_obs", "_actions", "_rewards", "_terminated", "_episode_end", "_log_probs", "_scored")


def sample_window(n: int, size: int, rng: np.random.Generator) -> tuple[int, int]:
    """Bounds ``(start, stop)`` of a contiguous window of ``size`` among ``n`` transitions, its start uniform
    where a full window fits (Figure 3); with fewer than ``size`` transitions, all of them."""
    if n < 1:
        raise ValueError("cannot sample a window from an empty trajectory memory")
    if n <= size:
        return 0, n
    start = int(rng.integers(0, n - size + 1))
    return start, start + size


def concatenate(runs: Sequence[Transitions]) -> Transitions:
    """Runs of transitions one after the other; one run is returned as it is."""
    if len(runs) == 1:
        return runs[0]
    return Transitions(*(np.concatenate([getattr(r, f.name) for r in runs]) for f in fields(Transitions)))


@dataclass(frozen=True)
class Batch:
    """The units' trajectory memories as tensors (no copy), one after the other."""

    obs: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor
    episode_end: torch.Tensor
    behaviour_log_probs: torch.Tensor

    @classmethod
    def of(cls, data: Transitions) -> Batch:
        """The transitions as tensors sharing their arrays (the fields of the same names)."""
        return cls(*(torch.from_numpy(getattr(data, f.name)) for f in fields(cls)))


@dataclass(frozen=True)
class Windows:
    """One optimisation's windows, one per unit, as rows of the units' memories one after the other: one
    unit's as a slice, several units' grouped by their window's length, ``groups``: (units, length)."""

    rows: slice | torch.Tensor
    groups: tuple[tuple[np.ndarray, int], ...]

    @classmethod
    def of(cls, offsets: np.ndarray, spans: Sequence[tuple[int, int]]) -> Windows:
        """The windows ``spans`` (unit u's in its memory, which starts at row ``offsets[u]``)."""
        if len(spans) == 1:
            (start, stop), one = spans[0], np.zeros(1, dtype=np.int64)
            return cls(slice(int(offsets[0]) + start, int(offsets[0]) + stop), ((one, stop - start),))
        starts = np.array([start for start, _ in spans], dtype=np.int64)
        lengths = np.array([stop - start for start, stop in spans], dtype=np.int64)
        groups, rows = [], []
        for length in sorted(set(lengths.tolist()), reverse=True):  # a memory shorter than U: all of it
            members = np.flatnonzero(lengths == length)
            groups.append((members, int(length)))
            rows.append(((offsets[members] + starts[members])[:, None] + np.arange(length)).reshape(-1))
        return cls(torch.from_numpy(np.concatenate(rows)), tuple(groups))

    @property
    def lengths(self) -> list[int]:
        """Each window's length, in the order of :attr:`rows`."""
        return [length for units, length in self.groups for _ in units]

    def parts(self) -> Generator[tuple[np.ndarray, slice, tuple[int, int]], None, None]:
        """Each group's units, its part of :attr:`rows` and that part's (units, length) shape."""
        at = 0
        for units, length in self.groups:
            yield units, slice(at, at + units.size * length), (units.size, length)
            at += units.size * length


def score_unscored(
    memories: list[TrajectoryMemory], log_probs: Callable[[np.ndarray, np.ndarray], np.ndarray]
) -> None:
    """Score every memory's unscored transitions with ``log_probs(obs, actions)``, in one call for all."""
    slots = [memory.unscored() for memory in memories]
    if not any(s.size for s in slots):
        return
    stored = [memory.slots(s) for memory, s in zip(memories, slots, strict=True)]
    obs, actions = (np.concatenate([part[i] for part in stored]) for i in (0, 1))
    scores = log_probs(obs, actions)
    at = 0
    for memory, s in zip(memories, slots, strict=True):
        memory.score(s, scores[at : at + s.size])
        at += s.size


ROWS = 256  # transitions a unit may have pending before every unit's are moved into its memory


class PendingTransitions:
    """Up to :data:`ROWS` transitions per unit, unit u's i-th pending one in row i of column u (one array
    assignment per field and time step for every unit at once)."""

    def __init__(self, units: int, obs_dim: int, action_dim: int = 0) -> None:
        self.counts = np.zeros(units, dtype=np.int64)  # each unit's pending transitions
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
        """One transition for each of the distinct ``units`` (row j of each array is ``units[j]``'s); first
        every unit's pending ones move into ``memories`` if a unit's are full."""
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
        """Move every unit's pending transitions into its memory, in order."""
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
