"""What the worker's state machine (:mod:`fleetrl.federation.worker_machine`) asks of its runner, as data.

The machine decides; the runner (:class:`fleetrl.federation.worker.FederatedWorker`) does: it publishes, plays
the learner's rounds and steps, applies answers to the agent through the scheme, and reports back. Every
input of the machine returns one :class:`WorkerStep`, whose outputs are executed in order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fleetrl.federation.messages import Message, RoundConfig
from fleetrl.federation.rounds import RoundRecord, WorkerSummary


@dataclass(frozen=True)
class Publish:
    """Publish ``payload`` on ``topic`` (QoS 1, retained if ``retain``); ``message`` is what it encodes (None
    for a status)."""

    topic: str
    payload: bytes
    retain: bool = False
    message: Message | None = None


@dataclass(frozen=True)
class Announce:
    """Announce the worker's live status (retained, and again after every reconnect of the transport)."""

    topic: str
    payload: bytes


@dataclass(frozen=True)
class TakeParameters:
    """``scheme.take_parameters(agent, flat)``: a transfer's parameters, or a joining worker's from the
    welcome (the fleet's model θ*, or the fleet's start)."""

    flat: np.ndarray


@dataclass(frozen=True)
class ApplyAverage:
    """``scheme.apply_average(agent, flat, completed=..., contributed=...)``: the fleet's average."""

    flat: np.ndarray
    completed: bool
    contributed: bool


@dataclass(frozen=True)
class PlayRound:
    """Play round ``round`` (``learner.play_round``) and report it with
    :meth:`~fleetrl.federation.worker_machine.WorkerMachine.round_played` — for a per-round scheme with what
    ``scheme.outgoing`` shares; a per-step scheme's update reports through ``update_begun`` and
    ``step_computed`` first. A per-round scheme's ``local_loss(agent, config)`` is installed before it."""

    round: int
    config: RoundConfig = field(default_factory=dict)
    """what the chief asks of every worker for this round (its scheme's ``configure``)"""


@dataclass(frozen=True)
class ComputeStep:
    """Compute the gradients of optimisation step ``step`` (``agent.step_gradients``) and report them with
    :meth:`~fleetrl.federation.worker_machine.WorkerMachine.step_computed`."""

    step: int


@dataclass(frozen=True)
class ApplyStep:
    """``scheme.apply_step_answer(agent, flat)``: the chief's combination of one optimisation step."""

    flat: np.ndarray


@dataclass(frozen=True)
class EndUpdate:
    """Every step of the round's update was exchanged: ``agent.end_update()`` and let the round finish."""


@dataclass(frozen=True)
class Record:
    """A round is over: hand its record to ``on_record``."""

    record: RoundRecord


@dataclass(frozen=True)
class Checkpoint:
    """The round's answers are applied; ``next_round`` is the next to play (the moment to checkpoint)."""

    next_round: int


@dataclass(frozen=True)
class Finish:
    """The worker's run is over (a round inside an update is abandoned)."""

    summary: WorkerSummary


@dataclass(frozen=True)
class Refused:
    """The chief refused this worker's shared settings (raise
    :class:`~fleetrl.federation.shared_settings.SettingsRefused`)."""

    reason: str


@dataclass(frozen=True)
class TimedOut:
    """Nothing from the chief for the whole reply timeout (raise :class:`TimeoutError`)."""

    detail: str


WorkerOutput = (
    Publish
    | Announce
    | TakeParameters
    | ApplyAverage
    | PlayRound
    | ComputeStep
    | ApplyStep
    | EndUpdate
    | Record
    | Checkpoint
    | Finish
    | Refused
    | TimedOut
)
"""Everything a :class:`WorkerStep` can hold."""


@dataclass(frozen=True)
class WorkerStep:
    """What the worker does after one input, in order."""

    outputs: tuple[WorkerOutput, ...] = ()

    def __add__(self, other: WorkerStep) -> WorkerStep:
        """Both steps, this one first."""
        return WorkerStep(self.outputs + other.outputs)

    @property
    def published(self) -> tuple[Message, ...]:
        """The messages published (statuses left out)."""
        return tuple(o.message for o in self.outputs if isinstance(o, Publish) and o.message is not None)

    @property
    def actions(self) -> tuple[WorkerOutput, ...]:
        """Everything but publishing."""
        return tuple(o for o in self.outputs if not isinstance(o, Publish | Announce))
