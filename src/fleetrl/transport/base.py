"""The small interface every transport offers: bytes in, bytes out on MQTT-style topics; nothing about RL."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable


@dataclass(frozen=True)
class Will:
    """A last will: published by the broker (or bus) for a client that vanishes without closing."""

    topic: str
    payload: bytes
    qos: int = 1
    retain: bool = True


@dataclass(frozen=True)
class Received:
    """One message taken from a transport's receive queue."""

    topic: str
    payload: bytes
    retained: bool = False


@runtime_checkable
class Transport(Protocol):
    """A publish/subscribe client (``LocalTransport``, ``MqttTransport``): messages to subscribed topics are
    queued and taken with :meth:`receive`, from a single consumer thread."""

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        """Connect as ``client_id``; ConnectionError if not connected within ``timeout`` s (None: default)."""
        ...

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        """Send ``payload`` to ``topic`` (queued if briefly disconnected)."""
        ...

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        """Receive messages matching ``topic_filter`` (MQTT wildcards ``+`` and ``#``) from now on."""
        ...

    def receive(self, timeout: float | None = None) -> Received | None:
        """The next queued message, waiting at most ``timeout`` seconds (None: forever); None on timeout."""
        ...

    def announce(self, topic: str, payload: bytes) -> None:
        """Publish ``payload`` retained on ``topic`` now and again after every reconnect (``online``)."""
        ...

    def close(self) -> None:
        """Disconnect cleanly after sending what was published (the will is not published)."""
        ...


def topic_matches(topic_filter: str, topic: str) -> bool:
    """Whether ``topic`` matches the MQTT ``topic_filter`` (``+`` one level, ``#`` the rest)."""
    filt = topic_filter.split("/")
    parts = topic.split("/")
    for i, level in enumerate(filt):
        if level == "#":
            return True
        if i >= len(parts):
            return False
        if level != "+" and level != parts[i]:
            return False
    return len(filt) == len(parts)
