"""The worker of Algorithm 2 (lines 7–31) over a learner and a transport: the loop, the clock and the
transport around the pure :class:`~.worker.machine.WorkerMachine`, whose actions it executes (the learner's
side through its scheme kind's :mod:`.worker.play`). Joining, resuming and re-sends: docs/protocol.md.
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

    :param learner: plays rounds; its ``agent`` exposes the actor (see :class:`RoundPlayer`). If the plan's
        scheme ``stays_after_completion``, it must keep learning after its criterion holds.
    :param transport: an unconnected transport; :meth:`run` connects it (with an ``offline`` last will) and
        closes it.
    :param plan: the run as this worker sees it (:class:`~fleetrl.federation.plan.WorkerPlan`, built for
        ``learner.agent``; its ``start_round`` resumes from a checkpoint: docs/protocol.md, "Checkpoints and
        resume"). A ``welcome`` carrying other settings, or the chief's ``refused``, raises
        :class:`~fleetrl.federation.shared_settings.SettingsRefused`.
    :param key: the fleet key: sign what is sent, accept only what is signed with it.
    :param on_record: called with every :class:`FederatedRound`.
    :param on_round_done: called with the next round to play after each round's answer was applied and
        before that round starts (the moment to checkpoint the learner).
    :param clock: the time source handed to the state machine (seconds).
    :param status_fields: who this process is (pid, host, keep-alive: :func:`~.chief.lease.holder_fields`),
        said in its status so a second process with its id is refused naming it.
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
        """Prepare the worker; nothing is sent before :meth:`run`."""
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
        except SettingsRefused:  # never admitted: the chief keeps waiting for a worker with its settings
            # offline, so no stale online holds the place (the chief that refused it does not drop the id)
            with contextlib.suppress(Exception):
                self.transport.publish(machine.own_status, machine.status(OFFLINE), retain=True)
            raise
        except BaseException:
            # A worker dying of an error closes its connection cleanly, so its last will never fires: it says
            # what the will would have, or the chief waits for it at every exchange (without a deadline,
            # for ever). What went wrong goes on up.
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
        # MIN_WAIT past a resend or timeout, so the tick finds it due; a catch-up (due at once) reads only
        # what is already queued
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
