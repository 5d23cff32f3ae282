"""MqttTransport through real brokers: mosquitto (child process) and amqtt (embedded)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import pytest

from fleetrl.transport.base import Transport, Will
from fleetrl.transport.broker import EmbeddedBroker, SnapshotSubscriptions, free_port, mqtt_ready
from fleetrl.transport.mqtt import BrokerAddress, MqttTransport


def client(url: str, client_id: str, will: Will | None = None) -> MqttTransport:
    transport = MqttTransport(url, reconnect_delay=(1, 2))
    transport.connect(client_id, will=will, timeout=10)
    return transport


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("mqtt://localhost", BrokerAddress("localhost", 1883)),
        ("mqtt://10.0.0.5:1884", BrokerAddress("10.0.0.5", 1884)),
        ("mqtts://broker.lan", BrokerAddress("broker.lan", 8883, tls=True)),
        ("mqtt://fleet:s%40cret@h:1", BrokerAddress("h", 1, username="fleet", password="s@cret")),
    ],
)
def test_url_parsing(url: str, expected: BrokerAddress) -> None:
    assert BrokerAddress.parse(url) == expected
    assert "cret" not in BrokerAddress.parse(url).url


@pytest.mark.parametrize("url", ["http://h:1", "mqtt://", "mqtt://h:99999", "h:1883"])
def test_bad_urls_are_refused(url: str) -> None:
    with pytest.raises(ValueError, match="bad broker URL"):
        BrokerAddress.parse(url)


def test_connect_to_nothing_fails_with_a_clear_error() -> None:
    with pytest.raises(ConnectionError, match="cannot reach the broker"):
        MqttTransport(f"mqtt://127.0.0.1:{free_port()}").connect("x", timeout=0.5)


@pytest.mark.mqtt
def test_publish_subscribe_round_trip(broker: EmbeddedBroker) -> None:
    a, b = client(broker.url, "rt-a"), client(broker.url, "rt-b")
    try:
        assert isinstance(a, Transport)
        for end in (a, b):  # Nagle would stall every QoS 1 round trip by 40+ ms
            sock = end._client.socket() if end._client else None
            assert isinstance(sock, socket.socket)
            assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
        b.subscribe("rt/+/x")
        time.sleep(0.2)  # SUBACK before another client's publish
        payload = bytes(range(256)) * 600  # ~150 KB, the size of a real gradient
        a.publish("rt/1/x", payload)
        got = b.receive(5)
        assert got is not None and (got.topic, got.payload) == ("rt/1/x", payload)
    finally:
        a.close()
        b.close()


@pytest.mark.mqtt
def test_retained_status_reaches_a_late_subscriber(broker: EmbeddedBroker) -> None:
    a = client(broker.url, "ret-a")
    a.publish("ret/status/chief", b"online", retain=True)
    a.close()
    late = client(broker.url, "ret-late")
    try:
        late.subscribe("ret/status/+")
        got = late.receive(5)
        assert got is not None and (got.payload, got.retained) == (b"online", True)
    finally:
        late.close()


@pytest.mark.mqtt
def test_a_retained_message_reaches_only_its_subscribers(broker: EmbeddedBroker) -> None:
    # amqtt 0.12.1 handed every connecting client the retained messages of every client's subscriptions
    owner = client(broker.url, "own-a")
    other = None
    try:
        owner.subscribe("own/a")
        owner.publish("own/a", b"for a only", retain=True)
        got = owner.receive(5)
        assert got is not None and got.payload == b"for a only"
        other = client(broker.url, "own-b")
        other.subscribe("own/b")
        assert other.receive(1.0) is None
    finally:
        owner.close()
        if other is not None:
            other.close()


def test_amqtt_subscriptions_loop_over_a_snapshot() -> None:
    subscriptions = SnapshotSubscriptions({"a": [], "b": []})
    seen = []
    for topic in subscriptions:  # a SUBSCRIBE and a disconnect while amqtt loops (across an await)
        seen.append(topic)
        subscriptions["c"] = []
        subscriptions.pop("b", None)
    for topic, _subscribers in subscriptions.items():
        subscriptions[topic + "+"] = []
    assert seen == ["a", "b"]
    assert set(subscriptions) == {"a", "c", "a+", "c+"}
    assert subscriptions.get("a") == [] and "b" not in subscriptions


DYING_CLIENT = """
import sys, time
from fleetrl.transport.base import Will
from fleetrl.transport.mqtt import MqttTransport
t = MqttTransport(sys.argv[1])
t.connect("dying-worker", will=Will("will/status/dying-worker", b"offline"))
t.publish("will/status/dying-worker", b"online", retain=True)
print("ready", flush=True)
time.sleep(60)
"""


@pytest.mark.mqtt
def test_last_will_is_delivered_as_offline_when_a_client_dies(broker: EmbeddedBroker) -> None:
    watcher = client(broker.url, "will-watcher")
    proc = subprocess.Popen([sys.executable, "-c", DYING_CLIENT, broker.url], stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
        watcher.subscribe("will/status/+")
        got = watcher.receive(5)
        assert got is not None and got.payload == b"online"
        os.kill(proc.pid, signal.SIGKILL)
        while got is not None and got.payload == b"online":  # the live copy may follow the retained one
            got = watcher.receive(10)
        assert got is not None and (got.topic, got.payload) == ("will/status/dying-worker", b"offline")
    finally:
        proc.kill()
        proc.wait()
        watcher.close()


@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_client_reconnects_and_resubscribes_after_a_broker_restart() -> None:
    port = free_port()
    first = EmbeddedBroker("mosquitto", port=port).start()
    sub = client(first.url, "rc-sub")
    try:
        sub.subscribe("rc/t")
        first.close()
        assert not mqtt_ready("127.0.0.1", port, timeout=0.2)
        with EmbeddedBroker("mosquitto", port=port) as second:
            pub = client(second.url, "rc-pub")
            deadline = time.monotonic() + 15
            got = None
            while got is None and time.monotonic() < deadline:  # the subscriber comes back with backoff
                pub.publish("rc/t", b"again")
                got = sub.receive(0.5)
            pub.close()
            assert got is not None and got.payload == b"again"
    finally:
        sub.close(flush_timeout=0.5)


@pytest.mark.mqtt
def test_embedded_broker_listens_on_loopback_only(broker: EmbeddedBroker) -> None:
    assert broker.url.startswith("mqtt://127.0.0.1:")
    assert mqtt_ready("127.0.0.1", broker.port)


def test_unknown_broker_kind_is_refused() -> None:
    with pytest.raises(ValueError, match="choose auto, mosquitto or amqtt"):
        EmbeddedBroker("rabbit")
