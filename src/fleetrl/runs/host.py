"""A unit host in a run: many units in one worker, one member of the federation carrying U units.

Each unit keeps its identity: its env (its own dynamics, simulated or behind its device bridge), its seed,
its completion criterion, its metrics rows under its own worker id, its model file. The host is one
:class:`~fleetrl.federation.worker.runner.FederatedWorker` of id :func:`~fleetrl.runs.host_settings.host_id`
whose learner is a :class:`~fleetrl.agent.host_learner.HostLearner` and whose messages say ``units`` = U.
"""

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import torch

from fleetrl.agent.host_agent import HostAgent
from fleetrl.agent.host_learner import HostLearner
from fleetrl.federation.events import WorkerEvent
from fleetrl.federation.wire.signing import FleetKey
from fleetrl.federation.worker.actions import FederatedRound
from fleetrl.federation.worker.runner import FederatedWorker, WorkerSummary
from fleetrl.runs.factory import action_space_of, agent_for, unit_criterion, unit_env
from fleetrl.runs.host_settings import host_id
from fleetrl.runs.plans import worker_plan
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.roles import metrics_row
from fleetrl.runs.rundir import model_path
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.base import Transport

log = logging.getLogger(__name__)

Emit = Callable[[MetricsRow], None]


def make_host_learner(specs: Sequence[WorkerSpec]) -> HostLearner:
    """The learner of a host of the specs' units (one run's, in order): each unit's env and criterion as
    :func:`~fleetrl.runs.factory.make_learner` builds them, one agent with each unit's seed, its network
    the run's start (a one-policy scheme's: the network the run's seed draws).

    :raises ValueError: no spec, or units of different runs
    """
    if not specs or any(s.learning != specs[0].learning for s in specs):
        raise ValueError("a unit host needs one or more units of one run")
    torch.set_num_threads(1)
    learning = specs[0].learning
    built = [unit_env(spec) for spec in specs]
    unit = built[0][1]
    config = learning.ppo()
    agent = HostAgent(unit.obs_dim, action_space_of(unit), config, [s.worker_seed for s in specs])
    scheme = learning.federation_scheme()
    if scheme.shared_start:
        agent.set_model_parameters(agent_for(unit, config, seed=learning.seed).model_parameters())
    criteria = [
        unit_criterion(spec, description) for spec, (_, description) in zip(specs, built, strict=True)
    ]
    return HostLearner(
        [env for env, _ in built], agent, criteria, keep_learning=scheme.stays_after_completion
    )


def unit_rows(
    record: FederatedRound, learner: HostLearner, specs: Sequence[WorkerSpec], started: float
) -> list[MetricsRow]:
    """One metrics row per unit of a host's round: each unit's own figures under its own worker id; its
    event is the host's, or ``completed`` where the unit's criterion holds (as its own worker would say)."""
    rows = []
    for spec, result in zip(specs, learner.unit_rounds, strict=True):
        event = record.label
        if result.completed and record.event is not WorkerEvent.RUN_ENDED:
            event = WorkerEvent.COMPLETED.label(None)
        rows.append(metrics_row(spec.worker, record.round, result, started, event))
    return rows


def train_host(
    specs: Sequence[WorkerSpec],
    transport: Transport,
    run_id: str,
    emit: Emit,
    *,
    reply_timeout: float | None = 600.0,
    resend_interval: float | None = 5.0,
    key: FleetKey | None = None,
    learner: HostLearner | None = None,
    status_fields: Mapping[str, str | int] | None = None,
) -> WorkerSummary:
    """Federated mode for a host of the specs' units over ``transport``: one worker carrying them (its
    messages signed with ``key`` if given); every unit's rows emitted each round; every unit's model file
    (the host's one network) saved at the end."""
    if learner is None:
        learner = make_host_learner(specs)
        log.info("host of units %d-%d: learner ready", specs[0].worker, specs[-1].worker)
    first = specs[0]
    started = time.monotonic()

    def record(r: FederatedRound) -> None:
        for row in unit_rows(r, learner, specs, started):
            emit(row)

    plan = worker_plan(
        first.learning, learner.agent, run_id=run_id, worker_id=host_id([spec.worker for spec in specs]),
        units=len(specs), reply_timeout=reply_timeout, resend_interval=resend_interval,
    )  # fmt: skip
    worker = FederatedWorker(learner, transport, plan, key=key, on_record=record, status_fields=status_fields)
    try:
        return worker.run()
    finally:
        for spec in specs:
            learner.agent.save(model_path(Path(spec.out), spec.worker))
