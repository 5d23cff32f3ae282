"""amqtt's broker (amqtt 0.12.1, as requirements.lock pins it) with two of its faults mended.

A connecting client gets the retained messages of its own subscriptions only (amqtt sent those of every
client's, as mosquitto does not), and the loops over the subscriptions run on a snapshot (a SUBSCRIBE during
an ``await`` broke another client's connection). Tested in tests/transport/test_mqtt_transport.py.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import cache
from typing import Any


class SnapshotSubscriptions(dict[str, Any]):
    """amqtt's topic filter → subscribers, whose loops see a snapshot: a SUBSCRIBE or a disconnect during an
    ``await`` inside the loop changes the dict, not the loop."""

    def __iter__(self) -> Iterator[str]:
        return iter(list(dict.keys(self)))

    def items(self) -> Any:
        return list(dict.items(self))


@cache
def mended_broker_class() -> type:
    """amqtt's ``Broker`` with both faults mended (amqtt is imported here, lazily: ~200 ms)."""
    from amqtt.broker import Broker

    class MendedBroker(Broker):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._subscriptions: dict[str, Any] = SnapshotSubscriptions(self._subscriptions)

        async def _publish_retained_messages_for_subscription(
            self, subscription: tuple[str, int], session: Any
        ) -> None:
            topic_filter = subscription[0]
            subscribers = self._subscriptions.get(topic_filter, ())
            if any(subscriber.client_id == session.client_id for subscriber, _qos in subscribers):
                await super()._publish_retained_messages_for_subscription(subscription, session)

    return MendedBroker
