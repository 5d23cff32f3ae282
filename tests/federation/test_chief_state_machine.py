"""Algorithm 1 as a pure state machine: averages, transfers, W, the end of the run, and what it rejects."""

from __future__ import annotations

import itertools
from typing import Any

import msgpack
import numpy as np
import pytest
from conftest import chief_of
from hypothesis import given, settings
from hypothesis import strategies as st

from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.messages import VERSION, Message, Reason, decode, encode, envelope

LAYOUT = [("w", (2,))]
RUN = "r1"


def chief(workers: tuple[str, ...] = ("1", "2", "3"), max_rounds: int = 10) -> Chief:
    return Chief(ChiefPlan(run_id=RUN, workers=workers, layout=LAYOUT, max_rounds=max_rounds, scheme="paper"))


def grad(sender: str, rnd: int, values: list[float]) -> Message:
    return Message("gradient", RUN, sender, rnd, flat=np.array(values, np.float32), metrics={"score": 1.0})


def params(sender: str, rnd: int, values: list[float]) -> Message:
    return Message("parameters", RUN, sender, rnd, flat=np.array(values, np.float32))


def wire(message: Message) -> bytes:
    return encode(message, layout=LAYOUT)


def feed(c: Chief, *messages: Message) -> list[ChiefStep]:
    return [c.receive_bytes(wire(m), topic_worker=m.sender, now=0.0) for m in messages]


def out(steps: list[ChiefStep]) -> list[Message]:
    return [m for s in steps for m in s.outgoing]


def rejected(step: ChiefStep) -> Reason | None:
    reasons = [e.reason for e in step.events if e.kind == "rejected"]
    return reasons[0] if reasons else None


ROUND1 = [grad("1", 1, [1.0, 2.0]), grad("2", 1, [3.0, 4.0]), grad("3", 1, [5.0, 9.0])]


def test_average_against_hand_computed_values() -> None:
    c = chief()
    steps = feed(c, *ROUND1)
    assert [s.outgoing for s in steps[:2]] == [(), ()]
    (reply,) = out(steps)
    assert (reply.type, reply.round, reply.sender, reply.contributors) == (
        "average",
        1,
        "chief",
        ("1", "2", "3"),
    )
    np.testing.assert_allclose(reply.flat, [3.0, 5.0])
    assert c.round == 2 and c.members == ("1", "2", "3")
    closed = next(e for e in steps[-1].events if e.kind == "averaged")
    assert closed.averaged == ("1", "2", "3") and "averaged 1,2,3 (mean)" in str(closed)


def test_average_is_bit_identical_whatever_the_arrival_order() -> None:
    g = [grad(w, 1, list(np.random.default_rng(int(w)).normal(size=2))) for w in ("1", "2", "3", "10")]
    answers = set()
    for order in itertools.permutations(g):
        (reply,) = out(feed(chief(("1", "2", "3", "10")), *order))
        assert reply.flat is not None
        answers.add(reply.flat.tobytes())
        assert reply.contributors == ("1", "2", "3", "10")  # numeric ids sort numerically
    assert len(answers) == 1


def test_transfer_forwards_parameters_and_w_shrinks() -> None:
    c = chief()
    steps = feed(c, grad("1", 1, [1, 1]), params("2", 1, [7, 8]), grad("3", 1, [5, 5]))
    (reply,) = out(steps)
    assert (reply.type, reply.origin, reply.finished) == ("transfer", "2", ("2",))
    np.testing.assert_array_equal(reply.flat, [7, 8])  # the parameters, not an average of anything
    assert c.members == ("1", "3") and c.round == 2 and not c.finished
    assert c.transfers == [(1, "2", ("1", "3"))]
    # round 2 closes with the two remaining workers only
    (reply2,) = out(feed(c, grad("3", 2, [2, 2]), grad("1", 2, [4, 0])))
    assert reply2.type == "average" and reply2.contributors == ("1", "3")
    np.testing.assert_allclose(reply2.flat, [3, 1])


def test_two_finish_in_one_round_lowest_id_is_forwarded_both_leave() -> None:
    c = chief(("2", "10", "3"))
    (reply,) = out(feed(c, params("10", 1, [10, 10]), params("2", 1, [2, 2]), grad("3", 1, [0, 0])))
    assert (reply.origin, reply.finished) == ("2", ("2", "10"))
    np.testing.assert_array_equal(reply.flat, [2, 2])
    assert c.members == ("3",)


def test_message_from_a_worker_no_longer_in_w_is_rejected_and_changes_nothing() -> None:
    c = chief()
    feed(c, grad("1", 1, [1, 1]), params("2", 1, [7, 8]), grad("3", 1, [5, 5]))
    (step,) = feed(c, grad("2", 2, [100, 100]))
    assert rejected(step) == Reason.NOT_IN_W and step.outgoing == ()
    (reply,) = out(feed(c, grad("1", 2, [1, 1]), grad("3", 2, [3, 3])))
    np.testing.assert_allclose(reply.flat, [2, 2])


def test_run_ends_when_w_is_empty() -> None:
    c = chief(("1", "2"))
    steps = feed(c, params("1", 1, [1, 1]), params("2", 1, [2, 2]))
    transfer, done = out(steps)
    assert transfer.type == "transfer" and transfer.finished == ("1", "2")
    assert (done.type, done.round) == ("done", 1)
    assert c.finished and c.end_reason == "W is empty" and c.members == ()
    (late,) = feed(c, grad("1", 2, [0, 0]))
    assert rejected(late) == Reason.RUN_OVER


def test_run_ends_at_m_rounds() -> None:
    c = chief(("1",), max_rounds=3)
    for rnd in (1, 2):
        (reply,) = out(feed(c, grad("1", rnd, [rnd, rnd])))
        assert reply.type == "average"
    average, done = out(feed(c, grad("1", 3, [3, 3])))
    assert average.type == "average" and done.type == "done"
    assert c.finished and c.end_reason == "reached M=3 rounds" and c.round == 3


def test_duplicates_and_stragglers_do_not_corrupt_a_round() -> None:
    c = chief()
    feed(c, *ROUND1)
    steps = feed(
        c,
        grad("1", 2, [1, 1]),
        grad("1", 2, [999, 999]),  # duplicate (sender, round) with other content: the first one counts
        grad("2", 1, [999, 999]),  # straggler resend of a closed round
        grad("3", 3, [999, 999]),  # from the future
        grad("2", 2, [3, 3]),
        grad("3", 2, [5, 5]),
    )
    assert [rejected(s) for s in steps[1:4]] == [Reason.DUPLICATE, Reason.STALE_ROUND, Reason.FUTURE_ROUND]
    (reply,) = out(steps)
    np.testing.assert_allclose(reply.flat, [3, 3])
    assert c.rejections == {Reason.DUPLICATE: 1, Reason.STALE_ROUND: 1, Reason.FUTURE_ROUND: 1}


def _raw(**changes: Any) -> bytes:
    env = envelope(grad("2", 1, [1, 1]), layout=LAYOUT)
    env.update(changes)
    return bytes(msgpack.packb(env, use_bin_type=True))


BAD = [
    (_raw(version=VERSION + 1), Reason.WRONG_VERSION),
    (_raw(tensors=[["w", [3]]], data=b"\0" * 12), Reason.LAYOUT_MISMATCH),
    (_raw(data=np.array([np.nan, 0], "<f4").tobytes()), Reason.NOT_FINITE),
    (_raw(data=np.array([np.inf, 0], "<f4").tobytes()), Reason.NOT_FINITE),
    (b"\x00" * 100_000, Reason.OVERSIZED),
    (_raw(sender="chief"), Reason.UNKNOWN_SENDER),  # no worker id (a new valid id may join)
    (_raw(round=0), Reason.BAD_ROUND),
    (b"not msgpack \xc1", Reason.NOT_MSGPACK),
    (_raw(run_id="other"), Reason.WRONG_RUN_ID),
    (_raw(type="average"), Reason.UNEXPECTED_TYPE),
]


@pytest.mark.parametrize(("payload", "reason"), BAD)
def test_bad_messages_are_rejected_and_never_change_the_average(payload: bytes, reason: Reason) -> None:
    c = chief()
    first, second, third = ROUND1
    steps = feed(c, first)
    steps.append(c.receive_bytes(payload, topic_worker="2", now=0.0))
    steps += feed(c, second, third)
    assert rejected(steps[1]) == reason and steps[1].outgoing == ()
    assert c.rejections == {reason: 1}
    (reply,) = out(steps)
    np.testing.assert_allclose(reply.flat, [3.0, 5.0])
    assert any("rejected message from 2" in str(e) for e in steps[1].events)


def test_sender_must_match_its_topic() -> None:
    c = chief()
    step = c.receive_bytes(wire(grad("1", 1, [1, 1])), topic_worker="3", now=0.0)
    assert rejected(step) == Reason.TOPIC_MISMATCH and c.answered == ()


@settings(max_examples=150, deadline=None)
@given(st.lists(st.binary(max_size=200), max_size=6), st.permutations(list(range(3))))
def test_junk_interleaved_with_a_round_never_changes_the_average(junk: list[bytes], order: list[int]) -> None:
    c = chief()
    outgoing: list[Message] = []
    for i, k in enumerate(order):
        for blob in junk[i::3]:
            outgoing += c.receive_bytes(blob, topic_worker=ROUND1[k].sender, now=0.0).outgoing
        outgoing += c.receive_bytes(wire(ROUND1[k]), topic_worker=ROUND1[k].sender, now=0.0).outgoing
    (reply,) = outgoing
    np.testing.assert_allclose(reply.flat, [3.0, 5.0])


def test_outgoing_messages_are_valid_on_the_wire() -> None:
    c = chief()
    (reply,) = out(feed(c, *ROUND1))
    back = decode(wire(reply), run_id=RUN, known_senders=("chief",), layout=LAYOUT)
    assert back.contributors == ("1", "2", "3")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"workers": []}, "at least one worker"),
        ({"workers": ["chief"]}, "reserved"),
        ({"workers": ["a/b"]}, "bad worker id"),
        ({"max_rounds": 0}, "max_rounds"),
        ({"aggregator": "mode"}, "unknown aggregator"),
    ],
)
def test_bad_configuration_is_refused(kwargs: dict[str, Any], match: str) -> None:
    args: dict[str, Any] = dict(run_id=RUN, workers=["1"], layout=LAYOUT, max_rounds=3, scheme="paper")
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        chief_of(Chief, **args)


# ---- a per-step scheme: a resumed worker replays its round, the chief answers each step again ----

K = 5


def step_grad(sender: str, rnd: int, step: int, value: float) -> Message:
    return Message("step_gradient", RUN, sender, rnd, step=step, flat=np.full(2, value, np.float32))


def pergrad_chief(**kwargs: Any) -> Chief:
    return chief_of(  # type: ignore[no-any-return]
        Chief,
        run_id=RUN,
        workers=("1", "2"),
        layout=LAYOUT,
        max_rounds=3,
        scheme="pergrad",
        steps_per_round=K,
        **kwargs,
    )


def play_steps(c: Chief, rnd: int, steps: range, now: float = 0.0) -> list[Message]:
    """Both workers send each of ``steps`` of round ``rnd``: the answers, in order."""
    answers = []
    for k in steps:
        c.receive(step_grad("1", rnd, k, k), now=now)
        (answer,) = c.receive(step_grad("2", rnd, k, 10 * rnd + k), now=now).outgoing
        answers.append(answer)
    return answers


def test_a_replayed_step_is_answered_with_that_steps_answer_one_step_after_the_other() -> None:
    c = pergrad_chief()
    closed = play_steps(c, 1, range(3))  # steps 0..2 closed, step 3 open
    assert [(a.round, a.step) for a in closed] == [(1, 0), (1, 1), (1, 2)]
    for k in range(3):  # worker 1, resumed, replays round 1 from step 0
        step = c.receive(step_grad("1", 1, k, k), now=10.0)
        assert step.outgoing == (closed[k],) and rejected(step) is Reason.STALE_ROUND
        assert step.events[-1].detail == ("answer of round 1" if k == 0 else f"answer of round 1 step {k}")
    assert (c.round, c.answered) == (1, ())  # nothing changed: step 3 is open, and is played as usual
    (last,) = play_steps(c, 1, range(3, 4), now=10.0)
    assert (last.round, last.step, last.contributors) == (1, 3, ("1", "2"))


def test_a_worker_replaying_the_round_the_chief_just_closed_gets_its_answers() -> None:
    c = pergrad_chief()
    round1 = play_steps(c, 1, range(K))
    play_steps(c, 2, range(1))  # round 2's step 0 closed too: round 1's answers are still kept
    replies = [c.receive(step_grad("1", 1, k, k), now=10.0).outgoing for k in range(K)]
    assert replies == [(a,) for a in round1]
    play_steps(c, 2, range(1, K))
    play_steps(c, 3, range(1))
    (fallback,) = c.receive(step_grad("1", 1, 0, 0), now=20.0).outgoing
    assert (fallback.round, fallback.step) == (3, 0)  # round 1 is forgotten: the last answer


def test_the_resend_holdoff_counts_per_answer() -> None:
    c = pergrad_chief(resend_holdoff=1.0)
    closed = play_steps(c, 1, range(3), now=0.0)
    assert c.receive(step_grad("1", 1, 2, 2), now=0.5).outgoing == ()  # crossed step 2's answer in flight
    assert c.receive(step_grad("1", 1, 0, 0), now=5.0).outgoing == (closed[0],)
    assert (
        c.receive(step_grad("1", 1, 0, 0), now=5.5).outgoing == ()
    )  # a flood of one message: once per holdoff
    assert c.receive(step_grad("2", 1, 0, 0), now=5.5).outgoing == (closed[0],)  # another worker's
    assert c.receive(step_grad("1", 1, 1, 1), now=5.5).outgoing == (closed[1],)  # the next step: at once
    assert c.receive(step_grad("1", 1, 0, 0), now=6.0).outgoing == (closed[0],)


def test_after_the_end_the_last_step_is_answered_with_done_and_earlier_steps_without() -> None:
    c = pergrad_chief()
    for rnd in (1, 2):
        play_steps(c, rnd, range(K))
    *_, last = play_steps(c, 3, range(K - 1))
    c.receive(step_grad("1", 3, K - 1, 0), now=0.0)
    final, done = c.receive(step_grad("2", 3, K - 1, 0), now=0.0).outgoing
    assert c.finished and done.type == "done"
    assert c.receive(step_grad("1", 3, K - 2, 0), now=5.0).outgoing == (last,)
    step = c.receive(step_grad("1", 3, K - 1, 0), now=5.0)
    assert step.outgoing == (final, done) and rejected(step) is Reason.RUN_OVER
