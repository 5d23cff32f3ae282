"""The chief of Algorithm 1 as a pure state machine: messages in → messages out, no sockets, no clocks.

Round semantics (docs/protocol.md has the full rules):

* The chief keeps W, the workers still learning, and the open round i (from 1). It accepts from each worker in
  W exactly one ``gradient`` or ``parameters`` message for round i, keyed by (sender, round): a second one is
  a rejected duplicate, a message for an earlier round is stale, for a later round is from the future, from a
  worker no longer in W is rejected — none of them changes anything.
* Round i closes when every worker in W has answered. Answers are read in sorted worker-id order, never
  arrival order, so the same inputs give bit-identical outputs on any transport.
* If no answer carries parameters: the gradients are combined by the aggregator (the paper's mean) and one
  ``average`` message is broadcast (Algorithm 1, lines 11–13).
* If one or more answers carry parameters (lines 6–9): the parameters of the lowest worker id among them are
  broadcast in one ``transfer`` message whose ``finished`` lists every worker that sent parameters; all of
  those leave W. The remaining workers replace their actor parameters; their gradients of that round are
  discarded (the paper's else-branch is not taken). The finished workers read the same message as their
  acknowledgement and exit.
* The run ends after the round in which W becomes empty, or after round M; a ``done`` message is then
  broadcast.

Every decision is returned as a :class:`ChiefEvent`, whose ``str()`` is a log line for people.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from fleetrl.federation.aggregation import Aggregator, get_aggregator
from fleetrl.federation.messages import Layout, Message, MessageRejected, Reason, decode
from fleetrl.federation.topics import CHIEF_ID, sorted_workers, validate_id, validate_worker_id

_FROM_WORKERS = ("gradient", "parameters")


@dataclass(frozen=True)
class ChiefEvent:
    """One decision of the chief.

    :param kind: ``rejected``, ``accepted``, ``averaged``, ``transfer`` or ``run_ended``.
    :param round: the chief's open round when it happened (the closed round for ``averaged``/``transfer``).
    :param sender: who sent the message concerned (``rejected``/``accepted``), if known.
    :param reason: why a message was rejected.
    :param detail: free text (rejection detail, or why the run ended).
    :param answered: workers whose answers closed the round.
    :param averaged: workers whose gradients entered the aggregate.
    :param dropped: workers that left W this round.
    :param origin: the worker whose parameters were transferred.
    :param remaining: W after the round.
    :param scores: the ``score`` metric each answer carried, if any.
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

    def __str__(self) -> str:
        """One human-readable line."""
        ids = ",".join
        if self.kind == "rejected":
            reason = self.reason.value if self.reason else "?"
            return f"round {self.round}: rejected message from {self.sender or '?'}: {reason} ({self.detail})"
        if self.kind == "accepted":
            return f"round {self.round}: {self.detail} from {self.sender}"
        scores = " ".join(f"{k}={v:g}" for k, v in self.scores.items())
        if self.kind == "averaged":
            return (
                f"round {self.round}: answered {ids(self.answered)}; "
                f"averaged {ids(self.averaged)} ({self.detail}); W={{{ids(self.remaining)}}} scores {scores}"
            )
        if self.kind == "transfer":
            return (
                f"round {self.round}: answered {ids(self.answered)}; "
                f"transfer parameters of {self.origin} to {ids(self.remaining) or 'nobody'}; "
                f"dropped {ids(self.dropped)}; W={{{ids(self.remaining)}}} scores {scores}"
            )
        return f"round {self.round}: run ended: {self.detail}"


@dataclass(frozen=True)
class ChiefStep:
    """What the chief does after one input: messages to broadcast (in order) and events to log."""

    outgoing: tuple[Message, ...] = ()
    events: tuple[ChiefEvent, ...] = ()


class Chief:
    """Algorithm 1 (the chief) for one run.

    :param run_id: the run.
    :param workers: the initial W (worker ids).
    :param layout: the actor's tensor layout every gradient or parameter message must match.
    :param max_rounds: M, the last round.
    :param aggregator: name of a registered aggregation rule (see :mod:`fleetrl.federation.aggregation`).
    :param max_bytes: message size cap; default from the layout.
    """

    def __init__(
        self,
        *,
        run_id: str,
        workers: Iterable[str],
        layout: Layout,
        max_rounds: int,
        aggregator: str = "mean",
        max_bytes: int | None = None,
    ) -> None:
        """Create the chief with W = ``workers`` and round 1 open."""
        self.run_id = validate_id(run_id, "run id")
        self.all_workers: tuple[str, ...] = tuple(sorted_workers({validate_worker_id(w) for w in workers}))
        if not self.all_workers:
            raise ValueError("a run needs at least one worker")
        if max_rounds < 1:
            raise ValueError(f"max_rounds must be >= 1, got {max_rounds}")
        self.layout = list(layout)
        self.max_rounds = max_rounds
        self.aggregator_name = aggregator
        self._aggregate: Aggregator = get_aggregator(aggregator)
        self.max_bytes = max_bytes
        self._members: set[str] = set(self.all_workers)
        self._round = 1
        self._pending: dict[str, Message] = {}
        self._end_reason: str | None = None
        self.rejections: Counter[Reason] = Counter()
        """How many messages were rejected, by reason."""
        self.transfers: list[tuple[int, str, tuple[str, ...]]] = []
        """(round, origin, recipients) of every model transfer."""

    @property
    def round(self) -> int:
        """The open round (after the end: the last round played)."""
        return self._round

    @property
    def members(self) -> tuple[str, ...]:
        """W: the workers still learning, sorted."""
        return tuple(sorted_workers(self._members))

    @property
    def answered(self) -> tuple[str, ...]:
        """Workers that have answered the open round so far, sorted."""
        return tuple(sorted_workers(self._pending))

    @property
    def finished(self) -> bool:
        """True once the run has ended."""
        return self._end_reason is not None

    @property
    def end_reason(self) -> str | None:
        """Why the run ended (``W is empty`` or ``reached M rounds``), or None while it runs."""
        return self._end_reason

    def receive_bytes(self, payload: bytes, *, topic_worker: str | None = None) -> ChiefStep:
        """Decode and handle one payload; any defect becomes a ``rejected`` event, never an exception.

        :param payload: bytes received on a worker topic.
        :param topic_worker: the worker id of the topic it arrived on; the envelope's sender must match it.
        """
        try:
            message = decode(
                payload,
                run_id=self.run_id,
                known_senders=self.all_workers,
                layout=self.layout,
                max_bytes=self.max_bytes,
            )
        except MessageRejected as exc:
            return self._reject(topic_worker, exc.reason, exc.detail)
        if topic_worker is not None and message.sender != topic_worker:
            return self._reject(topic_worker, Reason.TOPIC_MISMATCH, f"envelope says {message.sender!r}")
        return self.receive(message)

    def receive(self, message: Message) -> ChiefStep:
        """Handle one decoded message from a worker (Algorithm 1, lines 2–5; closes the round when
        complete)."""
        sender = message.sender
        if self.finished:
            return self._reject(sender, Reason.RUN_OVER, f"round {message.round}")
        if message.type not in _FROM_WORKERS:
            return self._reject(sender, Reason.UNEXPECTED_TYPE, message.type)
        if sender not in self._members:
            known = sender in self.all_workers
            return self._reject(
                sender, Reason.NOT_IN_W if known else Reason.UNKNOWN_SENDER, f"round {message.round}"
            )
        if message.round < self._round:
            return self._reject(
                sender, Reason.STALE_ROUND, f"round {message.round} < open round {self._round}"
            )
        if message.round > self._round:
            return self._reject(
                sender, Reason.FUTURE_ROUND, f"round {message.round} > open round {self._round}"
            )
        if sender in self._pending:
            return self._reject(sender, Reason.DUPLICATE, f"{message.type} for round {message.round}")
        self._pending[sender] = message
        accepted = ChiefEvent("accepted", self._round, sender=sender, detail=message.type)
        if self._members.issubset(self._pending):
            step = self._close_round()
            return ChiefStep(step.outgoing, (accepted, *step.events))
        return ChiefStep(events=(accepted,))

    def _reject(self, sender: str | None, reason: Reason, detail: str) -> ChiefStep:
        self.rejections[reason] += 1
        return ChiefStep(
            events=(ChiefEvent("rejected", self._round, sender=sender, reason=reason, detail=detail),)
        )

    def _close_round(self) -> ChiefStep:
        rnd = self._round
        answered = tuple(sorted_workers(self._pending))
        scores = {
            w: self._pending[w].metrics["score"] for w in answered if "score" in self._pending[w].metrics
        }
        completed = tuple(w for w in answered if self._pending[w].type == "parameters")
        if completed:
            origin = completed[0]
            self._members.difference_update(completed)
            remaining = self.members
            reply = Message(
                "transfer", self.run_id, CHIEF_ID, rnd, flat=self._pending[origin].flat, origin=origin,
                finished=completed,
            )  # fmt: skip
            self.transfers.append((rnd, origin, remaining))
            event = ChiefEvent(
                "transfer",
                rnd,
                answered=answered,
                dropped=completed,
                origin=origin,
                remaining=remaining,
                scores=scores,
            )
        else:
            flats = [self._require_flat(self._pending[w]) for w in answered]
            average = self._aggregate(flats)
            reply = Message("average", self.run_id, CHIEF_ID, rnd, flat=average, contributors=answered)
            event = ChiefEvent(
                "averaged", rnd, answered=answered, averaged=answered, detail=self.aggregator_name,
                remaining=self.members, scores=scores,
            )  # fmt: skip
        outgoing: list[Message] = [reply]
        events: list[ChiefEvent] = [event]
        self._pending = {}
        if not self._members or rnd >= self.max_rounds:
            self._end_reason = "W is empty" if not self._members else f"reached M={self.max_rounds} rounds"
            outgoing.append(Message("done", self.run_id, CHIEF_ID, rnd))
            events.append(ChiefEvent("run_ended", rnd, detail=self._end_reason, remaining=self.members))
        else:
            self._round = rnd + 1
        return ChiefStep(tuple(outgoing), tuple(events))

    @staticmethod
    def _require_flat(message: Message) -> np.ndarray:
        if message.flat is None:  # decode guarantees tensors for gradient messages
            raise AssertionError(f"gradient from {message.sender} has no tensors")
        return message.flat
