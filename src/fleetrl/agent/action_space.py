"""The action space an agent acts in: ``n`` discrete actions (a softmax head), or a 1-D box of continuous
values (a Gaussian head); a model file records it (:meth:`ActionSpace.to_dict`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np

if TYPE_CHECKING:
    from fleetrl.envs.catalog import ActionSpec

DISCRETE = "discrete"
BOX = "box"


class UnsupportedActionSpace(ValueError):
    """An env's action space the agent cannot act in (it says which spaces are supported)."""


SUPPORTED = "Discrete(n) with n >= 2, or a 1-D float Box with finite low < high"  # for error messages


@dataclass(frozen=True)
class ActionSpace:
    """``n`` discrete actions (``low``/``high`` empty), or a box ``low`` ≤ a ≤ ``high`` (``n`` = 0)."""

    n: int = 0
    low: tuple[float, ...] = ()
    high: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.n != 0 and (self.low or self.high):
            raise ValueError("an action space is discrete (n) or a box (low, high), not both")
        if self.n == 0:
            size = len(self.low)
            if size < 1 or len(self.high) != size:
                raise UnsupportedActionSpace(f"a box needs equal non-empty low and high, got {self!r}")
            bounds = (*self.low, *self.high)
            if not all(math.isfinite(b) for b in bounds):
                raise UnsupportedActionSpace(
                    f"a box needs finite bounds, got low {list(self.low)}, high {list(self.high)} "
                    f"(supported: {SUPPORTED})"
                )
            if not all(lo < hi for lo, hi in zip(self.low, self.high, strict=True)):
                raise UnsupportedActionSpace(f"a box needs low < high in every component, got {self!r}")
        elif self.n < 2:
            raise UnsupportedActionSpace(f"need at least 2 discrete actions, got n={self.n}")

    @classmethod
    def discrete(cls, n: int) -> ActionSpace:
        """``n`` discrete actions 0 .. n−1."""
        return cls(n=int(n))

    @classmethod
    def box(cls, low: Any, high: Any) -> ActionSpace:
        """A box with bounds ``low`` and ``high`` (equal-length sequences, or scalars for one component)."""
        lo = np.atleast_1d(np.asarray(low, dtype=np.float64))
        hi = np.atleast_1d(np.asarray(high, dtype=np.float64))
        if lo.ndim != 1 or hi.ndim != 1:
            raise UnsupportedActionSpace(
                f"a box must be 1-D, got bounds of shape {lo.shape} (supported: {SUPPORTED})"
            )
        return cls(low=tuple(float(v) for v in lo), high=tuple(float(v) for v in hi))

    @classmethod
    def of(cls, space: gymnasium.spaces.Space[Any]) -> ActionSpace:
        """The action space of a Gymnasium env's ``action_space`` (else UnsupportedActionSpace)."""
        if isinstance(space, gymnasium.spaces.Discrete):
            if int(space.start) != 0:
                raise UnsupportedActionSpace(
                    f"a Discrete space must start at 0, got {space} (supported: {SUPPORTED})"
                )
            return cls.discrete(int(space.n))
        if isinstance(space, gymnasium.spaces.Box):
            if len(space.shape) != 1 or not np.issubdtype(space.dtype, np.floating):
                raise UnsupportedActionSpace(f"action space {space} is not supported ({SUPPORTED})")
            return cls.box(space.low, space.high)
        raise UnsupportedActionSpace(f"action space {space} is not supported ({SUPPORTED})")

    @classmethod
    def of_unit(cls, action: ActionSpec) -> ActionSpace:
        """The agent's action space for a unit's (``UnitDescription.action``)."""
        if action.kind == DISCRETE:
            return cls.discrete(action.n)
        return cls.box(action.low, action.high)

    @property
    def is_discrete(self) -> bool:
        """True for discrete actions, False for a box."""
        return self.n != 0

    @property
    def dim(self) -> int:
        """Components of a continuous action (0 for discrete: an action is one index)."""
        return len(self.low)

    @property
    def head_size(self) -> int:
        """Width of the actor's output layer: ``n`` logits, or ``dim`` means."""
        return self.n if self.is_discrete else self.dim

    def centre(self) -> np.ndarray:
        """(low + high) / 2 per component, float64 (box only)."""
        return (np.asarray(self.low) + np.asarray(self.high)) / 2.0

    def half_range(self) -> np.ndarray:
        """(high − low) / 2 per component, float64 (box only)."""
        return (np.asarray(self.high) - np.asarray(self.low)) / 2.0

    @cached_property
    def bounds32(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) as float32 arrays (box only; built once)."""
        return np.asarray(self.low, dtype=np.float32), np.asarray(self.high, dtype=np.float32)

    def clip(self, action: np.ndarray) -> np.ndarray:
        """A continuous action clipped to the bounds, float32 (what the env is sent; a new array)."""
        low, high = self.bounds32
        return np.minimum(np.maximum(np.asarray(action, dtype=np.float32), low), high)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (what a model file records)."""
        if self.is_discrete:
            return {"kind": DISCRETE, "n": self.n}
        return {"kind": BOX, "low": list(self.low), "high": list(self.high)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ActionSpace:
        """The inverse of :meth:`to_dict`; ValueError for anything else."""
        kind = data.get("kind") if isinstance(data, dict) else None
        if kind == DISCRETE:
            return cls.discrete(int(data["n"]))
        if kind == BOX:
            return cls.box(data["low"], data["high"])
        raise ValueError(f"unknown action space {data!r} (kind must be {DISCRETE!r} or {BOX!r})")

    @classmethod
    def from_architecture(cls, arch: dict[str, Any]) -> ActionSpace:
        """The action space a model file's architecture records: its ``action_space``, else ``n_actions``."""
        if "action_space" in arch:
            return cls.from_dict(arch["action_space"])
        return cls.discrete(int(arch["n_actions"]))

    def __str__(self) -> str:
        if self.is_discrete:
            return f"Discrete({self.n})"
        return f"Box(low={list(self.low)}, high={list(self.high)})"


def as_action_space(actions: int | ActionSpace) -> ActionSpace:
    """``actions`` as an :class:`ActionSpace`: an int is that many discrete actions."""
    if isinstance(actions, ActionSpace):
        return actions
    if isinstance(actions, bool) or not isinstance(actions, int | np.integer):
        raise TypeError(f"actions must be an int (discrete) or an ActionSpace, got {actions!r}")
    return ActionSpace.discrete(int(actions))
