"""A run's roles built from its scheme: each scheme kind (per round, per step, asynchronous) brings its own
chief and worker machine."""

from __future__ import annotations

from typing import Any

from fleetrl.federation.chief.asynchronous import AsyncChief
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.schemes import AsyncScheme, RoundScheme, Scheme, StepScheme, resolve_scheme
from fleetrl.federation.worker.asynchronous import AsyncWorkerMachine
from fleetrl.federation.worker.machine import WorkerMachine
from fleetrl.federation.worker.per_step import StepWorkerMachine

ROLES: dict[type, tuple[type[Chief], type[WorkerMachine]]] = {
    AsyncScheme: (AsyncChief, AsyncWorkerMachine),
    StepScheme: (Chief, StepWorkerMachine),
    RoundScheme: (Chief, WorkerMachine),
}
"""a scheme kind → its chief and its worker's machine (a scheme takes its nearest kind's)"""


def roles_of(scheme: Scheme) -> tuple[type[Chief], type[WorkerMachine]]:
    """The chief and the worker machine of ``scheme``'s kind."""
    return next(ROLES[kind] for kind in type(scheme).__mro__ if kind in ROLES)


def new_chief(**options: Any) -> Chief:
    """The chief ``options['scheme']`` needs (``options``: the chief's parameters)."""
    options["scheme"] = resolve_scheme(options["scheme"])
    return roles_of(options["scheme"])[0](**options)


def new_worker_machine(*, scheme: Scheme, **options: Any) -> WorkerMachine:
    """The worker machine ``scheme`` needs (``options``: the machine's parameters)."""
    return roles_of(scheme)[1](scheme=scheme, **options)
