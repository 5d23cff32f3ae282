"""A unit new to the fleet joins a running run (:class:`fleetrl.federation.chief.answer.Roster`,
docs/protocol.md "A new unit joins"): the chief's state machine, fed bytes as the broker delivers them."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.chief.answer import Roster
from fleetrl.federation.chief.checkpoint import chief_from_state, chief_to_state
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.shared_settings import shared_text
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import status_payload
from fleetrl.runs.settings import LearningSettings

RUN = "fleet"
LAYOUT = [("w", (2,))]
SETTINGS = dict(env="qube", fleet_seed=0, preset="standard", scheme="paper", target_score=2450.0)


def chief(*, open_fleet: bool = True, scheme: str = "paper", steps: int = 1) -> Chief:
    return Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("0", "1"),
            layout=LAYOUT,
            max_rounds=5,
            scheme=scheme,
            open_fleet=open_fleet,
            settings=shared_text(LearningSettings(**{**SETTINGS, "scheme": scheme})),
            steps_per_round=steps,
        )
    )


def join(worker: str, **changes: object) -> bytes:
    settings = shared_text(LearningSettings(**{**SETTINGS, **changes}))  # type: ignore[arg-type]
    return encode(Message("join", RUN, worker, 1, settings=settings), layout=LAYOUT)


def gradient(worker: str, value: float, rnd: int = 1, kind: str = "gradient", step: int = 0) -> bytes:
    flat = np.full(2, value, np.float32)
    return encode(Message(kind, RUN, worker, rnd, flat=flat, step=step), layout=LAYOUT)


def online(worker: str) -> bytes:
    return status_payload(b"online", run_id=RUN, node=worker, incarnation=1)


def test_a_new_unit_s_matching_join_puts_it_in_w_and_welcomes_it_with_the_fleet_s_model() -> None:
    c = chief(scheme="fedavg")  # its average is the fleet's model
    c.receive_bytes(gradient("0", 1.0, kind="model"), topic_worker="0", now=0.0)
    c.receive_bytes(gradient("1", 3.0, kind="model"), topic_worker="1", now=0.0)  # round 1: (2, 2)
    assert c.status("7", online("7"), now=0.5).events == ()  # its online before its join: nothing yet
    step = c.receive_bytes(join("7", scheme="fedavg"), topic_worker="7", now=1.0)
    assert [(e.kind, e.sender) for e in step.events] == [("admitted", "7"), ("welcome", "7")]
    (welcome,) = step.outgoing
    assert welcome.type == "welcome" and welcome.round == 2
    assert welcome.flat is not None and np.array_equal(welcome.flat, [2.0, 2.0])  # the fleet's average
    assert c.members == ("0", "1", "7") and c.all_workers == ("0", "1", "7")
    c.receive_bytes(gradient("0", 1.0, rnd=2, kind="model"), topic_worker="0", now=2.0)
    c.receive_bytes(gradient("1", 1.0, rnd=2, kind="model"), topic_worker="1", now=2.0)
    assert c.round == 2  # round 2 waits for the new unit as for every member of W
    closed = c.receive_bytes(gradient("7", 4.0, rnd=2, kind="model"), topic_worker="7", now=2.0)
    (average,) = closed.outgoing
    assert average.contributors == ("0", "1", "7") and np.array_equal(average.flat, [2.0, 2.0])


def test_a_new_unit_is_heard_only_after_its_join_and_only_if_its_settings_match() -> None:
    c = chief()
    early = c.receive_bytes(gradient("7", 1.0), topic_worker="7", now=0.0)
    reasons = [(e.reason, e.detail) for e in early.events]
    assert reasons == [(Reason.UNKNOWN_SENDER, "gradient before its join")]
    refused = c.receive_bytes(join("8", preset="paper"), topic_worker="8", now=0.0)
    assert [m.type for m in refused.outgoing] == ["refused"] and "8" not in c.all_workers
    assert c.members == ("0", "1")


def test_a_closed_fleet_takes_only_its_own_workers() -> None:
    c = chief(open_fleet=False)
    step = c.receive_bytes(join("7"), topic_worker="7", now=0.0)
    assert [e.reason for e in step.events] == [Reason.UNKNOWN_SENDER] and step.outgoing == ()
    assert [e.reason for e in c.status("7", online("7"), now=0.0).events] == [Reason.UNKNOWN_SENDER]
    assert c.all_workers == ("0", "1")


def test_an_admitted_unit_survives_the_chief_s_checkpoint() -> None:
    c = chief()
    c.receive_bytes(join("7"), topic_worker="7", now=0.0)
    restored = chief_from_state(*chief_to_state(c), now=5.0)
    assert restored.all_workers == ("0", "1", "7") and restored.members == ("0", "1", "7")
    assert restored.roster.open_fleet
    closed = chief_from_state(*chief_to_state(chief(open_fleet=False)), now=5.0)
    assert not closed.roster.open_fleet


def test_under_a_per_step_scheme_the_open_exchange_does_not_wait_for_a_unit_that_just_joined() -> None:
    c = chief(scheme="pergrad", steps=2)
    c.receive_bytes(join("7", scheme="pergrad"), topic_worker="7", now=0.0)
    assert "7" in c.state.pace.behind
    c.receive_bytes(gradient("0", 1.0, kind="step_gradient"), topic_worker="0", now=0.1)
    step = c.receive_bytes(gradient("1", 3.0, kind="step_gradient"), topic_worker="1", now=0.1)
    (answer,) = step.outgoing
    assert answer.contributors == ("0", "1") and c.state.step == 1


@pytest.mark.parametrize("bad", ["chief", "", "a/b", "x" * 65])
def test_the_roster_admits_only_valid_new_ids(bad: str) -> None:
    roster = Roster(["0"])
    assert bad not in roster and not roster.may_join(bad)
    with pytest.raises(ValueError, match="cannot join"):
        roster.admit(bad)
    roster.admit("12")
    assert roster.workers == ("0", "12") and "12" in roster and not roster.may_join("12")
