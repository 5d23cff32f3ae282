"""The chief's round rules that need none of its state: which configurations can run, and how a scheme's
answer to a closed exchange becomes the broadcast message and the event people read."""

from __future__ import annotations

from dataclasses import dataclass

from fleetrl.federation.events import ChiefEvent
from fleetrl.federation.messages import Message
from fleetrl.federation.schemes import Granularity, RoundAnswer, Scheme
from fleetrl.federation.topics import CHIEF_ID


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
    remaining: tuple[str, ...]
    """W after the answer"""


def answer_message(answer: RoundAnswer, run_id: str, rnd: int, step: int) -> Message:
    """The ``average`` or ``transfer`` message the chief broadcasts for round ``rnd``'s exchange ``step``."""
    return Message(
        answer.kind, run_id, CHIEF_ID, rnd, flat=answer.flat, origin=answer.origin,
        finished=answer.finished, contributors=answer.contributors, step=step,
    )  # fmt: skip


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
