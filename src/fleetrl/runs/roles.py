"""What one worker does in a run, in individual or federated mode, wherever it runs (process or thread).

Both modes report every round as a :class:`~fleetrl.runs.records.MetricsRow` through ``emit`` and save the
worker's model when they end, however they end. An uneven unit (its spec's ``uneven``:
:mod:`fleetrl.runs.uneven`) plays through its wrappers here: slowed, absent at times, its messages delayed,
its work and its link paused at times.
"""

import logging
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from fleetrl.agent.learner import Learner, RoundResult
from fleetrl.federation.wire.signing import FleetKey
from fleetrl.federation.worker.runner import FederatedWorker, WorkerSummary
from fleetrl.runs.checkpoints import WorkerCheckpoint
from fleetrl.runs.factory import make_learner
from fleetrl.runs.plans import worker_plan
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.rundir import model_path
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import uneven_unit, unit_stall
from fleetrl.transport.base import Transport
from fleetrl.transport.delayed import DelayedTransport
from fleetrl.transport.stalled import StalledTransport

log = logging.getLogger(__name__)

Emit = Callable[[MetricsRow], None]
FINISHED_REASONS = ("transfer_out", "every unit completed")
"""how a worker's run ends when it left W having completed (paper: its θ was forwarded; fedavg: the last
average)"""


def metrics_row(worker: int, round_: int, result: RoundResult, started: float, event: str) -> MetricsRow:
    """The metrics row of ``result`` (``wall_time`` counted from ``started``, the worker's start)."""
    return MetricsRow.of(worker, round_, result, round(time.monotonic() - started, 4), event)


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
    spec: WorkerSpec,
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
    """Federated mode (Algorithm 2): one worker of run ``run_id`` over ``transport``; save the model.

    :param checkpoint_dir: commit the worker's state there after every round (see
        :class:`~fleetrl.runs.checkpoints.WorkerCheckpoint`); None: no checkpoints.
    :param resume: first restore the state committed in ``checkpoint_dir`` (if there is one) and continue
        from its round; a worker whose run was already over returns at once.
    :param status_fields: who this process is, said in its status
        (:func:`~fleetrl.federation.chief.lease.holder_fields`).
    """
    learner = learner or make_learner(spec)
    started = time.monotonic()
    store = None if checkpoint_dir is None else WorkerCheckpoint(checkpoint_dir, spec, run_id)
    start_round = None
    if resume and store is not None and store.exists():
        where = store.load(learner)
        log.info("worker %d: resumed from %s at round %d", spec.worker, checkpoint_dir, where.next_round)
        if where.ended is not None:
            log.info("worker %d: its run was already over (%s)", spec.worker, where.ended)
            return WorkerSummary(
                str(spec.worker), where.next_round - 1, where.ended in FINISHED_REASONS, where.ended
            )
        start_round = where.next_round
    elif resume:
        log.warning("worker %d: nothing to resume in %s; starting afresh", spec.worker, checkpoint_dir)
    stall = unit_stall(spec.uneven, seed=spec.learning.seed, worker=spec.worker)
    if stall is not None:  # innermost: a message due to leave a slow uplink during a pause waits too
        transport = StalledTransport(transport, stall.wait)
    if spec.uneven is not None and spec.uneven.link_delay > 0:
        transport = DelayedTransport(transport, spec.uneven.link_delay)
    player = uneven_unit(learner, spec.uneven, seed=spec.learning.seed, worker=spec.worker)
    plan = worker_plan(
        spec.learning, player.agent, run_id=run_id, worker_id=str(spec.worker), reply_timeout=reply_timeout,
        resend_interval=resend_interval, start_round=start_round, restarted=resume and start_round is None,
    )  # fmt: skip
    worker = FederatedWorker(
        player,
        transport,
        plan,
        key=key,
        on_record=lambda r: emit(metrics_row(spec.worker, r.round, r.result, started, r.label)),
        on_round_done=None if store is None else lambda next_round: store.save(learner, next_round),
        status_fields=status_fields,
    )
    try:
        summary = worker.run()
        if store is not None:
            store.save(learner, summary.rounds + 1, ended=summary.reason)
        return summary
    finally:
        learner.agent.save(model_path(Path(spec.out), spec.worker))
