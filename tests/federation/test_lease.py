"""The lease and epoch rules without a broker (issue 42): status fields under the signature, the epoch a
starting chief takes, who supersedes whom, a chief deposed by a worker message of a newer epoch, a worker
that ignores an older chief."""

from __future__ import annotations

import numpy as np
import pytest

from fleetrl.federation.chief.lease import chief_epoch, place_refusal, supersedes
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.messages import Message, MessageRejected, decode, encode
from fleetrl.federation.wire.signing import FleetKey, Status, parse_status, status_payload

LAYOUT = [("w", (2,))]
KEY = FleetKey(b"k" * 32)


def test_status_fields_round_trip_and_are_signed() -> None:
    fields = {"epoch": 3, "pid": 12, "host": "h-1.lan", "keepalive": 2}
    payload = status_payload(b"online", run_id="r", node="chief", incarnation=7, key=KEY, fields=fields)
    status = parse_status(payload, run_id="r", node="chief", key=KEY)
    assert (status.state, status.incarnation, status.number("epoch"), status.fields["host"]) == (
        "online",
        7,
        3,
        "h-1.lan",
    )
    forged = payload.replace(b"epoch=3", b"epoch=9")
    with pytest.raises(MessageRejected, match="bad signature"):
        parse_status(forged, run_id="r", node="chief", key=KEY)
    plain = status_payload(b"offline", run_id="r", node="0", incarnation=5, key=KEY)  # no fields: the old tag
    assert plain.count(b" ") == 2 and parse_status(plain, run_id="r", node="0", key=KEY).fields == {}


def test_the_epoch_a_chief_takes_and_who_supersedes_whom() -> None:
    assert chief_epoch(checkpoint=None, retained=None) == 0
    assert chief_epoch(checkpoint=0, retained=None) == 1
    assert chief_epoch(checkpoint=1, retained=Status("offline", 5, {"epoch": "4"})) == 5
    assert chief_epoch(checkpoint=None, retained=Status("ended", 5)) == 1  # a run id used again
    newer = Status("online", 20, {"epoch": "2"})
    assert supersedes(newer, epoch=1, incarnation=10)
    assert not supersedes(Status("online", 5, {"epoch": "0"}), epoch=1, incarnation=10)
    assert supersedes(Status("online", 20, {"epoch": "1"}), epoch=1, incarnation=10)  # same epoch, later
    assert not supersedes(Status("offline", 10, {"epoch": "1"}), epoch=1, incarnation=10)  # its own will


def test_only_an_online_status_holds_a_place() -> None:
    topic = "fleetrl/r/status/chief"
    assert place_refusal("r", "chief", None, topic) is None
    assert place_refusal("r", "chief", Status("offline", 1), topic) is None
    line = place_refusal(
        "r", "chief", Status("online", 1, {"pid": "9", "host": "h", "keepalive": "2"}), topic
    )
    assert line is not None and "pid 9 on host h" in line and "lease (3 s" in line and "\n" not in line


def _chief() -> Chief:
    return Chief(ChiefPlan(run_id="r", workers=["0"], layout=LAYOUT, max_rounds=3, scheme="paper"))


def test_a_worker_message_of_a_newer_epoch_deposes_the_chief_and_changes_nothing() -> None:
    chief = _chief()
    older = Message("gradient", "r", "0", 1, flat=np.ones(2, np.float32), epoch=0)
    newer = Message("gradient", "r", "0", 1, flat=np.ones(2, np.float32), epoch=1)
    chief.take_epoch(1)
    assert chief.superseded is None and chief.receive(older, now=0.0).outgoing  # older stamps are taken
    chief = _chief()
    step = chief.receive(newer, now=0.0)
    assert step.outgoing == () and chief.round == 1 and chief.superseded is not None
    assert [e.kind for e in step.events] == ["deposed"]


def test_the_epoch_is_on_the_wire() -> None:
    message = Message("average", "r", "chief", 2, flat=np.ones(2, np.float32), epoch=4)
    decoded = decode(encode(message, layout=LAYOUT), run_id="r", known_senders=("chief",), layout=LAYOUT)
    assert decoded.epoch == 4
