"""The chief's answers: which configurations can run, how a scheme's answer to a closed exchange becomes the
broadcast message and the event people read, the welcome or refusal of a joining worker, and the answers
kept to answer re-sends (:class:`AnswerBook`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.messages import Message
from fleetrl.federation.schemes import COMPLETED, Granularity, RoundAnswer, Scheme
from fleetrl.federation.topics import CHIEF_ID, sorted_workers


def check_round_rules(
    scheme: Scheme, max_rounds: int, quorum: float, round_timeout: float | None, steps_per_round: int
) -> None:
    """Raise ValueError naming the first setting of a chief that cannot run (see :class:`Chief`)."""
    if max_rounds < 1:
        raise ValueError(f"max_rounds must be >= 1, got {max_rounds}")
    if not 0.0 < quorum <= 1.0:
        raise ValueError(f"quorum must be in (0, 1], got {quorum}")
    if round_timeout is not None and not round_timeout > 0:
        raise ValueError(f"round_timeout must be > 0 seconds, got {round_timeout}")
    if quorum < 1.0 and round_timeout is None:
        raise ValueError("a quorum below 1 needs a round timeout (--round-timeout)")
    per_step = scheme.granularity is Granularity.STEP
    if steps_per_round < 1 or (steps_per_round != 1 and not per_step):
        raise ValueError(
            f"steps_per_round = {steps_per_round}: scheme {scheme.name!r} sends "
            + ("per step (at least 1)" if per_step else "once per round (1)")
        )
    if per_step and quorum < 1.0:
        raise ValueError(f"scheme {scheme.name!r} averages every step: it needs every worker (quorum 1)")


@dataclass(frozen=True)
class ClosedExchange:
    """Who took part in an exchange the chief just closed."""

    round: int
    answered: tuple[str, ...]
    """the workers whose answers were combined, sorted"""
    late: tuple[str, ...]
    """members of W that had not answered (stragglers)"""
    scores: dict[str, float]
    """each answering worker's round score, if it sent one"""
    completed: tuple[str, ...]
    """answering workers whose criterion holds"""
    remaining: tuple[str, ...] = ()
    """W after the answer"""

    @classmethod
    def of(cls, rnd: int, pending: Mapping[str, Message], members: Iterable[str]) -> ClosedExchange:
        """Round ``rnd``'s exchange closing with the ``pending`` answers while W is ``members``."""
        answered = tuple(sorted_workers(pending))
        late = tuple(sorted_workers(set(members) - set(answered)))
        scores = {w: pending[w].metrics["score"] for w in answered if "score" in pending[w].metrics}
        completed = tuple(w for w in answered if pending[w].type == COMPLETED)
        return cls(rnd, answered, late, scores, completed)


def where(rnd: int, step: int) -> str:
    """An exchange for people: ``round 4``, or ``round 4 step 3``."""
    return f"round {rnd}" if step == 0 else f"round {rnd} step {step}"


def answer_message(answer: RoundAnswer, run_id: str, rnd: int, step: int) -> Message:
    """The ``average`` or ``transfer`` message the chief broadcasts for round ``rnd``'s exchange ``step``."""
    return Message(
        answer.kind, run_id, CHIEF_ID, rnd, flat=answer.flat, origin=answer.origin,
        finished=answer.finished, contributors=answer.contributors, step=step,
    )  # fmt: skip


def welcome_step(
    run_id: str, worker: str, rnd: int, model: Message | None, settings: Mapping[str, str]
) -> ChiefStep:
    """The ``welcome`` to ``worker`` for the open round ``rnd``: the fleet model θ* (``model``'s vector and
    origin) if there is one, and the settings every worker must share; with its event."""
    welcome = Message(
        "welcome", run_id, CHIEF_ID, rnd,
        flat=model.flat if model else None, origin=model.origin if model else None, settings=dict(settings),
    )  # fmt: skip
    detail = f"of round {rnd}" + (f" with θ* of {welcome.origin}" if welcome.origin else "")
    return ChiefStep((welcome,), (ChiefEvent("welcome", rnd, sender=worker, detail=detail),))


def refusal_step(run_id: str, worker: str, rnd: int, why: str) -> ChiefStep:
    """The ``refused`` to ``worker`` (its settings differ from the run's: ``why``), with its event."""
    refusal = Message("refused", run_id, CHIEF_ID, rnd, finished=(worker,), detail=why)
    return ChiefStep((refusal,), (ChiefEvent("refused", rnd, sender=worker, detail=why),))


def answer_event(answer: RoundAnswer, closed: ClosedExchange, aggregator: str) -> ChiefEvent:
    """The ``transfer`` or ``averaged`` event of the answer (``aggregator``: the rule's name, for the log)."""
    if answer.kind == "transfer":
        return ChiefEvent(
            "transfer", closed.round, answered=closed.answered, dropped=tuple(answer.leave_w),
            origin=answer.origin, remaining=closed.remaining, scores=closed.scores, late=closed.late,
        )  # fmt: skip
    completed = f"; completed: {','.join(closed.completed)}" if closed.completed else ""
    return ChiefEvent(
        "averaged", closed.round, answered=closed.answered, averaged=answer.contributors,
        detail=aggregator + completed, remaining=closed.remaining, scores=closed.scores, late=closed.late,
    )  # fmt: skip


class AnswerBook:
    """The answers the chief broadcast, kept to answer re-sends (docs/protocol.md, "Broker loss and idempotent
    resends").

    It keeps the answer of every exchange of the open round and of the round before it, and the last answer
    (followed by ``done`` once the run ended). A worker resumed from its checkpoint replays its round from
    step 0 and re-sends each step's message; each is answered with the answer of exactly that (round, step),
    so the worker continues as if it had never stopped. A re-send of an exchange no longer kept (older, or
    lost with a restarted chief, which keeps only the last answer) gets the last answer.

    :param holdoff: least seconds between two re-sends of one answer to one worker, counted from its
        broadcast too (a flood of one stale message, or a re-send crossing the broadcast, is answered at most
        once per hold-off).
    :param last: the last answer of a restored chief (re-sent to each worker's first re-send at once).
    """

    def __init__(self, holdoff: float, last: tuple[Message, ...] = ()) -> None:
        """An empty book (or a restored chief's, holding only ``last``)."""
        self.holdoff = holdoff
        self.last = last
        """the last answer broadcast (and ``done`` after the end)"""
        self._kept: dict[tuple[int, int], tuple[Message, ...]] = {}  # (round, step) → its answer
        self._sent: dict[tuple[str, int, int], float] = {}  # (worker, round, step) → last sent

    def broadcast(self, reply: Message, workers: Iterable[str], now: float) -> None:
        """Keep ``reply``, broadcast to ``workers`` at ``now``; forget answers of rounds before the last."""
        rnd, step = reply.round, reply.step
        self.last = (reply,)
        self._kept = {at: answer for at, answer in self._kept.items() if at[0] >= rnd - 1}
        self._kept[rnd, step] = self.last
        self._sent = {key: t for key, t in self._sent.items() if key[1] >= rnd - 1}
        self._sent.update(((worker, rnd, step), now) for worker in workers)

    def end(self, done: Message) -> None:
        """The run ended: ``done`` follows the last answer whenever it is sent again."""
        if self.last:
            self._kept[self.last[0].round, self.last[0].step] = (*self.last, done)
        self.last = (*self.last, done)

    def resend(self, worker: str, at: tuple[int, int], now: float) -> tuple[Message, ...]:
        """The answer to send again for ``worker``'s stale message of (round, step) ``at``: that exchange's,
        else the last; nothing if there is none yet or within the hold-off of its last sending."""
        answer = self._kept.get(at, self.last)
        if not answer:
            return ()
        key = (worker, answer[0].round, answer[0].step)
        if now < self._sent.get(key, -math.inf) + self.holdoff:
            return ()
        self._sent[key] = now
        return answer
