"""A run's plan from its resolved settings: the one builder of what its chief (a site's too) and each of its
workers are built from (:mod:`fleetrl.federation.plan`)."""

from collections.abc import Sequence
from typing import Any, Protocol

import torch

from fleetrl.envs.catalog import describe_env
from fleetrl.federation.kinds import kind_of
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.shared_settings import LearningSettings, shared_text
from fleetrl.runs.factory import agent_for, probe_agent


class RoundRules(Protocol):
    """What a chief's plan takes of the resolved round rules (:class:`fleetrl.runs.settings.RoundRules`)."""

    @property
    def aggregation(self) -> str: ...
    @property
    def chief_quorum(self) -> float: ...
    @property
    def round_timeout(self) -> float | None: ...
    @property
    def max_staleness(self) -> int | None: ...


def chief_plan(
    learning: LearningSettings, rules: RoundRules, *, run_id: str, workers: Sequence[str], **role: Any
) -> tuple[ChiefPlan, dict[str, Any]]:
    """The plan of a run of resolved ``learning`` and ``rules`` as its chief (or a site's) sees it, and what
    that chief keeps of the fleet (:meth:`~fleetrl.federation.kinds.Kind.chief_fleet`): the scheme object and
    one agent built once. ``role``: the chief's own settings (``dropout_grace``, ``open_fleet``)."""
    scheme = learning.federation_scheme()
    agent = fleet_agent(learning) if scheme.shared_start else probe_agent(learning.env, learning.ppo())
    plan = ChiefPlan(
        run_id=run_id, workers=workers, scheme=scheme, layout=scheme.layout(agent),
        steps_per_round=scheme.exchanges_per_round(agent), max_rounds=learning.max_rounds,
        settings=shared_text(learning), aggregator=rules.aggregation, quorum=rules.chief_quorum,
        round_timeout=rules.round_timeout, max_staleness=rules.max_staleness, **role,
    )  # fmt: skip
    return plan, kind_of(scheme).chief_fleet(scheme, agent)


def worker_plan(
    learning: LearningSettings, agent: FederatedAgent, *, run_id: str, worker_id: str, **role: Any
) -> WorkerPlan:
    """The plan of a run of resolved ``learning`` as one of its workers sees it, whose learner's agent is
    ``agent``. ``role``: the worker's own settings (``units``, ``reply_timeout``, ``start_round``, …)."""
    return WorkerPlan.for_agent(
        agent, scheme=learning.federation_scheme(), run_id=run_id, worker_id=worker_id,
        max_rounds=learning.max_rounds, settings=shared_text(learning), **role,
    )  # fmt: skip


def fleet_agent(learning: LearningSettings) -> Any:
    """An agent at the fleet's start, built as :func:`~fleetrl.runs.factory.make_learner` builds a worker's
    from the settings' learning seed. Torch is set to one thread in this process, as in every worker (the
    initialisation's QR differs with the threads)."""
    torch.set_num_threads(1)
    config = learning.ppo()
    return agent_for(describe_env(learning.env, config.last_step), config, seed=learning.seed)
