"""What the roles decide, as data: the chief's :class:`ChiefEvent` (a log line for people) and
:class:`ChiefStep`; the worker's :class:`WorkerEvent` (what a round did), written to metrics files by
:meth:`WorkerEvent.label`."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from fleetrl.federation.wire.messages import Message, Reason


@dataclass(frozen=True)
class ChiefEvent:
    """One decision of the chief.

    :param kind: ``rejected``, ``accepted``, ``averaged``, ``transfer``, ``run_ended``, ``dropped`` (left W),
        ``rejoined``, ``welcome``, ``resent`` (an answer sent again), ``admitted`` (new to the run),
        ``joined`` (shared settings match), ``refused`` (they differ), ``deposed`` (a newer chief runs the
        run) or, at an edge aggregator, ``forwarded`` (the site's sum went to the root).
    :param round: the chief's open round (the closed round for ``averaged``/``transfer``).
    """

    kind: str
    round: int
    sender: str | None = None  # who sent the message concerned, or the worker dropped, rejoined, welcomed
    reason: Reason | None = None  # why a message was rejected
    detail: str = ""
    answered: tuple[str, ...] = ()  # workers whose answers closed the round
    averaged: tuple[str, ...] = ()  # workers whose vectors entered the aggregate
    dropped: tuple[str, ...] = ()  # workers that left W this round
    origin: str | None = None  # the worker whose parameters were transferred
    remaining: tuple[str, ...] = ()  # W after the round
    scores: dict[str, float] = field(default_factory=dict)  # the score each answer carried
    late: tuple[str, ...] = ()  # members that had not answered when a deadline closed the round

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
    """What one round did for a worker, beside a round in which it sent its scheme's message and applied the
    answer (:class:`Sent`)."""

    COMPLETED = "completed"  # its criterion held; its parameters were averaged and it stays (fedavg)
    LATE = "late"  # its message missed the round; the scheme applied the answer
    TRANSFER_IN = "transfer_in"  # replaced its shared parameters with the peer's
    TRANSFER_OUT = "transfer_out"  # sent its parameters, which the chief forwarded; it left W
    FINISHED = "finished"  # sent its parameters, but a lower id's were forwarded that round; it left W
    RUN_ENDED = "run_ended"  # the chief ended the run while it waited
    INTERRUPTED = "interrupted"
    """it went down while playing this round and came back (``--resume``) after its fleet had gone on: what
    it played is lost (the row has no figures)"""

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
    """A round in which the worker sent its scheme's round message (``gradient``, ``model``,
    ``step_gradient`` …) and applied the chief's answer; labelled with that message type."""

    message: str

    @property
    def value(self) -> str:
        """The message type."""
        return self.message

    def label(self, peer: str | None = None) -> str:
        """The message type, for the metrics files and log lines alike."""
        return self.message

    describe = label


RoundEvent = WorkerEvent | Sent
"""What one round did for a worker."""
