"""The worker of Algorithm 2 (lines 7–31) on top of a learner: play a round, send, wait for the chief, apply.

Each round the worker calls ``learner.play_round()`` (the episode and, unless learning is complete, the K PPO
optimisations). It then sends what its scheme (:mod:`fleetrl.federation.schemes`) says — ``paper``: the
actor's last gradient, ``fedavg``: its whole model; once the completion criterion holds, a ``parameters``
message — to the chief, and waits for the chief's answer for that round:

* ``average``: the scheme applies it (``paper``: through the actor's optimiser, line 31; ``fedavg``: the
  average model replaces the worker's);
* ``transfer`` listing this worker in ``finished``: the chief acknowledged its parameters; the worker is
  finished and stops (it has left W; what the chief forwarded — its own parameters or a lower id's — is in the
  record);
* ``transfer`` not listing it: the scheme replaces its shared parameters with the received ones (line 29) and
  it keeps learning;
* an ``average`` listing it in ``finished``: the run is complete for it (``fedavg``'s last round);
* ``done``: the run is over.

The worker also stops after round M. Every round produces a :class:`FederatedRound` through ``on_record``.

Join: before its first round the worker publishes a retained ``join`` carrying its shared settings; a chief
``refused`` naming it, or a ``welcome`` whose settings differ, raises
:class:`~fleetrl.federation.shared_settings.SettingsRefused` (``fleetrl worker`` exits 2).

Reliability (issue 7): the worker starts (or, restarted with the same id, rejoins) at the round named by the
chief's ``welcome``, taking the last transferred parameters if it carries them. It re-sends its round's
message (and, before the welcome, its ``online`` status) every ``resend_interval`` seconds without an
answer, so a message lost to a broker restart is repaired; the chief answers a resend for a closed round
with its answer again. A worker that falls behind (a straggler under a quorum) applies every later answer it
finds queued and continues at the chief's round.

The rules live in the pure state machine :class:`~fleetrl.federation.worker_machine.WorkerMachine`; this
module is its runner: the loop, the clock, the transport, and the learner (the machine's actions are executed
here, on the agent through the scheme).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

from fleetrl.federation.messages import Layout, RoundConfig
from fleetrl.federation.rounds import (
    AbandonUpdate,
    Announce,
    ApplyAverage,
    ApplyFleetStep,
    ApplyStep,
    BeginUpdate,
    Checkpoint,
    ComputeStep,
    EndUpdate,
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
from fleetrl.federation.schemes import RoundScheme, Scheme, StepScheme, resolve_scheme
from fleetrl.federation.schemes.base import LocalTraining
from fleetrl.federation.shared_settings import SettingsRefused, SharedSettings
from fleetrl.federation.signing import FleetKey
from fleetrl.federation.step_worker import StepWorkerMachine, worker_machine
from fleetrl.federation.topics import OFFLINE, validate_id, validate_worker_id
from fleetrl.federation.worker_machine import ENDED_GRACE
from fleetrl.transport.base import Transport, Will

__all__ = ["FederatedRound", "FederatedWorker", "RoundPlayer", "WorkerSummary"]

log = logging.getLogger(__name__)

MIN_WAIT = 0.001
"""the shortest wait for a resend or timeout that is due (never a busy loop)"""


class FederatedWorker:
    """Algorithm 2 for one worker, talking to the chief only through ``transport``.

    :param learner: plays rounds; its ``agent`` exposes the actor (see :class:`RoundPlayer`).
    :param transport: an unconnected transport; :meth:`run` connects it (with an ``offline`` last will) and
        closes it.
    :param run_id: the run.
    :param worker_id: this worker's id (a topic level; not ``chief``).
    :param max_rounds: M.
    :param on_record: called with every :class:`FederatedRound`.
    :param reply_timeout: seconds to wait for the chief (at start, and each round); None waits forever.
    :param resend_interval: seconds without an answer after which the round's message (or, before the
        welcome, the ``online`` status) is sent again; None never re-sends.
    :param key: the fleet key: sign what is sent, accept only what is signed with it.
    :param start_round: resuming from a checkpoint: the first round the learner's state has not played. A
        ``welcome`` for that round or the next keeps the state as it is and plays that round (see
        docs/protocol.md, "Checkpoints and resume"); a later one means rounds were missed while down, and the
        worker rejoins like a fresh one; an earlier one is an error (the chief lost rounds).
    :param restarted: resumed with no checkpoint to resume from (it went down before its first one): round
        1 is recorded as interrupted if the fleet went on without it.
    :param on_round_done: called with the next round to play after each round's answer was applied and
        before that round starts (the moment to checkpoint the learner).
    :param scheme: the federation scheme (or its name); the chief's must be the same. If it
        ``stays_after_completion`` the learner must keep learning after its criterion holds
        (``Learner.keep_learning``).
    :param settings: this worker's shared settings (:mod:`fleetrl.federation.shared_settings`), sent in its
        ``join``; a ``welcome`` carrying others, or the chief's ``refused``, raises
        :class:`~fleetrl.federation.shared_settings.SettingsRefused`.
    :param clock: the time source handed to the state machine (seconds).
    :param units: the units the learner plays (a unit host: U), said in every message it contributes; the
        chief weighs its answers by them.
    :param ended_grace: seconds to wait, unwelcomed, for a new chief once the chief's retained status says
        the run has ended; then :meth:`run` raises
        :class:`~fleetrl.federation.rounds.RunEndedError`.
    :param status_fields: who this process is (pid, host, keep-alive: :func:`~.lease.holder_fields`), said
        in its status so a second process with its id is refused naming it.
    """

    def __init__(
        self,
        learner: RoundPlayer,
        transport: Transport,
        *,
        run_id: str,
        worker_id: str,
        max_rounds: int,
        on_record: Callable[[FederatedRound], None] | None = None,
        reply_timeout: float | None = 600.0,
        resend_interval: float | None = 5.0,
        key: FleetKey | None = None,
        start_round: int | None = None,
        restarted: bool = False,
        on_round_done: Callable[[int], None] | None = None,
        scheme: str | Scheme,
        settings: SharedSettings | None = None,
        clock: Callable[[], float] = time.monotonic,
        units: int = 1,
        ended_grace: float = ENDED_GRACE,
        status_fields: Mapping[str, str | int] | None = None,
    ) -> None:
        """Prepare the worker; nothing is sent before :meth:`run`."""
        self.learner = learner
        self.transport = transport
        self.run_id = validate_id(run_id, "run id")
        self.worker_id = validate_worker_id(worker_id)
        self.max_rounds = max_rounds
        self.on_record = on_record
        self.key = key
        self.on_round_done = on_round_done
        self.clock = clock
        self.scheme = resolve_scheme(scheme)
        self.layout: Layout = list(self.scheme.layout(learner.agent))
        self.machine = worker_machine(
            scheme=self.scheme,
            steps_per_round=self.scheme.exchanges_per_round(learner.agent),
            run_id=self.run_id,
            worker_id=self.worker_id,
            max_rounds=max_rounds,
            layout=self.layout,
            welcome_layout=self.scheme.welcome_layout(learner.agent),
            settings=settings,
            key=key,
            reply_timeout=reply_timeout,
            resend_interval=resend_interval,
            start_round=start_round,
            restarted=restarted,
            incarnation=time.time_ns(),
            units=units,
            ended_grace=ended_grace,
            status_fields=status_fields,
        )
        self._queue: deque[WorkerOutput] = deque()
        self._played: Any = None
        """a per-step round under way: what ``learner.begin_round`` returned"""

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
        agent = self.learner.agent
        match output:
            case Publish(topic, payload, retain, _):
                self.transport.publish(topic, payload, retain=retain)
            case Announce(topic, payload):
                self.transport.announce(topic, payload)
            case TakeParameters(flat):
                self.scheme.take_parameters(agent, flat)
            case ApplyAverage(flat, completed, contributed):
                assert isinstance(self.scheme, RoundScheme), "averages come per step to a per-step scheme"
                self.scheme.apply_average(agent, flat, completed=completed, contributed=contributed)
            case PlayRound(_, config):
                self._play_round(config)
            case BeginUpdate():  # a per-step round joins the fleet's exchange: line 11
                assert isinstance(self.scheme, StepScheme), "a per-step round comes to a per-step scheme"
                units = self.learner
                weights = self.scheme.unit_weights(units.unit_progress(), units.units_completed())
                steps = agent.begin_update() if self._played.updates else 0
                weight = None if weights is None else float(sum(weights))
                begun = self._step_machine.update_begun(steps, now=self.clock(), weight=weight)
                self._queue.extend(begun.outputs)
            case ApplyFleetStep(k, flat):  # behind the fleet: its step, taken outside an update
                assert isinstance(self.scheme, StepScheme), "step answers come to a per-step scheme"
                self.scheme.catch_up_step(agent, k, flat)
            case ComputeStep(k):  # a per-step round: step k's gradient to the chief
                flat = agent.step_gradients(k)
                self._queue.extend(self._step_machine.step_computed(k, flat, now=self.clock()).outputs)
            case ApplyStep(flat):  # the chief's combination: the agent steps and takes the next gradient
                assert isinstance(self.scheme, StepScheme), "step answers come to a per-step scheme"
                self.scheme.apply_step_answer(agent, flat)
            case EndUpdate():
                self._end_round()
            case AbandonUpdate():
                self._end_round(abandoned=True)
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
                raise AssertionError(f"worker {self.worker_id}: {output} out of turn")

    def _play_round(self, config: RoundConfig) -> None:
        """Play the round the machine asked for and report it. A per-round scheme's local loss for the round
        (with the chief's ``config``) is installed first; a per-step scheme's round plays its episodes here
        and reports its update's steps as the machine asks for them (:meth:`_execute`)."""
        agent = self.learner.agent
        if isinstance(self.scheme, RoundScheme):
            self._install_local_loss(self.scheme, config)
            result = self.learner.play_round()
            share = self.scheme.outgoing(agent, completed=bool(result.completed))  # lines 8, 25
            self._queue.extend(self.machine.round_played(result, now=self.clock(), share=share).outputs)
            return
        self._played = self.learner.begin_round()
        completed = bool(self.learner.completed)
        collected = self._step_machine.round_collected(completed=completed, now=self.clock())
        self._queue.extend(collected.outputs)

    @property
    def _step_machine(self) -> StepWorkerMachine:
        """The machine of a per-step scheme's worker (its actions come to no other)."""
        assert isinstance(self.machine, StepWorkerMachine), "per-step actions come to a per-step scheme"
        return self.machine

    def _end_round(self, *, abandoned: bool = False) -> None:
        """Every step of a per-step round was applied (or the fleet went on past this worker's step:
        ``abandoned``): finish the update and report the round."""
        played, self._played = self._played, None
        agent = self.learner.agent
        stats = None
        if abandoned:
            agent.abandon_update()
        elif played.updates:
            stats = agent.end_update()
        result = self.learner.end_round(played, stats)
        self._queue.extend(self.machine.round_played(result, now=self.clock()).outputs)

    def _install_local_loss(self, scheme: RoundScheme, config: RoundConfig) -> None:
        """Hand the agent what ``scheme`` adds to its local training's loss this round (or nothing)."""
        agent = self.learner.agent
        extra = scheme.local_loss(agent, config)
        if isinstance(agent, LocalTraining):
            agent.set_extra_loss(extra)
        elif extra is not None:
            raise TypeError(
                f"scheme {scheme.name!r} adds a term to local training, which this agent "
                f"({type(agent).__name__}) cannot take: it has no set_extra_loss(fn)"
            )
