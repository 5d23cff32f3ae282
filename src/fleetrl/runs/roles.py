"""What one worker, or one unit host of several units, does in a run (process or thread): it reports every
round as a :class:`~fleetrl.runs.records.MetricsRow` through ``emit`` and saves its model however it ends; an
uneven unit plays through its wrappers (:mod:`fleetrl.runs.uneven`)."""

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from fleetrl.agent.learner import Learner, RoundResult
from fleetrl.federation.events import WorkerEvent
from fleetrl.federation.wire.signing import FleetKey
from fleetrl.federation.worker.actions import FederatedRound
from fleetrl.federation.worker.runner import FederatedWorker, WorkerSummary
from fleetrl.runs.checkpoints import WorkerCheckpoint
from fleetrl.runs.factory import make_host_learner, make_learner, worker_plan
from fleetrl.runs.host_settings import host_id
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.rundir import model_path
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import UnitConditions, uneven_unit, unit_stall
from fleetrl.transport.base import Transport
from fleetrl.transport.delayed import DelayedTransport
from fleetrl.transport.stalled import StalledTransport

log = logging.getLogger(__name__)

Emit = Callable[[MetricsRow], None]
FINISHED_REASONS = ("transfer_out", "every unit completed")
"""how a worker's run ends when it left W having completed"""


def metrics_row(worker: int, round_: int, result: RoundResult, started: float, event: str) -> MetricsRow:
    """The metrics row of ``result`` (``wall_time`` counted from ``started``, the worker's start)."""
    return MetricsRow.of(worker, round_, result, round(time.monotonic() - started, 4), event)


def uneven_transport(
    transport: Transport, conditions: UnitConditions | None, *, seed: int, worker: int
) -> Transport:
    """``transport`` paused with the unit's stalls and delayed by its link delay."""
    stall = unit_stall(conditions, seed=seed, worker=worker)
    if stall is not None:  # innermost: a message due to leave a slow uplink during a pause waits too
        transport = StalledTransport(transport, stall.wait)
    if conditions is not None and conditions.link_delay > 0:
        transport = DelayedTransport(transport, conditions.link_delay)
    return transport


def train_alone(spec: WorkerSpec, emit: Emit, learner: Learner | None = None) -> None:
    """Individual mode: play rounds until the criterion holds or M rounds pass; save the model."""
    learner = learner or make_learner(spec)
    player = uneven_unit(learner, spec.uneven, seed=spec.learning.seed, worker=spec.worker)
    started = time.monotonic()
    try:
        for _ in range(spec.learning.max_rounds):
            result = player.play_round()
            event = "completed" if result.completed else ""
            emit(metrics_row(spec.worker, result.round, result, started, event))
            if result.completed:
                break
    finally:
        learner.agent.save(model_path(Path(spec.out), spec.worker))


def train_federated(
    specs: Sequence[WorkerSpec],
    transport: Transport,
    run_id: str,
    emit: Emit,
    *,
    reply_timeout: float | None = 600.0,
    learner: Learner | None = None,
    resend_interval: float | None = 5.0,
    key: FleetKey | None = None,
    checkpoint_dir: Path | None = None,
    resume: bool = False,
    status_fields: Mapping[str, str | int] | None = None,
) -> WorkerSummary:
    """Federated mode (Algorithm 2): one member of run ``run_id`` over ``transport``, a worker of one spec's
    unit or the unit host (id :func:`host_id`) of several; every unit's rows emitted each round, every unit's
    model saved however it ends.

    :param checkpoint_dir: (a worker) commit its state there after every round; None: no checkpoints.
    :param resume: first restore the state committed in ``checkpoint_dir`` (if any) and continue from its
        round; a worker whose run was already over returns at once.
    :param status_fields: who this process is, said in its status.
    """
    first, host = specs[0], len(specs) > 1
    if learner is None:
        learner = make_host_learner(specs)
        log.info("host of units %d-%d: learner ready", first.worker, specs[-1].worker)
    started = time.monotonic()
    store = None if checkpoint_dir is None else WorkerCheckpoint(checkpoint_dir, first, run_id)
    start_round = None
    if resume and store is not None and store.exists():
        where = store.load(learner)
        log.info("worker %d: resumed from %s at round %d", first.worker, checkpoint_dir, where.next_round)
        if where.ended is not None:
            log.info("worker %d: its run was already over (%s)", first.worker, where.ended)
            return WorkerSummary(
                str(first.worker), where.next_round - 1, where.ended in FINISHED_REASONS, where.ended
            )
        start_round = where.next_round
    elif resume:
        log.warning("worker %d: nothing to resume in %s; starting afresh", first.worker, checkpoint_dir)
    conditions = host_conditions(specs) if host else first.uneven
    seed = first.learning.seed
    transport = uneven_transport(transport, conditions, seed=seed, worker=first.worker)
    player = uneven_unit(learner, conditions, seed=seed, worker=first.worker)

    def record(r: FederatedRound) -> None:
        if not host:
            emit(metrics_row(first.worker, r.round, r.result, started, r.label))
            return
        for row in unit_rows(r, learner, specs, started):
            emit(row)

    member = host_id([spec.worker for spec in specs]) if host else str(first.worker)
    plan = worker_plan(
        first.learning, player.agent, run_id=run_id, worker_id=member, units=len(specs),
        reply_timeout=reply_timeout, resend_interval=resend_interval, start_round=start_round,
        restarted=resume and start_round is None,
    )  # fmt: skip
    worker = FederatedWorker(
        player,
        transport,
        plan,
        key=key,
        on_record=record,
        on_round_done=None if store is None else lambda next_round: store.save(learner, next_round),
        status_fields=status_fields,
    )
    try:
        summary = worker.run()
        if store is not None:
            store.save(learner, summary.rounds + 1, ended=summary.reason)
        return summary
    finally:
        for spec in specs:
            learner.agent.save(model_path(Path(spec.out), spec.worker))


def host_conditions(specs: Sequence[WorkerSpec]) -> UnitConditions | None:
    """What slows, delays, stalls and absents a unit host: its units' largest slowdown, link delay and stall,
    the fleet's absence (None: no unit is uneven); each unit's pace and env stalls stay in its env."""
    uneven = [spec.uneven for spec in specs if spec.uneven is not None]
    if not uneven:
        return None
    return UnitConditions(
        slowdown=max(c.slowdown for c in uneven),
        link_delay=max(c.link_delay for c in uneven),
        absent=uneven[0].absent,
        absent_rounds=uneven[0].absent_rounds,
        stall=max(c.stall for c in uneven),
    )


def unit_rows(
    record: FederatedRound, learner: Learner, specs: Sequence[WorkerSpec], started: float
) -> list[MetricsRow]:
    """One metrics row per unit of a host's round, under the unit's worker id; its event is the host's, or
    ``completed`` where the unit's criterion holds."""
    rows = []
    for spec, result in zip(specs, learner.unit_rounds, strict=True):
        event = record.label
        if result.completed and record.event is not WorkerEvent.RUN_ENDED:
            event = WorkerEvent.COMPLETED.label(None)
        rows.append(metrics_row(spec.worker, record.round, result, started, event))
    return rows
