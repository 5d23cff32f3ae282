"""The worker's vocabulary: what it needs of its learner (:class:`RoundPlayer`), a round's record
(:class:`FederatedRound`), the outputs its state machine hands the runner (one :class:`WorkerStep` per
input, executed in order), and where the machine is (:class:`Phase`) and what it waits for (:class:`Wait`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum, auto
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from fleetrl.federation.events import RoundEvent
from fleetrl.federation.schemes import FederatedAgent
from fleetrl.federation.wire.messages import Message, RoundConfig

if TYPE_CHECKING:  # the learner (and torch) is not imported by the federation's pure parts
    from fleetrl.agent.criterion import RoundResult

log = logging.getLogger(__name__)

ANSWERS = ("average", "transfer", "done")
"""The chief's answers to a round."""


class RoundPlayer(Protocol):
    """What the worker needs from the learner (``fleetrl.agent.learner.Learner`` provides it)."""

    @property
    def agent(self) -> FederatedAgent:
        """The agent whose actor is federated."""

    @property
    def completed(self) -> bool:
        """The completion criterion has held (after this round's episodes, inside ``play_round``)."""

    def play_round(self) -> RoundResult:
        """Play one episode and, unless learning is complete, optimise (Algorithm 2, lines 2–24)."""

    def begin_round(self) -> Any:
        """The round's episodes alone; the result's ``updates`` says whether an update follows."""

    def end_round(self, played: Any, stats: Any) -> RoundResult:
        """The round's outcome from :meth:`begin_round`'s result and the update's statistics (None: none)."""


@dataclass(frozen=True)
class FederatedRound:
    """One round of one worker: the learner's result with the federation's round number (a resumed
    worker's learner counts its own), its event and ``peer``, the other worker of a transfer."""

    worker_id: str
    round: int
    result: RoundResult
    event: RoundEvent
    peer: str | None = None

    @property
    def label(self) -> str:
        """The round's event as metrics files name it (:meth:`.events.WorkerEvent.label`)."""
        return self.event.label(self.peer)


@dataclass(frozen=True)
class WorkerSummary:
    """How a worker's run ended; ``finished``: it left W by sending its parameters."""

    worker_id: str
    rounds: int
    finished: bool
    reason: str


def resume_round(start_round: int | None, welcome_round: int, worker_id: str) -> int | None:
    """The round a worker resumed at ``start_round`` plays first when welcomed at ``welcome_round``; None:
    rejoin at the welcome's round like a fresh worker. RuntimeError if the chief is behind the checkpoint."""
    if start_round is None:
        return None
    if welcome_round < start_round:
        raise RuntimeError(
            f"worker {worker_id}: the chief is at round {welcome_round} but this worker's "
            f"checkpoint is at round {start_round}: the chief lost rounds (resume it from its checkpoint)"
        )
    if welcome_round <= start_round + 1:
        # the round it died in is replayed: same state and RNGs, so the chief gets a copy of its message
        return start_round
    log.warning(
        "worker %s: rounds %d-%d were played without this worker; rejoining at round %d",
        worker_id, start_round, welcome_round - 1, welcome_round,
    )  # fmt: skip
    return None


def answer_for(rnd: int, step: int = 0) -> Callable[[Message], bool]:
    """Accepts ``done`` or the chief's answer for round ``rnd`` (step ``step``) or a later one."""
    return lambda m: m.type == "done" or (m.type in ANSWERS and (m.round, m.step) >= (rnd, step))


class WorkerOutput:
    """One thing the worker's state machine asks of its runner."""


@dataclass(frozen=True)
class Publish(WorkerOutput):
    """Publish ``payload`` on ``topic``; ``message`` is what it encodes (None for a status)."""

    topic: str
    payload: bytes
    retain: bool = False
    message: Message | None = None


@dataclass(frozen=True)
class Announce(WorkerOutput):
    """Announce the worker's live status (retained, and again after every reconnect)."""

    topic: str
    payload: bytes


@dataclass(frozen=True)
class TakeParameters(WorkerOutput):
    """``scheme.take_parameters(agent, flat)``: a transfer's, or the welcome's fleet model or start."""

    flat: np.ndarray


@dataclass(frozen=True)
class ApplyAverage(WorkerOutput):
    """``scheme.apply_average(agent, flat, completed=..., contributed=...)``: the fleet's average."""

    flat: np.ndarray
    completed: bool
    contributed: bool


@dataclass(frozen=True)
class PlayRound(WorkerOutput):
    """Play round ``round`` with the chief's ``config`` (its scheme's ``configure``) and report it."""

    round: int
    config: RoundConfig = field(default_factory=dict)


@dataclass(frozen=True)
class ComputeStep(WorkerOutput):
    """Compute the gradients of optimisation step ``step`` and report them."""

    step: int


@dataclass(frozen=True)
class BeginUpdate(WorkerOutput):
    """A per-step round's episodes are played: ``agent.begin_update()`` and report its steps."""


@dataclass(frozen=True)
class ApplyFleetStep(WorkerOutput):
    """``scheme.catch_up_step(agent, step, flat)``: a fleet's step taken while no update is under way."""

    step: int
    flat: np.ndarray


@dataclass(frozen=True)
class ApplyStep(WorkerOutput):
    """``scheme.apply_step_answer(agent, flat)``: the chief's combination of one optimisation step."""

    flat: np.ndarray


@dataclass(frozen=True)
class EndUpdate(WorkerOutput):
    """Every step of the round's update was exchanged: ``agent.end_update()`` and finish the round."""


@dataclass(frozen=True)
class AbandonUpdate(WorkerOutput):
    """The fleet went on past this worker: ``agent.abandon_update()`` and finish the round without it."""


@dataclass(frozen=True)
class Record(WorkerOutput):
    """A round is over: hand its record to ``on_record``."""

    record: FederatedRound


@dataclass(frozen=True)
class Checkpoint(WorkerOutput):
    """The round's answers are applied; ``next_round`` is the next to play (the moment to checkpoint)."""

    next_round: int


@dataclass(frozen=True)
class Finish(WorkerOutput):
    """The worker's run is over."""

    summary: WorkerSummary


@dataclass(frozen=True)
class Refused(WorkerOutput):
    """The chief refused this worker's shared settings (raise ``SettingsRefused``)."""

    reason: str


@dataclass(frozen=True)
class RunEnded(WorkerOutput):
    """The run had ended before this worker was welcomed (raise :class:`RunEndedError`)."""

    detail: str


class RunEndedError(OSError):
    """A worker started after its run was over (``fleetrl worker`` exits 1)."""


@dataclass(frozen=True)
class TimedOut(WorkerOutput):
    """Nothing from the chief for the whole reply timeout (raise :class:`TimeoutError`)."""

    detail: str


@dataclass(frozen=True)
class WorkerStep:
    """What the worker does after one input, in order."""

    outputs: tuple[WorkerOutput, ...] = ()

    def __add__(self, other: WorkerStep) -> WorkerStep:
        return WorkerStep(self.outputs + other.outputs)

    @property
    def published(self) -> tuple[Message, ...]:
        """The messages published (statuses left out)."""
        return tuple(o.message for o in self.outputs if isinstance(o, Publish) and o.message is not None)

    @property
    def actions(self) -> tuple[WorkerOutput, ...]:
        """Everything but publishing."""
        return tuple(o for o in self.outputs if not isinstance(o, Publish | Announce))


NOTHING = WorkerStep()


class Phase(Enum):
    """Where the worker is: waiting for the chief (``WELCOME``, ``ANSWER``, ``STEP_ANSWER``, a per-step
    straggler's ``WAIT_ROUND``), for the runner (``PLAYING``, ``JOINING``, ``COMPUTING``, ``STEPS_DONE``),
    or applying answers already queued (``CATCH_UP`` after a round, a per-step worker's ``DRAIN``)."""

    NEW = auto()
    WELCOME = auto()
    PLAYING = auto()
    DRAIN = auto()
    WAIT_ROUND = auto()
    JOINING = auto()
    COMPUTING = auto()
    STEP_ANSWER = auto()
    STEPS_DONE = auto()
    ANSWER = auto()
    CATCH_UP = auto()
    DONE = auto()


QUEUED = (Phase.CATCH_UP, Phase.DRAIN)
"""phases that read only what is already queued (due at once)"""


@dataclass
class Wait:
    """Waiting for a chief message: what is wanted, what is re-sent (retained: the join), the deadlines."""

    wanted: Callable[[Message], bool]
    what: str
    resend: Publish
    deadline: float | None
    next_send: float | None
