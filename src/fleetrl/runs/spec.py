"""What one worker process needs to know, as JSON on its command line (nothing is pickled)."""

import json
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np


@dataclass
class WorkerSpec:
    """Everything that defines one worker of a run."""

    worker: int
    """worker id within the run (also the device unit it trains on, unless ``unit`` says otherwise)"""
    unit: int
    """device unit index in the fleet"""
    env: str
    """the unit type: a built-in's short name (``qube``, ``cartpole``) or ``package.module:factory``"""
    preset: str
    """PPO preset name (``paper`` or ``standard``)"""
    seed: int
    """the run's seed; the worker's own seed is derived from (seed, worker)"""
    fleet_seed: int
    """the fleet's seed: with ``unit`` it fixes the device's dynamics"""
    max_rounds: int
    """the paper's M: the most rounds the worker plays (each one episode, or with paper-code several)"""
    out: str
    """the run directory"""
    overrides: dict[str, Any] = field(default_factory=dict)
    """PPO config fields that replace the preset's"""
    device_url: str | None = None
    """broker of the unit's device bridge; None: the device is simulated in-process"""
    device_run_id: str = "default"
    """run id under which the device bridge serves the unit's topics"""
    fleet_profile: str | None = None
    """the simulated fleet's profile (QUBE; None: the default or a unit type with one fleet)"""
    scheme: str = "paper"
    """federated mode: the federation scheme (a name in :data:`fleetrl.federation.schemes.SCHEMES`)"""
    scheme_params: dict[str, Any] = field(default_factory=dict)
    """the scheme's parameters (``--scheme-param``)"""
    target_score: float | None = None
    """the completion criterion's target (the WMA of the last 10 scores); None: the unit type's default"""

    def to_json(self) -> str:
        """Serialise for a child process's command line."""
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "WorkerSpec":
        """Parse :meth:`to_json`'s output."""
        return cls(**json.loads(text))

    @property
    def worker_seed(self) -> int:
        """A seed for this worker alone, derived from the run's seed and the worker id."""
        return derive_seed(self.seed, self.worker)


def derive_seed(seed: int, index: int) -> int:
    """A well-mixed 31-bit seed for ``index`` under ``seed`` (same inputs, same output)."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0] & 0x7FFFFFFF)
