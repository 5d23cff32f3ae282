"""The chief of Algorithm 1 as a pure state machine: messages, statuses and time (``now``) in → messages and
events out. Its rules are docs/protocol.md's "Rounds" and "Reliability"; what it remembers is
:attr:`Chief.state`."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

from fleetrl.federation.aggregation import Aggregator, decomposes, get_aggregator
from fleetrl.federation.chief.answer import (
    ClosedExchange,
    JoinGate,
    Roster,
    admission,
    answer_event,
    answer_message,
    check_round_rules,
    refusal_step,
    welcome_step,
    where,
)
from fleetrl.federation.chief.state import AnswerBook, ChiefState, FleetModel
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import RoundContext
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.wire.messages import Layout, Message, MessageRejected, Reason, decode
from fleetrl.federation.wire.signing import FleetKey, parse_status
from fleetrl.federation.wire.topics import CHIEF_ID, sorted_workers

__all__ = ["Chief", "ChiefEvent", "ChiefStep"]

DEADLINE_DROP = "no message within the round deadline"
OFFLINE_DROP = "went offline"
EVERY_WORKER_DROPPED = "every worker dropped out"  # the run did not do its job: `fleetrl chief` exits 1


class Chief:
    """Algorithm 1 (the chief) for one run.

    :param key: the fleet key; if given, only messages and statuses signed with it are accepted.
    :param start: the fleet's start (a ``shared_start`` scheme), welcomed until the fleet has a model.
    :param fleet_model: a per-step scheme's fleet model: every welcome carries it.
    :param state: a restored chief's (:func:`.checkpoint.chief_from_state`); None: round 1.
    :param now: when the open round opened (a restored chief: now); None: at the first input.
    """

    def __init__(
        self, plan: ChiefPlan, *, key: FleetKey | None = None, start: FleetStart | None = None,
        fleet_model: FleetModel | None = None, state: ChiefState | None = None, now: float | None = None,
    ) -> None:  # fmt: skip
        if fleet_model is not None and start is None:
            start = fleet_model.start()
        if start is not None:
            plan = replace(plan, welcome_layout=start.layout)
        self.plan = plan
        self.run_id, self.scheme, self.max_rounds = plan.run_id, plan.scheme, plan.max_rounds
        self.roster = Roster(plan.workers, open_fleet=plan.open_fleet)
        self.layout = list(plan.layout)
        self.welcome_layout = list(plan.welcome_layout or plan.layout)
        self.fleet_model = fleet_model
        self.steps_per_round = plan.steps_per_round
        check_round_rules(
            self.scheme, plan.max_rounds, plan.quorum, plan.round_timeout, plan.steps_per_round,
            plan.max_staleness,
        )  # fmt: skip
        self._gate = JoinGate(plan.settings)
        self._aggregate: Aggregator = get_aggregator(plan.aggregator)
        self._waits = self.scheme.waits(plan.quorum, plan.round_timeout, plan.max_staleness)
        self.key = key
        if state is None:
            config = dict(self.scheme.configure(1, self.all_workers))
            model = None
            if start is not None:
                model = Message("welcome", plan.run_id, CHIEF_ID, 1, flat=start.flat, origin=CHIEF_ID)
            state = ChiefState(
                set(self.all_workers), AnswerBook(plan.resend_holdoff), model=model, config=config
            )
        self.state = state  # what the chief remembers (its checkpoint serialises it)
        self._opened_at: float | None = now
        self._pending: dict[str, Message] = {}  # the open exchange's answers (workers re-send them)
        self._restarted: set[str] = set()  # workers seen restarting, until their join (not a replayed one)
        # the state's records, under the names the runner and people read (the same objects: never rebound)
        self.rejections, self.completed, self.transfers = state.rejections, state.completed, state.transfers
        self.dropouts, self.rejoins = state.dropouts, state.rejoins
        self.superseded: str | None = None  # what showed a chief of a newer epoch: this one must stop

    @property
    def epoch(self) -> int:
        """The chief's epoch (:mod:`.lease`), stamped on every message it sends."""
        return self.state.epoch

    def take_epoch(self, epoch: int) -> None:
        """Run as the chief of ``epoch`` from now on."""
        if epoch < self.state.epoch:
            raise ValueError(f"epoch {epoch} is older than this chief's {self.state.epoch}")
        self.state.epoch = epoch

    @property
    def all_workers(self) -> tuple[str, ...]:
        """Every worker of the run (W and those that left it), in the fixed order."""
        return self.roster.workers

    def layout_of(self, message_type: str) -> Layout:
        """The layout of the tensors a message of ``message_type`` from the chief carries."""
        return self.welcome_layout if message_type in ("welcome", "done") else self.layout

    @property
    def settings(self) -> dict[str, str] | None:
        """The shared settings every worker must have (None: not checked)."""
        return self._gate.settings

    @property
    def round(self) -> int:
        """The open round (after the end: the last round played)."""
        return self.state.round

    @property
    def members(self) -> tuple[str, ...]:
        """W: the workers still learning, sorted."""
        return tuple(sorted_workers(self.state.members))

    @property
    def answered(self) -> tuple[str, ...]:
        """Workers that have answered the open round so far, sorted."""
        return tuple(sorted_workers(self._pending))

    @property
    def finished(self) -> bool:
        """True once the run has ended."""
        return self.state.end_reason is not None

    @property
    def end_reason(self) -> str | None:
        """Why the run ended (``W is empty`` or ``reached M rounds``), or None while it runs."""
        return self.state.end_reason

    def next_deadline(self) -> float | None:
        """When :meth:`tick` may next change something, or None."""
        if self.finished:
            return None
        times = list(self.state.suspects.values())
        # the round deadline acts only on answers (with none, tick keeps waiting, so the runner would poll)
        due = self._waits.deadline(self._opened_at)
        if due is not None and self._pending:
            times.append(due)
        return min(times, default=None)

    def receive_bytes(self, payload: bytes, *, topic_worker: str | None = None, now: float) -> ChiefStep:
        """Decode and handle one payload of ``topic_worker``'s topic; a defect is a ``rejected`` event."""
        try:
            message = decode(
                payload, run_id=self.run_id, known_senders=self.roster, layout=self.layout,
                max_bytes=self.plan.max_bytes, key=self.key, scheme_types=(self.scheme.round_message,),
                sums=decomposes(self.plan.aggregator),
            )  # fmt: skip
        except MessageRejected as exc:
            return self._reject(topic_worker, exc.reason, exc.detail)
        if topic_worker is not None and message.sender != topic_worker:
            return self._reject(topic_worker, Reason.TOPIC_MISMATCH, f"envelope says {message.sender!r}")
        return self.receive(message, now=now)

    def _newer_epoch(self, message: Message) -> ChiefStep | None:
        """A worker message stamped with a newer epoch: this chief is deposed (the runner stops it)."""
        if message.epoch <= self.state.epoch:
            return None  # an older stamp: sent (or re-sent) before the worker heard of this chief
        self.superseded = f"worker {message.sender}'s {message.type} carries epoch {message.epoch}"
        event = ChiefEvent("deposed", self.state.round, sender=message.sender, detail=self.superseded)
        return ChiefStep(events=(event,))

    def receive(self, message: Message, *, now: float) -> ChiefStep:
        """Handle one decoded worker message (Algorithm 1, lines 2–5; closes the round when complete)."""
        if (deposed := self._newer_epoch(message)) is not None:
            return deposed
        self._start_clock(now)
        sender, rnd = message.sender, message.round
        if message.type == "join":
            return self._join(message, now)
        if sender not in self.all_workers:  # a new unit's first word is its join
            return self._reject(sender, Reason.UNKNOWN_SENDER, f"{message.type} before its join")
        if (why := self._gate.refusal(sender)) is not None:
            return self._reject(sender, Reason.REFUSED, why)
        open_at = (self.state.round, self.steps_per_round if self.finished else self.state.step)
        refusal = admission(
            message, self.scheme, self.all_workers, self.steps_per_round, open_at, self.finished,
            self.state.left, self._pending,
        )  # fmt: skip
        if refusal is not None:
            step = self._reject(sender, *refusal)
            # a stale message (a resend after a lost answer, a straggler, a resumed worker replaying its
            # round): answer that exchange again, change nothing
            stale = refusal[0] in (Reason.STALE_ROUND, Reason.RUN_OVER) and (rnd, message.step) < open_at
            if stale and rnd == self.state.round and not self.finished:  # late, not silent: waited for again
                self._waits.heard(self.state.pace, sender)
            return step + self._resend(sender, (rnd, message.step), now) if stale else step
        step = self._rejoin(sender, f"sent {message.type} for round {rnd}")
        self.state.suspects.pop(sender, None)
        self._pending[sender] = message
        accepted = ChiefEvent("accepted", self.state.round, sender=sender, detail=message.type)
        step += ChiefStep(events=(accepted,))
        if self._all_in():
            return step + self._close_round(now)
        self._waits.note(self.state.pace, self.state.members, self.state.step, self._pending, now)
        return step

    def status(self, worker: str, payload: bytes, *, retained: bool = False, now: float) -> ChiefStep:
        """Handle a status payload of ``worker``: a live ``offline`` drops it from W after its grace, a live
        ``online`` brings it back, any ``online`` is welcomed; a retained one never changes W."""
        self._start_clock(now)
        if worker not in self.all_workers:  # a new unit's status: its join admits and welcomes it
            may_join = self.roster.may_join(worker)
            return ChiefStep() if may_join else self._reject(worker, Reason.UNKNOWN_SENDER, "status")
        try:
            status = parse_status(payload, run_id=self.run_id, node=worker, key=self.key)
        except MessageRejected as exc:
            return self._reject(worker, exc.reason, exc.detail)
        if status.state == "ended":  # a chief's state: no worker may say it
            return self._reject(worker, Reason.MALFORMED, "status 'ended' of a worker")
        if self.finished:
            return ChiefStep()
        known = self.state.incarnations.get(worker)
        inc = status.incarnation
        if inc is not None and known is not None and inc < known:  # an old status played again
            return self._reject(worker, Reason.REPLAYED, f"{status.state} of incarnation {inc} < {known}")
        if inc is not None:
            if known is None or inc > known:  # a new process: it joins afresh
                self._gate.new_incarnation(worker)
                if known is not None and status.state == "online":  # a restart: the new process re-sends
                    self._pending.pop(worker, None)  # what the dead one sent for the open exchange
                    self._restarted.add(worker)  # its join says whether it replays the open round
            self.state.incarnations[worker] = inc
        if status.state == "offline":
            # a worker refused at join leaves: the chief goes on waiting for one with its settings
            if retained or worker not in self.state.members or self._gate.refusal(worker) is not None:
                return ChiefStep()
            self.state.suspects[worker] = now + self.plan.dropout_grace
            return self.tick(now)
        if self._gate.refusal(worker) is not None:  # no welcome until a join that matches
            return self._refusal(worker)
        step = ChiefStep() if retained else self._rejoin(worker, "came back online")
        return step + self._welcome(worker)

    def _welcome(self, worker: str) -> ChiefStep:
        state = self.state
        return welcome_step(self.run_id, worker, state.round, state.model, self.settings or {}, state.config)

    def tick(self, now: float) -> ChiefStep:
        """Apply the deadlines at ``now``: offline workers whose grace ran out leave W; then the round
        deadline's rule (docs/protocol.md, "Reliability")."""
        self._start_clock(now)
        step = ChiefStep()
        gone = sorted_workers(w for w, t in self.state.suspects.items() if t <= now)
        for worker in gone:
            del self.state.suspects[worker]
        if gone:
            step = self._drop([w for w in gone if w in self.state.members], OFFLINE_DROP)
            step += self._maybe_close(now)
        due = self._waits.deadline(self._opened_at)
        if self.finished or due is None or now < due or not self._pending:
            return step
        leave = self._waits.silent_leave(self.state.members, self._pending)
        return step + self._drop(sorted_workers(leave), DEADLINE_DROP) + self._close_round(now)

    def _join(self, message: Message, now: float) -> ChiefStep:
        """Refuse a worker whose shared settings differ; admit and welcome a new one whose match. A restarted
        worker that will not replay the open round is not waited for in its later exchanges."""
        worker = message.sender
        outcome = self._gate.join(worker, message.settings)
        if outcome == "duplicate":  # a re-sent or replayed join: nothing to do
            return self._reject(worker, Reason.DUPLICATE, "join")
        if outcome != "joined":
            return self._refusal(worker)
        if worker in self.all_workers:
            joined = ChiefStep(events=(ChiefEvent("joined", self.state.round, sender=worker),))
            restarted = worker in self._restarted
            self._restarted.discard(worker)
            resumes = message.round == self.state.round
            if restarted and not resumes and self._waits.excused(self.state.pace, worker, self.state.step):
                self._waits.note(self.state.pace, self.state.members, self.state.step, self._pending, now)
                return joined + self._maybe_close(now)
            return joined
        if self.finished:
            return ChiefStep()
        self.roster.admit(worker)
        self._waits.admit(self.state.pace, worker)
        return ChiefStep(events=self.state.admit(worker)) + self._welcome(worker)

    def _refusal(self, worker: str) -> ChiefStep:
        return refusal_step(self.run_id, worker, self.state.round, self._gate.refusal(worker) or "")

    def _start_clock(self, now: float) -> None:
        if self._opened_at is None:
            self._opened_at = now

    def _reject(self, sender: str | None, reason: Reason, detail: str) -> ChiefStep:
        self.state.rejections[reason] += 1
        return ChiefStep(
            events=(ChiefEvent("rejected", self.state.round, sender=sender, reason=reason, detail=detail),)
        )

    def _resend(self, worker: str, at: tuple[int, int], now: float) -> ChiefStep:
        answer = self.state.answers.resend(worker, at, now)
        if not answer:
            return ChiefStep()
        detail = f"answer of {where(answer[0].round, answer[0].step)}"
        return ChiefStep(answer, (ChiefEvent("resent", self.state.round, sender=worker, detail=detail),))

    def _drop(self, workers: Iterable[str], reason: str) -> ChiefStep:
        return ChiefStep(events=self.state.drop(workers, reason))

    def _rejoin(self, worker: str, why: str) -> ChiefStep:
        return ChiefStep(events=self.state.rejoin(worker, why))

    def _all_in(self) -> bool:
        return self._waits.all_in(self.state.pace, self.state.members, self.state.step, self._pending)

    def _maybe_close(self, now: float) -> ChiefStep:
        if not self._pending and not self.state.members:
            return self._end(EVERY_WORKER_DROPPED)
        if self._all_in():
            return self._close_round(now)
        return ChiefStep()

    def _closing(self) -> tuple[ClosedExchange, dict[str, Message], bool]:
        """The closing exchange: who took part, the answers to combine, whether it is the round's last."""
        last_step = self.state.step == self.steps_per_round - 1
        closed = ClosedExchange.of(self.state.round, self._pending, self.state.members)
        # a completion counts from any exchange of the round its message got into, not only the last: a unit
        # that misses a round's later exchanges (a straggler, a unit paused whole) still has it counted
        for worker in closed.completed:
            self.state.completed.setdefault(worker, closed.round)
        answers = {w: self._pending[w] for w in closed.answered}
        self._waits.closed(self.state.pace, set(self.state.members), closed.answered, last_step)
        return closed, self._waits.averaged(self.state.pace, answers, self.state.step), last_step

    def _close_round(self, now: float) -> ChiefStep:
        rnd, exchange = self.state.round, self.state.step
        closed, answers, last_step = self._closing()
        context = RoundContext(
            self._aggregate, self.members, dict(self.state.completed), step=exchange, last_step=last_step
        )
        answer = self.scheme.combine(answers, context)
        self.state.members.difference_update(answer.leave_w)
        self.state.left.update(answer.leave_w)
        remaining = self.members
        opens = last_step and not answer.ends_run and bool(remaining) and rnd < self.max_rounds
        if opens:  # the answer opens round rnd + 1: what the scheme asks of every worker for it
            self.state.config = dict(self.scheme.configure(rnd + 1, remaining))
        config = self.state.config if opens else {}
        reply = answer_message(answer, self.run_id, rnd, exchange, answers, config)
        if answer.fleet_model and self.welcome_layout == self.layout:  # what a (re)joining worker takes
            self.state.model = reply
        if answer.kind == "transfer":
            self.state.transfers.append((rnd, str(answer.origin), remaining))
        event = answer_event(answer, replace(closed, remaining=remaining), self.plan.aggregator)
        if self.fleet_model is not None:  # the chief's copy steps as every worker does
            self.fleet_model.apply(reply)
        self._pending = {}
        self.state.answers.broadcast(reply, self.all_workers, now)
        step = ChiefStep((reply,), (event,))
        self.state.step = exchange + 1 if not last_step and not answer.ends_run else 0  # the next exchange
        if answer.ends_run:
            step += self._end("every unit completed")
        elif self.state.step == 0 and (not self.state.members or rnd >= self.max_rounds):
            step += self._end(
                "W is empty" if not self.state.members else f"reached M={self.max_rounds} rounds"
            )
        elif self.state.step == 0:
            self.state.round = rnd + 1
        self._opened_at = now
        if self.fleet_model is not None:  # a joining worker takes it as it now is (also after the end)
            self.state.model = self.fleet_model.welcome(self.run_id, self.state.round, self.state.step)
        return step

    def _end(self, reason: str) -> ChiefStep:
        self.state.end_reason = reason
        # a chief that keeps the fleet's model hands it out with the end: every worker ends with it
        final = None if self.fleet_model is None else self.fleet_model.snapshot()
        done = Message("done", self.run_id, CHIEF_ID, self.state.round, flat=final)
        self.state.answers.end(done)
        event = ChiefEvent("run_ended", self.state.round, detail=reason, remaining=self.members)
        return ChiefStep((done,), (event,))
