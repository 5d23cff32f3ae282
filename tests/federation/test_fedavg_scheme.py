"""The ``fedavg`` scheme in the chief's state machine: models averaged, mature workers stay, the run ends when
every unit of W has completed (hand-computed arrays, no broker)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fleetrl.federation.chief.checkpoint import chief_from_state, chief_to_state
from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import SCHEMES, get_scheme
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import status_payload

LAYOUT = [("w", (2,))]
RUN = "r1"


def fedavg_chief(workers: tuple[str, ...] = ("1", "2", "3"), max_rounds: int = 10) -> Chief:
    return Chief(
        ChiefPlan(run_id=RUN, workers=workers, layout=LAYOUT, max_rounds=max_rounds, scheme="fedavg")
    )


def model(sender: str, rnd: int, values: list[float], kind: str = "model") -> Message:
    return Message(kind, RUN, sender, rnd, flat=np.array(values, np.float32), metrics={"score": 1.0})


def feed(c: Chief, *messages: Message) -> list[ChiefStep]:
    return [c.receive_bytes(encode(m, layout=LAYOUT), topic_worker=m.sender, now=0.0) for m in messages]


def replies(steps: list[ChiefStep]) -> list[Message]:
    return [m for s in steps for m in s.outgoing]


def test_models_are_averaged_against_hand_computed_values() -> None:
    c = fedavg_chief()
    (reply,) = replies(
        feed(c, model("1", 1, [1.0, 2.0]), model("2", 1, [3.0, 4.0]), model("3", 1, [5.0, 9.0]))
    )
    assert (reply.type, reply.round, reply.contributors) == ("average", 1, ("1", "2", "3"))
    np.testing.assert_allclose(reply.flat, [3.0, 5.0])
    assert c.round == 2 and not c.finished


def test_a_mature_worker_is_averaged_and_stays_in_w() -> None:
    c = fedavg_chief()
    steps = feed(
        c, model("1", 1, [0.0, 0.0]), model("2", 1, [6.0, 3.0], "parameters"), model("3", 1, [3.0, 0.0])
    )
    (reply,) = replies(steps)
    assert reply.type == "average"  # no transfer: the mature model is one of the three averaged
    np.testing.assert_allclose(reply.flat, [3.0, 1.0])
    assert c.members == ("1", "2", "3") and c.completed == {"2": 1} and c.transfers == []
    event = next(e for s in steps for e in s.events if e.kind == "averaged")
    assert "completed: 2" in str(event)


def test_the_run_ends_once_every_unit_has_completed_at_least_once() -> None:
    c = fedavg_chief()
    feed(c, model("1", 1, [1, 1], "parameters"), model("2", 1, [1, 1]), model("3", 1, [1, 1]))
    feed(c, model("1", 2, [1, 1]), model("2", 2, [1, 1], "parameters"), model("3", 2, [1, 1]))
    assert not c.finished  # 1 completed in round 1 and counts, though its criterion no longer holds
    assert c.state.answers.last[0].finished == ()
    steps = feed(c, model("1", 3, [1, 1]), model("2", 3, [1, 1]), model("3", 3, [2, 2], "parameters"))
    kinds = [m.type for m in replies(steps)]
    assert kinds == ["average", "done"]
    assert replies(steps)[0].finished == ("1", "2", "3")  # every member leaves W with the last average
    assert c.finished and c.end_reason == "every unit completed"
    assert c.completed == {"1": 1, "2": 2, "3": 3}


def test_a_dropped_worker_need_not_complete() -> None:
    c = fedavg_chief(workers=("1", "2"))
    offline = status_payload(b"offline", run_id=RUN, node="2", incarnation=1)
    c.status("2", offline, now=0.0)
    c.tick(10.0)  # the grace ran out: 2 left W
    assert c.members == ("1",)
    steps = [
        c.receive_bytes(encode(model("1", 1, [4, 4], "parameters"), layout=LAYOUT), topic_worker="1", now=0.0)
    ]
    assert [m.type for m in replies(steps)] == ["average", "done"]
    assert c.end_reason == "every unit completed"


def test_gradients_are_refused_in_a_fedavg_run_and_models_in_a_paper_run() -> None:
    c = fedavg_chief()
    # each chief's decoder takes its own scheme's round message only: another scheme's is an unknown type
    (step,) = feed(c, Message("gradient", RUN, "1", 1, flat=np.zeros(2, np.float32)))
    assert [e.reason for e in step.events] == [Reason.UNKNOWN_TYPE]
    paper = Chief(ChiefPlan(run_id=RUN, workers=("1",), layout=LAYOUT, max_rounds=3, scheme="paper"))
    (step,) = feed(paper, model("1", 1, [1, 1]))
    assert [e.reason for e in step.events] == [Reason.UNKNOWN_TYPE]
    assert [e.reason for e in paper.receive(model("1", 1, [1, 1]), now=0.0).events] == [
        Reason.UNEXPECTED_TYPE
    ]
    assert c.round == 1 and paper.round == 1


def test_a_joining_worker_is_welcomed_with_the_fleet_model() -> None:
    c = fedavg_chief(workers=("1", "2"))
    feed(c, model("1", 1, [2, 0]), model("2", 1, [0, 2]))
    online = status_payload(b"online", run_id=RUN, node="2", incarnation=7)
    (welcome,) = c.status("2", online, now=0.0).outgoing
    assert (welcome.type, welcome.round, welcome.origin) == ("welcome", 2, None)
    np.testing.assert_allclose(welcome.flat, [1.0, 1.0])


def test_the_checkpoint_keeps_the_scheme_and_who_completed() -> None:
    c = fedavg_chief()
    feed(c, model("1", 1, [1, 1], "parameters"), model("2", 1, [1, 1]), model("3", 1, [1, 1]))
    fields, tensors = chief_to_state(c)
    restored = chief_from_state(json.loads(json.dumps(fields)), tensors, now=0.0)
    assert restored.scheme.name == "fedavg" and restored.completed == {"1": 1}
    feed(restored, model("1", 2, [1, 1]), model("2", 2, [1, 1], "parameters"))
    steps = feed(restored, model("3", 2, [1, 1], "parameters"))
    assert [m.type for m in replies(steps)] == ["average", "done"]


def test_unknown_scheme_names_the_choices() -> None:
    names = list(SCHEMES)
    choices = ", ".join(names[:-1]) + " or " + names[-1]
    with pytest.raises(ValueError) as info:
        get_scheme("fedvag")
    assert str(info.value) == (
        f"unknown federation scheme 'fedvag' (choose {choices}, or your own as package.module:Class)"
    )
    with pytest.raises(ValueError, match="unknown federation scheme"):
        ChiefPlan(run_id=RUN, workers=("1",), layout=LAYOUT, max_rounds=1, scheme="x")
    assert set(SCHEMES) >= {"paper", "fedavg", "fedavgm", "fedadam", "pergrad"}
