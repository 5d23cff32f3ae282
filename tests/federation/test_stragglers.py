"""A per-step scheme's chief with a quorum (docs/protocol.md, "Stragglers"), on hand-computed arrays: the
grace after the quorum, who is waited for, stale contributions averaged or left out, and the per-unit
counts."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chief_of

from fleetrl.federation.chief.checkpoint import chief_from_state, chief_to_state
from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.chief.stragglers import GRACE_FLOOR, quorum_count
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.wire.signing import status_payload

RUN = "straggle"
LAYOUT = [("g", (2,))]
K = 2


def make(**kwargs: object) -> Chief:
    options: dict[str, object] = {"quorum": 0.6, "max_rounds": 20}
    options.update(kwargs)
    return chief_of(  # type: ignore[no-any-return]
        Chief, run_id=RUN, workers=("0", "1", "2"), layout=LAYOUT, scheme="pergrad", steps_per_round=K,
        **options,
    )  # fmt: skip


def step(
    c: Chief, sender: str, rnd: int, k: int, values: list[float], now: float, stale: int = 0
) -> ChiefStep:
    flat = np.array(values, np.float32)
    return c.receive(Message("step_gradient", RUN, sender, rnd, step=k, flat=flat, staleness=stale), now=now)


def answers(s: ChiefStep) -> list[tuple[int, int, list[float], tuple[str, ...]]]:
    return [(m.round, m.step, m.flat.tolist(), m.contributors) for m in s.outgoing if m.flat is not None]


def test_quorum_count() -> None:
    assert [quorum_count(0.6, n) for n in (1, 2, 3, 5, 10)] == [1, 2, 2, 3, 6]
    assert quorum_count(1.0, 3) == 3


def test_the_grace_after_the_quorum_then_the_straggler_is_not_waited_for_until_it_takes_part() -> None:
    c = make()
    assert c.tick(0.0) == ChiefStep()  # round 1 opens at 0
    assert answers(step(c, "0", 1, 0, [1.0, 2.0], now=2.0)) == []
    assert answers(step(c, "1", 1, 0, [3.0, 4.0], now=4.0)) == []  # 2 of 3: the quorum, at 4 s
    assert c.next_deadline() == pytest.approx(5.0)  # a quarter of the 4 s the quorum took
    assert answers(c.tick(4.9)) == []
    assert answers(c.tick(5.0)) == [(1, 0, [2.0, 3.0], ("0", "1"))]
    # the round's later steps wait only for its participants: no grace
    assert answers(step(c, "0", 1, 1, [0.0, 0.0], now=5.1)) == []
    assert answers(step(c, "1", 1, 1, [2.0, 2.0], now=5.2)) == [(1, 1, [1.0, 1.0], ("0", "1"))]
    assert c.state.pace.behind == {"2"} and c.state.pace.late == {"2": 1}
    # round 2: worker 2 is behind, so its first step closes with 0 and 1 at once
    step(c, "0", 2, 0, [1.0, 1.0], now=6.0)
    assert answers(step(c, "1", 2, 0, [3.0, 3.0], now=6.1)) == [(2, 0, [2.0, 2.0], ("0", "1"))]
    # worker 2 joins round 2's step 1 (it answers the open exchange) and so takes part in round 2
    step(c, "2", 2, 1, [9.0, 9.0], now=6.2, stale=1)
    step(c, "0", 2, 1, [0.0, 0.0], now=6.3)
    assert answers(step(c, "1", 2, 1, [0.0, 0.0], now=6.4)) == [(2, 1, [3.0, 3.0], ("0", "1", "2"))]
    assert c.state.pace.behind == set() and c.round == 3 and c.members == ("0", "1", "2")


def test_every_member_in_phase_answering_closes_at_once_and_the_floor_bounds_a_short_grace() -> None:
    c = make()
    c.tick(0.0)
    step(c, "0", 1, 0, [1.0, 1.0], now=0.1)
    step(c, "1", 1, 0, [1.0, 1.0], now=0.2)
    assert c.next_deadline() == pytest.approx(0.2 + GRACE_FLOOR)
    assert answers(step(c, "2", 1, 0, [4.0, 4.0], now=0.3)) == [(1, 0, [2.0, 2.0], ("0", "1", "2"))]


def test_with_quorum_1_every_member_is_waited_for() -> None:
    c = make(quorum=1.0)
    c.tick(0.0)
    step(c, "0", 1, 0, [1.0, 1.0], now=1.0)
    step(c, "1", 1, 0, [1.0, 1.0], now=2.0)
    assert c.next_deadline() is None and answers(c.tick(1000.0)) == []
    assert len(answers(step(c, "2", 1, 0, [1.0, 1.0], now=1001.0))) == 1


@pytest.mark.parametrize(("bound", "expected", "stale"), [(None, [3.0, 3.0], {}), (0, [1.0, 1.0], {"2": 1})])
def test_a_stale_contribution_is_averaged_within_the_bound_else_counted_and_left_out(
    bound: int | None, expected: list[float], stale: dict[str, int]
) -> None:
    c = make(quorum=1.0, max_staleness=bound)
    step(c, "2", 1, 0, [7.0, 7.0], now=0.0, stale=2)
    step(c, "0", 1, 0, [1.0, 1.0], now=0.0)
    (got,) = answers(step(c, "1", 1, 0, [1.0, 1.0], now=0.0))
    assert got[2] == expected and c.state.pace.stale == stale


def test_a_completion_in_a_stale_message_still_counts() -> None:
    c = make(quorum=1.0, max_staleness=0, max_rounds=1)
    for k in range(K):
        for w in ("0", "1"):
            c.receive(Message("parameters", RUN, w, 1, step=k, flat=np.ones(2, np.float32)), now=0.0)
        c.receive(
            Message("parameters", RUN, "2", 1, step=k, flat=np.ones(2, np.float32), staleness=3), now=0.0
        )
    assert c.completed == {"0": 1, "1": 1, "2": 1} and c.end_reason == "every unit completed"


def test_a_round_timeout_closes_with_whoever_answered_and_drops_nobody() -> None:
    c = make(quorum=1.0, round_timeout=3.0)
    c.tick(0.0)
    step(c, "0", 1, 0, [1.0, 1.0], now=1.0)
    assert answers(c.tick(3.0)) == [(1, 0, [1.0, 1.0], ("0",))] and c.members == ("0", "1", "2")


def test_what_the_pace_rules_keep_survives_a_checkpoint() -> None:
    c = make()
    c.tick(0.0)
    step(c, "0", 1, 0, [1.0, 1.0], now=1.0)
    step(c, "1", 1, 0, [1.0, 1.0], now=1.0)
    c.tick(2.0)
    step(c, "0", 1, 1, [1.0, 1.0], now=2.0)
    step(c, "1", 1, 1, [1.0, 1.0], now=2.0)
    fields, tensors = chief_to_state(c)
    back = chief_from_state(fields, tensors, now=0.0)
    assert back.state.pace == c.state.pace and back.plan.max_staleness == c.plan.max_staleness
    assert back.state.pace.behind == {"2"} and back.state.pace.missed == {"2"}


def test_a_completion_counts_from_the_round_s_first_exchange_when_the_unit_misses_the_last() -> None:
    """Worker 2 completed and got into round 1's step 0 only (then it stalled): its completion is counted,
    and the run ends at the round's last exchange once every member has completed."""
    c = make()  # K = 2
    c.tick(0.0)
    for w in ("0", "1", "2"):
        c.receive(Message("parameters", RUN, w, 1, step=0, flat=np.ones(2, np.float32)), now=0.1)
    assert c.completed == {"0": 1, "1": 1, "2": 1} and c.end_reason is None  # not before the round's end
    for w in ("0", "1"):
        c.receive(Message("parameters", RUN, w, 1, step=1, flat=np.ones(2, np.float32)), now=0.2)
    assert c.end_reason is None
    (done,) = [m for m in c.tick(0.2 + GRACE_FLOOR).outgoing if m.type == "done"]
    assert c.end_reason == "every unit completed" and done.round == 1


def test_a_silent_member_that_missed_an_exchange_gets_no_grace_until_it_answers_again() -> None:
    """A participant paused whole: its first missed exchange costs one grace, the next ones none while it is
    silent; the exchange it gets into again makes it waited for (with its grace) once more. K = 4 here."""
    c = Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("0", "1", "2"),
            layout=LAYOUT,
            scheme="pergrad",
            steps_per_round=4,
            quorum=0.6,
            max_rounds=20,
        )
    )
    c.tick(0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [3.0, 3.0], now=0.1)
    assert c.state.pace.participants == {"0", "1", "2"} and c.state.pace.missed == set()
    # step 1: worker 2 stops answering; the quorum at 0.2, the grace (the floor) runs out at 0.45
    step(c, "0", 1, 1, [1.0, 1.0], now=0.15)
    step(c, "1", 1, 1, [3.0, 3.0], now=0.2)
    assert c.next_deadline() == pytest.approx(0.2 + GRACE_FLOOR)
    assert answers(c.tick(0.45)) == [(1, 1, [2.0, 2.0], ("0", "1"))]
    assert c.state.pace.missed == {"2"}
    # step 2: worker 2 missed the last exchange: not waited for, no grace — 0 and 1 close it at once
    step(c, "0", 1, 2, [1.0, 1.0], now=0.5)
    assert answers(step(c, "1", 1, 2, [5.0, 5.0], now=0.55)) == [(1, 2, [3.0, 3.0], ("0", "1"))]
    # step 3: back, worker 2 answers before the others close the exchange: it is in, and waited for again
    step(c, "2", 1, 3, [6.0, 6.0], now=0.6)
    step(c, "0", 1, 3, [0.0, 0.0], now=0.61)
    assert answers(step(c, "1", 1, 3, [0.0, 0.0], now=0.62)) == [(1, 3, [2.0, 2.0], ("0", "1", "2"))]
    assert c.state.pace.missed == set() and c.round == 2 and c.state.pace.behind == set()
    # round 2 step 0 waits for it with its grace as for anyone: 0 and 1 at 0.7, the floor until 0.95
    step(c, "0", 2, 0, [1.0, 1.0], now=0.65)
    step(c, "1", 2, 0, [1.0, 1.0], now=0.7)
    assert c.next_deadline() == pytest.approx(0.7 + GRACE_FLOOR)


def test_a_member_that_answers_late_is_not_silent_and_is_waited_for_again() -> None:
    """A unit that is only slow: its answer to the exchange it missed comes late, so the next one waits for it
    (with its grace) as before; a late answer of an older round says nothing of the open one."""
    c = Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("0", "1", "2"),
            layout=LAYOUT,
            scheme="pergrad",
            steps_per_round=4,
            quorum=0.6,
            max_rounds=20,
        )
    )
    c.tick(0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [3.0, 3.0], now=0.1)
    step(c, "0", 1, 1, [1.0, 1.0], now=0.15)
    step(c, "1", 1, 1, [3.0, 3.0], now=0.2)
    c.tick(0.45)  # step 1 closed without worker 2
    assert c.state.pace.missed == {"2"}
    step(c, "2", 1, 1, [9.0, 9.0], now=0.5)  # its answer to step 1, late: rejected, answered again
    assert c.state.pace.missed == set()
    step(c, "0", 1, 2, [1.0, 1.0], now=0.55)
    assert answers(step(c, "1", 1, 2, [1.0, 1.0], now=0.6)) == []  # waiting for worker 2: the grace
    assert c.next_deadline() == pytest.approx(0.6 + GRACE_FLOOR)
    assert answers(step(c, "2", 1, 2, [4.0, 4.0], now=0.65)) == [(1, 2, [2.0, 2.0], ("0", "1", "2"))]
    # missed again at step 3 (its grace runs out); a late answer of round 1 heard in round 2 does not count
    step(c, "0", 1, 3, [1.0, 1.0], now=0.7)
    step(c, "1", 1, 3, [1.0, 1.0], now=0.75)
    c.tick(0.75 + GRACE_FLOOR)
    assert c.round == 2 and c.state.pace.missed == {"2"}
    step(c, "2", 1, 3, [1.0, 1.0], now=1.1)
    assert c.state.pace.missed == {"2"}


def test_a_silent_member_that_missed_a_round_s_last_exchange_is_not_waited_for_at_the_next_s_first() -> None:
    c = make()  # K = 2
    c.tick(0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [1.0, 1.0], now=0.1)
    step(c, "0", 1, 1, [1.0, 1.0], now=0.2)
    step(c, "1", 1, 1, [1.0, 1.0], now=0.3)
    assert answers(c.tick(0.3 + GRACE_FLOOR)) != []  # worker 2 missed round 1's last exchange
    assert c.state.pace.behind == set() and c.state.pace.missed == {"2"}  # it took part in round 1
    step(c, "0", 2, 0, [1.0, 1.0], now=0.6)
    assert answers(step(c, "1", 2, 0, [3.0, 3.0], now=0.7)) == [(2, 0, [2.0, 2.0], ("0", "1"))]


def test_with_quorum_1_a_member_that_missed_an_exchange_is_still_waited_for() -> None:
    c = make(quorum=1.0, round_timeout=1.0)
    c.tick(0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [1.0, 1.0], now=0.1)
    step(c, "0", 1, 1, [1.0, 1.0], now=0.2)
    step(c, "1", 1, 1, [1.0, 1.0], now=0.3)
    assert answers(c.tick(1.1)) != []  # the round timeout closed step 1 without worker 2
    step(c, "0", 2, 0, [1.0, 1.0], now=1.2)
    assert answers(step(c, "1", 2, 0, [1.0, 1.0], now=1.3)) == []  # still waiting for worker 2
    assert answers(step(c, "2", 2, 0, [1.0, 1.0], now=1.4)) == [(2, 0, [1.0, 1.0], ("0", "1", "2"))]


def test_bad_staleness_bounds_are_refused() -> None:
    with pytest.raises(ValueError, match="max_staleness must be >= 0"):
        make(max_staleness=-1)


def join(c: Chief, sender: str, resumes_at: int, now: float) -> ChiefStep:
    """A new process of ``sender``: online, then its join naming the round it resumes at (0: none)."""
    online(c, sender, int(now * 1000), now)
    return c.receive(Message("join", RUN, sender, resumes_at), now=now)


def online(c: Chief, sender: str, incarnation: int, now: float) -> ChiefStep:
    payload = status_payload(b"online", run_id=RUN, node=sender, incarnation=incarnation)
    return c.status(sender, payload, now=now)


def test_a_process_that_will_not_replay_the_open_round_is_not_waited_for_in_its_later_steps() -> None:
    c = make()
    c.tick(0.0)
    online(c, "2", 1, now=0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [1.0, 1.0], now=0.1)
    assert c.state.step == 1 and c.state.pace.participants == {"0", "1", "2"}
    step(c, "0", 1, 1, [2.0, 2.0], now=0.2)
    step(c, "1", 1, 1, [4.0, 4.0], now=0.3)  # 2 of 3 waited for: the quorum, the grace starts
    # worker 2 restarted without a checkpoint (join round 0): the step closes with 0 and 1 at once
    assert answers(join(c, "2", 0, now=0.35)) == [(1, 1, [3.0, 3.0], ("0", "1"))]
    assert c.round == 2 and c.state.pace.behind == {"2"}  # it joins round 2's first exchange as behind
    # one resumed at the open round replays it: still waited for
    c = make()
    c.tick(0.0)
    online(c, "2", 1, now=0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [1.0, 1.0], now=0.1)
    step(c, "0", 1, 1, [2.0, 2.0], now=0.2)
    step(c, "1", 1, 1, [4.0, 4.0], now=0.3)
    assert answers(join(c, "2", 1, now=0.35)) == [] and "2" in c.state.pace.participants
    assert answers(step(c, "2", 1, 1, [6.0, 6.0], now=0.4)) == [(1, 1, [4.0, 4.0], ("0", "1", "2"))]

    # the retained join of a process this chief did not see restart (a resumed chief) changes nothing
    c = make()
    c.tick(0.0)
    for sender in ("0", "1", "2"):
        step(c, sender, 1, 0, [1.0, 1.0], now=0.1)
    c.receive(Message("join", RUN, "2", 0), now=0.2)
    assert "2" in c.state.pace.participants
