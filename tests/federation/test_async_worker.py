"""The worker machine of an asynchronous scheme (``fedasync``) without threads, transport or clock: it waits
for the answer to its own round, ignores another worker's answer (only its model is kept), and takes the
newest model it has seen before each round."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from conftest import machine_of

from fleetrl.federation.events import Sent, WorkerEvent
from fleetrl.federation.kinds import new_worker_machine
from fleetrl.federation.schemes import get_scheme
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.worker.actions import (
    Checkpoint,
    Finish,
    PlayRound,
    Record,
    TakeParameters,
    WorkerStep,
)
from fleetrl.federation.worker.asynchronous import AsyncWorkerMachine

RUN = "async-machine"
ME = "1"
FAKE_LAYOUT: list[tuple[str, tuple[int, ...]]] = [("trunk.weight", (4, 3)), ("head.bias", (3,))]


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


def machine(**kwargs: Any) -> AsyncWorkerMachine:
    options: dict[str, Any] = {"reply_timeout": 60.0, "resend_interval": 5.0, "max_rounds": 10}
    made = machine_of(
        new_worker_machine,
        scheme=get_scheme("fedasync"),
        run_id=RUN,
        worker_id=ME,
        layout=FAKE_LAYOUT,
        **options | kwargs,
    )
    assert isinstance(made, AsyncWorkerMachine)
    return made


def fleet_model(version: int) -> np.ndarray:
    return np.full(15, float(version), np.float32)


def chief(kind: str, rnd: int, version: int, **fields: Any) -> Message:
    """A message of the chief carrying the fleet model of ``version`` (each version its own values); a
    welcome for this worker unless it names another."""
    if kind == "welcome":
        fields.setdefault("contributors", (ME,))
    return Message(kind, RUN, "chief", rnd, flat=fleet_model(version), model_version=version, **fields)


def taken(step: WorkerStep) -> list[float]:
    """The versions of the models taken (each model's values are its version)."""
    return [float(o.flat[0]) for o in step.outputs if isinstance(o, TakeParameters)]


def play(m: AsyncWorkerMachine, result: Outcome = RESULT) -> Message:
    (sent,) = m.round_played(result, now=0.0, share=("async_model", fleet_model(99))).published
    return sent


def test_the_welcomes_model_is_taken_and_the_contribution_names_its_version() -> None:
    m = machine()
    m.start(now=0.0)
    step = m.receive(chief("welcome", 1, 4), now=0.0)
    assert taken(step) == [4.0] and step.actions[-1] == PlayRound(1)
    sent = play(m)
    assert (sent.type, sent.round, sent.model_version) == ("async_model", 1, 4)


def test_another_workers_answer_is_not_this_workers_answer_but_its_model_is_kept() -> None:
    m = machine()
    m.start(now=0.0)
    m.receive(chief("welcome", 1, 0), now=0.0)
    play(m)
    other = m.receive(chief("average", 1, 1, origin="2", contributors=("2",)), now=1.0)
    assert other == WorkerStep() and m.newest is not None and m.newest.model_version == 1
    later = m.receive(chief("average", 3, 2, origin="2", contributors=("2",)), now=1.5)  # its round 3
    assert later == WorkerStep()
    own = m.receive(chief("average", 1, 3, origin=ME, contributors=(ME,)), now=2.0)
    (record,) = [o.record for o in own.outputs if isinstance(o, Record)]
    assert record.round == 1 and record.event == Sent("async_model")
    newer = m.receive(chief("average", 2, 5, origin="0", contributors=("0",)), now=2.1)  # while catching up
    assert newer == WorkerStep()
    assert m.receive(chief("average", 1, 4, origin="2"), now=2.2) == WorkerStep()  # older than 5: not kept
    nxt = m.tick(now=2.5)
    assert [type(a) for a in nxt.actions] == [Checkpoint, TakeParameters, PlayRound]
    assert nxt.actions[0] == Checkpoint(2) and nxt.actions[2] == PlayRound(2)
    assert taken(nxt) == [5.0]  # the newest seen, not its own answer's (3)
    assert play(m).model_version == 5


def test_an_answer_that_left_the_contribution_out_records_the_round_as_late() -> None:
    m = machine()
    m.start(now=0.0)
    m.receive(chief("welcome", 1, 0), now=0.0)
    play(m)
    own = m.receive(chief("average", 1, 2, origin=ME, contributors=()), now=1.0)
    (record,) = [o.record for o in own.outputs if isinstance(o, Record)]
    assert record.event is WorkerEvent.LATE


def test_the_end_of_the_run_is_taken_from_the_answer_listing_this_worker_as_finished() -> None:
    m = machine()
    m.start(now=0.0)
    m.receive(chief("welcome", 1, 0), now=0.0)
    play(m, Outcome(score=20.0, steps=4, wma=15.0, completed=True))
    end = m.receive(chief("average", 1, 7, origin="0", finished=("0", ME)), now=1.0)  # another's last answer
    (finish,) = [o for o in end.outputs if isinstance(o, Finish)]
    assert finish.summary.finished and finish.summary.reason == "every unit completed" and m.finished


def test_another_workers_welcome_gives_a_model_but_not_this_workers_round() -> None:
    m = machine()
    m.start(now=0.0)
    assert m.receive(chief("welcome", 7, 3, contributors=("2",)), now=0.0) == WorkerStep()
    mine = m.receive(chief("welcome", 2, 3), now=0.1)
    assert taken(mine) == [3.0] and mine.actions[-1] == PlayRound(2)


def test_a_worker_resumed_within_a_round_replays_it_from_the_welcomes_model() -> None:
    m = machine(start_round=3)
    m.start(now=0.0)
    step = m.receive(chief("welcome", 4, 9), now=0.0)  # the chief took its round 3 before it died
    assert taken(step) == [9.0] and step.actions[-1] == PlayRound(3)


def test_a_worker_back_after_its_fleet_went_on_records_the_round_it_went_down_in() -> None:
    m = machine(start_round=3)
    m.start(now=0.0)
    step = m.receive(chief("welcome", 7, 9), now=0.0)
    records = [a.record for a in step.actions if isinstance(a, Record)]
    assert [(r.round, r.event, r.result.steps) for r in records] == [(3, WorkerEvent.INTERRUPTED, 0)]
    assert step.actions[-1] == PlayRound(7)
