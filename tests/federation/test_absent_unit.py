"""An absent unit in a federated run (runs.uneven around a worker's learner): while it pauses it sends
nothing, the fleet closes its rounds without it under a quorum, and it comes back and plays on."""

from __future__ import annotations

import threading
import time
from typing import Any

from fleetrl.runs.uneven import UnevenUnit
from fleetrl.transport.base import Transport
from fleetrl.transport.local import LocalBus


class RecordingTransport:
    """A transport that notes when each message was published."""

    def __init__(self, inner: Transport) -> None:
        self.inner = inner
        self.sent: list[float] = []

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        self.sent.append(time.monotonic())
        self.inner.publish(topic, payload, qos=qos, retain=retain)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def test_an_absent_unit_sends_nothing_while_away_and_comes_back(fleet_runner: Any, fake_learner: Any) -> None:
    # the deadline 40× a round, so a loaded machine does not drop a present unit (a 0.5 s deadline dropped
    # two in a loaded CI run); away for two deadlines
    rounds, round_seconds, away_rounds, deadline = 14, 0.05, 80, 2.0
    pauses: list[tuple[float, float]] = []

    def sleep(seconds: float) -> None:
        started = time.monotonic()
        time.sleep(seconds)
        pauses.append((started, time.monotonic()))

    learners: dict[str, Any] = {w: fake_learner(int(w), None, round_seconds) for w in ("1", "2", "3")}
    schedule = iter([0, 0, away_rounds] + [0] * rounds)  # away before its 4th round
    learners["3"] = UnevenUnit(learners["3"], absent_for=schedule, sleep=sleep)
    bus = LocalBus()
    recorders: dict[str, RecordingTransport] = {}
    lock = threading.Lock()

    def transport(role: str) -> Transport:
        with lock:
            recorders[role] = RecordingTransport(bus.client())
            return recorders[role]  # type: ignore[return-value]

    result = fleet_runner(
        bus.client,
        learners,
        max_rounds=rounds,
        role_transport=transport,
        chief_kwargs={"quorum": 0.6, "round_timeout": deadline},
    )
    assert len(pauses) == 1
    away_from, away_to = pauses[0]
    assert away_to - away_from >= away_rounds * round_seconds
    assert not [t for t in recorders["3"].sent if away_from <= t <= away_to]  # no message, no resend
    assert [t for t in recorders["3"].sent if t > away_to]  # it came back and spoke again
    averaged = [e for e in result.events if e.kind == "averaged"]
    assert any("3" not in e.averaged for e in averaged)  # rounds closed without it while it was away
    assert any("3" in e.averaged for e in averaged[-3:])  # and with it again after
    assert result.chief.end_reason == f"reached M={rounds} rounds" and result.chief.dropouts == ()
