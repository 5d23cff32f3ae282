"""A run's roles built from its scheme: each scheme kind (per round, per step, asynchronous) brings its own
chief, worker machine and worker play."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fleetrl.federation.chief.asynchronous import AsyncChief
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.schemes import AsyncScheme, RoundScheme, Scheme, StepScheme, resolve_scheme
from fleetrl.federation.worker.asynchronous import AsyncWorkerMachine
from fleetrl.federation.worker.machine import WorkerMachine
from fleetrl.federation.worker.per_step import StepWorkerMachine
from fleetrl.federation.worker.play import Play, RoundPlay, StepPlay


@dataclass(frozen=True)
class Kind:
    """A scheme kind's roles."""

    chief: type[Chief]
    machine: type[WorkerMachine]
    """the worker's pure state machine"""
    play: type[Play]
    """what the worker does with its learner"""


KINDS: dict[type, Kind] = {
    AsyncScheme: Kind(AsyncChief, AsyncWorkerMachine, RoundPlay),
    StepScheme: Kind(Chief, StepWorkerMachine, StepPlay),
    RoundScheme: Kind(Chief, WorkerMachine, RoundPlay),
}
"""a scheme kind → its roles (a scheme takes its nearest kind's)"""


def kind_of(scheme: Scheme) -> Kind:
    """The roles of ``scheme``'s kind."""
    return next(KINDS[kind] for kind in type(scheme).__mro__ if kind in KINDS)


def new_chief(**options: Any) -> Chief:
    """The chief ``options['scheme']`` needs (``options``: the chief's parameters)."""
    options["scheme"] = resolve_scheme(options["scheme"])
    return kind_of(options["scheme"]).chief(**options)


def new_worker_machine(*, scheme: Scheme, **options: Any) -> WorkerMachine:
    """The worker machine ``scheme`` needs (``options``: the machine's parameters)."""
    return kind_of(scheme).machine(scheme=scheme, **options)
