"""The in-process bus: MQTT-like delivery, wildcards, retained messages and last wills."""

from __future__ import annotations

import threading

import pytest

from fleetrl.transport.base import Transport, Will, topic_matches
from fleetrl.transport.local import LocalBus, LocalTransport


@pytest.mark.parametrize(
    ("topic_filter", "topic", "matches"),
    [
        ("a/b", "a/b", True),
        ("a/+", "a/b", True),
        ("a/+", "a/b/c", False),
        ("a/#", "a/b/c", True),
        ("a/#", "a", True),
        ("+/+/worker/+", "fleetrl/r/worker/3", True),
        ("fleetrl/r/worker/+", "fleetrl/r2/worker/3", False),
        ("a/b", "a/b/c", False),
        ("a/b/c", "a/b", False),
    ],
)
def test_topic_filters(topic_filter: str, topic: str, matches: bool) -> None:
    assert topic_matches(topic_filter, topic) is matches


def connected(bus: LocalBus, client_id: str, will: Will | None = None) -> LocalTransport:
    client = bus.client()
    client.connect(client_id, will=will)
    return client


def test_publish_subscribe_round_trip_in_order() -> None:
    bus = LocalBus()
    a, b = connected(bus, "a"), connected(bus, "b")
    assert isinstance(a, Transport)
    b.subscribe("t/+")
    for i in range(5):
        a.publish(f"t/{i}", bytes([i]))
    got = [b.receive(1) for _ in range(5)]
    assert [(r.topic, r.payload) for r in got if r] == [(f"t/{i}", bytes([i])) for i in range(5)]
    assert b.receive(0.01) is None
    assert a.receive(0.01) is None  # not subscribed


def test_retained_message_is_delivered_on_subscribe_and_cleared_by_empty_payload() -> None:
    bus = LocalBus()
    a = connected(bus, "a")
    a.publish("s/chief", b"online", retain=True)
    late = connected(bus, "late")
    late.subscribe("s/#")
    got = late.receive(1)
    assert got is not None and (got.payload, got.retained) == (b"online", True)
    a.publish("s/chief", b"", retain=True)
    later = connected(bus, "later")
    later.subscribe("s/#")
    assert later.receive(0.01) is None


def test_will_is_published_when_a_client_dies_not_when_it_closes() -> None:
    bus = LocalBus()
    watcher = connected(bus, "w")
    watcher.subscribe("status/+")
    clean = connected(bus, "clean", Will("status/clean", b"offline"))
    dying = connected(bus, "dying", Will("status/dying", b"offline"))
    clean.close()
    dying.abort()
    got = watcher.receive(1)
    assert got is not None and (got.topic, got.payload) == ("status/dying", b"offline")
    assert watcher.receive(0.01) is None


def test_use_before_connect_is_an_error() -> None:
    with pytest.raises(ConnectionError):
        LocalBus().client().publish("t", b"x")


def test_many_threads_publish_without_loss() -> None:
    bus = LocalBus()
    sink = connected(bus, "sink")
    sink.subscribe("t/#")
    senders = [connected(bus, f"s{i}") for i in range(4)]

    def send(client: LocalTransport, i: int) -> None:
        for k in range(200):
            client.publish(f"t/{i}", k.to_bytes(2, "big"))

    threads = [threading.Thread(target=send, args=(c, i)) for i, c in enumerate(senders)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    received = [sink.receive(1) for _ in range(800)]
    per_sender: dict[str, list[int]] = {}
    for r in received:
        assert r is not None
        per_sender.setdefault(r.topic, []).append(int.from_bytes(r.payload, "big"))
    assert all(v == list(range(200)) for v in per_sender.values()) and len(per_sender) == 4
