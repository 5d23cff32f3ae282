"""What a federated round is, seen from the worker: the learner's side of it (protocols) and its record.

:class:`RoundPlayer` is what the worker needs from the learner (``fleetrl.agent.learner.Learner``), whose
``play_round`` returns a :class:`RoundOutcome` (``fleetrl.agent.learner.RoundResult`` provides it); every
round becomes one :class:`RoundRecord`, and a worker's run ends with a :class:`WorkerSummary`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from fleetrl.federation.events import RoundEvent
from fleetrl.federation.messages import Message
from fleetrl.federation.schemes import FederatedAgent

log = logging.getLogger(__name__)

ANSWERS = ("average", "transfer", "done")
"""The chief's answers to a round."""


class RoundFigures(Protocol):
    """The figures of one round: the episode and the update's statistics."""

    @property
    def score(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def wma(self) -> float: ...
    @property
    def actor_loss(self) -> float: ...
    @property
    def critic_loss(self) -> float: ...
    @property
    def entropy(self) -> float: ...


class RoundOutcome(RoundFigures, Protocol):
    """What one ``play_round`` reports (``fleetrl.agent.learner.RoundResult`` provides it)."""

    @property
    def completed(self) -> bool: ...


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

    def play_round(self, update: Callable[[], Any] | None = None) -> RoundOutcome:
        """Play one episode and, unless learning is complete, optimise (Algorithm 2, lines 2–24); ``update``
        replaces the agent's own update (a per-step scheme exchanges every step with the chief in it)."""
        ...


@dataclass(frozen=True)
class RoundRecord:
    """One round of one worker, for metrics files and the live view: the learner's figures of the round
    (its :class:`RoundOutcome`, ``fleetrl.agent.learner.RoundResult``, kept as it is: the figures live in one
    place) with what the federation made of it.

    ``round`` is the federation's round (a resumed or rejoining worker's learner counts its own);
    ``event`` is a :class:`~fleetrl.federation.events.WorkerEvent`, or a
    :class:`~fleetrl.federation.events.Sent` naming the scheme's message; ``peer`` the other worker of a
    transfer.
    """

    worker_id: str
    round: int
    outcome: RoundFigures
    """the learner's report of the round (score, steps, wma, losses, entropy)"""
    event: RoundEvent
    peer: str | None = None
    """the other worker of a transfer (``transfer_in``: the origin; ``finished``: the one forwarded)"""

    @property
    def score(self) -> float:
        """The round's score (the learner's)."""
        return float(self.outcome.score)

    @property
    def wma(self) -> float:
        """The weighted moving average of the scores after this round."""
        return float(self.outcome.wma)

    @property
    def steps(self) -> int:
        """Environment steps of the round."""
        return int(self.outcome.steps)

    @property
    def actor_loss(self) -> float:
        """The update's actor loss (NaN without an update)."""
        return float(self.outcome.actor_loss)

    @property
    def critic_loss(self) -> float:
        """The update's critic loss (NaN without an update)."""
        return float(self.outcome.critic_loss)

    @property
    def entropy(self) -> float:
        """The update's mean policy entropy (NaN without an update)."""
        return float(self.outcome.entropy)


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
