"""A unit's transport that stalls with the unit (``--stall``, :mod:`fleetrl.runs.uneven`): while the unit
is paused nothing leaves it and nothing reaches it; what it sends, what arrives and a receive's timeout all
wait for the pause's end, as for a stopped process. Innermost of a unit's transports; the client's keepalive
runs meanwhile and a last will is the broker's, so neither is held.
"""

from __future__ import annotations

from collections.abc import Callable

from fleetrl.transport.base import Received, Transport, Will


class StalledTransport:
    """``inner`` whose sends and receives wait out the unit's pauses.

    :param inner: the transport the messages go through
    :param wait: waits out the pause under way, if any (a stalling unit's
        :meth:`~fleetrl.runs.uneven.Stall.wait`, returning the seconds it waited); may be called from
        any thread
    """

    def __init__(self, inner: Transport, wait: Callable[[], float]) -> None:
        self.inner = inner
        self._wait = wait

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        """Connect ``inner`` once the unit is not paused."""
        self._wait()
        self.inner.connect(client_id, will=will, timeout=timeout)

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        """Send ``payload`` once the unit is not paused."""
        self._wait()
        self.inner.publish(topic, payload, qos=qos, retain=retain)

    def announce(self, topic: str, payload: bytes) -> None:
        """Announce ``payload`` once the unit is not paused."""
        self._wait()
        self.inner.announce(topic, payload)

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        """Subscribe once the unit is not paused."""
        self._wait()
        self.inner.subscribe(topic_filter, qos=qos)

    def receive(self, timeout: float | None = None) -> Received | None:
        """The next message ``inner`` received (None: ``timeout`` ran out), taken once the unit is not
        paused and handed over once it is not paused (a pause that began while it waited is waited out); a
        pause before it counts against ``timeout``."""
        waited = self._wait()
        received = self.inner.receive(None if timeout is None else max(0.0, timeout - waited))
        self._wait()
        return received

    def close(self) -> None:
        """Close ``inner`` (the unit's goodbye), once the unit is not paused."""
        self._wait()
        self.inner.close()
