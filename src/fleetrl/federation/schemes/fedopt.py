"""``fedavgm`` and ``fedadam``: fedavg with a server optimiser stepping the fleet's model (Reddi et al. 2021).
The chief keeps the global model x and treats the round's aggregate as a pseudo-gradient Δ = aggregate − x:

* ``momentum`` (FedAvgM, Hsu et al. 2019): v ← β·v + Δ;  x ← x + η_s·v
* ``adam`` (FedAdam, Reddi et al. 2021, Algorithm 2, no bias correction):
  m ← β₁·m + (1 − β₁)·Δ;  v ← β₂·v + (1 − β₂)·Δ²;  x ← x + η_s·m / (√v + τ)

x starts as the first round's aggregate (that answer is fedavg's). η_s = 1 and β = 0 is fedavg, bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from fleetrl.federation.schemes.base import RoundAnswer, RoundContext
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.wire.messages import Message

OWN_PARAMETERS = {"momentum": {"momentum": 0.0}, "adam": {"beta1": 0.9, "beta2": 0.99, "tau": 1e-3}}
"""each optimiser's own parameters and their defaults (another optimiser's are refused, not ignored)"""


class FedAvgMScheme(FedAvgScheme):
    """Model averaging whose average is a pseudo-gradient for a server optimiser: ``momentum`` (β) or
    ``adam`` (β₁, β₂, τ), with the server learning rate η_s (``server_lr``); ValueError for a value out of
    range or a parameter of the other optimiser."""

    name = "fedavgm"
    summary = "fedavg whose average steps the fleet model through a server optimiser (momentum or adam)"
    default_optimizer: ClassVar[str] = "momentum"
    default_server_lr: ClassVar[dict[str, float]] = {"momentum": 1.0, "adam": 0.01}

    def __init__(
        self,
        *,
        optimizer: str | None = None,
        server_lr: float | None = None,
        momentum: float | None = None,
        beta1: float | None = None,
        beta2: float | None = None,
        tau: float | None = None,
    ) -> None:
        self.optimizer = self.default_optimizer if optimizer is None else optimizer
        if self.optimizer not in OWN_PARAMETERS:
            raise ValueError(f"optimizer {self.optimizer!r}: choose {' or '.join(OWN_PARAMETERS)}")
        given = {"momentum": momentum, "beta1": beta1, "beta2": beta2, "tau": tau}
        own = OWN_PARAMETERS[self.optimizer]
        foreign = sorted(k for k, v in given.items() if v is not None and k not in own)
        if foreign:
            raise ValueError(f"{', '.join(foreign)}: not a parameter of the {self.optimizer} optimizer")
        values = {k: float(default if (v := given[k]) is None else v) for k, default in own.items()}
        self.server_lr = self.default_server_lr[self.optimizer] if server_lr is None else float(server_lr)
        if not (np.isfinite(self.server_lr) and self.server_lr > 0):
            raise ValueError(f"server_lr = {self.server_lr!r}: must be > 0")
        for key in ("momentum", "beta1", "beta2"):
            if key in values and not 0.0 <= values[key] < 1.0:
                raise ValueError(f"{key} = {values[key]!r}: must be in [0, 1)")
        if "tau" in values and not values["tau"] > 0:
            raise ValueError(f"tau = {values['tau']!r}: must be > 0")
        self.hyper: dict[str, float] = values  # the optimiser's own parameters
        self.x: np.ndarray | None = None  # the global model (None until the first round closes)
        self.moments: dict[str, np.ndarray] = {}  # v (momentum), or m and v (adam), float32

    def params(self) -> dict[str, Any]:
        """Every parameter the optimiser reads, defaults filled in (so equal settings give equal maps)."""
        return {"optimizer": self.optimizer, "server_lr": self.server_lr, **self.hyper}

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """fedavg's answer, but carrying x after one server step with Δ = aggregate − x."""
        answer = super().combine(answers, context)
        aggregate = np.asarray(answer.flat, np.float32)
        if self.x is None:
            self.x = aggregate.copy()
            self.moments = {k: np.zeros_like(aggregate) for k in self._moment_names()}
        else:
            self.x = self._step(self.x, aggregate)
        return RoundAnswer(
            answer.kind,
            self.x.copy(),
            contributors=answer.contributors,
            finished=answer.finished,
            fleet_model=True,
            ends_run=answer.ends_run,
        )

    def _moment_names(self) -> tuple[str, ...]:
        return ("v",) if self.optimizer == "momentum" else ("m", "v")

    def _step(self, x: np.ndarray, aggregate: np.ndarray) -> np.ndarray:
        """x after one step (float64 arithmetic, float32 state)."""
        x64 = x.astype(np.float64)
        delta = aggregate.astype(np.float64) - x64
        h = self.hyper
        if self.optimizer == "momentum":
            v = h["momentum"] * self.moments["v"].astype(np.float64) + delta
            self.moments["v"] = v.astype(np.float32)
            step = v
        else:
            m = h["beta1"] * self.moments["m"].astype(np.float64) + (1.0 - h["beta1"]) * delta
            v = h["beta2"] * self.moments["v"].astype(np.float64) + (1.0 - h["beta2"]) * delta**2
            self.moments["m"], self.moments["v"] = m.astype(np.float32), v.astype(np.float32)
            step = m / (np.sqrt(v) + h["tau"])
        return np.asarray(x64 + self.server_lr * step, np.float32)

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """x and the moments (none before the first round)."""
        if self.x is None:
            return {}, {}
        return {}, {"x": self.x.copy(), **{k: v.copy() for k, v in self.moments.items()}}

    def restore(self, fields: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> None:
        """Take back x and the moments; ValueError if a tensor is missing or of another shape."""
        del fields
        if not tensors:
            self.x, self.moments = None, {}
            return
        missing = sorted({"x", *self._moment_names()} - set(tensors))
        if missing:
            raise ValueError(f"scheme {self.name} state lacks {', '.join(missing)}")
        x = np.asarray(tensors["x"], np.float32)
        moments = {k: np.asarray(tensors[k], np.float32) for k in self._moment_names()}
        if any(m.shape != x.shape for m in moments.values()):
            raise ValueError(f"scheme {self.name} state: moments and x differ in shape")
        self.x, self.moments = x.copy(), {k: m.copy() for k, m in moments.items()}


class FedAdamScheme(FedAvgMScheme):
    """:class:`FedAvgMScheme` with Adam as the server optimiser by default (FedAdam)."""

    name = "fedadam"
    summary = "fedavg whose average steps the fleet model through a server Adam (FedAdam)"
    default_optimizer = "adam"
