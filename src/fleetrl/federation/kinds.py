"""Each scheme kind (per round, per step, asynchronous) brings its own chief, worker machine and worker
play; the roles of a run built from its plan."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fleetrl.federation.chief.asynchronous import AsyncChief
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.chief.state import FleetModel
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.schemes import AsyncScheme, RoundScheme, Scheme, StepScheme
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.worker.asynchronous import AsyncWorkerMachine
from fleetrl.federation.worker.machine import WorkerMachine
from fleetrl.federation.worker.per_step import StepWorkerMachine
from fleetrl.federation.worker.play import Play, RoundPlay, StepPlay


def _fleet_model(scheme: StepScheme, agent: FederatedAgent) -> dict[str, Any]:
    """A per-step scheme's chief keeps the fleet's model: its copy steps as every worker does."""
    return {"fleet_model": FleetModel(scheme, agent)}


def _fleet_start(scheme: Scheme, agent: FederatedAgent) -> dict[str, Any]:
    """An asynchronous scheme's chief begins the fleet's model at the fleet's start."""
    return {"start": FleetStart(list(scheme.welcome_layout(agent)), scheme.start_parameters(agent))}


@dataclass(frozen=True)
class Kind:
    """A scheme kind's roles."""

    chief: type[Chief]
    machine: type[WorkerMachine]  # the worker's pure state machine
    play: type[Play]  # what the worker does with its learner
    fleet: Callable[[Any, FederatedAgent], dict[str, Any]] | None = None
    """what the chief of a one-policy fleet keeps of it (its ``start`` or ``fleet_model`` keyword), from an
    agent at the fleet's start"""

    def chief_fleet(self, scheme: Scheme, agent: FederatedAgent) -> dict[str, Any]:
        """What the chief of ``scheme`` keeps of the fleet, from ``agent`` at the fleet's start."""
        return {} if self.fleet is None or not scheme.shared_start else self.fleet(scheme, agent)


KINDS: dict[type, Kind] = {  # a scheme takes its nearest kind's roles
    AsyncScheme: Kind(AsyncChief, AsyncWorkerMachine, RoundPlay, _fleet_start),
    StepScheme: Kind(Chief, StepWorkerMachine, StepPlay, _fleet_model),
    RoundScheme: Kind(Chief, WorkerMachine, RoundPlay),
}


def kind_of(scheme: Scheme) -> Kind:
    """The roles of ``scheme``'s kind."""
    return next(KINDS[kind] for kind in type(scheme).__mro__ if kind in KINDS)


def new_chief(plan: ChiefPlan, **options: Any) -> Chief:
    """The chief of ``plan``'s scheme kind (``options``: :class:`~.chief.machine.Chief`'s others)."""
    return kind_of(plan.scheme).chief(plan, **options)


def new_worker_machine(plan: WorkerPlan, **options: Any) -> WorkerMachine:
    """The worker machine ``plan``'s scheme needs (``options``: the machine's others)."""
    return kind_of(plan.scheme).machine(plan, **options)
