"""What one worker process needs to know, as JSON on its command line (nothing is pickled)."""

import json
from dataclasses import asdict, dataclass

import numpy as np

from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.uneven import UnitConditions


@dataclass(frozen=True, kw_only=True)
class WorkerSpec:
    """Everything that defines one worker of a run: its id and device unit, the run's resolved learning
    settings and directory, the broker and run id of the unit's device bridge (None: simulated in-process),
    and how the unit is uneven (None: it is not)."""

    worker: int
    unit: int
    learning: LearningSettings
    out: str
    device_url: str | None = None
    device_run_id: str = "default"
    uneven: UnitConditions | None = None

    def to_json(self) -> str:
        data = asdict(self)
        if self.uneven is None:  # an even unit's spec is the one it was before the setting existed
            del data["uneven"]
        return json.dumps(data, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "WorkerSpec":
        data = json.loads(text)
        uneven = data.pop("uneven", None)
        learning = LearningSettings(**data.pop("learning"))
        conditions = None if uneven is None else UnitConditions(**uneven)
        return cls(**data, learning=learning, uneven=conditions)

    @property
    def worker_seed(self) -> int:
        """A seed for this worker alone, derived from the run's learning seed."""
        return derive_seed(self.learning.seed, self.worker)


def derive_seed(seed: int, index: int) -> int:
    """A well-mixed 31-bit seed for ``index`` under ``seed`` (same inputs, same output)."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0] & 0x7FFFFFFF)
