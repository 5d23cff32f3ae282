"""``fedasync``: the staleness weighting on hand-computed arrays, and the chief's asynchronous path as a pure
state machine (arrival order, versions, re-sends, late joiners, the end, checkpoint and resume)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import chief_of

from fleetrl.federation.chief.answer import check_round_rules
from fleetrl.federation.chief.asynchronous import AsyncChief
from fleetrl.federation.chief.checkpoint import chief_from_state, chief_to_state
from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.kinds import new_chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import get_scheme
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.schemes.fedasync import FedAsyncScheme
from fleetrl.federation.wire.messages import Message, Reason, decode, encode
from fleetrl.federation.wire.signing import status_payload

RUN = "async-run"
LAYOUT: list[tuple[str, tuple[int, ...]]] = [("w", (2,))]
X0 = np.zeros(2, np.float32)


def scheme(alpha: float = 0.5, decay: float = 1.0) -> FedAsyncScheme:
    made = get_scheme("fedasync", alpha=alpha, decay=decay)
    assert isinstance(made, FedAsyncScheme)
    return made


def make(workers: tuple[str, ...] = ("0", "1"), max_rounds: int = 5, **kwargs: object) -> Chief:
    return chief_of(  # type: ignore[no-any-return]
        new_chief, run_id=RUN, workers=workers, layout=LAYOUT, max_rounds=max_rounds, scheme=scheme(),
        start=FleetStart(LAYOUT, X0), **kwargs,
    )  # fmt: skip


def model(sender: str, rnd: int, values: list[float], base: int, kind: str = "async_model") -> Message:
    """Worker ``sender``'s contribution of its round ``rnd``, played from fleet model version ``base``."""
    flat = np.array(values, np.float32)
    return Message(kind, RUN, sender, rnd, flat=flat, samples=10, model_version=base)


def send(c: Chief, m: Message, now: float = 0.0) -> ChiefStep:
    return c.receive_bytes(encode(m, layout=LAYOUT), topic_worker=m.sender, now=now)


def online(c: Chief, worker: str, inc: int = 1) -> ChiefStep:
    return c.status(worker, status_payload(b"online", run_id=RUN, node=worker, incarnation=inc), now=0.0)


def answer(step: ChiefStep) -> Message:
    (reply,) = [m for m in step.outgoing if m.type == "average"]
    return reply


# ---- the staleness weighting ----


def test_the_weight_falls_with_staleness_as_alpha_times_s_plus_1_to_the_minus_a() -> None:
    s = scheme(alpha=0.6, decay=0.5)
    assert [s.weight(k) for k in (0, 1, 3)] == pytest.approx([0.6, 0.6 / np.sqrt(2), 0.3])
    x, xw = np.array([0.0, 10.0], np.float32), np.array([10.0, 0.0], np.float32)
    assert s.mix(x, xw, 0) == pytest.approx([6.0, 4.0])
    assert s.mix(x, xw, 1) == pytest.approx([4.2426407, 5.7573593])
    assert s.mix(x, xw, 3) == pytest.approx([3.0, 7.0])
    assert scheme(alpha=1.0, decay=0.0).mix(x, xw, 3) == pytest.approx(xw)  # α = 1, a = 0: the newest wins


@pytest.mark.parametrize(
    ("params", "match"),
    [({"alpha": 0.0}, "alpha = 0.0: must be in"), ({"alpha": 1.5}, "must be in \\(0, 1\\]"),
     ({"decay": -1.0}, "decay = -1.0: must be >= 0"), ({"beta": 1.0}, "has no parameter")],
)  # fmt: skip
def test_settings_out_of_range_are_refused_in_one_line(params: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        get_scheme("fedasync", **params)


def test_a_round_barrier_setting_is_refused_for_an_asynchronous_scheme() -> None:
    with pytest.raises(ValueError, match="no round barrier"):
        check_round_rules(scheme(), 10, 0.6, 5.0, 1)
    with pytest.raises(ValueError, match="no round barrier"):
        check_round_rules(scheme(), 10, 1.0, 5.0, 1)
    check_round_rules(scheme(), 10, 1.0, None, 1, max_staleness=2)
    with pytest.raises(ValueError, match="aggregation 'median' does not apply"):
        make(aggregator="median")


# ---- the chief ----


def test_two_workers_at_their_own_pace_are_applied_in_arrival_order_with_their_staleness() -> None:
    c = make()
    assert isinstance(c, AsyncChief)
    # worker 0 is fast: its rounds 1 and 2 arrive before worker 1's round 1 (α = 0.5, a = 1)
    first = answer(send(c, model("0", 1, [2.0, 2.0], base=0)))  # s = 0: x = 0.5·0 + 0.5·2
    assert (first.round, first.origin, first.contributors, first.model_version) == (1, "0", ("0",), 1)
    assert first.flat == pytest.approx([1.0, 1.0])
    second = answer(send(c, model("0", 2, [3.0, 3.0], base=1)))  # s = 0: x = 0.5·1 + 0.5·3
    assert (second.round, second.model_version) == (2, 2) and second.flat == pytest.approx([2.0, 2.0])
    slow = answer(send(c, model("1", 1, [6.0, 10.0], base=0)))  # s = 2: α_2 = 0.5/3
    assert (slow.round, slow.origin, slow.model_version) == (1, "1", 3)
    assert slow.flat == pytest.approx([2.0 * 5 / 6 + 6.0 / 6, 2.0 * 5 / 6 + 10.0 / 6])
    counts = c.state.contribution_counts()
    assert counts["0"]["applied"] == 2 and counts["0"]["staleness_max"] == 0
    assert counts["1"] | {"staleness_mean": 2.0} == counts["1"] and counts["1"]["last_round"] == 1
    # the answer is what goes on the wire: the worker's decoder takes it with its version
    wire = encode(slow, layout=LAYOUT)
    assert decode(wire, run_id=RUN, known_senders=("chief",), layout=LAYOUT).model_version == 3


def test_a_resent_contribution_is_answered_again_and_never_applied_twice() -> None:
    c = make()
    send(c, model("0", 1, [2.0, 2.0], base=0))
    again = send(c, model("0", 1, [2.0, 2.0], base=0), now=5.0)
    reply = answer(again)
    assert [e.reason for e in again.events if e.kind == "rejected"] == [Reason.DUPLICATE]
    assert (reply.round, reply.origin, reply.model_version) == (1, "0", 1)
    assert reply.flat == pytest.approx([1.0, 1.0])
    assert send(c, model("0", 1, [2.0, 2.0], base=0), now=5.5).outgoing == ()  # within the hold-off
    assert c.state.contribution_counts()["0"]["applied"] == 1


def test_a_late_joiner_is_welcomed_with_the_current_model_and_a_returning_one_with_its_next_round() -> None:
    c = make(workers=("0", "1", "2"))
    send(c, model("0", 1, [2.0, 2.0], base=0))
    send(c, model("0", 2, [4.0, 4.0], base=1))
    (late,) = online(c, "2").outgoing
    assert (late.type, late.round, late.model_version, late.contributors) == ("welcome", 1, 2, ("2",))
    assert late.flat == pytest.approx([2.5, 2.5])
    (back,) = online(c, "0", inc=2).outgoing  # worker 0 restarted: its own count goes on
    assert (back.round, back.model_version) == (3, 2)


def test_a_unit_new_to_the_fleet_joins_with_the_current_model_and_its_own_round_1() -> None:
    c = make()
    send(c, model("0", 1, [2.0, 2.0], base=0))
    join = Message("join", RUN, "7", 1)
    step = c.receive_bytes(encode(join, layout=LAYOUT), topic_worker="7", now=1.0)
    assert [(e.kind, e.sender) for e in step.events] == [("admitted", "7"), ("welcome", "7")]
    (welcome,) = step.outgoing
    assert (welcome.round, welcome.model_version, welcome.contributors) == (1, 1, ("7",))
    assert welcome.flat == pytest.approx([1.0, 1.0]) and "7" in c.members
    reply = answer(send(c, model("7", 1, [3.0, 3.0], base=1)))  # s = 0: x = 0.5·1 + 0.5·3
    assert (reply.origin, reply.model_version) == ("7", 2) and reply.flat == pytest.approx([2.0, 2.0])


def test_a_contribution_staler_than_the_bound_is_answered_but_left_out() -> None:
    c = make(max_staleness=1)
    send(c, model("0", 1, [2.0, 2.0], base=0))
    send(c, model("0", 2, [4.0, 4.0], base=1))
    reply = answer(send(c, model("1", 1, [9.0, 9.0], base=0)))  # s = 2 > 1
    assert (reply.origin, reply.contributors, reply.model_version) == ("1", (), 2)
    assert reply.flat == pytest.approx([2.5, 2.5])
    assert c.state.contribution_counts()["1"]["left_out"] == 1


def test_the_run_ends_when_every_member_completed_and_late_contributions_get_the_end() -> None:
    c = make()
    send(c, model("0", 1, [2.0, 2.0], base=0, kind="parameters"))
    assert not c.finished
    end = send(c, model("1", 1, [2.0, 2.0], base=0, kind="parameters"))
    assert [m.type for m in end.outgoing] == ["average", "done"] and c.finished
    assert answer(end).finished == ("0", "1") and c.end_reason == "every unit completed"
    late = send(c, model("0", 2, [1.0, 1.0], base=1), now=3.0)  # 0 was playing: the end again
    assert [m.type for m in late.outgoing] == ["average", "done"] and answer(late).finished == ("0", "1")


def test_the_run_ends_once_every_member_played_m_rounds() -> None:
    c = make(max_rounds=2)
    for rnd in (1, 2):
        send(c, model("0", rnd, [1.0, 1.0], base=rnd - 1))
    assert not c.finished
    send(c, model("1", 1, [1.0, 1.0], base=0))
    done = send(c, model("1", 2, [1.0, 1.0], base=3))
    assert done.outgoing[-1].type == "done" and c.end_reason == "reached M=2 rounds"
    assert [e.reason for e in send(c, model("1", 3, [1.0, 1.0], base=3)).events] == [Reason.BAD_ROUND]


def test_a_chief_resumed_from_its_checkpoint_answers_exactly_like_the_original() -> None:
    c = make()
    send(c, model("0", 1, [2.0, 2.0], base=0))
    send(c, model("1", 1, [6.0, 4.0], base=0))
    fields, tensors = chief_to_state(c)
    restored = chief_from_state(json.loads(json.dumps(fields)), tensors, now=0.0)
    assert isinstance(restored, AsyncChief)
    for chief in (c, restored):
        dup = send(chief, model("1", 1, [6.0, 4.0], base=0), now=10.0)  # a re-send: answered, not applied
        assert answer(dup).model_version == 2
    nxt = [answer(send(chief, model("0", 2, [5.0, 1.0], base=1), now=11.0)) for chief in (c, restored)]
    assert nxt[0].model_version == nxt[1].model_version == 3
    assert np.array_equal(nxt[0].flat, nxt[1].flat)
    assert restored.state.contribution_counts() == c.state.contribution_counts()


def test_an_asynchronous_chief_needs_the_fleets_start() -> None:
    with pytest.raises(ValueError, match="needs the fleet's start"):
        new_chief(ChiefPlan(run_id=RUN, workers=("0",), layout=LAYOUT, max_rounds=3, scheme="fedasync"))
