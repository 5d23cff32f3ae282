"""The chief's state survives a round trip through JSON + tensors and a restored chief behaves identically."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import chief_of

from fleetrl.federation.chief.checkpoint import chief_from_state, chief_to_state, replay_last_answer
from fleetrl.federation.chief.machine import Chief, ChiefStep
from fleetrl.federation.wire.messages import Message, Reason, encode
from fleetrl.federation.wire.signing import FleetKey, status_payload
from fleetrl.runs.checkpoints import ChiefCheckpoint

LAYOUT = [("w", (2,))]
RUN = "r1"
KEY = FleetKey(b"k" * 32)


def make(**kwargs: object) -> Chief:
    args: dict[str, object] = dict(
        run_id=RUN, workers=("1", "2", "3"), layout=LAYOUT, max_rounds=6, scheme="paper"
    )
    args.update(kwargs)
    return chief_of(Chief, **args)  # type: ignore[no-any-return]


def msg(sender: str, rnd: int, value: float, kind: str = "gradient") -> Message:
    return Message(kind, RUN, sender, rnd, flat=np.array([value, -value], np.float32))


def send(c: Chief, m: Message, now: float, key: FleetKey | None = None) -> ChiefStep:
    return c.receive_bytes(encode(m, layout=LAYOUT, key=key), topic_worker=m.sender, now=now)


def outgoing(step: ChiefStep) -> list[tuple[str, int, list[float] | None, tuple[str, ...]]]:
    return [(m.type, m.round, None if m.flat is None else m.flat.tolist(), m.finished) for m in step.outgoing]


def kinds(step: ChiefStep) -> list[str]:
    return [e.kind for e in step.events]


def roundtrip(c: Chief, now: float, key: FleetKey | None = None) -> Chief:
    fields, tensors = chief_to_state(c)
    fields = json.loads(json.dumps(fields))  # what the file holds
    return chief_from_state(fields, tensors, key=key, now=now)


Script = list[Callable[[Chief, float], ChiefStep]]


def script() -> Script:
    """Rounds 1-6: 2 sends parameters in round 3 (transfer), 3 goes offline and comes back in round 4."""
    steps: Script = []
    for rnd in range(1, 7):
        for w in ("1", "2", "3"):
            if w == "2" and rnd > 3:
                continue
            kind = "parameters" if (w, rnd) == ("2", 3) else "gradient"
            steps.append(lambda c, t, w=w, rnd=rnd, kind=kind: send(c, msg(w, rnd, rnd + int(w), kind), t))
        if rnd == 4:
            steps.append(
                lambda c, t: c.status(
                    "3", status_payload(b"offline", run_id=RUN, node="3", incarnation=5), now=0.0
                )
            )
            steps.append(
                lambda c, t: c.status(
                    "3", status_payload(b"online", run_id=RUN, node="3", incarnation=6), now=0.0
                )
            )
    return steps


def test_a_chief_restored_after_any_input_answers_exactly_like_the_original() -> None:
    """Cut after every input: answers of the open round are lost with the chief, and re-sent by workers."""
    steps = script()
    reference = make(dropout_grace=0.0)
    expected = [outgoing(step(reference, float(i))) for i, step in enumerate(steps)]
    assert reference.finished and reference.transfers == [(3, "2", ("1", "3"))] and reference.dropouts
    for cut in range(len(steps)):
        chief = make(dropout_grace=0.0)
        seen, accepted = [], []  # accepted: inputs of the open round, which the workers re-send after a crash
        for i, step in enumerate(steps[:cut]):
            done = step(chief, float(i))
            seen.append(outgoing(done))
            closed = {"averaged", "transfer"} & set(kinds(done))
            accepted = [] if closed else accepted + [step] * ("accepted" in kinds(done))
        chief = roundtrip(chief, now=float(cut))
        assert all(step(chief, float(cut)).outgoing == () for step in accepted)
        seen += [outgoing(step(chief, float(i))) for i, step in enumerate(steps[cut:], start=cut)]
        assert seen == expected, f"restored after input {cut}"
        assert (chief.transfers, chief.dropouts, chief.rejoins) == (
            reference.transfers, reference.dropouts, reference.rejoins,
        )  # fmt: skip


def test_a_restored_chief_answers_a_resend_at_once_and_replays_its_last_answer() -> None:
    chief = make()
    for w in ("1", "2", "3"):
        send(chief, msg(w, 1, float(w)), now=0.0)
    restored = roundtrip(chief, now=1000.0)
    assert restored.round == 2 and restored.rejections == chief.rejections
    again = send(restored, msg("3", 1, 3.0), now=1000.0)  # a worker that missed the answer re-sends
    assert [e.reason for e in again.events if e.kind == "rejected"] == [Reason.STALE_ROUND]
    (resent,) = again.outgoing
    assert resent.type == "average" and resent.round == 1 and resent.flat is not None
    np.testing.assert_allclose(resent.flat, [2.0, -2.0])
    (replayed,) = replay_last_answer(restored).outgoing
    assert replayed == resent and replay_last_answer(make()) == ChiefStep()


def test_the_fleet_key_must_be_given_back_exactly_when_the_run_was_signed() -> None:
    fields, tensors = chief_to_state(make(key=KEY))
    with pytest.raises(ValueError, match="with a fleet key"):
        chief_from_state(fields, tensors, now=0.0)
    assert chief_from_state(fields, tensors, key=KEY, now=0.0).key is KEY
    with pytest.raises(ValueError, match="without a fleet key"):
        chief_from_state(*chief_to_state(make()), key=KEY, now=0.0)


def test_the_checkpoint_file_refuses_other_settings(tmp_path: Path) -> None:
    store = ChiefCheckpoint(tmp_path)
    store.save(make())
    assert ChiefCheckpoint(tmp_path).load(now=0.0, expect=make()).round == 1
    with pytest.raises(ValueError, match="max_rounds: checkpoint 6, now 9"):
        ChiefCheckpoint(tmp_path).load(now=0.0, expect=make(max_rounds=9))
