"""A unit's transport that stalls with the unit (``--stall``, :mod:`fleetrl.runs.uneven`): while the unit is
paused nothing leaves it and nothing reaches it, as for a stopped process (the client's keepalive runs on)."""

from __future__ import annotations

from collections.abc import Callable

from fleetrl.transport.base import Received, Transport, Will


class StalledTransport:
    """``inner`` whose every call first waits out the unit's pause, if any (``wait``: a stalling unit's
    :meth:`~fleetrl.runs.uneven.Stall.wait`, returning the seconds it waited; callable from any thread)."""

    def __init__(self, inner: Transport, wait: Callable[[], float]) -> None:
        self.inner = inner
        self._wait = wait

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        self._wait()
        self.inner.connect(client_id, will=will, timeout=timeout)

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        self._wait()
        self.inner.publish(topic, payload, qos=qos, retain=retain)

    def announce(self, topic: str, payload: bytes) -> None:
        self._wait()
        self.inner.announce(topic, payload)

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        self._wait()
        self.inner.subscribe(topic_filter, qos=qos)

    def receive(self, timeout: float | None = None) -> Received | None:
        """The next message (None: ``timeout`` ran out), taken and handed over outside a pause; a pause before
        it counts against ``timeout``."""
        waited = self._wait()
        received = self.inner.receive(None if timeout is None else max(0.0, timeout - waited))
        self._wait()
        return received

    def close(self) -> None:
        self._wait()
        self.inner.close()
