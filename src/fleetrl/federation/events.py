"""What the roles decide, as data: the chief's :class:`ChiefEvent` (a log line for people) and
:class:`ChiefStep`; the worker's :class:`WorkerEvent` (what a round did), which metrics files write through
:meth:`WorkerEvent.label` — one vocabulary from the state machine to the CSV."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from fleetrl.federation.wire.messages import Message, Reason


@dataclass(frozen=True)
class ChiefEvent:
    """One decision of the chief.

    :param kind: ``rejected``, ``accepted``, ``averaged``, ``transfer``, ``run_ended``, ``dropped``
        (a worker left W: offline or silent past the deadline), ``rejoined`` (a dropped worker is back in W),
        ``welcome`` (the open round was announced to a worker coming online), ``resent`` (the last answer
        was sent again for a worker that re-sent a closed round), ``admitted`` (a worker new to the run
        joined W: :mod:`.chief.roster`), ``joined`` (a worker's shared settings match the chief's),
        ``refused``
        (they differ: ``detail`` names the setting), ``deposed`` (an input showed a chief of a newer epoch:
        this one stops) or, at an edge aggregator, ``forwarded`` (an exchange closed at the site: its
        members' sum went to the root).
    :param round: the chief's open round when it happened (the closed round for ``averaged``/``transfer``).
    :param sender: who sent the message concerned, or the worker dropped, rejoined or welcomed.
    :param reason: why a message was rejected.
    :param detail: free text (rejection detail, why a worker was dropped, why the run ended).
    :param answered: workers whose answers closed the round.
    :param averaged: workers whose gradients entered the aggregate.
    :param dropped: workers that left W this round.
    :param origin: the worker whose parameters were transferred.
    :param remaining: W after the round.
    :param scores: the ``score`` metric each answer carried, if any.
    :param late: workers still in W that had not answered when a deadline closed the round (stragglers).
    """

    kind: str
    round: int
    sender: str | None = None
    reason: Reason | None = None
    detail: str = ""
    answered: tuple[str, ...] = ()
    averaged: tuple[str, ...] = ()
    dropped: tuple[str, ...] = ()
    origin: str | None = None
    remaining: tuple[str, ...] = ()
    scores: dict[str, float] = field(default_factory=dict)
    late: tuple[str, ...] = ()

    def __str__(self) -> str:
        """One human-readable line."""
        ids = ",".join
        if self.kind == "rejected":
            reason = self.reason.value if self.reason else "?"
            return f"round {self.round}: rejected message from {self.sender or '?'}: {reason} ({self.detail})"
        if self.kind == "joined":
            return f"round {self.round}: worker {self.sender} joined (shared settings match)"
        if self.kind == "refused":
            return f"round {self.round}: worker {self.sender} refused: {self.detail}"
        if self.kind in ("accepted", "resent", "welcome"):
            return f"round {self.round}: {self.kind} {self.detail} for {self.sender}".replace("  ", " ")
        if self.kind in ("dropped", "rejoined", "admitted"):
            w = ids(self.remaining)
            return f"round {self.round}: worker {self.sender} {self.kind}: {self.detail}; W={{{w}}}"
        scores = " ".join(f"{k}={v:g}" for k, v in self.scores.items())
        late = f"; late {ids(self.late)}" if self.late else ""
        if self.kind == "averaged":
            return (
                f"round {self.round}: answered {ids(self.answered)}{late}; "
                f"averaged {ids(self.averaged)} ({self.detail}); W={{{ids(self.remaining)}}} scores {scores}"
            )
        if self.kind == "forwarded":
            return (
                f"round {self.round}: answered {ids(self.answered)}{late}; sent the sum of "
                f"{ids(self.averaged)} to the root ({self.detail}); W={{{ids(self.remaining)}}}"
            )
        if self.kind == "transfer":
            return (
                f"round {self.round}: answered {ids(self.answered)}{late}; "
                f"transfer parameters of {self.origin} to {ids(self.remaining) or 'nobody'}; "
                f"dropped {ids(self.dropped)}; W={{{ids(self.remaining)}}} scores {scores}"
            )
        if self.kind == "deposed":
            return f"round {self.round}: a newer chief runs this run ({self.detail}): stopping"
        return f"round {self.round}: run ended: {self.detail}"


@dataclass(frozen=True)
class ChiefStep:
    """What the chief does after one input: messages to broadcast (in order) and events to log."""

    outgoing: tuple[Message, ...] = ()
    events: tuple[ChiefEvent, ...] = ()

    def __add__(self, other: ChiefStep) -> ChiefStep:
        """Both steps, this one first."""
        return ChiefStep(self.outgoing + other.outgoing, self.events + other.events)


class WorkerEvent(StrEnum):
    """What one round did for a worker (:attr:`.worker.actions.FederatedRound.event`), beside the
    round in which it sent its scheme's message and applied the answer (:class:`Sent`)."""

    COMPLETED = "completed"
    """its criterion held; it sent its parameters, which were averaged, and it stays (``fedavg``)"""
    LATE = "late"
    """its message missed the round, which the chief closed without it; the scheme applied the answer"""
    TRANSFER_IN = "transfer_in"
    """replaced its shared parameters with the peer's (a transfer)"""
    TRANSFER_OUT = "transfer_out"
    """sent its parameters, which the chief forwarded; it left W"""
    FINISHED = "finished"
    """sent its parameters, but the peer's (a lower id) were forwarded in the same round; it left W"""
    RUN_ENDED = "run_ended"
    """the chief ended the run while it waited"""
    INTERRUPTED = "interrupted"
    """it went down while playing this round and came back (``--resume``) after its fleet had gone on: what
    it played is lost (the row has no figures); the round stays in its books"""

    def label(self, peer: str | None = None) -> str:
        """The event as metrics files write it: ``completed+`` marks a round whose criterion held when the
        worker left W, ``:K`` names the peer of a transfer."""
        if self is WorkerEvent.TRANSFER_OUT:
            return "completed+transfer_out"
        if self is WorkerEvent.FINISHED:
            return f"completed+finished:{peer}"
        if self is WorkerEvent.TRANSFER_IN:
            return f"transfer_in:{peer}"
        return self.value

    def describe(self, peer: str | None = None) -> str:
        """The event for a log line (``transfer_in from K``)."""
        return f"{self.value} from {peer}" if peer is not None else self.value


@dataclass(frozen=True)
class Sent:
    """A round in which the worker sent its scheme's round message — ``gradient`` (``paper``), ``model``
    (``fedavg``), ``step_gradient`` (``pergrad``: every step's) … — and applied the chief's answer; labelled
    with that message type, which only the scheme names."""

    message: str

    @property
    def value(self) -> str:
        """The message type."""
        return self.message

    def label(self, peer: str | None = None) -> str:
        """The metrics files' label: the message type."""
        del peer
        return self.message

    def describe(self, peer: str | None = None) -> str:
        """The log line's: the message type."""
        del peer
        return self.message


RoundEvent = WorkerEvent | Sent
"""What one round did for a worker."""
