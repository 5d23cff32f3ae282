"""What the chief says: which configurations can run, how a scheme's answer to a closed exchange becomes the
broadcast message (with what it stands for and the next round's configuration) and the event people read,
and the welcome or refusal of a joining worker. What it keeps of them is :mod:`.chief.state`'s."""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.schemes import COMPLETED, RoundAnswer, Scheme
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.wire.messages import Message, Reason, RoundConfig
from fleetrl.federation.wire.topics import CHIEF_ID, sorted_workers


def check_round_rules(
    scheme: Scheme,
    max_rounds: int,
    quorum: float,
    round_timeout: float | None,
    steps_per_round: int,
    max_staleness: int | None = None,
    aggregation: str = "mean",
) -> None:
    """Raise ValueError naming the first setting of a chief that cannot run (see :class:`Chief`;
    ``aggregation``: the aggregation rule's name)."""
    if max_rounds < 1:
        raise ValueError(f"max_rounds must be >= 1, got {max_rounds}")
    if not 0.0 < quorum <= 1.0:
        raise ValueError(f"quorum must be in (0, 1], got {quorum}")
    if round_timeout is not None and not round_timeout > 0:
        raise ValueError(f"round_timeout must be > 0 seconds, got {round_timeout}")
    if max_staleness is not None and max_staleness < 0:
        raise ValueError(f"max_staleness must be >= 0 rounds, got {max_staleness}")
    scheme.check_rules(quorum, round_timeout, steps_per_round, aggregation)


def admission(
    message: Message,
    scheme: Scheme,
    workers: Collection[str],
    steps_per_round: int,
    open_at: tuple[int, int],
    finished: bool,
    left: Collection[str],
    pending: Collection[str],
) -> tuple[Reason, str] | None:
    """Why the chief rejects a worker's round message (reason, detail), or None if it takes it for the open
    exchange ``open_at`` (round, step; after the end: past the last one). Messages are keyed (sender, round,
    step); ``left``: workers that left W for good; ``pending``: who answered the open exchange."""
    sender, rnd, at = message.sender, message.round, (message.round, message.step)
    if message.step >= steps_per_round:
        return Reason.BAD_ROUND, f"step {message.step} of {steps_per_round} per round"
    if not scheme.accepts(message.type):
        return Reason.UNEXPECTED_TYPE, message.type
    if sender not in workers:
        return Reason.UNKNOWN_SENDER, f"round {rnd}"
    if at < open_at:
        reason = Reason.RUN_OVER if finished else Reason.STALE_ROUND
        return reason, f"{where(*at)} before the open {where(*open_at)}"
    if finished:
        return Reason.RUN_OVER, f"round {rnd}"
    if sender in left:
        return Reason.NOT_IN_W, f"round {rnd}"
    if at > open_at:
        return Reason.FUTURE_ROUND, f"{where(*at)} > open {where(*open_at)}"
    if sender in pending:
        return Reason.DUPLICATE, f"{message.type} for round {rnd}"
    return None


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


def answer_message(
    answer: RoundAnswer, run_id: str, rnd: int, step: int, answers: Mapping[str, Message], config: RoundConfig
) -> Message:
    """The ``average`` or ``transfer`` message the chief broadcasts for round ``rnd``'s exchange ``step``:
    it stands for the samples and units of the ``answers`` it combines (a transfer: its origin's), and carries
    ``config``, what the scheme asks for the round it opens (empty if it opens none)."""
    origin = answer.origin if answer.origin in answers else None
    behind = [answers[w] for w in ((origin,) if origin is not None else answer.contributors)]
    return Message(
        answer.kind, run_id, CHIEF_ID, rnd, flat=answer.flat, origin=answer.origin,
        finished=answer.finished, contributors=answer.contributors, step=step,
        samples=sum(m.samples for m in behind), units=sum(m.units for m in behind), config=config,
    )  # fmt: skip


def start_welcome(run_id: str, start: FleetStart | None) -> Message | None:
    """The welcome that hands out the fleet's ``start`` in round 1 (None: the fleet has none)."""
    return (
        None if start is None else Message("welcome", run_id, CHIEF_ID, 1, flat=start.flat, origin=CHIEF_ID)
    )


def welcome_step(
    run_id: str,
    worker: str,
    rnd: int,
    model: Message | None,
    settings: Mapping[str, str],
    config: RoundConfig,
) -> ChiefStep:
    """The ``welcome`` to ``worker`` for the open round ``rnd``: the fleet's model (θ* of a transfer, the last
    average, or the fleet's start: ``model``'s vector and origin) if there is one, the settings every worker
    must share, and ``config`` (what the scheme asks for the round); with its event."""
    welcome = Message(
        "welcome", run_id, CHIEF_ID, rnd,
        flat=model.flat if model else None, origin=model.origin if model else None, settings=dict(settings),
        config=config, step=model.step if model and model.round == rnd else 0,
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
