"""The worker of a per-step scheme (``pergrad``) as a pure state machine: each round's update exchanged
with the fleet step by step, every fleet answer applied in order, so the fleet stays one policy.
docs/protocol.md, "Stragglers under a per-step scheme"."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import numpy as np

from fleetrl.federation.events import Sent, WorkerEvent
from fleetrl.federation.plan import WorkerPlan
from fleetrl.federation.schemes import COMPLETED
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.worker import actions
from fleetrl.federation.worker.actions import NOTHING, Phase, WorkerStep, WorkerSummary, answer_for
from fleetrl.federation.worker.machine import WorkerMachine

if TYPE_CHECKING:  # the learner (and torch) is not imported by the pure machine
    from fleetrl.agent.criterion import RoundResult

log = logging.getLogger(__name__)


class StepWorkerMachine(WorkerMachine):
    """Algorithm 2 for one worker of a per-step scheme; the plan's ``steps_per_round`` is K, the exchanges
    of one round."""

    current_model = True

    def __init__(self, plan: WorkerPlan, **options: Any) -> None:
        super().__init__(plan, **options)
        if self.plan.steps_per_round < 1:
            raise ValueError(f"steps_per_round must be >= 1, got {self.plan.steps_per_round}")
        self.fleet_at = (0, 0)
        """the fleet's open exchange (round, step) as this worker knows it: every answer before it applied"""
        self.played_round = 0
        """the round the fleet was at when this worker began playing what it contributes"""
        self._completed = False
        self._steps = 0
        self._step = 0
        self._last_answer: Message | None = None
        self._wait_until: float | None = None
        self._rejoining = False
        self._overtaken: Message | None = None
        """an answer past what this worker could take part in: its round ends without its update"""

    # ---- reports of the runner ----

    def round_collected(self, *, completed: bool, now: float) -> WorkerStep:
        """The round's episodes are played: apply the fleet's answers queued, then join its next round."""
        del now
        if self.phase is not Phase.PLAYING:
            raise RuntimeError(f"worker {self.worker_id}: round {self.round} collected out of turn")
        self._completed, self.phase = completed, Phase.DRAIN
        return NOTHING

    def update_begun(self, steps: int, *, now: float) -> WorkerStep:
        """The update has ``steps`` steps (0: none this round): exchange step 0."""
        del now
        if self.phase is not Phase.JOINING:
            raise RuntimeError(f"worker {self.worker_id}: an update began out of turn")
        self._steps, self._step, self._last_answer = steps, 0, None
        if steps == 0:
            self.phase = Phase.STEPS_DONE
            return WorkerStep((actions.EndUpdate(),))
        self.phase = Phase.COMPUTING
        return WorkerStep((actions.ComputeStep(0),))

    def step_computed(self, step: int, flat: np.ndarray, *, now: float) -> WorkerStep:
        """The gradients of step ``step``: send them and wait for the chief's answer."""
        if self.phase is not Phase.COMPUTING or step != self._step:
            raise RuntimeError(f"worker {self.worker_id}: step {step} reported out of turn")
        self.phase = Phase.STEP_ANSWER
        kind = COMPLETED if self._completed else self.plan.scheme.round_message
        message = Message(
            kind, self.run_id, self.worker_id, self.round, step=step, flat=flat,
            staleness=self.round - self.played_round, units=self.plan.units,
        )  # fmt: skip
        what = f"the chief's answer for round {self.round} step {step}"
        return self._send(message, answer_for(self.round, step), what, now)

    def round_played(
        self, outcome: RoundResult, *, now: float, share: tuple[str, np.ndarray] | None = None
    ) -> WorkerStep:
        """Every step of the round's update was applied: record the round (``late`` if the update was
        abandoned: the worker then takes the fleet's model again)."""
        del share
        reply = self._last_answer
        if self.phase is not Phase.STEPS_DONE:
            raise RuntimeError(f"worker {self.worker_id}: round {self.round} ended without its steps")
        if self._overtaken is not None:
            overtaken, self._overtaken = self._overtaken, None
            recorded = self._round_over(outcome, overtaken, WorkerEvent.LATE, None, False)
            return recorded + self._rejoin_fleet(now)
        if reply is None:
            raise RuntimeError(f"worker {self.worker_id}: round {self.round} ended without an exchange")
        if reply.type == "done":
            return self._round_over(outcome, reply, WorkerEvent.RUN_ENDED, None, True)
        event = WorkerEvent.COMPLETED if outcome.completed else Sent(self.plan.scheme.round_message)
        return self._round_over(outcome, reply, event, None, self.worker_id in reply.finished)

    # ---- the rules ----

    def _welcomed(self, welcome: Message) -> WorkerStep:
        """As :class:`WorkerMachine`; the welcome's model is the fleet's at the exchange it names. A worker
        that missed answers takes it whatever its checkpoint, and plays the welcome's round."""
        if self._rejoining and welcome.type == "welcome" and welcome.flat is not None:
            self._rejoining, self._config = False, dict(welcome.config)
            self.fleet_at = (welcome.round, welcome.step)
            return WorkerStep((actions.TakeParameters(welcome.flat),)) + self._begin_round(welcome.round)
        step = super()._welcomed(welcome)
        if any(isinstance(o, actions.TakeParameters) for o in step.outputs):
            self.fleet_at = max(self.fleet_at, (welcome.round, welcome.step))
        return step

    def _begin_round(self, rnd: int) -> WorkerStep:
        self.played_round = rnd
        self.fleet_at = max(self.fleet_at, (rnd, 0))
        return super()._begin_round(rnd)

    def _answered(self, reply: Message) -> WorkerStep:
        """The chief's answer to this worker's step (Algorithm 2, lines 21 and 23)."""
        if reply.type == "done":  # the run ended inside the round
            return self._finish(
                WorkerSummary(self.worker_id, self.round - 1, finished=False, reason="run ended")
            )
        if (reply.round, reply.step) != (self.round, self._step):
            # the fleet went on past this step (its answer was lost): the update stops, the round is recorded
            log.warning(
                "worker %s: the fleet is at round %d step %d, past this worker's step %d of round %d; taking "
                "the fleet's model again", self.worker_id, reply.round, reply.step, self._step, self.round,
            )  # fmt: skip
            self._overtaken, self.phase = reply, Phase.STEPS_DONE
            return WorkerStep((actions.AbandonUpdate(),))
        if reply.flat is None:
            raise AssertionError("decode guarantees tensors for an average")
        self._last_answer, self.fleet_at = reply, self._after(reply)
        self._step += 1
        if self._step < self._steps:
            self.phase = Phase.COMPUTING
            return WorkerStep((actions.ApplyStep(reply.flat), actions.ComputeStep(self._step)))
        self.phase = Phase.STEPS_DONE
        return WorkerStep((actions.ApplyStep(reply.flat), actions.EndUpdate()))

    def _between(self, message: Message, now: float) -> WorkerStep:
        """Outside this worker's own exchanges: the fleet's answers are applied in order."""
        if self.phase not in (Phase.CATCH_UP, Phase.DRAIN, Phase.WAIT_ROUND):
            return NOTHING
        if message.type == "done":
            return self._finish(WorkerSummary(self.worker_id, self.fleet_at[0] - 1, False, "run ended"))
        if message.type != "average" or (message.round, message.step) < self.fleet_at:
            return NOTHING  # a copy of an answer already applied
        if (message.round, message.step) > self.fleet_at:  # answers it never got: the fleet's model again
            log.warning(
                "worker %s: never got the answer of round %d step %d; taking the fleet's model again",
                self.worker_id, *self.fleet_at,
            )  # fmt: skip
            if self.phase in (Phase.DRAIN, Phase.WAIT_ROUND):  # a round played, not yet contributed
                self._overtaken, self.phase = message, Phase.STEPS_DONE
                return WorkerStep((actions.AbandonUpdate(),))  # recorded as late, then the fleet's model
            return self._rejoin_fleet(now)
        if message.flat is None:
            raise AssertionError("decode guarantees tensors for an average")
        self.fleet_at = self._after(message)
        self._config = dict(message.config) if message.config else self._config
        applied = WorkerStep((actions.ApplyFleetStep(message.step, message.flat),))
        if self.phase is Phase.WAIT_ROUND and self.fleet_at[1] == 0:
            return applied + self._join()
        return applied

    def _rejoin_fleet(self, now: float) -> WorkerStep:
        """Join again: the welcome hands the fleet's model as it is now (:meth:`_welcomed`)."""
        self._rejoining = True
        return self.start(now=now)

    def _queue_read(self, now: float) -> WorkerStep:
        """Nothing more is queued: after a round, play the fleet's open round; before an update, join the
        fleet's round-opening exchange or wait for the end of its round."""
        if self.phase is Phase.CATCH_UP:
            nxt = self.fleet_at[0]
            return WorkerStep((actions.Checkpoint(nxt),)) + self._begin_round(nxt)
        if self.fleet_at[1] == 0:
            return self._join()
        log.info(
            "worker %s: the fleet is at round %d step %d; joining its next round", self.worker_id,
            *self.fleet_at,
        )  # fmt: skip
        self.phase = Phase.WAIT_ROUND
        self._wait_until = None if self.plan.reply_timeout is None else now + self.plan.reply_timeout
        return NOTHING

    def _join(self) -> WorkerStep:
        """Contribute what was played to the fleet's round-opening exchange ``fleet_at``."""
        rnd = self.fleet_at[0]
        if rnd > self.max_rounds:
            reason = f"reached M={self.max_rounds}"
            return self._finish(WorkerSummary(self.worker_id, self.max_rounds, finished=False, reason=reason))
        if rnd > self.played_round:
            log.info(
                "worker %s: played in round %d, contributes to round %d (staleness %d)", self.worker_id,
                self.played_round, rnd, rnd - self.played_round,
            )  # fmt: skip
        self.round, self.phase = rnd, Phase.JOINING
        return WorkerStep((actions.BeginUpdate(),))

    def _after(self, answer: Message) -> tuple[int, int]:
        """The exchange that follows ``answer``'s."""
        if answer.step + 1 < self.plan.steps_per_round:
            return (answer.round, answer.step + 1)
        return (answer.round + 1, 0)

    def next_deadline(self) -> float | None:
        """When :meth:`tick` is due."""
        if self.phase is Phase.WAIT_ROUND:
            return self._wait_until
        return super().next_deadline()

    def tick(self, *, now: float) -> WorkerStep:
        """As :meth:`WorkerMachine.tick`; a straggler waiting for the fleet's next round times out too."""
        if self.phase is not Phase.WAIT_ROUND:
            return super().tick(now=now)
        if self._wait_until is None or now < self._wait_until:
            return NOTHING
        return self._timed_out("the end of the fleet's round")
