"""A slow uplink, simulated: every message a client sends reaches the transport a fixed delay after it was
sent, in order, without blocking the sender; what it receives (and its will, the broker's) is not delayed."""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable

from fleetrl.transport.base import Received, Transport, Will

log = logging.getLogger(__name__)

Send = Callable[[], None]


class DelayedTransport:
    """``inner`` with ``delay`` seconds (≥ 0) added to every message published or announced through it, by one
    sender thread started at :meth:`connect`; :meth:`close` first lets every message in flight arrive."""

    def __init__(
        self, inner: Transport, delay: float, *, clock: Callable[[], float] = time.monotonic
    ) -> None:
        if not delay >= 0:
            raise ValueError(f"a link delay must be ≥ 0 seconds, got {delay!r}")
        self.inner = inner
        self.delay = delay
        self._clock = clock
        self._in_flight: queue.Queue[tuple[float, Send] | None] = queue.Queue()
        self._sender: threading.Thread | None = None

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        """Connect ``inner`` and start the sender."""
        self.inner.connect(client_id, will=will, timeout=timeout)
        if self._sender is None:
            self._sender = threading.Thread(target=self._send_loop, name=f"{client_id}-uplink", daemon=True)
            self._sender.start()

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        """Send ``payload``: it reaches ``inner`` ``delay`` seconds from now."""
        self._send(lambda: self.inner.publish(topic, payload, qos=qos, retain=retain))

    def announce(self, topic: str, payload: bytes) -> None:
        self._send(lambda: self.inner.announce(topic, payload))

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        """Subscribe at once (a request, not a message the unit sends)."""
        self.inner.subscribe(topic_filter, qos=qos)

    def receive(self, timeout: float | None = None) -> Received | None:
        return self.inner.receive(timeout)

    def close(self) -> None:
        """Let every message in flight arrive, then close ``inner``."""
        if self._sender is not None:
            self._in_flight.put(None)
            self._sender.join()
            self._sender = None
        self.inner.close()

    def _send(self, send: Send) -> None:
        if self._sender is None:
            raise ConnectionError("publish before connect")
        self._in_flight.put((self._clock() + self.delay, send))

    def _send_loop(self) -> None:
        while (item := self._in_flight.get()) is not None:
            due, send = item
            wait = due - self._clock()
            if wait > 0:
                time.sleep(wait)
            try:
                send()
            except Exception as err:  # a message lost on the way, as on a real link; the worker resends
                log.warning("delayed uplink: a message could not be sent: %s", err)
