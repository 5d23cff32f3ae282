"""Checkpoints of a run's chief (``OUT/checkpoints/chief/``) and workers (``OUT/checkpoints/worker-K/``) for
``--resume``, each a :class:`~fleetrl.agent.statestore.StateStore` (docs/protocol.md, "Checkpoints and
resume")."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetrl.agent.learner import Learner
from fleetrl.agent.state import learner_state, load_learner_state
from fleetrl.agent.statestore import StateStore
from fleetrl.federation.chief.checkpoint import chief_config, chief_from_state, chief_to_state
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.wire.signing import FleetKey
from fleetrl.runs.spec import WorkerSpec

log = logging.getLogger(__name__)


def chief_checkpoint_dir(out: Path) -> Path:
    return Path(out) / "checkpoints" / "chief"


def worker_checkpoint_dir(out: Path, worker: int) -> Path:
    return Path(out) / "checkpoints" / f"worker-{worker}"


class ChiefCheckpoint:
    """The chief's checkpoint in ``directory`` (created on the first save): pass :meth:`save` as
    ``run_chief(checkpoint=...)``."""

    def __init__(self, directory: Path) -> None:
        self.store = StateStore(directory, "chief")

    def exists(self) -> bool:
        return self.store.exists()

    def save(self, chief: Chief) -> None:
        """Commit the chief's state (before its step's messages are published)."""
        self.store.save(*chief_to_state(chief))

    def load(self, *, key: FleetKey | None = None, now: float, expect: Chief | None = None) -> Chief:
        """The chief as last committed, its open round starting at ``now`` (``key``: the run's fleet key, if
        it was signed). ``expect``: a chief of the current command line, whose settings must be the
        checkpoint's and whose fleet model the resumed chief keeps. FileNotFoundError: no checkpoint;
        ValueError: a corrupt checkpoint, or settings that differ."""
        fields, tensors = self.store.load()
        model = None if expect is None else expect.fleet_model
        chief = chief_from_state(fields, tensors, key=key, now=now, fleet_model=model)
        if expect is not None:
            _same_settings(chief_config(chief), chief_config(expect), "chief")
        log.info(
            "resumed the chief of run %s at round %d (W={%s})",
            chief.run_id,
            chief.round,
            ",".join(chief.members),
        )
        return chief


@dataclass(frozen=True)
class WorkerResume:
    """Where a worker's checkpoint left it: the first round it has not played, and why it stopped if its run
    was over for it (None: it was mid-run)."""

    next_round: int
    ended: str | None


class WorkerCheckpoint:
    """A federated worker's checkpoint in ``directory``, written after every round; a checkpoint of another
    run, or of a worker built from another spec, is refused."""

    def __init__(self, directory: Path, spec: WorkerSpec, run_id: str) -> None:
        self.store = StateStore(directory, "worker")
        self.identity = _identity(spec, run_id)

    def exists(self) -> bool:
        return self.store.exists()

    def save(self, learner: Learner, next_round: int, ended: str | None = None) -> None:
        fields, tensors = learner_state(learner)
        self.store.save(
            {"worker": self.identity, "next_round": next_round, "ended": ended, **fields}, tensors
        )

    def where(self) -> WorkerResume | None:
        """Where the committed state left the worker, without loading it (None: nothing committed)."""
        if not self.exists():
            return None
        fields, _ = self.store.load()
        return WorkerResume(int(fields["next_round"]), fields["ended"])

    def load(self, learner: Learner) -> WorkerResume:
        """Restore the committed state into ``learner`` and say where it was (FileNotFoundError: none;
        ValueError: corrupt, or of another worker, run or configuration)."""
        fields, tensors = self.store.load()
        _same_settings(fields.pop("worker"), self.identity, "worker")
        resume = WorkerResume(int(fields.pop("next_round")), fields.pop("ended"))
        load_learner_state(learner, fields, tensors)
        return resume


def _identity(spec: WorkerSpec, run_id: str) -> dict[str, Any]:
    learning = spec.learning
    return {
        "run_id": run_id,
        "worker": spec.worker,
        "unit": spec.unit,
        "env": learning.env,
        "preset": learning.preset,
        "seed": learning.seed,
        "fleet_seed": learning.fleet_seed,
        "fleet_profile": learning.fleet_profile,
        "max_rounds": learning.max_rounds,
        "target_score": learning.target_score,
        "overrides": json.loads(json.dumps(learning.overrides, sort_keys=True)),  # as the JSON record has it
        "scheme": learning.scheme,
        "scheme_params": json.loads(json.dumps(learning.scheme_params, sort_keys=True)),
    }


def _same_settings(saved: dict[str, Any], current: dict[str, Any], role: str) -> None:
    differ = [
        f"{k}: checkpoint {saved.get(k)!r}, now {current.get(k)!r}"
        for k in sorted(set(saved) | set(current))
        if saved.get(k) != current.get(k)
    ]
    if differ:
        raise ValueError(
            f"the {role} checkpoint was written with other settings ({'; '.join(differ)}); "
            "resume with the settings the run started with"
        )
