"""The worker of Algorithm 2 as a pure state machine: chief messages, time and the runner's reports in →
messages to publish and actions for the runner out; it never touches the agent. Its rules:
docs/protocol.md, "The worker as a state machine". :mod:`.per_step` and :mod:`.asynchronous` extend it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from fleetrl.agent.criterion import interrupted_round
from fleetrl.federation.events import RoundEvent, Sent, WorkerEvent
from fleetrl.federation.plan import WorkerPlan
from fleetrl.federation.shared_settings import settings_difference
from fleetrl.federation.wire.messages import Message, MessageRejected, RoundConfig, decode, encode
from fleetrl.federation.wire.signing import FleetKey, parse_status, status_payload
from fleetrl.federation.wire.topics import CHIEF_ID, ONLINE, chief_topic, status_topic, worker_topic
from fleetrl.federation.worker import actions
from fleetrl.federation.worker.actions import (
    ANSWERS,
    NOTHING,
    QUEUED,
    FederatedRound,
    Phase,
    Wait,
    WorkerOutput,
    WorkerStep,
    WorkerSummary,
    answer_for,
    resume_round,
)

if TYPE_CHECKING:  # the learner (and torch) is not imported by the pure machine
    from fleetrl.agent.criterion import RoundResult

log = logging.getLogger(__name__)


class WorkerMachine:
    """Algorithm 2 for one worker, without its learner or its transport.

    :param key: the fleet key: sign what is sent, accept only what is signed with it.
    :param incarnation: this process's incarnation (newer than any earlier one with the same id).
    :param status_fields: who this process is, said in its status.
    """

    current_model = False
    """a welcome from the chief carries the fleet's model as it is now, not only its start"""

    def __init__(
        self,
        plan: WorkerPlan,
        *,
        key: FleetKey | None = None,
        incarnation: int = 0,
        status_fields: Mapping[str, str | int] | None = None,
    ) -> None:
        self.plan = plan
        self.run_id, self.worker_id, self.max_rounds = plan.run_id, plan.worker_id, plan.max_rounds
        self.settings: dict[str, str] = dict(plan.settings or {})
        self.key = key
        self.incarnation = incarnation
        self.status_fields = dict(status_fields or {})
        self.chief_epoch = 0
        """the highest chief epoch seen: older chiefs' messages are ignored, every message sent carries it"""
        self._ended_at: float | None = None  # when the chief's status said ``ended`` (a chief online clears)
        self.chief_topic = chief_topic(plan.run_id)
        self.chief_status = status_topic(plan.run_id, CHIEF_ID)
        self.own_status = status_topic(plan.run_id, plan.worker_id)
        self.topic = worker_topic(plan.run_id, plan.worker_id)
        self.phase = Phase.NEW
        self.round = 0
        """the round being played (or waited for)"""
        self.summary: WorkerSummary | None = None
        self._wait: Wait | None = None
        self._outcome: RoundResult | None = None
        self._caught_up_to = 0
        self._config: RoundConfig = {}  # the chief's configuration for the next round played
        self.model_version = 0
        """the fleet model version this worker's round started from (an asynchronous scheme's; else 0)"""

    def status(self, state: bytes) -> bytes:
        """This worker's signed live status ``state`` (``online``/``offline``; the runner's last will)."""
        return status_payload(
            state, run_id=self.run_id, node=self.worker_id, incarnation=self.incarnation, key=self.key,
            fields=self.status_fields,
        )  # fmt: skip

    def start(self, *, now: float) -> WorkerStep:
        """Announce ``online`` and send the retained ``join``; wait for the welcome."""
        self.phase = Phase.WELCOME
        rnd = 0 if self.plan.start_round is None else self.plan.start_round  # resumed at (0: none)
        join = Message("join", self.run_id, self.worker_id, rnd, settings=self.settings)
        online = WorkerStep((actions.Announce(self.own_status, self.status(ONLINE)),))
        return online + self._send(join, self._welcome_wanted(), "the chief's welcome", now, retain=True)

    def _welcome_wanted(self) -> Callable[[Message], bool]:
        """What welcomes this worker: a ``welcome`` (the same for every worker) or ``done``."""
        return lambda m: m.type in ("welcome", "done")

    def receive_bytes(self, topic: str, payload: bytes, *, now: float) -> WorkerStep:
        """A payload from the chief's topic or its status topic."""
        if topic == self.chief_status:
            self._chief_status(payload, now)
            return NOTHING
        try:
            message = decode(
                payload, run_id=self.run_id, known_senders=(CHIEF_ID,), layout=self.plan.layout, key=self.key,
                layouts=dict.fromkeys(("welcome", "done"), self.plan.welcome_layout or self.plan.layout),
            )  # fmt: skip
        except MessageRejected as exc:
            log.warning("worker %s: rejected a chief message: %s", self.worker_id, exc)
            return NOTHING
        if message.epoch < self.chief_epoch:  # a deposed chief's (or one it sent before it was replaced)
            log.info(
                "worker %s: ignoring %s of round %d from a chief of epoch %d (following epoch %d)",
                self.worker_id, message.type, message.round, message.epoch, self.chief_epoch,
            )  # fmt: skip
            return NOTHING
        self._follow(message.epoch, f"its {message.type} of round {message.round}")
        return self.receive(message, now=now)

    def receive(self, message: Message, *, now: float) -> WorkerStep:
        """A decoded chief message. A ``done`` that ends the run with the fleet's final model: the model is
        taken before the :class:`~.actions.Finish`, so every worker ends with the chief's model."""
        step = self._dispatch(message, now)
        outputs = step.outputs
        at = next((i for i, o in enumerate(outputs) if isinstance(o, actions.Finish)), None)
        if message.type != "done" or message.flat is None or at is None:
            return step
        return WorkerStep((*outputs[:at], actions.TakeParameters(message.flat), *outputs[at:]))

    def _dispatch(self, message: Message, now: float) -> WorkerStep:
        if self.phase is Phase.DONE:
            return NOTHING
        if message.type == "refused":
            return self._refused(message.detail) if self.worker_id in message.finished else NOTHING
        if self._wait is None and self.phase is not Phase.WELCOME:
            return self._between(message, now)
        if self._wait is None or not self._wait.wanted(message):
            log.debug("worker %s: ignoring %s of round %d", self.worker_id, message.type, message.round)
            return NOTHING
        self._wait = None
        if self.phase is Phase.WELCOME:
            return self._welcomed(message)
        return self._answered(message)

    def tick(self, *, now: float) -> WorkerStep:
        """Time passed with nothing received: re-send, time out, or (catching up) nothing more is queued."""
        if self.phase in QUEUED:
            return self._queue_read(now)
        if (over := self._gives_up_at()) is not None and now >= over:
            return self._run_ended()
        wait = self._wait
        if wait is None:
            return NOTHING
        if wait.deadline is not None and now >= wait.deadline:
            return self._timed_out(wait.what)
        if wait.next_send is None or now < wait.next_send:
            return NOTHING
        log.info("worker %s: nothing yet; re-sending while waiting for %s", self.worker_id, wait.what)
        wait.next_send = now + (self.plan.resend_interval or 0.0)
        out: tuple[WorkerOutput, ...] = (wait.resend,)
        if wait.resend.retain:
            out = (actions.Publish(self.own_status, self.status(ONLINE), True), *out)
        return WorkerStep(out)

    def next_deadline(self) -> float | None:
        """When :meth:`tick` is due (None: only a message or a report moves the machine)."""
        if self.phase in QUEUED:
            return -math.inf  # due at once: only what is already queued is read
        if self._wait is None:
            return None
        times = [t for t in (self._wait.deadline, self._wait.next_send, self._gives_up_at()) if t is not None]
        return min(times, default=None)

    def _follow(self, epoch: int, what: str) -> None:
        """Follow the chief of ``epoch`` if it is newer than the one followed (a takeover)."""
        if epoch > self.chief_epoch:
            log.warning("worker %s: following the chief of epoch %d (%s)", self.worker_id, epoch, what)
            self.chief_epoch = epoch

    def _chief_status(self, payload: bytes, now: float) -> None:
        """The chief's status: ``ended`` while waiting for the welcome starts the grace after which the
        worker gives up; ``online`` ends that grace."""
        try:
            status = parse_status(payload, run_id=self.run_id, node=CHIEF_ID, key=self.key)
        except MessageRejected as exc:
            log.warning("worker %s: rejected the chief's status: %s", self.worker_id, exc)
            return
        if (epoch := status.number("epoch")) is not None:
            self._follow(epoch, f"its status says {status.state}")
        if status.state == "online":
            self._ended_at = None
        elif status.state == "offline":
            log.warning("worker %s: the chief went offline; waiting", self.worker_id)
        elif self.phase is Phase.WELCOME and self._ended_at is None:
            self._ended_at = now
            log.warning(
                "worker %s: the chief of run %r says the run has ended; waiting %g s for a new chief of it",
                self.worker_id, self.run_id, self.plan.ended_grace,
            )  # fmt: skip

    def _gives_up_at(self) -> float | None:
        """When a worker waiting for its welcome gives up on a run its chief said has ended."""
        if self._ended_at is None or self.phase is not Phase.WELCOME:
            return None
        return self._ended_at + self.plan.ended_grace

    @property
    def finished(self) -> bool:
        """The worker's run is over (finished, refused or timed out)."""
        return self.phase is Phase.DONE

    # ---- reports of the runner ----

    def round_played(
        self, outcome: RoundResult, *, now: float, share: tuple[str, np.ndarray] | None = None
    ) -> WorkerStep:
        """The round was played; ``share``: what ``scheme.outgoing`` sends."""
        if self.phase is not Phase.PLAYING or share is None:
            raise RuntimeError(f"worker {self.worker_id}: round {self.round} reported out of turn")
        kind, flat = share
        metrics = {"score": float(outcome.score), "wma": float(outcome.wma), "steps": float(outcome.steps)}
        finite = {k: v for k, v in metrics.items() if math.isfinite(v)}
        self._outcome, self.phase = outcome, Phase.ANSWER
        message = Message(  # it stands for the round's transitions of this worker's units
            kind, self.run_id, self.worker_id, self.round, flat=flat, metrics=finite,
            samples=int(outcome.steps), model_version=self.model_version, units=self.plan.units,
        )  # fmt: skip
        return self._send(message, self._answer_wanted(), f"the chief's answer for round {self.round}", now)

    def _answer_wanted(self) -> Callable[[Message], bool]:
        """What answers the round just sent."""
        return answer_for(self.round)

    # ---- the rules ----

    def _welcomed(self, welcome: Message) -> WorkerStep:
        if welcome.type == "done":  # the run is over: the round a worker went down in was interrupted
            lost = self._round_lost(None, (welcome.round + 1, 0))
            return lost + self._finish(WorkerSummary(self.worker_id, 0, finished=False, reason="run ended"))
        why = settings_difference(welcome.settings, self.settings) if welcome.settings else None
        if why is not None:
            return self._refused(why)
        resume = resume_round(self.plan.start_round, welcome.round, self.worker_id)
        out: tuple[WorkerOutput, ...] = ()
        # start from the fleet's model or start, unless resumed with its own (a current model is taken)
        resumed = self.plan.start_round is not None
        fleet_start = welcome.origin == CHIEF_ID and resumed and not self.current_model
        if welcome.flat is not None and resume is None and not fleet_start:
            out = (actions.TakeParameters(welcome.flat),)
        self._config = dict(welcome.config)
        log.info("worker %s: welcomed at round %d (θ* of %s)", self.worker_id, welcome.round, welcome.origin)
        rejoined = self._round_lost(resume, (welcome.round, welcome.step)) + WorkerStep(out)
        return rejoined + self._begin_round(welcome.round if resume is None else resume)

    @property
    def went_down_in(self) -> int | None:
        """The round an earlier process of this worker went down in (its checkpoint's next round, or 1 for
        one restarted before its first checkpoint); None for a fresh worker."""
        start = self.plan.start_round
        return start if start is not None else 1 if self.plan.restarted else None

    def _round_lost(self, resume: int | None, fleet_at: tuple[int, int]) -> WorkerStep:
        """A worker that went down, welcomed with the fleet at exchange ``fleet_at`` (round, step) past the
        start of that round and not replaying it (``resume`` None): that round is recorded as interrupted."""
        down = self.went_down_in
        if resume is not None or down is None or fleet_at <= (down, 0):
            return NOTHING
        lost = FederatedRound(self.worker_id, down, interrupted_round(down), WorkerEvent.INTERRUPTED)
        return WorkerStep((actions.Record(lost),))

    def _begin_round(self, rnd: int) -> WorkerStep:
        if rnd > self.max_rounds:
            reason = f"reached M={self.max_rounds}"
            return self._finish(WorkerSummary(self.worker_id, self.max_rounds, finished=False, reason=reason))
        self.round, self.phase = rnd, Phase.PLAYING
        return WorkerStep((actions.PlayRound(rnd, self._config),))

    def _answered(self, reply: Message) -> WorkerStep:
        """A per-round scheme: act on the chief's answer (Algorithm 2, lines 28-31)."""
        if self._outcome is None:
            raise AssertionError("an answer is awaited only after the round was played")
        completed = bool(self._outcome.completed)
        if reply.type == "done":
            return self._round_over(self._outcome, reply, WorkerEvent.RUN_ENDED, None, True)
        if reply.type == "transfer" and self.worker_id in reply.finished:
            if reply.origin == self.worker_id:
                return self._round_over(self._outcome, reply, WorkerEvent.TRANSFER_OUT, None, True)
            return self._round_over(self._outcome, reply, WorkerEvent.FINISHED, reply.origin, True)
        if reply.flat is None:
            raise AssertionError("decode guarantees tensors for average and transfer")
        if reply.type == "transfer":  # line 29
            over = self._round_over(self._outcome, reply, WorkerEvent.TRANSFER_IN, reply.origin, False)
            return WorkerStep((actions.TakeParameters(reply.flat),)) + over
        # the round may have closed without us (a straggler, or a resend): the fleet's update all the same
        contributed = self.worker_id in reply.contributors
        applied = WorkerStep((actions.ApplyAverage(reply.flat, completed, contributed),))
        event: RoundEvent = WorkerEvent.LATE
        if contributed:
            event = WorkerEvent.COMPLETED if completed else Sent(self.plan.scheme.round_message)
        return applied + self._round_over(self._outcome, reply, event, None, self.worker_id in reply.finished)

    def _round_over(
        self, outcome: RoundResult, reply: Message, event: RoundEvent, peer: str | None, leave: bool
    ) -> WorkerStep:
        """Record the round; stop if this worker leaves, else catch up with what is queued."""
        self._config = dict(reply.config)  # what the chief asks for the round this answer opens
        record = FederatedRound(self.worker_id, self.round, outcome, event, peer)
        log.info(
            "worker %s round %d: score %g wma %.1f steps %d actor %.4g critic %.4g entropy %.3f: %s",
            self.worker_id, self.round, outcome.score, outcome.wma, outcome.steps,
            outcome.actor_loss, outcome.critic_loss, outcome.entropy, event.describe(peer),
        )  # fmt: skip
        recorded = WorkerStep((actions.Record(record),))
        if leave:
            if reply.type == "average":  # the round in which the scheme's run completed
                summary = WorkerSummary(self.worker_id, self.round, True, "every unit completed")
            else:
                reason = "run ended" if event is WorkerEvent.RUN_ENDED else event.value
                summary = WorkerSummary(self.worker_id, self.round, reply.type == "transfer", reason)
            return recorded + self._finish(summary)
        self.phase, self._caught_up_to = Phase.CATCH_UP, reply.round
        return recorded

    def _between(self, message: Message, now: float) -> WorkerStep:
        """A chief message while no answer is awaited: after a round, a later answer queued is applied (the
        chief moved on without us)."""
        del now
        if self.phase is not Phase.CATCH_UP or message.type not in ANSWERS:
            return NOTHING
        if message.type == "done":
            return self._finish(WorkerSummary(self.worker_id, message.round, False, "run ended"))
        if message.round <= self._caught_up_to:
            return NOTHING
        log.info("worker %s: caught up with the %s of round %d", self.worker_id, message.type, message.round)
        self._caught_up_to, self._config = message.round, dict(message.config)
        if message.flat is None:
            return NOTHING
        if message.type == "transfer":
            return WorkerStep((actions.TakeParameters(message.flat),))
        return WorkerStep((actions.ApplyAverage(message.flat, completed=False, contributed=False),))

    def _queue_read(self, now: float) -> WorkerStep:
        """Nothing more is queued: the round after the last answer applied is played."""
        del now
        nxt = self._caught_up_to + 1
        return WorkerStep((actions.Checkpoint(nxt),)) + self._begin_round(nxt)

    def _send(
        self, message: Message, wanted: Callable[[Message], bool], what: str, now: float, retain: bool = False
    ) -> WorkerStep:
        """Publish ``message`` on the worker topic, then wait for what ``wanted`` accepts, re-sending it."""
        log.debug("worker %s: sending %s of round %d", self.worker_id, message.type, message.round)
        # stamped with the epoch followed, so an older chief that hears it knows it was replaced
        message = replace(message, epoch=self.chief_epoch)
        payload = encode(message, layout=self.plan.layout, key=self.key)
        publish = actions.Publish(self.topic, payload, retain, message)
        deadline = None if self.plan.reply_timeout is None else now + self.plan.reply_timeout
        next_send = None if self.plan.resend_interval is None else now + self.plan.resend_interval
        self._wait = Wait(wanted, what, publish, deadline, next_send)
        return WorkerStep((publish,))

    def _stop(self, output: WorkerOutput) -> WorkerStep:
        """The worker's run is over with ``output``."""
        self.phase, self._wait = Phase.DONE, None
        return WorkerStep((output,))

    def _timed_out(self, what: str) -> WorkerStep:
        return self._stop(actions.TimedOut(
            f"worker {self.worker_id}: nothing from the chief of run {self.run_id!r} for "
            f"{self.plan.reply_timeout:g} s (--reply-timeout) while waiting for {what}"
        ))  # fmt: skip

    def _run_ended(self) -> WorkerStep:
        return self._stop(actions.RunEnded(
            f"worker {self.worker_id}: run {self.run_id!r} had ended before this worker was welcomed (its "
            "chief's status says so, and no new chief of it came within "
            f"{self.plan.ended_grace:g} s); nothing to train: start a new run under another --run-id"
        ))  # fmt: skip

    def _finish(self, summary: WorkerSummary) -> WorkerStep:
        self.summary = summary
        return self._stop(actions.Finish(summary))

    def _refused(self, why: str) -> WorkerStep:
        return self._stop(actions.Refused(
            f"worker {self.worker_id}: refused by the chief of run {self.run_id!r}: {why}; start it with the"
            " chief's settings"
        ))  # fmt: skip
