"""What a federated round is, seen from the worker: the learner's side of it (protocols), what the worker's
state machine asks of its runner (the actions of a :class:`WorkerStep`), and the round's record.

:class:`RoundPlayer` is what the worker needs from the learner (``fleetrl.agent.learner.Learner``), whose
``play_round`` returns the learner's :class:`~fleetrl.agent.learner.RoundResult`; every round becomes one
:class:`FederatedRound` (that result with the worker, the federation's round and its event), and a worker's
run ends with a :class:`WorkerSummary`.

The machine (:mod:`fleetrl.federation.worker.machine`) decides; the runner
(:class:`.worker.runner.FederatedWorker`) does: it publishes, plays the learner's rounds and steps,
applies answers to the agent through the scheme, and reports back. Every input of the machine returns one
:class:`WorkerStep`, whose outputs are executed in order.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
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
        ...

    @property
    def completed(self) -> bool:
        """The completion criterion has held (after this round's episodes, inside ``play_round``)."""
        ...

    def play_round(self) -> RoundResult:
        """Play one episode and, unless learning is complete, optimise (Algorithm 2, lines 2–24)."""
        ...

    def begin_round(self) -> Any:
        """The round's episodes alone; the result's ``updates`` says whether an update follows (a per-step
        scheme's worker then drives it, exchanging every step with the chief)."""
        ...

    def end_round(self, played: Any, stats: Any) -> RoundResult:
        """The round's outcome from :meth:`begin_round`'s result and the update's statistics (None: none)."""
        ...


@dataclass(frozen=True)
class FederatedRound:
    """One round of one worker as the federation saw it: the learner's figures of the round (its
    :class:`~fleetrl.agent.learner.RoundResult`, kept whole: the figures live in that one value) with the
    worker, the federation's round number and what the federation made of the round.

    ``round`` is the federation's round (a resumed or rejoining worker's learner counts its own);
    ``event`` is a :class:`~fleetrl.federation.events.WorkerEvent`, or a
    :class:`~fleetrl.federation.events.Sent` naming the scheme's message; ``peer`` the other worker of a
    transfer.
    """

    worker_id: str
    round: int
    result: RoundResult
    """the learner's report of the round (score, steps, episodes, wma, the update's statistics)"""
    event: RoundEvent
    peer: str | None = None
    """the other worker of a transfer (``transfer_in``: the origin; ``finished``: the one forwarded)"""

    @property
    def label(self) -> str:
        """The round's event as metrics files name it (:meth:`.events.WorkerEvent.label`)."""
        return self.event.label(self.peer)


@dataclass(frozen=True)
class WorkerSummary:
    """How a worker's run ended."""

    worker_id: str
    rounds: int
    finished: bool
    """True if it left W by sending its parameters (fedavg: with the run's last average)."""
    reason: str


def resume_round(start_round: int | None, welcome_round: int, worker_id: str) -> int | None:
    """The round a worker resumed from a checkpoint at ``start_round`` (the first round its state has not
    played) plays first when the chief welcomes it at ``welcome_round``; None: rejoin at the welcome's round
    like a fresh worker (not resumed, or rounds were played without it). RuntimeError if the chief is behind
    the checkpoint (it lost rounds)."""
    if start_round is None:
        return None
    if welcome_round < start_round:
        raise RuntimeError(
            f"worker {worker_id}: the chief is at round {welcome_round} but this worker's "
            f"checkpoint is at round {start_round}: the chief lost rounds (resume it from its checkpoint)"
        )
    if welcome_round <= start_round + 1:
        # One round ahead: the message this worker sent before it died closed that round. Playing it again
        # gives the same message (same state, same RNGs); the chief answers the copy with that round's
        # answer, and the worker continues exactly as if it had never stopped.
        return start_round
    log.warning(
        "worker %s: rounds %d-%d were played without this worker; rejoining at round %d",
        worker_id, start_round, welcome_round - 1, welcome_round,
    )  # fmt: skip
    return None


def answer_for(rnd: int, step: int = 0) -> Callable[[Message], bool]:
    """Accepts the chief's answer for round ``rnd`` (step ``step``) or a later one (ours was missed), or
    ``done``; an earlier answer is stale."""
    return lambda m: m.type == "done" or (m.type in ANSWERS and (m.round, m.step) >= (rnd, step))


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
    :meth:`~fleetrl.federation.worker.machine.WorkerMachine.round_played` — for a per-round scheme with what
    ``scheme.outgoing`` shares; a per-step scheme's round reports its episodes with ``round_collected``
    and its update through ``update_begun`` and ``step_computed`` first. A per-round scheme's
    ``local_loss(agent, config)`` is installed before it."""

    round: int
    config: RoundConfig = field(default_factory=dict)
    """what the chief asks of every worker for this round (its scheme's ``configure``)"""


@dataclass(frozen=True)
class ComputeStep:
    """Compute the gradients of optimisation step ``step`` (``agent.step_gradients``) and report them with
    :meth:`~fleetrl.federation.worker.machine.WorkerMachine.step_computed`."""

    step: int


@dataclass(frozen=True)
class BeginUpdate:
    """A per-step round's episodes are played and the worker joins an exchange: ``agent.begin_update()``
    (no steps if the learner does not update this round) and report it with
    :meth:`~fleetrl.federation.worker.per_step.StepWorkerMachine.update_begun`."""


@dataclass(frozen=True)
class ApplyFleetStep:
    """``scheme.catch_up_step(agent, step, flat)``: an answer of the fleet's step ``step`` taken while this
    worker had no update under way (it was behind)."""

    step: int
    flat: np.ndarray


@dataclass(frozen=True)
class ApplyStep:
    """``scheme.apply_step_answer(agent, flat)``: the chief's combination of one optimisation step."""

    flat: np.ndarray


@dataclass(frozen=True)
class EndUpdate:
    """Every step of the round's update was exchanged: ``agent.end_update()`` and let the round finish."""


@dataclass(frozen=True)
class AbandonUpdate:
    """The fleet went on past this worker's round or step: ``agent.abandon_update()`` and let the round
    finish without its update."""


@dataclass(frozen=True)
class Record:
    """A round is over: hand its record to ``on_record``."""

    record: FederatedRound


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
class RunEnded:
    """The chief's status said the run had ended before this worker was welcomed (raise
    :class:`RunEndedError`)."""

    detail: str


class RunEndedError(OSError):
    """A worker started after its run was over: it could not do its job (``fleetrl worker`` exits 1)."""


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
    | BeginUpdate
    | ComputeStep
    | ApplyStep
    | AbandonUpdate
    | ApplyFleetStep
    | EndUpdate
    | Record
    | Checkpoint
    | Finish
    | Refused
    | RunEnded
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
