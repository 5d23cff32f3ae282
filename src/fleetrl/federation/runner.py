"""The chief's loop: drive the :class:`~fleetrl.federation.chief.Chief` state machine over a Transport."""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

from fleetrl.federation.chief import Chief, ChiefEvent
from fleetrl.federation.messages import Reason, encode
from fleetrl.federation.topics import (
    CHIEF_ID,
    OFFLINE,
    ONLINE,
    chief_topic,
    node_of_status_topic,
    status_filter,
    status_topic,
    worker_filter,
    worker_of_topic,
)
from fleetrl.transport.base import Transport, Will

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ChiefSummary:
    """How the chief's run ended."""

    rounds: int
    """the last round played"""
    end_reason: str
    transfers: tuple[tuple[int, str, tuple[str, ...]], ...]
    """(round, origin, recipients) of every model transfer"""
    rejections: dict[Reason, int]
    """rejected messages, by reason"""


def run_chief(
    chief: Chief,
    transport: Transport,
    *,
    on_event: Callable[[ChiefEvent], None] | None = None,
    idle_timeout: float | None = None,
) -> ChiefSummary:
    """Serve one run: connect, announce the chief online, answer every round until the chief ends the run.

    Workers wait for the chief's retained ``online`` status before their first round, so start this first (or
    at any time: workers block until it is online). Worker topics and payloads are given to the state machine
    as they come; what it returns is published, QoS 1, on the chief topic. Status changes of workers are
    logged (dropout handling is issue 7's).

    :param chief: the state machine (its run id, W and M define the run).
    :param transport: an unconnected transport; it is connected with an ``offline`` last will and closed at
        the end.
    :param on_event: called with every :class:`ChiefEvent` (also logged: rounds at INFO, rejections at
        WARNING).
    :param idle_timeout: raise TimeoutError when nothing arrives for this many seconds (None: wait forever).
    """
    run_id = chief.run_id
    own_status = status_topic(run_id, CHIEF_ID)
    out_topic = chief_topic(run_id)
    transport.connect(f"fleetrl-{run_id}-chief", will=Will(own_status, OFFLINE))
    try:
        transport.subscribe(worker_filter(run_id))
        transport.subscribe(status_filter(run_id))
        # after subscribing: workers may send once they see it
        transport.publish(own_status, ONLINE, retain=True)
        members = ",".join(chief.members)
        log.info(
            "chief of run %s online: W={%s}, M=%d, %s",
            run_id,
            members,
            chief.max_rounds,
            chief.aggregator_name,
        )
        while not chief.finished:
            received = transport.receive(idle_timeout)
            if received is None:
                waiting = sorted(set(chief.members) - set(chief.answered))
                raise TimeoutError(
                    f"chief: nothing for {idle_timeout} s in round {chief.round}; waiting for {waiting}"
                )
            worker = worker_of_topic(run_id, received.topic)
            if worker is None:
                node = node_of_status_topic(run_id, received.topic)
                if node is not None and node != CHIEF_ID:
                    log.info("chief: node %s is %s", node, received.payload[:16].decode("ascii", "replace"))
                continue
            step = chief.receive_bytes(received.payload, topic_worker=worker)
            for message in step.outgoing:
                transport.publish(out_topic, encode(message, layout=chief.layout))
            for event in step.events:
                _log_event(event)
                if on_event is not None:
                    on_event(event)
        transport.publish(own_status, OFFLINE, retain=True)
    finally:
        transport.close()
    return ChiefSummary(
        rounds=chief.round,
        end_reason=chief.end_reason or "?",
        transfers=tuple(chief.transfers),
        rejections=dict(Counter(chief.rejections)),
    )


def _log_event(event: ChiefEvent) -> None:
    if event.kind == "rejected":
        log.warning("chief: %s", event)
    elif event.kind == "accepted":
        log.debug("chief: %s", event)
    else:
        log.info("chief: %s", event)
