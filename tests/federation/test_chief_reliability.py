"""Issue 7 rules of the pure chief: deadlines, quorum, dropout, rejoin, resends, signatures — no broker."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chief_of

from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import FleetKey, status_payload

LAYOUT = [("w", (2,))]
RUN = "r1"
KEY = FleetKey(b"k" * 32)


def make(**kwargs: object) -> Chief:
    args: dict[str, object] = dict(
        run_id=RUN, workers=("1", "2", "3"), layout=LAYOUT, max_rounds=10, scheme="paper"
    )
    args.update(kwargs)
    return chief_of(Chief, **args)  # type: ignore[no-any-return]


def grad(sender: str, rnd: int, values: list[float], kind: str = "gradient") -> Message:
    return Message(kind, RUN, sender, rnd, flat=np.array(values, np.float32))


def send(c: Chief, m: Message, now: float = 0.0, key: FleetKey | None = None) -> ChiefStep:
    return c.receive_bytes(encode(m, layout=LAYOUT, key=key), topic_worker=m.sender, now=now)


def status(worker: str, state: bytes, inc: int, key: FleetKey | None = None) -> bytes:
    return status_payload(state, run_id=RUN, node=worker, incarnation=inc, key=key)


def kinds(step: ChiefStep) -> list[str]:
    return [e.kind for e in step.events]


def test_default_is_fully_synchronous_no_deadline() -> None:
    c = make()
    send(c, grad("1", 1, [1, 1]), now=0)
    send(c, grad("2", 1, [3, 3]), now=0)
    assert c.next_deadline() is None and c.tick(1e9).outgoing == () and c.round == 1


def test_silent_worker_is_dropped_at_the_deadline_and_the_round_closes() -> None:
    c = make(round_timeout=5.0)
    send(c, grad("1", 1, [1, 1]), now=0)
    send(c, grad("2", 1, [3, 3]), now=1)
    assert c.tick(4.9).outgoing == ()
    step = c.tick(5.0)
    (reply,) = step.outgoing
    np.testing.assert_allclose(reply.flat, [2, 2])
    assert reply.contributors == ("1", "2") and c.members == ("1", "2") and c.round == 2
    assert c.dropouts == [(1, "3", "no message within the round deadline")]
    assert kinds(step) == ["dropped", "averaged"]
    assert c.next_deadline() is None  # the next round opened at 5; its deadline acts once one answers
    send(c, grad("1", 2, [1, 1]), now=6)
    assert c.next_deadline() == 10.0


def test_nobody_answered_keeps_waiting_instead_of_emptying_w() -> None:
    c = make(round_timeout=5.0)
    c.tick(0.0)
    assert c.tick(100.0) == ChiefStep() and c.members == ("1", "2", "3")


def test_quorum_closes_with_the_fastest_and_keeps_the_straggler_in_w() -> None:
    c = make(quorum=0.6, round_timeout=2.0)  # ⌈0.6·3⌉ = 2
    send(c, grad("1", 1, [1, 1]), now=0)
    send(c, grad("2", 1, [3, 3]), now=0.5)
    (reply,) = c.tick(2.0).outgoing
    assert reply.contributors == ("1", "2") and c.members == ("1", "2", "3") and c.dropouts == []
    # the straggler's late message is stale and changes nothing; round 2 opens normally
    late = send(c, grad("3", 1, [99, 99]), now=2.1)
    assert late.events[0].reason == Reason.STALE_ROUND
    assert c.answered == ()


def test_quorum_not_met_drops_the_silent_ones() -> None:
    c = make(workers=("1", "2", "3", "4"), quorum=0.75, round_timeout=1.0)  # needs 3 of 4
    send(c, grad("1", 1, [1, 1]), now=0)
    send(c, grad("2", 1, [3, 3]), now=0)
    c.tick(1.0)
    assert c.members == ("1", "2") and [d[1] for d in c.dropouts] == ["3", "4"]


def test_last_will_drops_a_worker_after_its_grace_and_closes_a_round_waiting_only_for_it() -> None:
    c = make(dropout_grace=3.0)
    send(c, grad("1", 1, [1, 1]))
    send(c, grad("2", 1, [3, 3]))
    assert c.status("3", b"offline", now=10.0) == ChiefStep() and c.next_deadline() == 13.0
    assert c.tick(12.9) == ChiefStep() and "3" in c.members
    step = c.tick(13.0)
    assert kinds(step) == ["dropped", "averaged"] and c.members == ("1", "2")
    assert "went offline" in str(step.events[0]) and c.dropouts == [(1, "3", "went offline")]


def test_a_worker_back_within_its_grace_is_not_dropped() -> None:
    """A broker that shuts down publishes the wills of clients that are alive and will reconnect."""
    c = make(dropout_grace=3.0)
    send(c, grad("1", 1, [1, 1]), now=0)
    c.status("2", b"offline", now=0.5)
    send(c, grad("2", 1, [3, 3]), now=2.0)  # reconnected and re-sent
    assert c.tick(10.0) == ChiefStep() and c.members == ("1", "2", "3") and c.dropouts == []


def test_retained_offline_never_drops() -> None:
    c = make()
    assert c.status("3", b"offline", retained=True, now=0.0) == ChiefStep() and "3" in c.members


def test_rejoin_gets_the_open_round_and_the_last_transferred_parameters() -> None:
    c = make(dropout_grace=0.0)
    send(c, grad("1", 1, [1, 1]))
    send(c, grad("2", 1, [7, 8], kind="parameters"))
    c.status("3", status("3", b"offline", 1), now=0.0)  # worker 3 dies in round 1
    assert c.round == 2 and c.members == ("1",)
    step = c.status("3", status("3", b"online", 2), now=0.0)  # restarted with the same id
    assert kinds(step) == ["rejoined", "welcome"] and c.members == ("1", "3")
    (welcome,) = step.outgoing
    assert (welcome.type, welcome.round, welcome.origin) == ("welcome", 2, "2")
    np.testing.assert_array_equal(welcome.flat, [7, 8])
    assert c.rejoins == [(2, "3")]
    # round 2 now waits for the rejoined worker too
    send(c, grad("1", 2, [1, 1]))
    (reply,) = send(c, grad("3", 2, [3, 3])).outgoing
    assert reply.contributors == ("1", "3")


def test_a_restarted_worker_withdraws_what_its_dead_process_sent_for_the_open_round() -> None:
    """The new process (resumed: it replays the same round) sends its own message; the old one must not close
    the round behind its back while it replays."""
    c = make(workers=("1", "2"))
    c.status("1", status("1", b"online", 1), now=0.0)
    send(c, grad("1", 1, [9, 9]))  # then process 1 is killed
    c.status("1", status("1", b"online", 1), now=0.0)  # a reconnect of the same process withdraws nothing
    c.status("1", status("1", b"offline", 2), now=0.0)  # nor a new process that died before it came online
    assert c.answered == ("1",)
    c.status("1", status("1", b"online", 3), now=0.0)  # the restarted process
    assert c.answered == () and send(c, grad("2", 1, [3, 3])).outgoing == ()
    (reply,) = send(c, grad("1", 1, [1, 1])).outgoing
    np.testing.assert_array_equal(reply.flat, [2, 2])


def test_welcome_before_any_transfer_has_no_tensors_and_a_late_will_is_ignored() -> None:
    c = make()
    step = c.status("2", status("2", b"online", 5), retained=True, now=0.0)
    (welcome,) = step.outgoing
    assert welcome.type == "welcome" and welcome.flat is None and c.members == ("1", "2", "3")
    replay = c.status("2", status("2", b"offline", 4), now=0.0)  # will of an earlier incarnation
    assert replay.events[0].reason == Reason.REPLAYED and "2" in c.members


def test_dropped_worker_that_sends_for_the_open_round_is_readmitted() -> None:
    c = make(round_timeout=1.0)
    send(c, grad("1", 1, [1, 1]), now=0)
    send(c, grad("2", 1, [1, 1]), now=0)
    c.tick(1.0)
    assert c.members == ("1", "2")
    step = send(c, grad("3", 2, [5, 5]), now=1.5)
    assert kinds(step) == ["rejoined", "accepted"] and c.members == ("1", "2", "3")


def test_resend_for_a_closed_round_repeats_the_answer_rate_limited() -> None:
    c = make(resend_holdoff=1.0)
    first = [send(c, grad(w, 1, [i, i]), now=0) for i, w in enumerate(("1", "2", "3"))]
    (answer,) = first[-1].outgoing
    assert send(c, grad("1", 1, [1, 1]), now=0.5).outgoing == ()  # crossed the answer in flight
    again = send(c, grad("1", 1, [1, 1]), now=1.5)
    assert again.outgoing == (answer,) and kinds(again) == ["rejected", "resent"]
    assert send(c, grad("1", 1, [1, 1]), now=2.0).outgoing == ()  # once per holdoff
    assert c.round == 2 and c.answered == ()


def test_resend_after_the_end_repeats_the_answer_and_done() -> None:
    c = make(workers=("1",), max_rounds=1)
    average, done = send(c, grad("1", 1, [1, 1])).outgoing
    step = send(c, grad("1", 1, [1, 1]), now=5.0)
    assert step.outgoing == (average, done) and step.events[0].reason == Reason.RUN_OVER


def test_signed_chief_rejects_unsigned_forged_and_bad_statuses() -> None:
    c = make(key=KEY)
    forged = FleetKey(b"x" * 32)
    assert send(c, grad("1", 1, [1, 1])).events[0].reason == Reason.UNSIGNED
    assert send(c, grad("1", 1, [1, 1]), key=forged).events[0].reason == Reason.BAD_SIGNATURE
    assert c.status("1", b"offline", now=0.0).events[0].reason == Reason.UNSIGNED
    assert c.status("1", status("1", b"offline", 3, forged), now=0.0).events[0].reason == Reason.BAD_SIGNATURE
    assert c.members == ("1", "2", "3") and c.answered == ()
    assert kinds(send(c, grad("1", 1, [1, 1]), key=KEY)) == ["accepted"]
    replay = send(c, grad("1", 1, [1, 1]), key=KEY)
    assert replay.events[0].reason == Reason.DUPLICATE
    # a signed message cannot be moved to another sender's topic
    moved = c.receive_bytes(encode(grad("1", 1, [1, 1]), layout=LAYOUT, key=KEY), topic_worker="2", now=0.0)
    assert moved.events[0].reason == Reason.TOPIC_MISMATCH


def test_tampering_with_a_signed_message_breaks_the_signature() -> None:
    c = make(key=KEY)
    payload = bytearray(encode(grad("1", 1, [1, 1]), layout=LAYOUT, key=KEY))
    payload[-1] ^= 0x01
    assert c.receive_bytes(bytes(payload), topic_worker="1", now=0.0).events[0].reason == Reason.BAD_SIGNATURE


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"quorum": 0.5}, "needs a round timeout"),
        ({"quorum": 0.0, "round_timeout": 1.0}, "quorum must be"),
        ({"round_timeout": 0.0}, "round_timeout must be"),
    ],
)
def test_bad_reliability_settings_are_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make(**kwargs)


def test_short_fleet_keys_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 16 bytes"):
        FleetKey(b"short")


def test_a_deadline_that_passed_with_nobody_answering_is_not_due_again() -> None:
    """Issue 14: the runner waits until next_deadline(); one in the past made it poll with a zero timeout."""
    c = make(round_timeout=3.0)
    c.tick(0.0)
    assert c.tick(10.0) == ChiefStep()
    due = c.next_deadline()
    assert due is None or due > 10.0
    send(c, grad("1", 1, [1, 1]), now=11.0)  # an answer after the deadline: now the rule applies at once
    assert c.next_deadline() == 3.0
    assert kinds(c.tick(11.0)) == ["dropped", "dropped", "averaged"] and c.round == 2
    assert c.members == ("1",)


def test_a_worker_s_status_saying_ended_is_rejected_and_changes_nothing() -> None:
    c = make(round_timeout=5.0)
    step = c.status("2", status("2", b"ended", 1), now=0.0)
    assert [e.reason for e in step.events] == [Reason.MALFORMED] and not step.outgoing
    assert c.members == ("1", "2", "3") and not c.state.suspects and not c.state.incarnations
