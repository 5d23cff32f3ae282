"""A per-step scheme's worker machine (no threads, transport or clock): each update step exchanged keyed
(round, step), ``done`` and a fleet gone past the worker's step inside a round, a resumed worker replaying
closed steps, and a straggler applying the fleet's answers it missed before joining the fleet's next round
with its staleness."""

from __future__ import annotations

from typing import Any

import numpy as np
from conftest import machine_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.events import Sent, WorkerEvent
from fleetrl.federation.kinds import new_worker_machine
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import resolve_scheme
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.worker.actions import (
    AbandonUpdate,
    ApplyFleetStep,
    ApplyStep,
    BeginUpdate,
    Checkpoint,
    ComputeStep,
    EndUpdate,
    PlayRound,
    Record,
    TakeParameters,
    TimedOut,
    WorkerStep,
)
from fleetrl.federation.worker.per_step import StepWorkerMachine

RUN = "machine-run"
LAYOUT: list[tuple[str, tuple[int, ...]]] = [("trunk.weight", (4, 3)), ("head.bias", (3,))]
FLAT = np.arange(15, dtype=np.float32)
K = 3


class Outcome:
    """What a round reports (the fields of the learner's RoundResult the machine reads)."""

    score, steps, wma, actor_loss, critic_loss, entropy = 10.0, 3, 9.0, 0.1, 0.2, 1.0

    def __init__(self, completed: bool = False) -> None:
        self.completed = completed


def machine(steps: int = K, **kwargs: Any) -> StepWorkerMachine:
    options: dict[str, Any] = {"reply_timeout": 60.0, "resend_interval": 5.0, "max_rounds": 10}
    options.update(kwargs)
    m = machine_of(
        new_worker_machine, run_id=RUN, worker_id="1", layout=LAYOUT, scheme=resolve_scheme("pergrad"),
        steps_per_round=steps,
        **options,
    )  # fmt: skip
    assert isinstance(m, StepWorkerMachine)
    return m


def answer(rnd: int, step: int, **fields: Any) -> Message:
    fields.setdefault("flat", FLAT + 100 * rnd + step)
    return Message("average", RUN, "chief", rnd, step=step, **fields)


def welcomed(m: StepWorkerMachine, rnd: int = 1) -> WorkerStep:
    m.start(now=0.0)
    return m.receive(Message("welcome", RUN, "chief", rnd), now=0.0)


def collected(
    m: StepWorkerMachine, *queued: Message, completed: bool = False, now: float = 0.0
) -> WorkerStep:
    """The round's episodes reported; ``queued`` read (the fleet's answers meanwhile); nothing more queued."""
    step = m.round_collected(completed=completed, now=now)
    assert m.next_deadline() == -np.inf  # only what is queued is read
    for message in queued:
        step += m.receive(message, now=now)
    return step + m.tick(now=now)


def records(step: WorkerStep) -> list[Record]:
    return [o for o in step.outputs if isinstance(o, Record)]


def test_the_per_step_exchange_keyed_by_step() -> None:
    m = machine()
    assert welcomed(m, 2).actions == (PlayRound(2),)
    assert collected(m).actions == (BeginUpdate(),)
    assert m.update_begun(K, now=0.0).actions == (ComputeStep(0),)
    for k in range(K):
        sent = m.step_computed(k, FLAT, now=0.0)
        assert [(x.type, x.round, x.step, x.staleness) for x in sent.published] == [
            ("step_gradient", 2, k, 0)
        ]
        assert m.receive(answer(1, k), now=0.0) == WorkerStep()  # stale
        got = m.receive(answer(2, k, contributors=("1",)), now=0.0)
        following = ComputeStep(k + 1) if k < K - 1 else EndUpdate()
        assert [type(a) for a in got.actions] == [ApplyStep, type(following)]
        assert got.actions[1] == following
    over = m.round_played(Outcome(), now=0.0)  # type: ignore[arg-type]
    (record,) = records(over)
    assert record.record.event == Sent("step_gradient") and record.record.round == 2
    assert m.tick(now=0.0).actions == (Checkpoint(3), PlayRound(3))


def test_done_mid_round_ends_without_a_record() -> None:
    m = machine(steps=4)
    welcomed(m, 1)
    collected(m)
    m.update_begun(4, now=0.0)
    m.step_computed(0, FLAT, now=0.0)
    m.receive(answer(1, 0), now=0.0)
    m.step_computed(1, FLAT, now=0.0)
    assert [x.step for x in m.tick(now=5.0).published] == [1]  # the step's gradient, re-sent
    ended = m.receive(Message("done", RUN, "chief", 1), now=11.0)
    assert not records(ended) and m.summary is not None
    assert (m.summary.rounds, m.summary.reason) == (0, "run ended")


def test_a_fleet_gone_past_the_worker_s_step_ends_its_update_records_the_round_and_takes_its_model() -> None:
    m = machine(steps=4)
    welcomed(m, 3)
    collected(m, completed=True)
    m.update_begun(4, now=0.0)
    assert m.step_computed(0, FLAT, now=0.0).published[0].type == "parameters"
    overtaken = m.receive(answer(3, 2), now=0.0)  # step 0's and 1's answers never came
    assert overtaken.actions == (AbandonUpdate(),) and m.summary is None
    over = m.round_played(Outcome(completed=True), now=1.0)  # type: ignore[arg-type]
    (record,) = records(over)
    assert (record.record.round, record.record.event) == (3, WorkerEvent.LATE)
    assert over.published[-1].type == "join" and m.summary is None  # joins again for the fleet's model
    model = np.arange(15, dtype=np.float32)
    back = m.receive(Message("welcome", RUN, "chief", 3, step=3, flat=model, origin="chief"), now=2.0)
    assert [type(a) for a in back.actions] == [TakeParameters, PlayRound] and back.actions[1] == PlayRound(3)
    assert m.fleet_at == (3, 3)


def test_a_straggler_applies_what_the_fleet_did_and_joins_its_next_round_with_the_staleness() -> None:
    """Welcomed at round 2, it played while the fleet closed the whole of rounds 2 and 3: it applies those 2·K
    answers in order (outside an update), then contributes what it played to round 4, two rounds stale."""
    m = machine()
    welcomed(m, 2)
    fleet = [answer(r, k) for r in (2, 3) for k in range(K)]
    step = collected(m, answer(1, K - 1), *fleet)  # an old copy first: ignored
    applied = [a for a in step.actions if isinstance(a, ApplyFleetStep)]
    assert [(a.step, a.flat[0]) for a in applied] == [(k, 100 * r + k) for r in (2, 3) for k in range(K)]
    assert step.actions[-1] == BeginUpdate() and m.fleet_at == (4, 0)
    m.update_begun(K, now=0.0)
    (sent,) = m.step_computed(0, FLAT, now=0.0).published
    assert (sent.round, sent.step, sent.staleness) == (4, 0, 2)


def test_a_straggler_that_finds_the_fleet_mid_round_waits_for_its_end() -> None:
    m = machine()
    welcomed(m, 1)
    step = collected(m, answer(1, 0), answer(1, 1))
    assert [type(a) for a in step.actions] == [ApplyFleetStep, ApplyFleetStep]  # no update begun
    assert m.next_deadline() == 60.0  # the reply timeout, as for any wait for the chief
    last = m.receive(answer(1, K - 1, config={"mu": 0.5}), now=1.0)
    assert [type(a) for a in last.actions] == [ApplyFleetStep, BeginUpdate]
    m.update_begun(K, now=1.0)
    (sent,) = m.step_computed(0, FLAT, now=1.0).published
    assert (sent.round, sent.staleness) == (2, 1)
    m = machine()
    welcomed(m, 1)
    collected(m, answer(1, 0))
    assert m.tick(now=59.0) == WorkerStep()
    (timed_out,) = m.tick(now=60.0).actions
    assert isinstance(timed_out, TimedOut) and "the end of the fleet's round" in timed_out.detail


def test_a_gap_in_the_fleets_answers_while_behind_takes_the_fleet_s_model_again() -> None:
    m = machine(start_round=1)
    welcomed(m, 1)
    gap = collected(m, answer(1, 0), answer(1, 2))  # step 1's answer never came
    assert gap.actions[-1] == AbandonUpdate()  # the round it played is not contributed: recorded as late
    again = m.round_played(Outcome(), now=0.5)  # type: ignore[arg-type]
    assert [(r.record.round, r.record.event) for r in records(again)] == [(1, WorkerEvent.LATE)]
    assert [type(o).__name__ for o in again.outputs[-2:]] == ["Announce", "Publish"]  # online, then the join
    assert again.published[-1].type == "join" and m.summary is None
    model = np.arange(15, dtype=np.float32)
    back = m.receive(Message("welcome", RUN, "chief", 3, step=1, flat=model, origin="chief"), now=1.0)
    assert [type(a) for a in back.actions] == [TakeParameters, PlayRound] and back.actions[1] == PlayRound(3)
    assert m.fleet_at == (3, 1)  # the model is the fleet's as it is at round 3 step 1


def test_after_its_round_a_worker_applies_later_answers_queued_and_plays_the_fleets_open_round() -> None:
    m = machine()
    welcomed(m, 1)
    collected(m)
    m.update_begun(K, now=0.0)
    for k in range(K):
        m.step_computed(k, FLAT, now=0.0)
        m.receive(answer(1, k), now=0.0)
    m.round_played(Outcome(), now=0.0)  # type: ignore[arg-type]
    caught = m.receive(answer(2, 0), now=0.0)  # the fleet closed round 2's first step without it
    assert [type(a) for a in caught.actions] == [ApplyFleetStep]
    assert m.tick(now=0.0).actions == (Checkpoint(2), PlayRound(2))
    step = collected(m, answer(2, 1), answer(2, 2))
    assert step.actions[-1] == BeginUpdate() and m.round == 3


def test_a_worker_resumed_mid_round_replays_the_closed_steps_and_goes_on_at_the_open_one() -> None:
    """Killed after the chief closed steps 0-1 of round 1: the resumed worker plays round 1 again (same state,
    same gradients); the chief answers each re-sent step with its own answer; step 2 is played as usual."""
    steps = 4
    c = Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("1", "2"),
            layout=LAYOUT,
            max_rounds=10,
            scheme="pergrad",
            steps_per_round=steps,
        )
    )
    grads = {w: [np.full(15, 10 * int(w) + k, np.float32) for k in range(steps)] for w in ("1", "2")}

    def step_of(worker: str, k: int) -> Message:
        return Message("step_gradient", RUN, worker, 1, step=k, flat=grads[worker][k])

    for k in range(2):  # before the kill: both workers' steps 0 and 1
        c.receive(step_of("1", k), now=0.0)
        c.receive(step_of("2", k), now=0.0)
    m = machine(steps=steps, start_round=1)
    assert welcomed(m, 1).actions == (PlayRound(1),)
    collected(m, now=10.0)
    assert m.update_begun(steps, now=10.0).actions == (ComputeStep(0),)
    applied = []
    for k in range(steps):
        (sent,) = m.step_computed(k, grads["1"][k], now=10.0).published
        answers = c.receive(sent, now=10.0).outgoing
        if k >= 2:  # the open steps: closed when worker 2 sends too
            assert answers == ()
            answers = c.receive(step_of("2", k), now=10.0).outgoing
        (got_answer,) = answers
        assert (got_answer.round, got_answer.step) == (1, k)
        got = m.receive(got_answer, now=10.0)
        assert type(got.actions[0]) is ApplyStep and got.actions[1] == (
            ComputeStep(k + 1) if k < 3 else EndUpdate()
        )
        applied.append(got.actions[0].flat)
    expected = [(grads["1"][k] + grads["2"][k]) / 2 for k in range(steps)]
    np.testing.assert_array_equal(np.stack(applied), np.stack(expected))
    (record,) = records(m.round_played(Outcome(), now=10.0))  # type: ignore[arg-type]
    assert (record.record.round, record.record.event, m.summary) == (1, Sent("step_gradient"), None)


def test_done_with_the_fleet_s_model_is_taken_before_the_end_mid_update_or_back_after_the_end() -> None:
    m = machine(steps=4)
    welcomed(m, 1)
    collected(m)
    m.update_begun(4, now=0.0)
    m.step_computed(0, FLAT, now=0.0)
    ended = m.receive(Message("done", RUN, "chief", 1, flat=FLAT + 7), now=1.0)
    kinds = [type(o).__name__ for o in ended.outputs]
    assert kinds[-2:] == ["TakeParameters", "Finish"] and (ended.outputs[-2].flat == FLAT + 7).all()
    # resumed at round 8 after the run ended in round 10: the round it went down in, the model, the end
    m = machine(start_round=8)
    m.start(now=0.0)
    back = m.receive(Message("done", RUN, "chief", 10, flat=FLAT + 9), now=1.0)
    (lost,) = records(back)
    assert (lost.record.round, lost.record.event) == (8, WorkerEvent.INTERRUPTED)
    assert [type(o).__name__ for o in back.outputs][-2:] == ["TakeParameters", "Finish"]
    assert m.summary is not None and m.summary.reason == "run ended"
    # a done without a model (a chief that does not keep one) ends as before
    m = machine()
    m.start(now=0.0)
    plain = m.receive(Message("done", RUN, "chief", 3), now=1.0)
    assert [type(o).__name__ for o in plain.outputs] == ["Finish"]
