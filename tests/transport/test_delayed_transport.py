"""A delayed uplink: every message sent arrives a delay later, in the order sent; the sender does not wait;
what it receives is not delayed; closing lets the messages in flight arrive first."""

from __future__ import annotations

import time

import pytest

from fleetrl.transport.delayed import DelayedTransport
from fleetrl.transport.local import LocalBus

DELAY = 0.15


def test_messages_arrive_a_delay_later_in_order_and_the_sender_does_not_wait() -> None:
    bus = LocalBus()
    listener = bus.client()
    listener.connect("listener")
    listener.subscribe("up/#")
    sender = DelayedTransport(bus.client(), DELAY)
    sender.connect("slow-unit")
    started = time.monotonic()
    for k in range(5):
        sender.publish(f"up/{k}", str(k).encode())
    sender.announce("up/status", b"online")
    assert time.monotonic() - started < DELAY / 2  # six messages sent, none waited for
    arrived, waited = [], []
    for _ in range(6):
        arrived.append(listener.receive(timeout=5))
        waited.append(time.monotonic() - started)
    assert [m.topic for m in arrived if m is not None] == [f"up/{k}" for k in range(5)] + ["up/status"]
    assert min(waited) >= DELAY  # none arrived before its delay (however late a loaded machine woke us)
    sender.close()


def test_received_messages_are_not_delayed_and_close_delivers_what_is_in_flight() -> None:
    bus = LocalBus()
    other = bus.client()
    other.connect("other")
    other.subscribe("up/#")
    unit = DelayedTransport(bus.client(), DELAY)
    unit.connect("unit")
    unit.subscribe("down/#")
    started = time.monotonic()
    other.publish("down/x", b"now")
    received = unit.receive(timeout=5)
    assert received is not None and received.payload == b"now"
    assert time.monotonic() - started < DELAY / 2
    unit.publish("up/last", b"bye")
    unit.close()  # returns once the message in flight has left
    assert time.monotonic() - started >= DELAY
    last = other.receive(timeout=0)
    assert last is not None and last.topic == "up/last"


def test_a_negative_delay_and_sending_before_connect_are_refused() -> None:
    with pytest.raises(ValueError, match="≥ 0"):
        DelayedTransport(LocalBus().client(), -0.1)
    with pytest.raises(ConnectionError):
        DelayedTransport(LocalBus().client(), 0.1).publish("t", b"x")
