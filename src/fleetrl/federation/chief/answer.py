"""Who the chief takes and what it says: which configurations can run, who belongs to the run
(:class:`Roster`) and joined with matching settings (:class:`JoinGate`), which message it takes
(:func:`admission`), and the messages and events of an answer, a welcome and a refusal."""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.schemes import COMPLETED, RoundAnswer, Scheme
from fleetrl.federation.shared_settings import SharedSettings, settings_difference
from fleetrl.federation.wire.messages import Message, Reason, RoundConfig
from fleetrl.federation.wire.topics import CHIEF_ID, sorted_workers, validate_worker_id


def check_round_rules(
    scheme: Scheme, max_rounds: int, quorum: float, round_timeout: float | None, steps_per_round: int,
    max_staleness: int | None = None, aggregation: str = "mean",
) -> None:  # fmt: skip
    """Raise ValueError naming the first setting of a chief that cannot run."""
    if max_rounds < 1:
        raise ValueError(f"max_rounds must be >= 1, got {max_rounds}")
    if not 0.0 < quorum <= 1.0:
        raise ValueError(f"quorum must be in (0, 1], got {quorum}")
    if round_timeout is not None and not round_timeout > 0:
        raise ValueError(f"round_timeout must be > 0 seconds, got {round_timeout}")
    if max_staleness is not None and max_staleness < 0:
        raise ValueError(f"max_staleness must be >= 0 rounds, got {max_staleness}")
    scheme.check_rules(quorum, round_timeout, steps_per_round, aggregation)


class Roster:
    """The run's workers, in the fixed order; in an open fleet a unit new to it may join by the same
    handshake (docs/protocol.md, "A new unit joins"), a closed fleet takes only its own ids."""

    def __init__(self, workers: Iterable[str], *, open_fleet: bool = True) -> None:
        """The roster of ``workers``; ValueError if there is none or an id is not valid."""
        self.workers: tuple[str, ...] = tuple(sorted_workers({validate_worker_id(w) for w in workers}))
        if not self.workers:
            raise ValueError("a run needs at least one worker")
        self.open_fleet = open_fleet

    def __contains__(self, sender: object) -> bool:
        """Whether the chief reads a message of ``sender`` at all (a worker, or one that may join)."""
        if not isinstance(sender, str):
            return False
        return sender in self.workers or (self.open_fleet and self.may_join(sender))

    def may_join(self, worker: str) -> bool:
        """``worker`` is new to the run and may join it (an open fleet, a valid worker id)."""
        if not self.open_fleet or worker in self.workers:
            return False
        try:
            validate_worker_id(worker)
        except ValueError:
            return False
        return True

    def admit(self, worker: str) -> None:
        """``worker`` is one of the run's workers from now on."""
        if not self.may_join(worker):
            raise ValueError(f"worker {worker!r} cannot join: already a worker, or the fleet is closed")
        self.workers = tuple(sorted_workers((*self.workers, worker)))


class JoinGate:
    """Who joined with the chief's shared ``settings`` and who was refused, and why (None checks nothing)."""

    def __init__(self, settings: SharedSettings | None) -> None:
        self.settings: dict[str, str] | None = None if settings is None else dict(settings)
        self._refused: dict[str, str] = {}  # worker → why its last join was refused
        self._joined: set[str] = set()  # workers whose join matched, since their newest incarnation

    def join(self, worker: str, settings: SharedSettings) -> str:
        """Check a join: ``joined``, ``duplicate`` (a matching join already seen) or ``refused``."""
        why = None if self.settings is None else settings_difference(self.settings, settings)
        if why is not None:
            self._refused[worker] = why
            return "refused"
        if worker in self._joined:
            return "duplicate"
        self._joined.add(worker)
        self._refused.pop(worker, None)
        return "joined"

    def refusal(self, worker: str) -> str | None:
        """Why ``worker`` is refused, or None."""
        return self._refused.get(worker)

    def new_incarnation(self, worker: str) -> None:
        """A new process of ``worker`` came online: it joins afresh."""
        self._joined.discard(worker)
        self._refused.pop(worker, None)


def admission(
    message: Message, scheme: Scheme, workers: Collection[str], steps_per_round: int,
    open_at: tuple[int, int], finished: bool, left: Collection[str], pending: Collection[str],
) -> tuple[Reason, str] | None:  # fmt: skip
    """Why the chief rejects a worker's round message (reason, detail), or None if it takes it for the open
    exchange ``open_at`` (round, step; after the end: past the last one). ``left``: workers that left W for
    good; ``pending``: who answered the open exchange."""
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
    answered: tuple[str, ...]  # the workers whose answers were combined, sorted
    late: tuple[str, ...]  # members of W that had not answered (stragglers)
    scores: dict[str, float]  # each answering worker's round score, if it sent one
    completed: tuple[str, ...]  # answering workers whose criterion holds
    remaining: tuple[str, ...] = ()  # W after the answer

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
    """The ``average`` or ``transfer`` message for round ``rnd``'s exchange ``step``: it stands for the
    samples and units of the ``answers`` it combines (a transfer: its origin's) and carries ``config``, what
    the scheme asks for the round it opens (empty if none)."""
    origin = answer.origin if answer.origin in answers else None
    behind = [answers[w] for w in ((origin,) if origin is not None else answer.contributors)]
    return Message(
        answer.kind, run_id, CHIEF_ID, rnd, flat=answer.flat, origin=answer.origin,
        finished=answer.finished, contributors=answer.contributors, step=step,
        samples=sum(m.samples for m in behind), units=sum(m.units for m in behind), config=config,
    )  # fmt: skip


def welcome_step(
    run_id: str, worker: str, rnd: int, model: Message | None, settings: Mapping[str, str],
    config: RoundConfig,
) -> ChiefStep:  # fmt: skip
    """The ``welcome`` to ``worker`` for the open round ``rnd`` with its event: the fleet's ``model`` (θ* of
    a transfer, the last average, or the fleet's start) if any, the shared settings and ``config``."""
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
