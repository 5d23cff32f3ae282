"""``fedasync``: no round barrier — each worker's model is mixed into the fleet's on arrival, weighted by how
stale it is (Xie et al. 2019, "Asynchronous Federated Optimization"). A contribution x_w that started from
version b of the fleet model x (version v) has staleness s = v − b and is applied at once:

    α_s = α·(s + 1)^(−a),   x ← (1 − α_s)·x + α_s·x_w,   v ← v + 1

x starts as the fleet's start; mature workers stay; the run ends once every member of W has completed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from fleetrl.federation.schemes.base import (
    AsyncScheme,
    RoundAnswer,
    RoundContext,
    average_until_all_completed,
    flats,
)
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.wire.messages import Message

DEFAULT_ALPHA = 0.6  # α, the weight of a fresh contribution
DEFAULT_DECAY = 0.5  # a, how fast the weight falls with staleness


class FedAsyncScheme(AsyncScheme, FedAvgScheme):
    """FedAsync's staleness-weighted mixing of whole models, one contribution at a time: α in (0, 1], a ≥ 0
    (0: every contribution weighs α)."""

    name = "fedasync"
    summary = "no round barrier: each worker's model mixed into the fleet's on arrival, weighted by staleness"
    round_message = "async_model"

    def __init__(self, *, alpha: float = DEFAULT_ALPHA, decay: float = DEFAULT_DECAY) -> None:
        if not (np.isfinite(alpha) and 0.0 < alpha <= 1.0):
            raise ValueError(f"alpha = {alpha!r}: must be in (0, 1]")
        if not (np.isfinite(decay) and decay >= 0.0):
            raise ValueError(f"decay = {decay!r}: must be >= 0")
        self.alpha = float(alpha)
        self.decay = float(decay)
        self._model: np.ndarray | None = None
        self._version = 0

    def params(self) -> dict[str, Any]:
        """α and a."""
        return {"alpha": self.alpha, "decay": self.decay}

    @property
    def version(self) -> int:
        """How many contributions the fleet model has taken."""
        return self._version

    @property
    def model(self) -> np.ndarray | None:
        """The fleet model x (None before :meth:`begin`)."""
        return None if self._model is None else self._model.copy()

    def begin(self, start: np.ndarray) -> None:
        """x = the fleet's start, version 0."""
        self._model, self._version = np.asarray(start, np.float32).copy(), 0

    def weight(self, staleness: int) -> float:
        """α_s = α·(s + 1)^(−a), the weight of a contribution of staleness ``staleness``."""
        if staleness < 0:
            raise ValueError(f"staleness {staleness}: must be >= 0")
        return self.alpha * float(staleness + 1) ** (-self.decay)

    def mix(self, model: np.ndarray, contribution: np.ndarray, staleness: int) -> np.ndarray:
        """(1 − α_s)·``model`` + α_s·``contribution`` (float64 arithmetic, float32 result)."""
        w = self.weight(staleness)
        mixed = (1.0 - w) * model.astype(np.float64) + w * contribution.astype(np.float64)
        return np.asarray(mixed, np.float32)

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """Apply each contribution in turn, each a new version; the answer carries x after them, and ends the
        run once every member of W has completed."""
        if self._model is None:
            raise RuntimeError("scheme fedasync: the fleet model was never given its start (begin)")
        for flat, message in zip(flats(answers), answers.values(), strict=True):
            self._model = self.mix(self._model, flat, message.staleness)
            self._version += 1
        return average_until_all_completed(answers, context, fleet_model=True, flat=self._model.copy())

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The version and x (nothing before :meth:`begin`)."""
        if self._model is None:
            return {}, {}
        return {"version": self._version}, {"model": self._model.copy()}

    def restore(self, fields: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> None:
        """Take back the version and x; ValueError if x is missing."""
        if not fields and not tensors:
            self._model, self._version = None, 0
            return
        if "model" not in tensors:
            raise ValueError(f"scheme {self.name} state lacks the fleet model")
        self._model = np.asarray(tensors["model"], np.float32).copy()
        self._version = int(fields.get("version", 0))
