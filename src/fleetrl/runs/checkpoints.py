"""Checkpoint files of a run's roles, for ``--resume`` (docs/protocol.md, "Checkpoints and resume").

Layout under a run directory ``OUT``::

    OUT/checkpoints/chief/chief.json + chief-<n>.safetensors        (ChiefCheckpoint)
    OUT/checkpoints/worker-<K>/worker.json + worker-<n>.safetensors (WorkerCheckpoint)

Each is a :class:`~fleetrl.agent.statestore.StateStore`: the JSON record is the commit point, written through
a temporary file and ``os.replace`` after the tensors it names, so a role killed at any instant leaves its
previous or its new state. The chief's state comes from :mod:`fleetrl.federation.chief.state`, the worker's
from :mod:`fleetrl.agent.state` plus the worker's place in the run (its next round, or how it ended).
"""

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
    """Where the chief of the run in ``out`` keeps its checkpoint."""
    return Path(out) / "checkpoints" / "chief"


def worker_checkpoint_dir(out: Path, worker: int) -> Path:
    """Where worker ``worker`` of the run in ``out`` keeps its checkpoint."""
    return Path(out) / "checkpoints" / f"worker-{worker}"


class ChiefCheckpoint:
    """The chief's checkpoint in ``directory``: pass :meth:`save` as ``run_chief(checkpoint=...)``.

    :param directory: e.g. :func:`chief_checkpoint_dir` of the run directory.
    """

    def __init__(self, directory: Path) -> None:
        """Bind to ``directory`` (created on the first save)."""
        self.store = StateStore(directory, "chief")
        self.saves = 0
        """How many states this object committed."""

    def exists(self) -> bool:
        """True if a chief state was committed there."""
        return self.store.exists()

    def save(self, chief: Chief) -> None:
        """Commit the chief's state (before its step's messages are published)."""
        self.store.save(*chief_to_state(chief))
        self.saves += 1

    def load(self, *, key: FleetKey | None = None, now: float, expect: Chief | None = None) -> Chief:
        """The chief as last committed, its open round starting at ``now``.

        :param key: the run's fleet key (required if and only if the run was signed).
        :param expect: a chief built from the current command line; any setting that differs from the
            checkpoint's is an error (a run resumes with the settings it started with). Its fleet model
            (a per-step scheme's) is set to the saved one and kept by the resumed chief.
        :raises FileNotFoundError: no checkpoint in the directory
        :raises ValueError: a corrupt checkpoint, or settings that differ
        """
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
    """Where a worker's checkpoint left it."""

    next_round: int
    """the first round it has not played"""
    ended: str | None
    """why it stopped, if its run was over for it (finished, ``done``, M rounds); None: it was mid-run"""


class WorkerCheckpoint:
    """A federated worker's checkpoint in ``directory``, written after every round's answer is applied.

    :param directory: e.g. :func:`worker_checkpoint_dir` of the run directory.
    :param spec: the worker's spec; a checkpoint of a worker built another way is refused.
    :param run_id: the run; a checkpoint of another run is refused.
    """

    def __init__(self, directory: Path, spec: WorkerSpec, run_id: str) -> None:
        """Bind to ``directory`` (created on the first save)."""
        self.store = StateStore(directory, "worker")
        self.identity = _identity(spec, run_id)

    def exists(self) -> bool:
        """True if a worker state was committed there."""
        return self.store.exists()

    def save(self, learner: Learner, next_round: int, ended: str | None = None) -> None:
        """Commit the learner's state with the worker's next round (and how it ended, if it did)."""
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
        """Restore the committed state into ``learner`` (built from the same spec) and say where it was.

        :raises FileNotFoundError: no checkpoint in the directory
        :raises ValueError: a corrupt checkpoint, or one of another worker, run or configuration
        """
        fields, tensors = self.store.load()
        _same_settings(fields.pop("worker"), self.identity, "worker")
        resume = WorkerResume(int(fields.pop("next_round")), fields.pop("ended"))
        load_learner_state(learner, fields, tensors)
        return resume


def _identity(spec: WorkerSpec, run_id: str) -> dict[str, Any]:
    """What a worker's checkpoint must have been written with."""
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
