"""amqtt's broker with two faults of amqtt 0.12.1 (the version requirements.lock pins) mended.

The embedded broker falls back to amqtt where mosquitto is not installed — a fresh machine's ``make demo``.
Tried there as a new user would (``FLEETRL_HIDE_MOSQUITTO=1 fleetrl train --env cartpole --units 3
--max-rounds 1 --transport mqtt``, 20 runs), 2 runs started one worker a second late, each time for both
reasons below at once:

1. **Another client's retained messages.** When a client connects, amqtt publishes to it the retained
   messages of *every* topic filter any client has subscribed to (``Broker._handle_client_session`` loops
   over all of ``_subscriptions``), not only its own. A worker was handed the other workers' welcomes and
   statuses, which it rejected ("unknown sender"). MQTT sends a retained message to a client only for a
   subscription of its own, as mosquitto does: that is what the mended broker does.
2. **The subscriptions changing under a loop.** That loop, and the broadcast of each published message
   (``Broker._run_broadcast``), iterate over ``_subscriptions`` across ``await``: another client's
   SUBSCRIBE in between raised "dictionary changed size during iteration" in the connecting client's
   handler, amqtt dropped the connection, and the worker came back after its reconnect delay. The mended
   broker's subscriptions iterate over a snapshot of their keys and items.

Nothing else of amqtt changes. Tested in tests/transport/test_mqtt_transport.py (a retained message reaches
only its subscriber; a subscription made while another client connects does not break either).
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
