"""An in-process publish/subscribe bus for runs whose roles are threads: immediate delivery in publish
order, retained messages and last wills as on a broker, thread-safe and deterministic."""

from __future__ import annotations

import queue
import threading

from fleetrl.transport.base import Received, Will, topic_matches


class LocalBus:
    """The shared hub (the broker's role). Create one per run and give each role a :meth:`client`."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._clients: dict[str, LocalTransport] = {}
        self._retained: dict[str, bytes] = {}

    def client(self) -> LocalTransport:
        """A new, unconnected transport on this bus."""
        return LocalTransport(self)

    def _attach(self, client_id: str, client: LocalTransport) -> None:
        with self._lock:
            old = self._clients.get(client_id)
            self._clients[client_id] = client
        if old is not None and old is not client:  # MQTT: a second connect with the same id takes over
            old._detach(publish_will=True)

    def _detach(self, client_id: str, client: LocalTransport, will: Will | None) -> None:
        with self._lock:
            if self._clients.get(client_id) is client:
                del self._clients[client_id]
        if will is not None:
            self.publish(will.topic, will.payload, retain=will.retain)

    def _subscribed(self, client: LocalTransport, topic_filter: str) -> None:
        with self._lock:
            retained = [(t, p) for t, p in self._retained.items() if topic_matches(topic_filter, t)]
        for topic, payload in sorted(retained):
            client._deliver(Received(topic, payload, retained=True))

    def publish(self, topic: str, payload: bytes, *, retain: bool = False) -> None:
        """Deliver ``payload`` to every client subscribed to ``topic`` (and keep it if ``retain``)."""
        payload = bytes(payload)
        with self._lock:
            if retain:
                if payload:
                    self._retained[topic] = payload
                else:
                    self._retained.pop(topic, None)  # MQTT: an empty retained message clears the topic
            targets = [c for c in self._clients.values() if c._wants(topic)]
        for client in targets:
            client._deliver(Received(topic, payload))


class LocalTransport:
    """A :class:`~fleetrl.transport.base.Transport` on a :class:`LocalBus`."""

    def __init__(self, bus: LocalBus) -> None:
        self._bus = bus
        self._queue: queue.Queue[Received] = queue.Queue()
        self._filters: list[str] = []
        self._filters_lock = threading.Lock()
        self._client_id: str | None = None
        self._will: Will | None = None

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        self._client_id = client_id
        self._will = will
        self._bus._attach(client_id, self)

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        """Publish on the bus (delivery is always exactly once, whatever ``qos``)."""
        if self._client_id is None:
            raise ConnectionError("publish before connect")
        self._bus.publish(topic, payload, retain=retain)

    def announce(self, topic: str, payload: bytes) -> None:
        """Publish retained (the bus never drops a client: no reconnect to repeat it after)."""
        self.publish(topic, payload, retain=True)

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        """Receive messages matching ``topic_filter``; retained ones are delivered at once."""
        if self._client_id is None:
            raise ConnectionError("subscribe before connect")
        with self._filters_lock:
            self._filters.append(topic_filter)
        self._bus._subscribed(self, topic_filter)

    def receive(self, timeout: float | None = None) -> Received | None:
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def close(self) -> None:
        self._detach(publish_will=False)

    def abort(self) -> None:
        """Leave the bus as if the process died: the last will is published."""
        self._detach(publish_will=True)

    def _detach(self, *, publish_will: bool) -> None:
        if self._client_id is None:
            return
        client_id, self._client_id = self._client_id, None
        with self._filters_lock:
            self._filters.clear()
        self._bus._detach(client_id, self, self._will if publish_will else None)

    def _wants(self, topic: str) -> bool:
        with self._filters_lock:
            return any(topic_matches(f, topic) for f in self._filters)

    def _deliver(self, message: Received) -> None:
        self._queue.put(message)
