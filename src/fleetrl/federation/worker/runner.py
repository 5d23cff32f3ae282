"""The worker of Algorithm 2 (lines 7–31) over a learner and a transport: the loop around the pure
:class:`~.machine.WorkerMachine`, whose actions it executes (the learner's through :mod:`.play`).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections import deque
from collections.abc import Callable, Mapping

from fleetrl.federation.kinds import kind_of
from fleetrl.federation.plan import WorkerPlan
from fleetrl.federation.shared_settings import SettingsRefused
from fleetrl.federation.wire.signing import FleetKey
from fleetrl.federation.wire.topics import OFFLINE
from fleetrl.federation.worker.actions import (
    Announce,
    Checkpoint,
    FederatedRound,
    Finish,
    PlayRound,
    Publish,
    Record,
    Refused,
    RoundPlayer,
    RunEnded,
    RunEndedError,
    TakeParameters,
    TimedOut,
    WorkerOutput,
    WorkerSummary,
)
from fleetrl.transport.base import Transport, Will

__all__ = ["FederatedRound", "FederatedWorker", "RoundPlayer", "WorkerSummary"]

log = logging.getLogger(__name__)

MIN_WAIT = 0.001
"""the shortest wait for a resend or timeout that is due (never a busy loop)"""


class FederatedWorker:
    """Algorithm 2 for one worker, talking to the chief only through ``transport``.

    :param learner: plays rounds (:class:`RoundPlayer`); under a scheme that ``stays_after_completion`` it
        keeps learning after its criterion holds.
    :param transport: an unconnected transport; :meth:`run` connects it (``offline`` will) and closes it.
    :param plan: the run as this worker sees it, built for ``learner.agent`` (``start_round``: resumed from a
        checkpoint). A refusal of its settings raises ``SettingsRefused``.
    :param key: the fleet key: sign what is sent, accept only what is signed with it.
    :param on_record: called with every :class:`FederatedRound`.
    :param on_round_done: called with the next round to play once the last one's answer is applied.
    :param status_fields: who this process is (pid, host, keep-alive), said in its status.
    """

    def __init__(
        self,
        learner: RoundPlayer,
        transport: Transport,
        plan: WorkerPlan,
        *,
        key: FleetKey | None = None,
        on_record: Callable[[FederatedRound], None] | None = None,
        on_round_done: Callable[[int], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        status_fields: Mapping[str, str | int] | None = None,
    ) -> None:
        self.learner = learner
        self.transport = transport
        self.plan = plan
        self.run_id, self.worker_id, self.scheme = plan.run_id, plan.worker_id, plan.scheme
        self.on_record = on_record
        self.on_round_done = on_round_done
        self.clock = clock
        kind = kind_of(plan.scheme)
        self.machine = kind.machine(plan, key=key, incarnation=time.time_ns(), status_fields=status_fields)
        self.play = kind.play(plan.scheme, learner, self.machine, clock)
        self._queue: deque[WorkerOutput] = deque()

    def run(self) -> WorkerSummary:
        """Connect, wait for the chief's welcome, play rounds until finished, M rounds, or ``done``; close."""
        machine = self.machine
        client_id = f"fleetrl-{self.run_id}-worker-{self.worker_id}"
        self.transport.connect(client_id, will=Will(machine.own_status, machine.status(OFFLINE)))
        try:
            self.transport.subscribe(machine.chief_topic)
            self.transport.subscribe(machine.chief_status)
            self._queue.extend(machine.start(now=self.clock()).outputs)
            finish = self._drive(Finish)
            assert isinstance(finish, Finish)
            summary = finish.summary
            self.transport.publish(machine.own_status, machine.status(OFFLINE), retain=True)
        except BaseException:
            # a clean close fires no last will: say offline, or the chief waits for this worker (a refused one
            # too: no stale online holds its place)
            with contextlib.suppress(Exception):
                self.transport.publish(machine.own_status, machine.status(OFFLINE), retain=True)
            raise
        finally:
            self.transport.close()
        log.info("worker %s: %s after %d rounds", self.worker_id, summary.reason, summary.rounds)
        return summary

    def _drive(self, *until: type) -> WorkerOutput:
        """Execute the machine's outputs, feeding it the transport and the clock, until one of the ``until``
        types comes out (returned, not executed)."""
        while True:
            if not self._queue:
                self._feed()
                continue
            output = self._queue.popleft()
            if isinstance(output, until):
                return output
            self._execute(output)

    def _feed(self) -> None:
        """Wait for a chief message until the machine's next deadline; hand the machine what came, or the
        time."""
        deadline = self.machine.next_deadline()
        # MIN_WAIT past the deadline, so the tick finds it due; a catch-up (due at once) reads what is queued
        timeout = None if deadline is None else max(0.0, deadline - self.clock() + MIN_WAIT)
        received = self.transport.receive(timeout)
        now = self.clock()
        if received is None:
            step = self.machine.tick(now=now)
        else:
            step = self.machine.receive_bytes(received.topic, received.payload, now=now)
        self._queue.extend(step.outputs)

    def _execute(self, output: WorkerOutput) -> None:
        match output:
            case Publish(topic, payload, retain, _):
                self.transport.publish(topic, payload, retain=retain)
            case Announce(topic, payload):
                self.transport.announce(topic, payload)
            case TakeParameters(flat):
                self.scheme.take_parameters(self.learner.agent, flat)
            case PlayRound(_, config):
                self._queue.extend(self.play.play(config).outputs)
            case Record(record):
                if self.on_record is not None:
                    self.on_record(record)
            case Checkpoint(next_round):
                if self.on_round_done is not None:
                    self.on_round_done(next_round)
            case Refused(reason):
                raise SettingsRefused(reason)
            case TimedOut(detail):
                raise TimeoutError(detail)
            case RunEnded(detail):
                raise RunEndedError(detail)
            case _:
                step = self.play.execute(output)
                if step is None:
                    raise AssertionError(f"worker {self.worker_id}: {output} out of turn")
                self._queue.extend(step.outputs)
