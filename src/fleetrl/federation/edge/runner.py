"""The edge aggregator's loop: drive :class:`~.edge.aggregator.EdgeAggregator` over two transports, its
members' (downstream: the site's run) and the root's (upstream: the site is one worker there). A thread per
transport only queues what arrives; the state machine is fed from that queue on the caller's thread.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from fleetrl.federation.edge.aggregator import EdgeAggregator, EdgeStep
from fleetrl.federation.events import ChiefEvent
from fleetrl.federation.runner import MIN_WAIT, IdleTimeout
from fleetrl.federation.shared_settings import SettingsRefused
from fleetrl.federation.wire import topics
from fleetrl.federation.wire.messages import encode
from fleetrl.federation.wire.signing import status_payload
from fleetrl.federation.wire.topics import CHIEF_ID, ENDED, OFFLINE, ONLINE
from fleetrl.transport.base import Received, Transport, Will

log = logging.getLogger(__name__)

POLL = 0.1  # seconds a reader thread waits on its transport before looking whether the loop has ended


@dataclass(frozen=True)
class EdgeSummary:
    """How the site's run ended."""

    site: str
    rounds: int
    end_reason: str
    members: tuple[str, ...]  # the site's members when it ended


def run_edge(
    edge: EdgeAggregator, *, upstream: Transport, downstream: Transport,
    on_event: Callable[[ChiefEvent], None] | None = None, idle_timeout: float | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> EdgeSummary:  # fmt: skip
    """Serve one site until the root ends the run: connect both sides (unconnected transports to the root's
    and the site's broker, each with an ``offline`` last will), join the root, and relay.

    :param on_event: called with every event (also logged).
    :param idle_timeout: raise :class:`~.runner.IdleTimeout` when nothing arrives for this long (None: never).
    :raises SettingsRefused: the root refused the site's shared settings (its members were sent ``done``).
    """
    site = edge.site
    incarnation = time.time_ns()
    root_run, site_run, site_id = site.root_run, site.run_id, site.site_id
    up_status, down_status = topics.status_topic(root_run, site_id), topics.status_topic(site_run, CHIEF_ID)

    def up_state(state: bytes) -> bytes:
        return status_payload(state, run_id=root_run, node=site_id, incarnation=incarnation, key=site.key)

    def down_state(state: bytes) -> bytes:
        return status_payload(state, run_id=site_run, node=CHIEF_ID, incarnation=incarnation, key=site.key)

    def publish(step: EdgeStep) -> None:
        for message in step.up:
            retain = message.type == "join"
            if retain:  # a re-sent join goes with the site's online status, as a worker's does
                upstream.publish(up_status, up_state(ONLINE), retain=True)
            payload = encode(message, layout=site.layout, key=site.key)
            upstream.publish(topics.worker_topic(root_run, site_id), payload, retain=retain)
        for message in step.down:
            payload = encode(message, layout=site.layout_of(message.type), key=site.key)
            downstream.publish(topics.chief_topic(site_run), payload)
        for event in step.events:
            (log.warning if event.kind in ("rejected", "dropped", "refused") else log.info)(
                "site %s: %s", site_id, event
            )
            if on_event is not None:
                on_event(event)

    inbox: queue.Queue[tuple[str, Received]] = queue.Queue()
    stop = threading.Event()

    def reader(side: str, transport: Transport) -> None:
        while not stop.is_set():
            received = transport.receive(POLL)
            if received is not None:
                inbox.put((side, received))

    downstream.connect(f"fleetrl-{site_run}-chief", will=Will(down_status, down_state(OFFLINE)))
    upstream.connect(f"fleetrl-{root_run}-{site_id}", will=Will(up_status, up_state(OFFLINE)))
    readers = [
        threading.Thread(target=reader, args=(side, t), name=f"site-{site_id}-{side}", daemon=True)
        for side, t in (("up", upstream), ("down", downstream))
    ]
    try:
        downstream.subscribe(topics.worker_filter(site_run))
        downstream.subscribe(topics.status_filter(site_run))
        upstream.subscribe(topics.chief_topic(root_run))
        for thread in readers:
            thread.start()
        downstream.announce(down_status, down_state(ONLINE))
        upstream.announce(up_status, up_state(ONLINE))
        log.info("site %s of run %s online: members {%s}", site_id, root_run, ",".join(site.members))
        publish(edge.start(now=clock()))
        last_input = clock()
        while not edge.finished:
            now = clock()
            waits = [] if idle_timeout is None else [last_input + idle_timeout - now]
            if (deadline := edge.next_deadline()) is not None:
                waits.append(max(deadline - now + 0.001, MIN_WAIT))
            try:
                side, received = inbox.get(timeout=max(0.0, min(waits)) if waits else None)
            except queue.Empty:  # a deadline, or the idle timeout
                now = clock()
                publish(edge.tick(now))
                if idle_timeout is not None and now - last_input >= idle_timeout:
                    raise IdleTimeout(
                        f"site {site_id}: nothing for {idle_timeout:g} s in round {site.round}"
                    ) from None
                continue
            now = last_input = clock()
            publish(_feed(edge, side, received, now))
            publish(edge.tick(now))
        upstream.publish(up_status, up_state(OFFLINE), retain=True)
        downstream.publish(down_status, down_state(ENDED), retain=True)  # the site's run is over too
    finally:
        stop.set()
        for thread in readers:
            if thread.is_alive():
                thread.join(2 * POLL + 1)
        upstream.close()
        downstream.close()
    if site.refused:
        raise SettingsRefused(f"site {site_id}: {site.end_reason}; start it with the chief's settings")
    return EdgeSummary(site_id, site.round, site.end_reason or "?", site.members)


def _feed(edge: EdgeAggregator, side: str, received: Received, now: float) -> EdgeStep:
    """One received payload, to the side of the machine it belongs to."""
    site = edge.site
    if side == "up":
        return edge.root_bytes(received.payload, now=now)
    worker = topics.worker_of_topic(site.run_id, received.topic)
    if worker is not None:
        return edge.receive_bytes(received.payload, topic_worker=worker, now=now)
    node = topics.node_of_status_topic(site.run_id, received.topic)
    if node is not None and node != CHIEF_ID:
        return edge.status(node, received.payload, retained=received.retained, now=now)
    return EdgeStep()
