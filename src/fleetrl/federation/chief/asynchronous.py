"""The chief of an asynchronous scheme (``fedasync``) as a pure state machine, with no round barrier: each
contribution is mixed into the fleet model on arrival (unless staler than ``max_staleness``) and answered with
the model and its version; the rest is the synchronous chief's (docs/protocol.md, "Asynchronous schemes").
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from fleetrl.federation.chief.answer import check_round_rules
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.chief.state import Contributions
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import COMPLETED, AsyncScheme, RoundContext
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.wire.messages import Message, Reason
from fleetrl.federation.wire.topics import CHIEF_ID


class AsyncChief(Chief):
    """The chief of an asynchronous scheme: :class:`~.chief.machine.Chief`'s parameters, ``start`` required
    unless the scheme holds a restored model; the scheme keeps the fleet model (``fleet_model`` is unused)."""

    def __init__(self, plan: ChiefPlan, *, start: FleetStart | None = None, **options: Any) -> None:
        options.pop("fleet_model", None)
        super().__init__(plan, start=start, **options)
        if not isinstance(self.scheme, AsyncScheme):  # a check of what was built, not a choice of behaviour
            raise ValueError(f"scheme {self.scheme.name!r} is not asynchronous: use Chief")
        self.fleet: AsyncScheme = self.scheme
        check_round_rules(
            self.scheme, self.max_rounds, self.plan.quorum, self.plan.round_timeout, 1,
            self.plan.max_staleness, self.plan.aggregator,
        )  # fmt: skip
        if self.fleet.model is None:
            if start is None:
                raise ValueError(f"scheme {self.scheme.name!r}: the chief needs the fleet's start")
            self.fleet.begin(start.flat)
        self.state.model = None  # the scheme holds x (and the checkpoint keeps it with the scheme's state)
        self._resent: dict[str, float] = {}  # worker → when an answer was last sent again to it

    def receive(self, message: Message, *, now: float) -> ChiefStep:
        """Take one decoded worker message: apply a new contribution at once, answer a re-sent one again."""
        self._start_clock(now)
        sender, rnd = message.sender, message.round
        if message.type == "join":
            return self._join(message, now)
        if (why := self._gate.refusal(sender)) is not None:
            return self._reject(sender, Reason.REFUSED, why)
        refusal = self._admission(message)
        if refusal is not None:
            return self._reject(sender, *refusal)
        record = self.state.contributions.setdefault(sender, Contributions())
        if self.finished or rnd <= record.last_round:
            reason = Reason.RUN_OVER if self.finished else Reason.DUPLICATE
            detail = f"{message.type} for round {rnd} (taken up to {record.last_round})"
            step = self._reject(sender, reason, detail)
            return step + self._answer_again(sender, rnd, now)
        step = self._rejoin(sender, f"sent {message.type} for round {rnd}")
        accepted = ChiefEvent("accepted", rnd, sender=sender, detail=message.type)
        return step + ChiefStep(events=(accepted,)) + self._take(message, record, now)

    def _admission(self, message: Message) -> tuple[Reason, str] | None:
        """Why a worker's message is refused whatever its round (None: it is a contribution)."""
        sender, rnd = message.sender, message.round
        if not self.scheme.accepts(message.type):
            return Reason.UNEXPECTED_TYPE, message.type
        if sender not in self.all_workers:
            return Reason.UNKNOWN_SENDER, f"round {rnd}"
        if message.step != 0 or rnd > self.max_rounds:
            return Reason.BAD_ROUND, f"round {rnd} step {message.step} (M={self.max_rounds}, step 0 only)"
        if sender in self.state.left:
            return Reason.NOT_IN_W, f"round {rnd}"
        return None

    def _take(self, message: Message, record: Contributions, now: float) -> ChiefStep:
        """Apply (or, past the staleness bound, leave out) one new contribution and answer it."""
        sender, rnd = message.sender, message.round
        staleness = max(0, self.fleet.version - message.model_version)  # a base ahead: a resumed chief's
        if message.type == COMPLETED:
            self.state.completed.setdefault(sender, rnd)
        bound = self.plan.max_staleness
        applied = bound is None or staleness <= bound
        record.take(rnd, staleness, applied=applied)
        self.state.round = max(self.state.round, rnd)
        members = self.members
        if applied:
            context = RoundContext(self._aggregate, members, dict(self.state.completed))
            answer = self.fleet.combine({sender: replace(message, staleness=staleness)}, context)
            ends, finished = answer.ends_run, answer.finished
        else:
            ends = bool(members) and set(members).issubset(self.state.completed)
            finished = members if ends else ()
        reply = self._answer(sender, rnd, applied=applied, finished=finished, samples=message.samples)
        self.state.answers.broadcast(reply, self.all_workers, now)
        score = message.metrics.get("score")
        detail = f"version {self.fleet.version}, staleness {staleness}" + ("" if applied else ", left out")
        if message.type == COMPLETED:
            detail += f"; completed: {sender}"
        event = ChiefEvent(
            "averaged", rnd, answered=(sender,), averaged=reply.contributors, detail=detail,
            remaining=members, scores={} if score is None else {sender: score},
        )  # fmt: skip
        step = ChiefStep((reply,), (event,))
        if ends:
            return step + self._end("every unit completed")
        return step + self._maybe_close(now)

    def _answer(
        self, worker: str, rnd: int, *, applied: bool, finished: tuple[str, ...] = (), samples: int = 0
    ) -> Message:
        """The ``average`` answering ``worker``'s round ``rnd``: the fleet model x as it now is, and v."""
        return Message(
            "average", self.run_id, CHIEF_ID, rnd, flat=self.fleet.model, origin=worker, finished=finished,
            contributors=(worker,) if applied else (), samples=samples,
            model_version=self.fleet.version,
        )  # fmt: skip

    def _answer_again(self, worker: str, rnd: int, now: float) -> ChiefStep:
        """A re-sent contribution's answer again (x as it now is; after the end, the last answer and
        ``done``), at most once per hold-off."""
        if now < self._resent.get(worker, -float("inf")) + self.plan.resend_holdoff:
            return ChiefStep()
        self._resent[worker] = now
        answer = self.state.answers.last if self.finished else (self._answer(worker, rnd, applied=True),)
        if not answer:
            return ChiefStep()
        detail = f"answer of round {rnd}"
        return ChiefStep(answer, (ChiefEvent("resent", self.state.round, sender=worker, detail=detail),))

    def _welcome(self, worker: str) -> ChiefStep:
        """The ``welcome``: x and v, and the round after ``worker``'s last one taken."""
        record = self.state.contributions.get(worker, Contributions())
        rnd = min(record.last_round + 1, self.max_rounds)
        welcome = Message(
            "welcome", self.run_id, CHIEF_ID, rnd, flat=self.fleet.model, origin=CHIEF_ID,
            contributors=(worker,), settings=dict(self.settings or {}), model_version=self.fleet.version,
        )  # fmt: skip
        detail = f"of round {rnd} with the fleet model of version {self.fleet.version}"
        return ChiefStep((welcome,), (ChiefEvent("welcome", rnd, sender=worker, detail=detail),))

    def _maybe_close(self, now: float) -> ChiefStep:
        """The end if every member has played M rounds, or W is empty (the fleet has no rounds to close)."""
        played_out = {w for w, c in self.state.contributions.items() if c.last_round >= self.max_rounds}
        if self.state.members and self.state.members <= played_out:
            return self._end(f"reached M={self.max_rounds} rounds")
        if not self.state.members:
            return self._end("W is empty")
        return ChiefStep()
