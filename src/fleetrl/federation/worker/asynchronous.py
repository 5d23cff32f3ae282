"""The worker of an asynchronous scheme (``fedasync``) as a pure state machine: it counts its own rounds,
takes the newest fleet model seen before each, and waits for the answer to its own contribution.
docs/protocol.md, "Asynchronous schemes"."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from fleetrl.federation.events import RoundEvent, Sent, WorkerEvent
from fleetrl.federation.plan import WorkerPlan
from fleetrl.federation.shared_settings import settings_difference
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.worker import actions
from fleetrl.federation.worker.actions import NOTHING, Phase, WorkerStep, WorkerSummary, resume_round
from fleetrl.federation.worker.machine import WorkerMachine

log = logging.getLogger(__name__)

MODELS = ("welcome", "average")
"""the chief's messages that carry the fleet model and its version"""


class AsyncWorkerMachine(WorkerMachine):
    """Algorithm 2 for one worker of an asynchronous scheme."""

    current_model = True

    def __init__(self, plan: WorkerPlan, **options: Any) -> None:
        super().__init__(plan, **options)
        self.model_version = -1  # no fleet model taken yet
        self.newest: Message | None = None
        """the newest fleet model seen and not yet taken (taken before the next round)"""

    def receive(self, message: Message, *, now: float) -> WorkerStep:
        """A decoded chief message; a fleet model newer than every one seen is kept for the next round."""
        if message.type in MODELS and message.flat is not None and self.phase is not Phase.DONE:
            seen = self.model_version if self.newest is None else self.newest.model_version
            if message.model_version > seen:
                self.newest = message
        return super().receive(message, now=now)

    def _welcome_wanted(self) -> Callable[[Message], bool]:
        """A ``welcome`` naming this worker in ``contributors`` (it carries its own round), or ``done``."""
        me = self.worker_id
        return lambda m: m.type == "done" or (m.type == "welcome" and me in m.contributors)

    def _welcomed(self, welcome: Message) -> WorkerStep:
        """Joined: the first round is the welcome's (or its checkpoint's), played from the newest model."""
        if welcome.type == "done":
            return super()._welcomed(welcome)
        why = settings_difference(welcome.settings, self.settings) if welcome.settings else None
        if why is not None:
            return self._refused(why)
        resume = resume_round(self.plan.start_round, welcome.round, self.worker_id)
        self._config = dict(welcome.config)
        log.info(
            "worker %s: welcomed at round %d (fleet model version %d)", self.worker_id, welcome.round,
            welcome.model_version,
        )  # fmt: skip
        first = welcome.round if resume is None else resume
        return self._round_lost(resume, (welcome.round, 0)) + self._begin_round(first)

    def _begin_round(self, rnd: int) -> WorkerStep:
        """Take the newest fleet model seen, then play round ``rnd``."""
        taken = NOTHING
        if self.newest is not None and self.newest.flat is not None and rnd <= self.max_rounds:
            taken = WorkerStep((actions.TakeParameters(self.newest.flat),))
            self.model_version, self.newest = self.newest.model_version, None
        return taken + super()._begin_round(rnd)

    def _answer_wanted(self) -> Callable[[Message], bool]:
        """The chief's answer to this worker's round, an answer saying the run completed, or ``done``."""
        me, rnd = self.worker_id, self.round
        return lambda m: (
            m.type == "done"
            or (m.type == "average" and ((m.origin == me and m.round == rnd) or me in m.finished))
        )

    def _answered(self, reply: Message) -> WorkerStep:
        """The answer to this worker's round: record it (its model is taken before the next round)."""
        if self._outcome is None:
            raise AssertionError("an answer is awaited only after the round was played")
        if reply.type == "done":
            return self._round_over(self._outcome, reply, WorkerEvent.RUN_ENDED, None, True)
        contributed = reply.origin == self.worker_id and self.worker_id in reply.contributors
        event: RoundEvent = WorkerEvent.LATE
        if contributed:
            event = WorkerEvent.COMPLETED if self._outcome.completed else Sent(self.plan.scheme.round_message)
        return self._round_over(self._outcome, reply, event, None, self.worker_id in reply.finished)

    def _between(self, message: Message, now: float) -> WorkerStep:
        """Between this worker's rounds: only the run's end matters."""
        del now
        if self.phase is not Phase.CATCH_UP:
            return NOTHING
        if message.type == "done":
            return self._finish(WorkerSummary(self.worker_id, self.round, False, "run ended"))
        if message.type == "average" and self.worker_id in message.finished:
            return self._finish(WorkerSummary(self.worker_id, self.round, True, "every unit completed"))
        return NOTHING

    def _queue_read(self, now: float) -> WorkerStep:
        """Nothing more is queued: this worker's next round, from the newest model seen."""
        del now
        nxt = self.round + 1
        return WorkerStep((actions.Checkpoint(nxt),)) + self._begin_round(nxt)
