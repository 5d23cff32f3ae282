"""Building a worker's learner (env + PPO agent + completion criterion) from its spec, or a unit host's from
its units' specs, and a run's plan: what its chief (a site's too) and each worker are built from
(:mod:`fleetrl.federation.plan`)."""

from collections.abc import Sequence
from typing import Any, Protocol

import gymnasium
import torch

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.catalog import UnitDescription, describe_env, get_env_spec
from fleetrl.envs.wrappers import PacedEnv, StalledEnv
from fleetrl.federation.kinds import kind_of
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.shared_settings import LearningSettings, shared_text
from fleetrl.link.mqtt import MqttLink, open_mqtt_link
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import unit_stall
from fleetrl.transport.base import Transport


def agent_for(unit: UnitDescription, config: PPOConfig, seed: int) -> PPOAgent:
    """A PPO agent of ``unit``'s shapes (ValueError: actions of a space the agent does not handle)."""
    return PPOAgent(unit.obs_dim, ActionSpace.of_unit(unit.action), config, seed=seed)


def bridge_link(env: str, url: str, run_id: str, unit: int, transport: Transport | None = None) -> MqttLink:
    """A device link to the bridge serving ``unit`` of run ``run_id``: over ``transport`` (a role's login and
    TLS files), else over a plain transport to ``url``."""
    obs_size = describe_env(env).sensor_dim
    if transport is None:
        return open_mqtt_link(url, run_id, unit, obs_size=obs_size)
    return MqttLink(transport, run_id, unit, obs_size=obs_size)


def make_learner(spec: WorkerSpec, device_transport: Transport | None = None) -> Learner:
    """The learner for one worker: :func:`make_host_learner` of its one unit."""
    return make_host_learner([spec], device_transport)


def unit_env(
    spec: WorkerSpec, device_transport: Transport | None = None
) -> tuple[gymnasium.Env[Any, Any], UnitDescription]:
    """The env of the spec's unit and its description: simulated in-process, or through its device bridge
    (``spec.device_url``), paced and stalling if its spec says so."""
    learning = spec.learning
    env_spec, last_step = get_env_spec(learning.env), learning.ppo().last_step
    if spec.device_url is None:
        env, unit = env_spec.make(
            spec.unit, learning.fleet_seed, fleet_profile=learning.fleet_profile, last_step=last_step
        )
    else:  # the device bridge draws the unit (with the same fleet profile)
        link = bridge_link(learning.env, spec.device_url, spec.device_run_id, spec.unit, device_transport)
        env, unit = env_spec.make(spec.unit, learning.fleet_seed, link=link, last_step=last_step)
    if spec.uneven is not None and spec.uneven.step_seconds is not None:
        env = PacedEnv(env, spec.uneven.step_seconds, reset_scale=spec.uneven.reset_scale)
    stall = unit_stall(spec.uneven, seed=learning.seed, worker=spec.worker)
    if stall is not None:
        env = StalledEnv(env, stall.wait)
    return env, unit


def unit_criterion(spec: WorkerSpec, unit: UnitDescription) -> CompletionCriterion:
    """The completion criterion of the spec's unit: the run's target score, or the unit type's own."""
    learning = spec.learning
    target = learning.target_score
    return CompletionCriterion(
        target if target is not None else get_env_spec(learning.env).default_target(unit)
    )


def probe_agent(env: str, config: PPOConfig) -> PPOAgent:
    """An agent of the shapes of ``env`` with ``config`` (seed 0, its weights unused), built on one thread
    (a multi-threaded orthogonal init is slow on a loaded machine)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return agent_for(describe_env(env, config.last_step), config, seed=0)
    finally:
        torch.set_num_threads(threads)


def make_host_learner(specs: Sequence[WorkerSpec], device_transport: Transport | None = None) -> Learner:
    """The learner of a unit host of the specs' units (one run's, in order): each unit's env
    (:func:`unit_env`) and criterion, one agent with each unit's seed; under a scheme with a shared start,
    the network the run's seed draws.

    :raises ValueError: no spec, or units of different runs
    """
    if not specs or any(s.learning != specs[0].learning for s in specs):
        raise ValueError("a unit host needs one or more units of one run")
    torch.set_num_threads(1)
    learning = specs[0].learning
    built = [unit_env(spec, device_transport) for spec in specs]
    unit = built[0][1]
    config = learning.ppo()
    seeds = [s.worker_seed for s in specs]
    agent = PPOAgent(unit.obs_dim, ActionSpace.of_unit(unit.action), config, seeds)
    scheme = learning.federation_scheme()
    if scheme.shared_start:  # every unit from the same initial network: the run's, not its own
        agent.set_model_parameters(agent_for(unit, config, seed=learning.seed).model_parameters())
    criteria = [
        unit_criterion(spec, description) for spec, (_, description) in zip(specs, built, strict=True)
    ]
    envs = [env for env, _ in built]
    return Learner(envs, agent, criteria, seeds, keep_learning=scheme.stays_after_completion)


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
    config = learning.ppo()
    if scheme.shared_start:  # the fleet's start as every worker draws it
        torch.set_num_threads(1)  # as in every worker: the initialisation's QR differs with the threads
        agent = agent_for(describe_env(learning.env, config.last_step), config, seed=learning.seed)
    else:
        agent = probe_agent(learning.env, config)
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
