"""The chief's loop: drive the :class:`~fleetrl.federation.chief.Chief` state machine over a Transport."""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fleetrl.federation.chief import Chief, ChiefEvent, ChiefStep
from fleetrl.federation.chief_state import chief_fields
from fleetrl.federation.messages import Reason, encode
from fleetrl.federation.signing import status_payload
from fleetrl.federation.topics import (
    CHIEF_ID,
    ENDED,
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

IDLE_LOG_INTERVAL = 30.0
"""seconds between the chief's log lines while nothing arrives"""
MIN_WAIT = 0.005
"""the shortest wait for a deadline that is due (a state machine bug would otherwise spin a core)"""


class IdleTimeout(TimeoutError):
    """The chief heard nothing for its whole idle timeout (no worker came, or all went away)."""


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
    dropouts: tuple[tuple[int, str, str], ...] = ()
    """(round, worker, reason) of every worker that left W without transferring"""
    rejoins: tuple[tuple[int, str], ...] = ()
    """(round, worker) of every dropped worker that came back"""
    scheme: str = field(kw_only=True)
    """the federation scheme"""
    completed: tuple[tuple[str, int], ...] = ()
    """(worker, round) of the first round each worker's criterion held"""
    contributions: dict[str, dict[str, Any]] = field(default_factory=dict)
    """an asynchronous scheme's: worker → its contributions taken, and their staleness"""

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready account (chief.json)."""
        return {
            "rounds": self.rounds,
            "end_reason": self.end_reason,
            "transfers": [{"round": r, "from": o, "to": list(t)} for r, o, t in self.transfers],
            "rejections": {str(k): v for k, v in self.rejections.items()},
            "dropouts": [{"round": r, "worker": w, "reason": why} for r, w, why in self.dropouts],
            "rejoins": [{"round": r, "worker": w} for r, w in self.rejoins],
            "scheme": self.scheme,
            "completed": dict(self.completed),
            **({"contributions": self.contributions} if self.contributions else {}),
        }


def run_chief(
    chief: Chief,
    transport: Transport,
    *,
    on_event: Callable[[ChiefEvent], None] | None = None,
    idle_timeout: float | None = None,
    clock: Callable[[], float] = time.monotonic,
    checkpoint: Callable[[Chief], None] | None = None,
    first_step: ChiefStep | None = None,
    idle_log_interval: float = IDLE_LOG_INTERVAL,
) -> ChiefSummary:
    """Serve one run: connect, announce the chief online, answer every round until the chief ends the run.

    Workers wait for the chief's ``welcome`` (sent when it sees their ``online`` status) before their first
    round, so the start order does not matter. Worker topics, worker statuses and the passing of time (the
    round deadline) are given to the state machine as they come; what it returns is published, QoS 1, on the
    chief topic, signed if the chief has a fleet key.

    :param chief: the state machine (its run id, W and M define the run).
    :param transport: an unconnected transport; it is connected with an ``offline`` last will and closed at
        the end.
    :param on_event: called with every :class:`ChiefEvent` (also logged: rounds at INFO, rejections at
        WARNING).
    :param idle_timeout: raise :class:`IdleTimeout` when nothing arrives for this many seconds (None: wait
        forever). While it waits the chief sleeps in ``receive`` (no polling) and logs who it is waiting for
        every ``idle_log_interval`` seconds.
    :param clock: the time source handed to the state machine (seconds).
    :param checkpoint: called with the chief at the start and whenever its durable state
        (:func:`~fleetrl.federation.chief_state.chief_fields`) changed — a round closed, a worker left,
        rejoined or restarted, the run ended — *before* the step's messages are published, so no worker ever
        acts on an answer the checkpoint does not hold (write-ahead).
    :param first_step: published right after the chief announces itself online (a resumed chief passes
        :func:`~fleetrl.federation.chief_state.replay_last_answer`).
    """
    run_id = chief.run_id
    own_status = status_topic(run_id, CHIEF_ID)
    out_topic = chief_topic(run_id)
    incarnation = time.time_ns()

    def status(state: bytes) -> bytes:
        return status_payload(state, run_id=run_id, node=CHIEF_ID, incarnation=incarnation, key=chief.key)

    committed = [chief_fields(chief) if checkpoint is not None else None]
    if checkpoint is not None:  # a chief killed before its first round closes can be resumed too
        checkpoint(chief)

    def publish(step: ChiefStep) -> None:
        if checkpoint is not None and (fields := chief_fields(chief)) != committed[0]:
            checkpoint(chief)
            committed[0] = fields
        for message in step.outgoing:
            transport.publish(out_topic, encode(message, layout=chief.layout_of(message.type), key=chief.key))
        for event in step.events:
            _log_event(event)
            if on_event is not None:
                on_event(event)

    transport.connect(f"fleetrl-{run_id}-chief", will=Will(own_status, status(OFFLINE)))
    try:
        transport.subscribe(worker_filter(run_id))
        transport.subscribe(status_filter(run_id))
        # after subscribing: workers may send once they see it
        transport.announce(own_status, status(ONLINE))
        members = ",".join(chief.members)
        params = " ".join(f"{k}={v}" for k, v in chief.scheme.params().items())
        log.info(
            "chief of run %s online: W={%s}, M=%d, scheme %s%s, %s",
            run_id,
            members,
            chief.max_rounds,
            chief.scheme.name,
            f" ({params})" if params else "",
            chief.aggregator_name,
        )
        if first_step is not None:
            publish(first_step)
        last_input = clock()
        next_note = last_input + idle_log_interval  # the next "still waiting" log line
        while not chief.finished:
            now = clock()
            waits = [next_note - now]
            if idle_timeout is not None:
                waits.append(last_input + idle_timeout - now)
            if (deadline := chief.next_deadline()) is not None:
                waits.append(max(deadline - now + 0.001, MIN_WAIT))  # MIN_WAIT: never a busy loop
            received = transport.receive(max(0.0, min(waits)))
            now = clock()
            if received is None:
                publish(chief.tick(now))
                waiting = sorted(set(chief.members) - set(chief.answered))
                if idle_timeout is not None and now - last_input >= idle_timeout:
                    raise IdleTimeout(
                        f"no worker message for {idle_timeout:g} s (--idle-timeout) in round {chief.round}; "
                        f"waiting for {waiting}"
                    )
                if now >= next_note:
                    log.info(
                        "chief: round %d, idle for %.0f s, waiting for %s%s",
                        chief.round, now - last_input, waiting,
                        "" if idle_timeout is None else f" (giving up after {idle_timeout:g} s)",
                    )  # fmt: skip
                    next_note = now + idle_log_interval
                continue
            last_input = now
            next_note = now + idle_log_interval
            worker = worker_of_topic(run_id, received.topic)
            if worker is not None:
                publish(chief.receive_bytes(received.payload, topic_worker=worker, now=now))
            else:
                node = node_of_status_topic(run_id, received.topic)
                if node is not None and node != CHIEF_ID:
                    log.info("chief: node %s is %s", node, received.payload[:16].decode("ascii", "replace"))
                    publish(chief.status(node, received.payload, retained=received.retained, now=now))
            publish(chief.tick(now))
        # retained: a worker that starts after this learns the run is over, instead of waiting for a welcome
        transport.publish(own_status, status(ENDED), retain=True)
    finally:
        transport.close()
    return ChiefSummary(
        rounds=chief.round,
        end_reason=chief.end_reason or "?",
        transfers=tuple(chief.transfers),
        rejections=dict(Counter(chief.rejections)),
        dropouts=tuple(chief.dropouts),
        rejoins=tuple(chief.rejoins),
        scheme=chief.scheme.name,
        completed=tuple(chief.completed.items()),
        contributions=chief.state.contribution_counts(),
    )


def _log_event(event: ChiefEvent) -> None:
    if event.kind in ("rejected", "dropped", "refused"):
        log.warning("chief: %s", event)
    elif event.kind == "accepted":
        log.debug("chief: %s", event)
    else:
        log.info("chief: %s", event)
