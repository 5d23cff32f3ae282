"""The worker's state machine without threads, transport or clock: rounds, resends, stale and later answers,
``done``, refusal, timeouts and resume (the per-step exchange: test_step_worker.py); and the runner over an
in-process chief."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from conftest import machine_of, worker_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.events import Sent, WorkerEvent
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import resolve_scheme
from fleetrl.federation.wire.messages import Message, encode
from fleetrl.federation.wire.signing import FleetKey, status_payload
from fleetrl.federation.wire.topics import chief_topic, worker_of_topic
from fleetrl.federation.worker.actions import (
    Announce,
    ApplyAverage,
    Checkpoint,
    FederatedRound,
    Finish,
    PlayRound,
    Publish,
    Record,
    Refused,
    RunEnded,
    TakeParameters,
    TimedOut,
    WorkerStep,
    WorkerSummary,
    resume_round,
)
from fleetrl.federation.worker.machine import WorkerMachine
from fleetrl.federation.worker.runner import FederatedWorker
from fleetrl.transport.base import Received, Will
from fleetrl.transport.local import LocalBus

RUN = "machine-run"
FAKE_LAYOUT: list[tuple[str, tuple[int, ...]]] = [("trunk.weight", (4, 3)), ("head.bias", (3,))]
"""the layout of the shared fake agent (conftest)"""
FLAT = np.arange(15, dtype=np.float32)


@dataclass(frozen=True)
class Outcome:
    """What a round reports (the fields of the learner's RoundResult the worker reads)."""

    score: float
    steps: int
    wma: float
    completed: bool
    actor_loss: float = 0.1
    critic_loss: float = 0.2
    entropy: float = 1.0


RESULT = Outcome(score=10.0, steps=3, wma=9.0, completed=False)
DONE_RESULT = Outcome(20.0, 4, 15.0, True, float("nan"), float("nan"), float("nan"))


def machine(scheme: str = "paper", **kwargs: Any) -> WorkerMachine:
    options: dict[str, Any] = {"reply_timeout": 60.0, "resend_interval": 5.0, "max_rounds": 10}
    options.update(kwargs)
    return machine_of(
        WorkerMachine, run_id=RUN, worker_id="1", layout=FAKE_LAYOUT, scheme=resolve_scheme(scheme), **options
    )


def chief(kind: str, rnd: int, **fields: Any) -> Message:
    """A message of the chief."""
    if kind in ("average", "transfer") and "flat" not in fields:
        fields["flat"] = FLAT
    return Message(kind, RUN, "chief", rnd, **fields)


def welcomed(m: WorkerMachine, rnd: int = 1, **fields: Any) -> WorkerStep:
    m.start(now=0.0)
    return m.receive(chief("welcome", rnd, **fields), now=0.0)


def played(m: WorkerMachine, result: Outcome = RESULT, now: float = 0.0) -> WorkerStep:
    return m.round_played(result, now=now, share=("gradient", FLAT))


def records(step: WorkerStep) -> list[FederatedRound]:
    return [o.record for o in step.outputs if isinstance(o, Record)]


def test_join_then_a_round_end_to_end() -> None:
    m = machine()
    start = m.start(now=0.0)
    assert isinstance(start.outputs[0], Announce)
    join = start.outputs[1]
    assert isinstance(join, Publish) and join.retain and join.message is not None
    assert join.message.type == "join" and m.next_deadline() == 5.0
    assert welcomed(machine(), 1).actions == (PlayRound(1),)
    m.receive(chief("welcome", 1), now=0.0)
    sent = played(m)
    assert [(x.type, x.round, x.metrics["score"]) for x in sent.published] == [("gradient", 1, 10.0)]
    answer = m.receive(chief("average", 1, contributors=("1", "2")), now=1.0)
    apply, record = answer.actions
    assert isinstance(apply, ApplyAverage) and apply.contributed and not apply.completed
    assert isinstance(record, Record) and record.record.event == Sent("gradient")
    assert record.record.result is RESULT and record.record.round == 1
    assert m.next_deadline() == -np.inf  # catch-up: only what is queued
    assert m.tick(now=1.0).actions == (Checkpoint(2), PlayRound(2))


def test_resend_after_the_interval_without_an_answer() -> None:
    m = machine()
    m.start(now=0.0)
    assert m.tick(now=4.9) == WorkerStep()
    again = m.tick(now=5.0)
    assert [type(o) for o in again.outputs] == [Publish, Publish]  # the online status, then the join
    assert all(isinstance(o, Publish) and o.retain for o in again.outputs)
    m.receive(chief("welcome", 1), now=6.0)
    sent = played(m, now=10.0)
    assert m.next_deadline() == 15.0
    resent = m.tick(now=15.0)
    original = sent.outputs[0]
    assert isinstance(original, Publish) and resent.outputs == (original,)
    assert m.next_deadline() == 20.0


def test_a_stale_answer_is_ignored_and_a_late_round_is_applied_as_late() -> None:
    m = machine()
    welcomed(m, 3)
    played(m)
    assert m.receive(chief("average", 2, contributors=("1",)), now=1.0) == WorkerStep()
    assert m.receive(chief("welcome", 3), now=1.0) == WorkerStep()
    answer = m.receive(chief("average", 3, contributors=("2",)), now=2.0)
    apply = answer.actions[0]
    assert isinstance(apply, ApplyAverage) and (apply.completed, apply.contributed) == (False, False)
    assert records(answer)[0].event is WorkerEvent.LATE


def test_catch_up_with_later_answers_already_queued() -> None:
    m = machine()
    welcomed(m, 1)
    played(m)
    m.receive(chief("average", 1, contributors=("1",)), now=1.0)
    assert m.receive(chief("average", 1, contributors=("1",)), now=1.0) == WorkerStep()  # a resent copy
    later = m.receive(chief("transfer", 2, origin="3"), now=1.0)
    assert [type(a) for a in later.actions] == [TakeParameters]
    avg = m.receive(chief("average", 3, contributors=("2",)), now=1.0)
    assert [type(a) for a in avg.actions] == [ApplyAverage]
    assert m.tick(now=1.0).actions == (Checkpoint(4), PlayRound(4))


def test_the_answer_for_a_later_round_closes_ours_and_done_while_catching_up_ends() -> None:
    m = machine()
    welcomed(m, 1)
    played(m)
    answer = m.receive(chief("average", 2, contributors=("2",)), now=1.0)  # we missed round 1's
    assert records(answer)[0].round == 1 and records(answer)[0].event is WorkerEvent.LATE
    done = m.receive(chief("done", 4), now=1.0)
    assert m.summary is not None and done.actions == (Finish(m.summary),)
    assert (m.summary.rounds, m.summary.reason, m.finished) == (4, "run ended", True)


def test_done_while_waiting_for_the_answer_and_for_the_welcome() -> None:
    m = machine()
    welcomed(m, 2)
    played(m)
    done = m.receive(chief("done", 2), now=1.0)
    assert records(done)[0].event is WorkerEvent.RUN_ENDED
    assert m.summary is not None and (m.summary.rounds, m.summary.reason) == (2, "run ended")
    fresh = machine()
    fresh.start(now=0.0)
    assert isinstance(fresh.receive(chief("done", 5), now=0.0).actions[0], Finish)
    assert fresh.summary is not None and fresh.summary.rounds == 0


def test_transfers_out_finished_and_in() -> None:
    m = machine()
    welcomed(m)
    m.round_played(DONE_RESULT, now=0.0, share=("parameters", FLAT))
    out = m.receive(chief("transfer", 1, origin="1", finished=("1",)), now=1.0)
    assert records(out)[0].event is WorkerEvent.TRANSFER_OUT and m.summary is not None and m.summary.finished
    m = machine()
    welcomed(m)
    m.round_played(DONE_RESULT, now=0.0, share=("parameters", FLAT))
    fin = records(m.receive(chief("transfer", 1, origin="0", finished=("0", "1")), now=1.0))[0]
    assert (fin.event, fin.peer) == (WorkerEvent.FINISHED, "0")
    m = machine()
    welcomed(m)
    played(m)
    step = m.receive(chief("transfer", 1, origin="2", finished=("2",)), now=1.0)
    assert isinstance(step.actions[0], TakeParameters) and records(step)[0].peer == "2" and not m.finished


def test_refusal_by_the_chief_or_by_the_welcome_s_settings() -> None:
    m = machine(settings={"env": "cartpole"})
    m.start(now=0.0)
    assert m.receive(chief("refused", 1, finished=("2",), detail="not us"), now=0.0) == WorkerStep()
    refused = m.receive(chief("refused", 1, finished=("1",), detail="env differs"), now=0.0)
    assert isinstance(refused.actions[0], Refused) and "env differs" in refused.actions[0].reason
    assert m.finished
    m = machine(settings={"env": "cartpole"})
    m.start(now=0.0)
    step = m.receive(chief("welcome", 1, settings={"env": "qube"}), now=0.0)
    assert isinstance(step.actions[0], Refused) and "env" in step.actions[0].reason


def test_reply_timeout_before_the_welcome_and_in_a_round() -> None:
    m = machine(reply_timeout=12.0, resend_interval=None)
    m.start(now=0.0)
    assert m.next_deadline() == 12.0 and m.tick(now=11.0) == WorkerStep()
    out = m.tick(now=12.0).actions
    assert isinstance(out[0], TimedOut) and "welcome" in out[0].detail
    m = machine(reply_timeout=12.0)
    welcomed(m, 1)
    played(m, now=100.0)
    assert m.tick(now=111.0).actions == ()  # resent twice by now, not timed out
    assert isinstance(m.tick(now=112.0).actions[0], TimedOut)


def chief_status(state: bytes, key: FleetKey | None = None) -> bytes:
    return status_payload(state, run_id=RUN, node="chief", incarnation=7, key=key)


def test_a_run_whose_chief_says_ended_is_given_up_after_the_grace_unless_a_chief_comes_online() -> None:
    m = machine(reply_timeout=600.0, ended_grace=30.0)
    m.start(now=0.0)
    assert m.receive_bytes(m.chief_status, chief_status(b"ended"), now=1.0) == WorkerStep()
    assert m.next_deadline() == 5.0 and m.tick(now=5.0).outputs  # still re-sending its join meanwhile
    assert m.next_deadline() == 10.0 and not any(isinstance(a, RunEnded) for a in m.tick(now=30.9).actions)
    out = m.tick(now=31.0).actions
    assert len(out) == 1 and isinstance(out[0], RunEnded) and "run 'machine-run' had ended" in out[0].detail
    assert m.finished and m.next_deadline() is None
    # a chief of the run that comes online within the grace (the run id used again) is waited for
    m = machine(reply_timeout=600.0, ended_grace=30.0)
    m.start(now=0.0)
    m.receive_bytes(m.chief_status, chief_status(b"ended"), now=1.0)
    m.receive_bytes(m.chief_status, chief_status(b"online"), now=2.0)
    assert not any(isinstance(a, RunEnded) for t in range(3, 100) for a in m.tick(now=float(t)).actions)
    assert isinstance(m.receive(chief("welcome", 1), now=100.0).actions[0], PlayRound)


def test_ended_after_the_welcome_or_unsigned_under_a_key_changes_nothing() -> None:
    m = machine(ended_grace=1.0)
    welcomed(m, 1)
    assert m.receive_bytes(m.chief_status, chief_status(b"ended"), now=0.0) == WorkerStep()
    assert not any(isinstance(a, RunEnded) for a in m.tick(now=50.0).actions)
    key = FleetKey(b"k" * 32)
    m = machine(ended_grace=1.0, key=key)
    m.start(now=0.0)
    m.receive_bytes(m.chief_status, chief_status(b"ended"), now=0.0)  # unsigned: rejected
    m.receive_bytes(m.chief_status, chief_status(b"ended", FleetKey(b"x" * 32)), now=0.0)  # forged
    assert not any(isinstance(a, RunEnded) for a in m.tick(now=2.0).actions)
    m.receive_bytes(m.chief_status, chief_status(b"ended", key), now=3.0)
    assert isinstance(m.tick(now=4.0).actions[0], RunEnded)


def test_resume_at_the_welcome_s_round() -> None:
    assert resume_round(None, 7, "1") is None
    assert resume_round(5, 5, "1") == 5 and resume_round(5, 6, "1") == 5  # keep the state, replay round 5
    assert resume_round(5, 9, "1") is None  # rounds were played without it: rejoin
    with pytest.raises(RuntimeError, match="lost rounds"):
        resume_round(5, 4, "1")
    kept = welcomed(machine(start_round=5), 6, flat=FLAT)
    assert kept.actions == (PlayRound(5),)  # θ* is not taken: the state is the checkpoint's
    rejoined = welcomed(machine(start_round=5), 9, flat=FLAT)
    assert [type(a) for a in rejoined.actions] == [Record, TakeParameters, PlayRound]
    assert rejoined.actions[2] == PlayRound(9)
    # the round it went down in stays in its books, marked, without figures; a kept state records nothing
    lost = rejoined.actions[0].record
    assert (lost.worker_id, lost.round, lost.event) == ("1", 5, WorkerEvent.INTERRUPTED)
    assert (lost.result.steps, lost.result.episodes, lost.result.completed) == (0, 0, False)
    assert math.isnan(lost.result.score) and math.isnan(lost.result.wma)
    assert not any(isinstance(a, Record) for a in kept.actions)
    reached = WorkerSummary("1", 4, finished=False, reason="reached M=4")
    assert welcomed(machine(max_rounds=4), 5).actions == (Finish(reached),)


def test_a_worker_restarted_before_its_first_checkpoint_records_round_1_interrupted_if_missed() -> None:
    later = welcomed(machine(restarted=True), 3, flat=FLAT)
    assert [type(a) for a in later.actions] == [Record, TakeParameters, PlayRound]
    lost = later.actions[0].record
    assert (lost.round, lost.event, lost.result.steps) == (1, WorkerEvent.INTERRUPTED, 0)
    # welcomed at round 1's first exchange (the fleet waited for it): it plays round 1, nothing recorded
    assert welcomed(machine(restarted=True), 1).actions == (PlayRound(1),)
    # welcomed inside round 1 (a per-step scheme's fleet past step 0): what it plays goes to round 2
    inside = welcomed(machine(restarted=True), 1, step=3, flat=FLAT)
    assert [type(a) for a in inside.actions] == [Record, TakeParameters, PlayRound]
    assert inside.actions[0].record.round == 1
    assert welcomed(machine(), 3).actions == (PlayRound(3),)  # a fresh worker has no round it went down in
    # the run ended before it came back: round 1 is recorded, then it stops
    m = machine(restarted=True)
    m.start(now=0.0)
    ended = m.receive(chief("done", 4), now=1.0).actions
    assert [type(a) for a in ended] == [Record, Finish] and ended[0].record.round == 1


def test_the_worker_hands_its_machine_whether_it_was_restarted(fake_learner: Any) -> None:
    def worker(**options: Any) -> FederatedWorker:
        return worker_of(
            fake_learner(14, None), LocalBus().client(), run_id=RUN, worker_id="1", max_rounds=5,
            scheme="paper", **options,
        )  # fmt: skip

    assert worker(restarted=True).machine.went_down_in == 1
    assert worker(start_round=4).machine.went_down_in == 4
    assert worker().machine.went_down_in is None


# ---- the runner, over a chief in the same thread ----


@dataclass
class LoopbackTransport:
    """A transport whose broker is a :class:`Chief` in the same thread; ``receive`` advances a fake clock."""

    chief: Chief
    now: list[float] = field(default_factory=lambda: [0.0])
    inbox: list[Received] = field(default_factory=list)
    sent: list[str] = field(default_factory=list)
    drop_first: int = 0
    """worker messages lost before the chief sees them"""

    def connect(self, client_id: str, *, will: Will | None = None) -> None:
        pass

    def subscribe(self, topic_filter: str) -> None:
        pass

    def publish(self, topic: str, payload: bytes, *, retain: bool = False) -> None:
        worker = worker_of_topic(RUN, topic)
        if worker is None:
            step = self.chief.status("1", payload, retained=retain, now=self.now[0])
        elif self.drop_first > 0:
            self.drop_first -= 1
            return
        else:
            step = self.chief.receive_bytes(payload, topic_worker=worker, now=self.now[0])
        for message in step.outgoing:
            self.sent.append(message.type)
            self.inbox.append(Received(chief_topic(RUN), encode(message, layout=self.chief.layout)))

    def announce(self, topic: str, payload: bytes) -> None:
        self.publish(topic, payload, retain=True)

    def receive(self, timeout: float | None) -> Received | None:
        if self.inbox:
            return self.inbox.pop(0)
        assert timeout is not None, "the worker would wait forever"
        self.now[0] += timeout
        return None

    def close(self) -> None:
        pass


def test_the_runner_plays_a_run_over_an_in_process_chief_and_repairs_a_lost_message(
    fake_learner: Any,
) -> None:
    learner = fake_learner(11, complete_at=3)
    c = Chief(ChiefPlan(run_id=RUN, workers=["1"], layout=FAKE_LAYOUT, max_rounds=5, scheme="paper"))
    transport = LoopbackTransport(c, drop_first=2)  # the join and round 1's gradient are lost
    got: list[FederatedRound] = []
    checkpoints: list[int] = []
    worker = worker_of(
        learner,
        transport,  # type: ignore[arg-type]
        run_id=RUN,
        worker_id="1",
        max_rounds=5,
        on_record=got.append,
        on_round_done=checkpoints.append,
        clock=lambda: transport.now[0],
        scheme="paper",
    )
    summary = worker.run()
    assert [r.event for r in got] == [Sent("gradient"), Sent("gradient"), WorkerEvent.TRANSFER_OUT]
    assert (summary.rounds, summary.finished, learner.rounds) == (3, True, 3)
    assert checkpoints == [2, 3]
    assert transport.now[0] >= 5.0  # the lost gradient was re-sent after resend_interval


def test_the_fleet_s_start_is_taken_by_a_joining_worker_and_its_config_goes_to_the_round() -> None:
    start = {"flat": FLAT, "origin": "chief", "config": {"mu": 0.5}}
    fresh = welcomed(machine(), 1, **start)
    assert fresh.actions[0] == TakeParameters(FLAT) and fresh.actions[1] == PlayRound(1, {"mu": 0.5})
    # resumed with its own state (rounds went on without it): it keeps what it learned, not the start
    late = welcomed(machine(start_round=2), 5, **start)
    assert not any(isinstance(a, TakeParameters) for a in late.actions) and late.actions[-1] == PlayRound(
        5, {"mu": 0.5}
    )
    # a transfer's θ* is taken all the same
    transferred = welcomed(machine(start_round=2), 5, flat=FLAT, origin="2").actions
    assert [type(a) for a in transferred[:2]] == [Record, TakeParameters]


def test_the_join_names_the_round_the_worker_resumes_at_or_0() -> None:
    def joined(m: WorkerMachine) -> Message:
        (join,) = [x for x in m.start(now=0.0).published if x.type == "join"]
        return join

    assert joined(machine()).round == 0
    assert joined(machine(start_round=5)).round == 5
