"""A unit host in a run: one member of the federation carrying U units, one worker of id
:func:`~fleetrl.runs.host_settings.host_id` whose messages say ``units`` = U. Each unit keeps its env (paced
and stalling as its own), seed, criterion, metrics rows and model file; the host computes, sends and is
absent as one, under its units' strictest conditions (:func:`host_conditions`)."""

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import torch

from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
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
from fleetrl.runs.uneven import UnitConditions, uneven_unit, unit_stall
from fleetrl.transport.base import Transport
from fleetrl.transport.delayed import DelayedTransport
from fleetrl.transport.stalled import StalledTransport

log = logging.getLogger(__name__)

Emit = Callable[[MetricsRow], None]


def make_host_learner(specs: Sequence[WorkerSpec]) -> Learner:
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
    seeds = [s.worker_seed for s in specs]
    agent = PPOAgent(unit.obs_dim, action_space_of(unit), config, seeds)
    scheme = learning.federation_scheme()
    if scheme.shared_start:
        agent.set_model_parameters(agent_for(unit, config, seed=learning.seed).model_parameters())
    criteria = [
        unit_criterion(spec, description) for spec, (_, description) in zip(specs, built, strict=True)
    ]
    envs = [env for env, _ in built]
    return Learner(envs, agent, criteria, seeds, keep_learning=scheme.stays_after_completion)


def host_conditions(specs: Sequence[WorkerSpec]) -> UnitConditions | None:
    """What slows, delays, stalls and absents the host: its units' largest slowdown, link delay and stall
    (one process computes and sends for all of them), the fleet's absence; None if no unit is uneven. Each
    unit's pace (and its env's stalls) stay its own, in its env."""
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
    learner: Learner | None = None,
    status_fields: Mapping[str, str | int] | None = None,
) -> WorkerSummary:
    """Federated mode for a host of the specs' units over ``transport``: one worker carrying them (its
    messages signed with ``key`` if given); every unit's rows emitted each round; every unit's model file
    (the host's one network) saved at the end."""
    if learner is None:
        learner = make_host_learner(specs)
        log.info("host of units %d-%d: learner ready", specs[0].worker, specs[-1].worker)
    first, conditions = specs[0], host_conditions(specs)
    seed, started = first.learning.seed, time.monotonic()
    stall = unit_stall(conditions, seed=seed, worker=first.worker)
    if stall is not None:  # innermost: a message due to leave a slow uplink during a pause waits too
        transport = StalledTransport(transport, stall.wait)
    if conditions is not None and conditions.link_delay > 0:
        transport = DelayedTransport(transport, conditions.link_delay)

    def record(r: FederatedRound) -> None:
        for row in unit_rows(r, learner, specs, started):
            emit(row)

    player = uneven_unit(learner, conditions, seed=seed, worker=first.worker)
    plan = worker_plan(
        first.learning, player.agent, run_id=run_id, worker_id=host_id([spec.worker for spec in specs]),
        units=len(specs), reply_timeout=reply_timeout, resend_interval=resend_interval,
    )  # fmt: skip
    worker = FederatedWorker(player, transport, plan, key=key, on_record=record, status_fields=status_fields)
    try:
        return worker.run()
    finally:
        for spec in specs:
            learner.agent.save(model_path(Path(spec.out), spec.worker))
