"""What one worker process needs to know, as JSON on its command line (nothing is pickled)."""

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.uneven import UnitConditions


@dataclass(frozen=True, kw_only=True)
class WorkerSpec:
    """Everything that defines one worker of a run: the run's learning settings and where this worker is."""

    worker: int
    """worker id within the run (also the device unit it trains on, unless ``unit`` says otherwise)"""
    unit: int
    """device unit index in the fleet"""
    learning: LearningSettings
    """the run's resolved learning settings (env, fleet, preset and overrides, scheme, target, seed, M)"""
    out: str
    """the run directory"""
    device_url: str | None = None
    """broker of the unit's device bridge; None: the device is simulated in-process"""
    device_run_id: str = "default"
    """run id under which the device bridge serves the unit's topics"""
    uneven: UnitConditions | None = None
    """how this simulated unit is uneven (paced, slowed, on a slow link, absent at times); None: it is not"""

    def to_json(self) -> str:
        """Serialise for a child process's command line."""
        data: dict[str, Any] = {
            "worker": self.worker, "unit": self.unit, "learning": self.learning.to_json(), "out": self.out,
            "device_url": self.device_url, "device_run_id": self.device_run_id,
        }  # fmt: skip
        if self.uneven is not None:  # an even unit's spec is the one it was before the setting existed
            data["uneven"] = self.uneven.to_dict()
        return json.dumps(data, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "WorkerSpec":
        """Parse :meth:`to_json`'s output."""
        data = json.loads(text)
        uneven = data.pop("uneven", None)
        learning = LearningSettings(**data.pop("learning"))
        conditions = None if uneven is None else UnitConditions.from_dict(uneven)
        return cls(**data, learning=learning, uneven=conditions)

    @property
    def worker_seed(self) -> int:
        """A seed for this worker alone, derived from the run's learning seed and the worker id."""
        return derive_seed(self.learning.seed, self.worker)


def derive_seed(seed: int, index: int) -> int:
    """A well-mixed 31-bit seed for ``index`` under ``seed`` (same inputs, same output)."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0] & 0x7FFFFFFF)
