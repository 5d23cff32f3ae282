"""End to end: chief and three workers (fake learner) over the local bus and over MQTT, identical results."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from fleetrl.federation.wire.messages import Reason
from fleetrl.transport.base import Transport
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

Runner = Callable[..., Any]
Fleet = Callable[..., dict[str, Any]]

EXPECTED_EVENTS = {
    "1": ["gradient"] * 3 + ["transfer_in from 2", "gradient", "gradient", "transfer_out"],
    "2": ["gradient"] * 3 + ["transfer_out"],
    "3": ["gradient"] * 3
    + ["transfer_in from 2", "gradient", "gradient", "transfer_in from 1"]
    + ["gradient"] * 3,
}


def run_local(fleet_runner: Runner, fake_fleet: Fleet) -> Any:
    bus = LocalBus()
    return fleet_runner(bus.client, fake_fleet(), max_rounds=10)


def test_local_run_follows_algorithms_1_and_2(fleet_runner: Runner, fake_fleet: Fleet) -> None:
    result = run_local(fleet_runner, fake_fleet)
    assert {w: [r.event.describe(r.peer) for r in rs] for w, rs in result.records.items()} == EXPECTED_EVENTS
    assert result.chief.transfers == ((4, "2", ("1", "3")), (7, "1", ("3",)))
    assert result.chief.end_reason == "reached M=10 rounds" and result.chief.rounds == 10
    assert result.chief.rejections == {}
    assert result.workers["2"].finished and result.workers["1"].finished and not result.workers["3"].finished
    # after a transfer, the receiver plays with the sender's parameters: its score jumps to the sender's
    scores = result.scores()
    assert scores["1"][4] != scores["1"][3]
    kinds = [e.kind for e in result.events if e.kind != "accepted"]
    assert kinds.count("averaged") == 8 and kinds.count("transfer") == 2 and kinds[-1] == "run_ended"


def test_local_run_is_reproducible(fleet_runner: Runner, fake_fleet: Fleet) -> None:
    assert run_local(fleet_runner, fake_fleet).scores() == run_local(fleet_runner, fake_fleet).scores()


def test_run_ends_when_every_worker_has_transferred(fleet_runner: Runner, fake_learner: Any) -> None:
    learners = {"1": fake_learner(1, 3), "2": fake_learner(2, 3)}
    result = fleet_runner(LocalBus().client, learners, max_rounds=50)
    assert result.chief.end_reason == "W is empty" and result.chief.rounds == 3
    assert [r.event for r in result.records["1"]][-1] == "transfer_out"
    assert [r.event for r in result.records["2"]][-1] == "finished"  # 1's parameters were the ones forwarded
    assert result.records["2"][-1].peer == "1"


@pytest.mark.mqtt
def test_mqtt_run_gives_the_same_results_as_the_local_bus(
    fleet_runner: Runner, fake_fleet: Fleet, broker: EmbeddedBroker
) -> None:
    local = run_local(fleet_runner, fake_fleet)

    def make() -> Transport:
        return MqttTransport(broker.url)

    remote = fleet_runner(make, fake_fleet(), run_id=f"e2e-{broker.kind}", max_rounds=10)
    assert remote.records == {w: rs for w, rs in local.records.items()}
    assert remote.chief.transfers == local.chief.transfers
    # nothing refused but copies: a worker re-sends a round's message after 5 s without an answer (a loaded
    # machine), and the chief drops the copy of a message it has (at-least-once delivery is harmless)
    assert set(remote.chief.rejections) <= {Reason.DUPLICATE}


@pytest.mark.mqtt
def test_a_hostile_client_does_not_disturb_a_live_run(fleet_runner: Runner, fake_fleet: Fleet) -> None:
    """Junk published on worker topics during a run is rejected and the run gives the local results."""
    import threading

    from fleetrl.federation.wire.topics import worker_topic

    local = run_local(fleet_runner, fake_fleet)
    with EmbeddedBroker("auto") as broker:
        stop = threading.Event()

        def spam() -> None:
            intruder = MqttTransport(broker.url)
            intruder.connect("intruder")
            blobs = [b"\xc1junk", b"\x00" * 200_000, b"\x81\xa7version\x7f"]
            i = 0
            while not stop.is_set():
                intruder.publish(worker_topic("hostile", str(1 + i % 3)), blobs[i % 3])
                i += 1
                stop.wait(0.005)
            intruder.close()

        spammer = threading.Thread(target=spam)
        spammer.start()
        try:
            remote = fleet_runner(
                lambda: MqttTransport(broker.url), fake_fleet(pause=0.03), run_id="hostile", max_rounds=10
            )
        finally:
            stop.set()
            spammer.join()
    assert remote.records == local.records
    assert set(remote.chief.rejections) <= {Reason.NOT_MSGPACK, Reason.OVERSIZED, Reason.WRONG_VERSION}
    assert sum(remote.chief.rejections.values()) >= 10
