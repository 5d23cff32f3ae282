"""What a federated round is, seen from the worker: the learner's side of it (protocols) and its record.

:class:`RoundPlayer` is what the worker needs from the learner (``fleetrl.agent.learner.Learner``), whose
``play_round`` returns a :class:`RoundOutcome` (``fleetrl.agent.learner.RoundResult`` provides it); every
round becomes one :class:`RoundRecord`, and a worker's run ends with a :class:`WorkerSummary`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from fleetrl.federation.events import WorkerEvent
from fleetrl.federation.schemes import FederatedAgent


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
    """One round of one worker, for metrics files and the live view.

    ``event`` is a :class:`~fleetrl.federation.events.WorkerEvent`; ``peer`` the other worker of a
    transfer.
    """

    worker_id: str
    round: int
    score: float
    wma: float
    steps: int
    actor_loss: float
    critic_loss: float
    entropy: float
    event: WorkerEvent
    peer: str | None = None
    """the other worker of a transfer (``transfer_in``: the origin; ``finished``: the one forwarded)"""


@dataclass(frozen=True)
class WorkerSummary:
    """How a worker's run ended."""

    worker_id: str
    rounds: int
    finished: bool
    """True if it left W by sending its parameters (fedavg: with the run's last average)."""
    reason: str
