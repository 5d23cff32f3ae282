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

The worker also stops after round M. Every round produces a :class:`RoundRecord` through ``on_record``.

Join: before its first round the worker publishes a retained ``join`` carrying its shared settings; a chief
``refused`` naming it, or a ``welcome`` whose settings differ, raises
:class:`~fleetrl.federation.shared_settings.SettingsRefused` (``fleetrl worker`` exits 2).

Reliability (issue 7): the worker starts (or, restarted with the same id, rejoins) at the round named by the
chief's ``welcome``, taking the last transferred parameters if it carries them. It re-sends its round's
message (and, before the welcome, its ``online`` status) every ``resend_interval`` seconds without an
answer, so a message lost to a broker restart is repaired; the chief answers a resend for a closed round
with its answer again. A worker that falls behind (a straggler under a quorum) applies every later answer it
finds queued and continues at the chief's round.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from fleetrl.federation.events import WorkerEvent
from fleetrl.federation.messages import Layout, Message, MessageRejected, decode, encode
from fleetrl.federation.rounds import RoundFigures, RoundOutcome, RoundPlayer, RoundRecord, WorkerSummary
from fleetrl.federation.schemes import COMPLETED, Granularity, Scheme, resolve_scheme
from fleetrl.federation.shared_settings import SettingsRefused, SharedSettings, settings_difference
from fleetrl.federation.signing import FleetKey, status_payload
from fleetrl.federation.topics import (
    CHIEF_ID,
    OFFLINE,
    ONLINE,
    chief_topic,
    status_topic,
    validate_id,
    validate_worker_id,
    worker_topic,
)
from fleetrl.transport.base import Transport, Will

__all__ = ["FederatedWorker", "RoundFigures", "RoundOutcome", "RoundPlayer", "RoundRecord", "WorkerSummary"]

log = logging.getLogger(__name__)

ANSWERS = ("average", "transfer", "done")
"""The chief's answers to a round."""


class FederatedWorker:
    """Algorithm 2 for one worker, talking to the chief only through ``transport``.

    :param learner: plays rounds; its ``agent`` exposes the actor (see :class:`RoundPlayer`).
    :param transport: an unconnected transport; :meth:`run` connects it (with an ``offline`` last will) and
        closes it.
    :param run_id: the run.
    :param worker_id: this worker's id (a topic level; not ``chief``).
    :param max_rounds: M.
    :param on_record: called with every :class:`RoundRecord`.
    :param reply_timeout: seconds to wait for the chief (at start, and each round); None waits forever.
    :param resend_interval: seconds without an answer after which the round's message (or, before the
        welcome, the ``online`` status) is sent again; None never re-sends.
    :param key: the fleet key: sign what is sent, accept only what is signed with it.
    :param start_round: resuming from a checkpoint: the first round the learner's state has not played. A
        ``welcome`` for that round or the next keeps the state as it is and plays that round (see
        docs/protocol.md, "Checkpoints and resume"); a later one means rounds were missed while down, and the
        worker rejoins like a fresh one; an earlier one is an error (the chief lost rounds).
    :param on_round_done: called with the next round to play after each round's answer was applied and
        before that round starts (the moment to checkpoint the learner).
    :param scheme: the federation scheme (or its name); the chief's must be the same. If it
        ``stays_after_completion`` the learner must keep learning after its criterion holds
        (``Learner.keep_learning``).
    :param settings: this worker's shared settings (:mod:`fleetrl.federation.shared_settings`), sent in its
        ``join``; a ``welcome`` carrying others, or the chief's ``refused``, raises
        :class:`~fleetrl.federation.shared_settings.SettingsRefused`.
    """

    def __init__(
        self,
        learner: RoundPlayer,
        transport: Transport,
        *,
        run_id: str,
        worker_id: str,
        max_rounds: int,
        on_record: Callable[[RoundRecord], None] | None = None,
        reply_timeout: float | None = 600.0,
        resend_interval: float | None = 5.0,
        key: FleetKey | None = None,
        start_round: int | None = None,
        on_round_done: Callable[[int], None] | None = None,
        scheme: str | Scheme = "paper",
        settings: SharedSettings | None = None,
    ) -> None:
        """Prepare the worker; nothing is sent before :meth:`run`."""
        self.learner = learner
        self.transport = transport
        self.run_id = validate_id(run_id, "run id")
        self.worker_id = validate_worker_id(worker_id)
        self.max_rounds = max_rounds
        self.on_record = on_record
        self.reply_timeout = reply_timeout
        self.resend_interval = resend_interval
        self.key = key
        self.start_round = start_round
        self.on_round_done = on_round_done
        self.incarnation = time.time_ns()
        """This process's incarnation: newer than any earlier process with the same worker id."""
        self.scheme = resolve_scheme(scheme)
        self.per_step = self.scheme.granularity is Granularity.STEP
        self.settings: dict[str, str] = dict(settings or {})
        self.layout: Layout = list(self.scheme.layout(learner.agent))
        self._chief_topic = chief_topic(run_id)
        self._chief_status = status_topic(run_id, CHIEF_ID)
        self._own_status = status_topic(run_id, worker_id)
        self._topic = worker_topic(run_id, worker_id)

    def run(self) -> WorkerSummary:
        """Connect, wait for the chief's welcome, play rounds until finished, M rounds, or ``done``; close."""
        client_id = f"fleetrl-{self.run_id}-worker-{self.worker_id}"
        self.transport.connect(client_id, will=Will(self._own_status, self._status(OFFLINE)))
        try:
            self.transport.subscribe(self._chief_topic)
            self.transport.subscribe(self._chief_status)
            self.transport.announce(self._own_status, self._status(ONLINE))
            join = Message("join", self.run_id, self.worker_id, 1, settings=self.settings)
            join_payload = encode(join, layout=self.layout, key=self.key)
            # retained: a chief that subscribes later (started after this worker) still checks it
            self.transport.publish(self._topic, join_payload, retain=True)
            welcome = self._wait_for(
                lambda m: m.type in ("welcome", "done"), "the chief's welcome", join_payload, announce=True
            )
            self._check_settings(welcome)
            summary = self._rounds(welcome)
            self.transport.publish(self._own_status, self._status(OFFLINE), retain=True)
        finally:
            self.transport.close()
        log.info("worker %s: %s after %d rounds", self.worker_id, summary.reason, summary.rounds)
        return summary

    def _status(self, state: bytes) -> bytes:
        return status_payload(
            state, run_id=self.run_id, node=self.worker_id, incarnation=self.incarnation, key=self.key
        )

    def _rounds(self, welcome: Message) -> WorkerSummary:
        agent = self.learner.agent
        if welcome.type == "done":
            return WorkerSummary(self.worker_id, 0, finished=False, reason="run ended")
        resume = self._resume_round(welcome.round)
        if welcome.flat is not None and resume is None:  # rejoining: start from θ* (fedavg: the fleet's)
            self.scheme.take_parameters(agent, welcome.flat)
        log.info("worker %s: welcomed at round %d (θ* of %s)", self.worker_id, welcome.round, welcome.origin)
        rnd = welcome.round if resume is None else resume
        while rnd <= self.max_rounds:
            if self.per_step:
                stepped, reply = self._round_by_steps(rnd)
                if stepped is None:  # the run ended (or went on without us) inside the round
                    why = "run ended" if reply.type == "done" else "out of step with the fleet"
                    return WorkerSummary(self.worker_id, rnd - 1, finished=False, reason=why)
                result = stepped
                event, peer, leave = self._step_outcome(reply, bool(result.completed))
            else:
                result, reply = self._round_then_send(rnd)
                event, peer, leave = self._apply(reply, bool(result.completed))  # lines 28-31
            self._record(rnd, result, event, peer)
            if leave:
                if reply.type == "average":  # the round in which the scheme's run completed
                    return WorkerSummary(self.worker_id, rnd, finished=True, reason="every unit completed")
                reason = "run ended" if event is WorkerEvent.RUN_ENDED else event.value
                return WorkerSummary(self.worker_id, rnd, finished=reply.type == "transfer", reason=reason)
            rnd, stop = self._catch_up(reply.round)
            if stop is not None:
                return WorkerSummary(self.worker_id, rnd - 1, finished=False, reason=stop)
            if self.on_round_done is not None:
                self.on_round_done(rnd)
        return WorkerSummary(
            self.worker_id, self.max_rounds, finished=False, reason=f"reached M={self.max_rounds}"
        )

    def _round_then_send(self, rnd: int) -> tuple[RoundOutcome, Message]:
        """A per-round scheme: play the round (lines 2-24), send what the scheme shares, wait for the
        answer."""
        result = self.learner.play_round()
        kind, flat = self.scheme.outgoing(self.learner.agent, completed=bool(result.completed))  # lines 8, 25
        payload = self._send(rnd, 0, kind, flat, result)
        return result, self._wait_for(_answer_for(rnd), f"the chief's answer for round {rnd}", payload)

    def _round_by_steps(self, rnd: int) -> tuple[RoundOutcome | None, Message]:
        """A per-step scheme: play the episodes, then every optimisation step through the chief (send this
        worker's gradient of the step, apply the chief's combination); returns the round and the last
        step's answer, or None and the ``done`` (or later answer) that cut the round short."""
        answers: list[Message] = []

        def update() -> Any:
            agent = self.learner.agent
            completed = bool(self.learner.completed)
            kind = COMPLETED if completed else self.scheme.round_message
            for k in range(agent.begin_update()):
                payload = self._send(rnd, k, kind, agent.step_gradients(k), None)
                what = f"the chief's answer for round {rnd} step {k}"
                reply = self._wait_for(_answer_for(rnd, k), what, payload)
                answers.append(reply)
                if reply.type == "done" or (reply.round, reply.step) != (rnd, k):
                    raise _LeftTheFleet(reply)
                if reply.flat is None:
                    raise AssertionError("decode guarantees tensors for an average")
                self.scheme.apply_step_answer(agent, reply.flat)
            return agent.end_update()

        try:
            result = self.learner.play_round(update=update)
        except _LeftTheFleet as left:
            return None, left.reply
        return result, answers[-1]

    def _step_outcome(self, reply: Message, completed: bool) -> tuple[WorkerEvent, str | None, bool]:
        """The round's event for a per-step scheme (every step's answer is applied already)."""
        if reply.type == "done":
            return WorkerEvent.RUN_ENDED, None, True
        event = WorkerEvent.COMPLETED if completed else WorkerEvent(self.scheme.round_message)
        return event, None, self.worker_id in reply.finished

    def _send(self, rnd: int, step: int, kind: str, flat: np.ndarray, result: RoundOutcome | None) -> bytes:
        metrics: dict[str, float] = {}
        if result is not None:
            metrics = {"score": float(result.score), "wma": float(result.wma), "steps": float(result.steps)}
        message = Message(
            kind, self.run_id, self.worker_id, rnd, step=step, flat=flat, metrics=_finite(metrics)
        )
        payload = encode(message, layout=self.layout, key=self.key)
        self.transport.publish(self._topic, payload)
        log.debug("worker %s: sent %s for round %d step %d", self.worker_id, kind, rnd, step)
        return payload

    def _resume_round(self, welcome_round: int) -> int | None:
        """The round a worker resumed from a checkpoint plays first; None: rejoin at the welcome's round."""
        if self.start_round is None:
            return None
        if welcome_round < self.start_round:
            raise RuntimeError(
                f"worker {self.worker_id}: the chief is at round {welcome_round} but this worker's "
                f"checkpoint is at round {self.start_round}: the chief lost rounds (resume it from its "
                "checkpoint)"
            )
        if welcome_round <= self.start_round + 1:
            # One round ahead: the message this worker sent before it died closed that round. Playing it again
            # gives the same message (same state, same RNGs); the chief answers the copy with that round's
            # answer, and the worker continues exactly as if it had never stopped.
            return self.start_round
        log.warning(
            "worker %s: rounds %d-%d were played without this worker; rejoining at round %d",
            self.worker_id, self.start_round, welcome_round - 1, welcome_round,
        )  # fmt: skip
        return None

    def _apply(self, reply: Message, completed: bool) -> tuple[WorkerEvent, str | None, bool]:
        """Act on the chief's answer; return (event, peer, whether this worker stops)."""
        if reply.type == "done":
            return WorkerEvent.RUN_ENDED, None, True
        if reply.type == "transfer" and self.worker_id in reply.finished:
            if reply.origin == self.worker_id:
                return WorkerEvent.TRANSFER_OUT, None, True
            return WorkerEvent.FINISHED, reply.origin, True
        if reply.flat is None:
            raise AssertionError("decode guarantees tensors for average and transfer")
        if reply.type == "transfer":
            self.scheme.take_parameters(self.learner.agent, reply.flat)  # line 29
            return WorkerEvent.TRANSFER_IN, reply.origin, False
        # the round may have closed without us (a straggler, or a resend): the fleet's update all the same
        contributed = self.worker_id in reply.contributors
        self.scheme.apply_average(
            self.learner.agent, reply.flat, completed=completed, contributed=contributed
        )
        if not contributed:
            event = WorkerEvent.LATE
        else:
            event = WorkerEvent.COMPLETED if completed else WorkerEvent(self.scheme.round_message)
        return event, None, self.worker_id in reply.finished

    def _catch_up(self, last: int) -> tuple[int, str | None]:
        """Apply answers of later rounds already queued (the chief moved on without us); return (the next
        round to play, why to stop or None)."""
        while (received := self.transport.receive(0)) is not None:
            message = self._decode(received.topic, received.payload)
            if (
                message is None
                or message.type not in ANSWERS
                or (message.type != "done" and message.round <= last)
            ):
                continue
            if message.type == "done":
                return message.round + 1, "run ended"
            agent = self.learner.agent
            if message.flat is not None and message.type == "transfer":
                self.scheme.take_parameters(agent, message.flat)
            elif message.flat is not None:
                self.scheme.apply_average(agent, message.flat, completed=False, contributed=False)
            log.info(
                "worker %s: caught up with the %s of round %d", self.worker_id, message.type, message.round
            )
            last = message.round
        return last + 1, None

    def _check_settings(self, welcome: Message) -> None:
        """SettingsRefused if the chief's welcome carries shared settings that differ from this worker's."""
        why = settings_difference(welcome.settings, self.settings) if welcome.settings else None
        if why is not None:
            self._refused(why)

    def _refused(self, why: str) -> None:
        raise SettingsRefused(
            f"worker {self.worker_id}: refused by the chief of run {self.run_id!r}: {why}; start it with the"
            " chief's settings"
        )

    def _decode(self, topic: str, payload: bytes) -> Message | None:
        if topic == self._chief_status:
            if payload.startswith(OFFLINE):
                log.warning("worker %s: the chief went offline; waiting", self.worker_id)
            return None
        try:
            message = decode(
                payload, run_id=self.run_id, known_senders=(CHIEF_ID,), layout=self.layout, key=self.key
            )
        except MessageRejected as exc:
            log.warning("worker %s: rejected a chief message: %s", self.worker_id, exc)
            return None
        if message.type == "refused" and self.worker_id in message.finished:
            self._refused(message.detail)
        return None if message.type == "refused" else message

    def _wait_for(
        self, wanted: Callable[[Message], bool], what: str, resend: bytes, *, announce: bool = False
    ) -> Message:
        """The first chief message ``wanted`` accepts; re-send ``resend`` on the worker topic (and, if
        ``announce``, the retained ``online`` status first) every ``resend_interval`` s; TimeoutError after
        ``reply_timeout`` s."""
        deadline = None if self.reply_timeout is None else time.monotonic() + self.reply_timeout
        next_send = None if self.resend_interval is None else time.monotonic() + self.resend_interval
        while True:
            received = self.transport.receive(_remaining(_earliest(deadline, next_send)))
            if received is None:
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    raise TimeoutError(
                        f"worker {self.worker_id}: nothing from the chief of run {self.run_id!r} for "
                        f"{self.reply_timeout:g} s (--reply-timeout) while waiting for {what}"
                    )
                if next_send is not None and now >= next_send:
                    log.info("worker %s: nothing yet; re-sending while waiting for %s", self.worker_id, what)
                    if announce:
                        self.transport.publish(self._own_status, self._status(ONLINE), retain=True)
                    self.transport.publish(self._topic, resend, retain=announce)
                    next_send = now + (self.resend_interval or 0.0)
                continue
            message = self._decode(received.topic, received.payload)
            if message is not None and wanted(message):
                return message
            if message is not None:
                log.debug("worker %s: ignoring %s of round %d", self.worker_id, message.type, message.round)

    def _record(self, rnd: int, result: RoundOutcome, event: WorkerEvent, peer: str | None) -> None:
        record = RoundRecord(self.worker_id, rnd, result, event, peer)
        log.info(
            "worker %s round %d: score %g wma %.1f steps %d actor %.4g critic %.4g entropy %.3f: %s",
            self.worker_id, rnd, record.score, record.wma, record.steps,
            record.actor_loss, record.critic_loss, record.entropy, event.describe(peer),
        )  # fmt: skip
        if self.on_record is not None:
            self.on_record(record)


def _answer_for(rnd: int, step: int = 0) -> Callable[[Message], bool]:
    """Accepts the chief's answer for round ``rnd`` (step ``step``) or a later one (we missed ours), or
    ``done``."""
    return lambda m: m.type == "done" or (m.type in ANSWERS and (m.round, m.step) >= (rnd, step))


class _LeftTheFleet(Exception):
    """A per-step round cannot go on: the chief ended the run, or answered a later step than ours."""

    def __init__(self, reply: Message) -> None:
        super().__init__(reply.type)
        self.reply = reply


def _earliest(a: float | None, b: float | None) -> float | None:
    return b if a is None else a if b is None else min(a, b)


def _remaining(deadline: float | None) -> float | None:
    return None if deadline is None else max(0.0, deadline - time.monotonic())


def _finite(metrics: dict[str, float]) -> dict[str, float]:
    return {k: v for k, v in metrics.items() if math.isfinite(v)}
