"""The chief's loop: drive the :class:`~.chief.machine.Chief` state machine over a Transport."""

from __future__ import annotations

import contextlib
import logging
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from fleetrl.federation.chief.checkpoint import chief_fields
from fleetrl.federation.chief.lease import Deposed, deposed_line, describe, supersedes
from fleetrl.federation.chief.machine import Chief, ChiefEvent, ChiefStep
from fleetrl.federation.wire import topics
from fleetrl.federation.wire.messages import MessageRejected, Reason, encode
from fleetrl.federation.wire.signing import Status, parse_status, status_payload
from fleetrl.federation.wire.topics import CHIEF_ID, ENDED, OFFLINE, ONLINE
from fleetrl.transport.base import Transport, Will

log = logging.getLogger(__name__)

IDLE_LOG_INTERVAL = 30.0  # seconds between the chief's log lines while nothing arrives
MIN_WAIT = 0.005  # the shortest wait for a deadline that is due (never a busy loop)
LEASE_RETRY = 0.2  # seconds between two looks at the broker while a chief's lease is in doubt


def chief_client_id(run_id: str, epoch: int) -> str:
    """The chief's MQTT client id in ``epoch`` (a deposed chief never takes over its successor's session)."""
    return f"fleetrl-{run_id}-chief" + (f"-e{epoch}" if epoch else "")


class IdleTimeout(TimeoutError):
    """The chief heard nothing for its whole idle timeout (no worker came, or all went away)."""


@dataclass(frozen=True)
class ChiefSummary:
    """How the chief's run ended."""

    rounds: int  # the last round played
    end_reason: str
    transfers: tuple[tuple[int, str, tuple[str, ...]], ...]  # (round, origin, recipients)
    rejections: dict[Reason, int]
    dropouts: tuple[tuple[int, str, str], ...] = ()  # (round, worker, reason) of workers that left W
    rejoins: tuple[tuple[int, str], ...] = ()  # (round, worker) of dropped workers that came back
    scheme: str = field(kw_only=True)
    completed: tuple[tuple[str, int], ...] = ()  # (worker, the first round its criterion held)
    contributions: dict[str, dict[str, Any]] = field(default_factory=dict)  # an asynchronous scheme's

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
    chief: Chief, transport: Transport, *, on_event: Callable[[ChiefEvent], None] | None = None,
    idle_timeout: float | None = None, clock: Callable[[], float] = time.monotonic,
    checkpoint: Callable[[Chief], None] | None = None, first_step: ChiefStep | None = None,
    read_lease: Callable[[], Status | None] | None = None,
    status_fields: Mapping[str, str | int] | None = None,
) -> ChiefSummary:  # fmt: skip
    """Serve one run over ``transport`` (unconnected: connected with an ``offline`` will, closed at the end):
    announce the chief online, feed it worker messages, statuses and time, and publish what it returns on the
    chief topic until it ends the run.

    :param on_event: called with every :class:`ChiefEvent` (also logged).
    :param idle_timeout: raise :class:`IdleTimeout` when nothing arrives for this many seconds (None: never).
    :param checkpoint: called with the chief at the start and whenever its durable state changed, *before*
        the step's messages are published (write-ahead).
    :param first_step: published right after the chief is online (a resumed chief's last answer).
    :param read_lease: reads the run's retained chief status over a connection of its own: after a lost
        connection or a stall of half the keep-alive, the chief reads it before it acts again.
    :param status_fields: who this chief is (:func:`~.chief.lease.holder_fields`), said in its status.
    :raises Deposed: a chief status or a worker message showed a newer epoch; nothing was published or
        checkpointed after it.
    """
    run_id = chief.run_id
    own_status = topics.status_topic(run_id, CHIEF_ID)
    out_topic = topics.chief_topic(run_id)
    incarnation = time.time_ns()
    keepalive = getattr(transport, "keepalive", None)
    # a main loop late by this much may have been stopped (or starved) towards the end of its lease (1.5 ×
    # the keep-alive): look at the broker before acting again
    guard = None if keepalive is None else keepalive / 2

    def status(state: bytes) -> bytes:
        fields = {"epoch": chief.epoch, **(status_fields or {})}
        return status_payload(
            state, run_id=run_id, node=CHIEF_ID, incarnation=incarnation, key=chief.key, fields=fields
        )

    def deposed_by(other: Status) -> None:
        epoch = other.number("epoch") or 0
        raise Deposed(deposed_line(run_id, chief.epoch, f"epoch {epoch}, {describe(other)}"))

    lease = _Lease(transport, clock, guard)

    def confirm_lease() -> None:
        """Act again only once connected and no newer chief took the run (then re-announce online)."""
        log.info("chief: connection lost or process stalled; checking that no newer chief took over")
        while True:
            if lease.connected():
                try:
                    seen = None if read_lease is None else read_lease()
                except ConnectionError as exc:
                    log.info("chief: cannot read the chief status yet (%s)", exc)
                else:
                    if seen is not None and supersedes(seen, epoch=chief.epoch, incarnation=incarnation):
                        deposed_by(seen)
                    transport.publish(own_status, status(ONLINE), retain=True)
                    lease.confirmed()
                    return
            if idle_timeout is not None and clock() - last_input[0] >= idle_timeout:
                raise IdleTimeout(f"cut off from the broker for {idle_timeout:g} s (--idle-timeout)")
            time.sleep(LEASE_RETRY)

    committed = [chief_fields(chief) if checkpoint is not None else None]
    if checkpoint is not None:  # a chief killed before its first round closes can be resumed too
        checkpoint(chief)

    def publish(step: ChiefStep) -> None:
        if chief.superseded is not None:  # a worker follows a newer chief: act no more
            raise Deposed(deposed_line(run_id, chief.epoch, chief.superseded))
        if lease.in_doubt():
            confirm_lease()
        if checkpoint is not None and (fields := chief_fields(chief)) != committed[0]:
            checkpoint(chief)
            committed[0] = fields
        if lease.in_doubt():  # stopped during the step (or while it wrote: the checkpoint may lead the
            confirm_lease()  # answers, write-ahead): look before anything leaves or is logged
        for message in step.outgoing:
            stamped = replace(message, epoch=chief.epoch)
            transport.publish(out_topic, encode(stamped, layout=chief.layout_of(message.type), key=chief.key))
        for event in step.events:
            _log_event(event)
            if on_event is not None:
                on_event(event)

    def chief_status(payload: bytes) -> None:
        """A chief status: a newer chief deposes this one; an older one's (or this chief's will) is answered
        by announcing this chief again."""
        try:
            seen = parse_status(payload, run_id=run_id, node=CHIEF_ID, key=chief.key)
        except MessageRejected as exc:
            log.warning("chief: rejected a chief status: %s", exc)
            return
        if supersedes(seen, epoch=chief.epoch, incarnation=incarnation):
            deposed_by(seen)
        mine = seen.incarnation == incarnation
        if not (mine and seen.state == "online") and not chief.finished:
            if not mine and seen.state == "online":
                log.warning(
                    "chief: an older chief's status (%s, %s): announcing this one", seen.state, describe(seen)
                )
            transport.publish(own_status, status(ONLINE), retain=True)

    transport.connect(chief_client_id(run_id, chief.epoch), will=Will(own_status, status(OFFLINE)))
    last_input = [clock()]
    clean_exit = False
    try:
        transport.subscribe(topics.worker_filter(run_id))
        transport.subscribe(topics.status_filter(run_id))
        # after subscribing: workers may send once they see it. Not re-announced by the transport on a
        # reconnect: the lease is checked first (confirm_lease)
        transport.publish(own_status, status(ONLINE), retain=True)
        lease.confirmed()
        params = " ".join(f"{k}={v}" for k, v in chief.scheme.params().items())
        log.info(
            "chief of run %s online: W={%s}, M=%d, scheme %s%s, %s, epoch %d",
            run_id, ",".join(chief.members), chief.max_rounds, chief.scheme.name,
            f" ({params})" if params else "", chief.plan.aggregator, chief.epoch,
        )  # fmt: skip
        if first_step is not None:
            publish(first_step)
        next_note = last_input[0] + IDLE_LOG_INTERVAL  # the next "still waiting" log line
        while not chief.finished:
            now = clock()
            waits = [next_note - now]
            if idle_timeout is not None:
                waits.append(last_input[0] + idle_timeout - now)
            if (deadline := chief.next_deadline()) is not None:
                waits.append(max(deadline - now + 0.001, MIN_WAIT))  # MIN_WAIT: never a busy loop
            wait = max(0.0, min(waits))
            if guard is not None:  # waking often enough that a stop of more than the guard shows
                wait = min(wait, guard / 2)
            lease.expect_back(now + wait)
            received = transport.receive(wait)
            if lease.in_doubt():  # before anything that came is looked at
                confirm_lease()
            now = clock()
            if received is None:
                publish(chief.tick(now))
                waiting = sorted(set(chief.members) - set(chief.answered))
                if idle_timeout is not None and now - last_input[0] >= idle_timeout:
                    raise IdleTimeout(
                        f"no worker message for {idle_timeout:g} s (--idle-timeout) in round {chief.round}; "
                        f"waiting for {waiting}"
                    )
                if now >= next_note:
                    log.info(
                        "chief: round %d, idle for %.0f s, waiting for %s%s",
                        chief.round, now - last_input[0], waiting,
                        "" if idle_timeout is None else f" (giving up after {idle_timeout:g} s)",
                    )  # fmt: skip
                    next_note = now + IDLE_LOG_INTERVAL
                continue
            last_input[0] = now
            next_note = now + IDLE_LOG_INTERVAL
            worker = topics.worker_of_topic(run_id, received.topic)
            if worker is not None:
                publish(chief.receive_bytes(received.payload, topic_worker=worker, now=now))
            else:
                node = topics.node_of_status_topic(run_id, received.topic)
                if node == CHIEF_ID:
                    chief_status(received.payload)
                elif node is not None:
                    log.info("chief: node %s is %s", node, received.payload[:16].decode("ascii", "replace"))
                    publish(chief.status(node, received.payload, retained=received.retained, now=now))
            publish(chief.tick(now))
        # retained: a worker that starts after this learns the run is over, instead of waiting for a welcome
        transport.publish(own_status, status(ENDED), retain=True)
        clean_exit = True
    except Deposed:
        clean_exit = True  # the newer chief's status stands: say nothing
        raise
    finally:
        # an error or an interrupt: say what the will would have said (a clean close fires none)
        if not clean_exit:
            with contextlib.suppress(Exception):
                transport.publish(own_status, status(OFFLINE), retain=True)
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


class _Lease:
    """Whether the chief may act without looking at the broker first: not if its connection was lost since
    it last looked, or its loop came back late by more than ``guard`` s (its will may have fired)."""

    def __init__(self, transport: Transport, clock: Callable[[], float], guard: float | None) -> None:
        self.transport, self.clock, self.guard = transport, clock, guard
        self._losses = self._lost()
        self._back_by: float | None = None
        self._alive_at = clock()

    def _lost(self) -> int:
        return int(getattr(self.transport, "connection_losses", 0))

    def connected(self) -> bool:
        """Whether the transport's connection is up (a transport that cannot tell: yes)."""
        return bool(getattr(self.transport, "connected", True))

    def expect_back(self, when: float) -> None:
        """The loop is about to wait until ``when`` at most."""
        self._back_by = when

    def in_doubt(self) -> bool:
        """The connection was lost, or the loop is late by more than the guard, since the last look."""
        now = self.clock()
        late = False
        if self.guard is not None:
            expected = self._alive_at if self._back_by is None else max(self._alive_at, self._back_by)
            late = now - expected > self.guard
        self._back_by = None
        if self._lost() != self._losses or late or not self.connected():
            return True
        self._alive_at = now
        return False

    def confirmed(self) -> None:
        """The chief looked and still holds the run."""
        self._losses = self._lost()
        self._alive_at = self.clock()
        self._back_by = None
