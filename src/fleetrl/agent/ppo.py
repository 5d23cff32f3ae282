"""The Actor-Critic PPO agent of one unit or of U units of one policy (Eqs. 2-7; Algorithm 2, lines 3, 5, 8,
11-25, 29, 31): one network and optimiser state; each unit its own memory and random streams."""

from __future__ import annotations

from collections.abc import Generator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fleetrl.agent import optimisers
from fleetrl.agent.action_space import ActionSpace, as_action_space
from fleetrl.agent.checkpoint import architecture, check_tensors_fit, load_agent, save_agent
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.memory import PendingTransitions, TrajectoryMemory, score_unscored
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.optimisers import Named, flatten, flatten_tensors, layout, split
from fleetrl.agent.policy_numpy import NumpyPolicy
from fleetrl.agent.row_acting import FEW_ROWS, RowActing, UniformDraws
from fleetrl.agent.update import (
    ACTOR,
    CRITIC,
    ExtraLoss,
    Gradient,
    Model,
    StepExchange,
    UpdateStats,
    hand_back,
    ppo_update,
    step_parts,
)

__all__ = ["PPOAgent", "UpdateStats"]


class PPOAgent:
    """Actor-Critic PPO with a shared trunk; θ = trunk + policy head, μ = trunk + value head.

    :param actions: the action space; an int is that many discrete actions
    :param seed: one per unit (an int: one unit), for its action draws and window starts; the first also
        draws the initial weights, so unit 0 acts and learns as an agent of that unit alone
    """

    def __init__(
        self, obs_dim: int, actions: int | ActionSpace, config: PPOConfig, seed: int | Sequence[int]
    ) -> None:
        config.validate()
        self.seeds = tuple(int(s) for s in seed) if isinstance(seed, Sequence) else (int(seed),)
        if not self.seeds:
            raise ValueError("an agent needs at least one unit (one seed)")
        self.action_space = as_action_space(actions)
        self.obs_dim = obs_dim
        self.n_actions = self.action_space.n  # 0 for a box
        self.config = config
        self.seed = self.seeds[0]
        streams = [np.random.SeedSequence(s).spawn(2) for s in self.seeds]
        self._act_rngs = [np.random.default_rng(act) for act, _ in streams]
        self._window_rngs = [np.random.default_rng(window) for _, window in streams]
        if config.own_part != "none" and len(self.seeds) > 1:
            raise ValueError(f"own_part {config.own_part!r} is a unit's own: an agent of one unit only")
        generator = torch.Generator().manual_seed(self.seed)
        self.net = ActorCritic.from_config(obs_dim, self.action_space, config, generator)
        trunk = self.net.trunk_parameters()
        # θ: the trunk and the actor head, what the federation shares; μ: the trunk and the value head. Each
        # optimiser also steps the unit's own offsets (never shared).
        self._actor_named = trunk + self.net.head_parameters("policy")
        self._critic_named = trunk + self.net.head_parameters("value")
        self._actor_own = self.net.own_parameters([name for name, _ in self._actor_named])
        self._critic_own = self.net.own_parameters([name for name, _ in self._critic_named])
        actor_all = [p for _, p in self._actor_named + self._actor_own]
        critic_all = [p for _, p in self._critic_named + self._critic_own]
        own = [(f"own.{key}", p) for key, p in self.net.own.items()]
        self.actor_optimizer, self.critic_optimizer = optimisers.adams(
            config, (self._actor_named, self._actor_own), (self._critic_named, self._critic_own),
            (self._model_named(), own),
        )  # fmt: skip
        grows, dim = config.trajectory_memory == "per_round", self.action_space.dim
        self._memories = [TrajectoryMemory(config.memory_size, obs_dim, grows, dim) for _ in self.seeds]
        self.memory = self._memories[0]  # unit 0's
        few = self.units < FEW_ROWS  # a few units' transitions go straight into their memories
        self._pending = None if few else PendingTransitions(self.units, obs_dim, dim)
        self._policy = NumpyPolicy(self.net)
        self._discrete = self.action_space.is_discrete
        self._draws = UniformDraws(self._act_rngs)
        self._rows = RowActing(self._policy) if self._discrete else None
        both = (self.actor_optimizer, self.critic_optimizer)
        self._model = Model(self.net, actor_all, critic_all, *both, config)
        self._parts = step_parts(config)
        self._last_actor_gradient: Gradient | None = None  # line 25's: the last one the update applied
        self._exchange: StepExchange | None = None
        self.unit_stats: tuple[UpdateStats, ...] | None = None  # each unit's, of the last update

    @property
    def units(self) -> int:
        """U, the units this agent acts for."""
        return len(self.seeds)

    # ---- acting (Algorithm 2, lines 3 and 5) ------------------------------------------------------------

    def act(self, obs: np.ndarray) -> Any:
        """Sample unit 0's a_t ~ π_θ(·|s_t) (line 3): an index, or a vector."""
        if self._discrete:
            return self._policy.act(obs, float(self._act_rngs[0].random()))
        return self._policy.act_continuous(obs, self._act_rngs[0].standard_normal(self.action_space.dim))

    def act_units(self, obs: np.ndarray, units: np.ndarray) -> np.ndarray:
        """:meth:`act` for the distinct ``units`` at their observations ``obs`` (a row each), own draws."""
        if self._rows is not None:
            return self._rows.act(obs, self._draws.draw(units))
        dim = self.action_space.dim
        draws = [self._policy.act_continuous(row, self._act_rngs[u].standard_normal(dim))
                 for row, u in zip(obs, units.tolist(), strict=True)]  # fmt: skip
        return np.array(draws, dtype=np.float32).reshape(len(units), dim)

    def act_greedy(self, obs: np.ndarray) -> Any:
        """π_θ's most probable action: the arg-max index, or the Gaussian's mean clipped to the box."""
        if self._discrete:
            return self._policy.act_greedy(obs)
        return self._policy.act_continuous(obs, None)

    def env_action(self, action: Any) -> Any:
        """What the env is sent for an action of :meth:`act`: the index, or the vector clipped to the box."""
        return action if self._discrete else self.action_space.clip(action)

    def remember(
        self,
        obs: np.ndarray,
        action: int | np.ndarray,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        truncated: bool,
    ) -> None:
        """Store unit 0's ⟨s_t, a_t, r_{t+1}, s_{t+1}⟩ in its trajectory memory (line 5)."""
        self.memories[0].add(obs, action, reward, next_obs, terminated, truncated)

    def remember_units(self, units: np.ndarray, *transitions: np.ndarray) -> None:
        """:meth:`remember` for the distinct ``units`` (row j of each of the ``transitions`` arrays:
        ``units[j]``'s)."""
        if self._pending is not None:
            self._pending.add(self._memories, units, *transitions)
            return
        for u, *row in zip(units.tolist(), *transitions, strict=True):
            self._memories[u].add(*row)

    @property
    def memories(self) -> list[TrajectoryMemory]:
        """Each unit's trajectory memory, its pending transitions moved in."""
        self.store_pending()
        return self._memories

    def store_pending(self) -> None:
        """Move the transitions :meth:`remember_units` holds into each unit's memory."""
        if self._pending is not None:
            self._pending.drain(self._memories)

    # ---- learning (Algorithm 2, lines 11-25) ----------------------------------------------------------

    def needs_more_episodes(self, unit: int = 0) -> bool:
        """Whether the unit's round goes on with another episode (until a ``per_round`` memory is filled)."""
        stored = len(self._memories[unit]) + (0 if self._pending is None else int(self._pending.counts[unit]))
        return self.config.trajectory_memory == "per_round" and stored < self.config.memory_size

    def set_extra_loss(self, fn: ExtraLoss | None) -> None:
        """Add ``fn(net)``, a scalar, to each minibatch's loss (FedProx's proximal term); None: nothing."""
        self._model.extra_loss = fn

    def update(self) -> UpdateStats:
        """K optimisations on windows of each unit's memory (lines 11-24), each step its own gradient."""
        return hand_back(self.update_steps())

    def update_steps(self) -> Generator[Gradient, Gradient, UpdateStats]:
        """The update as a generator (:func:`~fleetrl.agent.update.ppo_update`) that returns the units' mean
        statistics; RuntimeError at its first step if a memory is empty."""
        empty = [u for u, memory in enumerate(self.memories) if len(memory) == 0]
        if empty:
            raise RuntimeError(f"update() needs a transition in every unit's memory; units {empty} have none")
        self._score_new_transitions()
        data = [memory.transitions() for memory in self.memories]
        finished = yield from ppo_update(self._model, data, self._window_rngs)
        self._last_actor_gradient = finished.actor_gradient
        self.unit_stats = finished.unit_stats
        self._end_round()
        return finished.stats

    # ---- the update as flat vectors, step by step (a scheme that combines the fleet's step gradients) ----

    def update_step_count(self) -> int:
        """How many steps an update takes: K, or 2K with ``optimisers='one_sequential'``."""
        return self.config.n_optimisations * len(self._parts)

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of step ``k``'s flat gradient: ``critic:<name>`` then ``actor:<name>`` (with
        ``one_sequential`` the critic at even, the actor at odd steps)."""
        return [
            (f"{part}:{name}", shape)
            for part, named, _ in self._step_named(k)
            for name, shape in layout(named)
        ]

    def begin_update(self) -> int:
        """Start :meth:`update_steps` (line 11 and step 0's gradient); the number of steps it takes."""
        if self._exchange is not None:
            raise RuntimeError("an update is already under way: finish it with end_update()")
        parts = lambda k: [(named, own) for _, named, own in self._step_named(k)]  # noqa: E731
        self._exchange = StepExchange(self.update_steps(), parts, self.update_step_count())
        return self._exchange.count

    def step_gradients(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient, flat float32 in :meth:`step_layout` order; each step is applied
        (:meth:`apply_step`) before the next is asked for."""
        return self._exchange_under_way().gradient_of(k)

    def apply_step(self, flat_grad: np.ndarray) -> None:
        """Lines 21 and 23: step the optimiser(s) with a gradient (its own, or the fleet's) for the step last
        asked for, then take the next step's gradient."""
        self._exchange_under_way().apply(flat_grad)

    def apply_fleet_step(self, k: int, flat_grad: np.ndarray) -> None:
        """Step the optimiser(s) with the fleet's gradient of step ``k`` of an update this agent took no part
        in (a straggler catching up)."""
        if self._exchange is not None:
            raise RuntimeError("an update is under way: its steps are applied with apply_step()")
        parts = self._step_named(k)
        chunks = split(flat_grad, [item for _, named, _ in parts for item in named], "step gradient")
        self._score_new_transitions()
        start = 0
        for part, named, _ in parts:  # the unit's own offsets: no gradient of theirs, not stepped
            self._model.step(part, chunks[start : start + len(named)])
            start += len(named)
        self._policy.refresh(self.net)

    def end_update(self) -> UpdateStats:
        """The update's statistics."""
        stats = self._exchange_under_way().finished()
        self._exchange = None
        return stats

    def abandon_update(self) -> None:
        """Drop the round's update (the fleet went on past this agent); the steps applied stay."""
        if self._exchange is not None:
            self._exchange.abandon()
        self._exchange = None
        self._end_round()

    def _end_round(self) -> None:
        self._policy.refresh(self.net)
        if self.config.trajectory_memory == "per_round":
            for memory in self.memories:
                memory.clear()

    def _exchange_under_way(self) -> StepExchange:
        if self._exchange is None:
            raise RuntimeError("no update under way: call begin_update() first")
        return self._exchange

    def _step_named(self, k: int) -> list[tuple[str, Named, int]]:
        named = {CRITIC: (self._critic_named, self._critic_own), ACTOR: (self._actor_named, self._actor_own)}
        return [(part, named[part][0], len(named[part][1])) for part in self._parts[k % len(self._parts)]]

    def _score_new_transitions(self) -> None:
        """Record log π(a|s) of the acting policy for every unit's transitions stored since θ last changed."""
        score_unscored(self.memories, self._log_probs)

    def _log_probs(self, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.net.log_probs(torch.from_numpy(obs), torch.from_numpy(actions)).numpy()

    # ---- what the federation exchanges (lines 8, 25, 29, 31) -------------------------------------------

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of θ, in the order of every flat actor vector (gradient or parameters)."""
        return layout(self._actor_named)

    def actor_gradient(self) -> np.ndarray:
        """The actor's last gradient of the round (line 25), flat float32."""
        if self._last_actor_gradient is None:
            raise RuntimeError("no actor gradient yet: call update() first")
        return flatten_tensors(self._last_actor_gradient[: len(self._actor_named)])

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        """Line 31: update π_θ with a received (average) gradient ḡ through the actor's Adam."""
        chunks = split(flat, self._actor_named, "actor gradient")
        self._score_new_transitions()
        self._model.step(ACTOR, chunks)
        self._policy.refresh(self.net)

    def actor_parameters(self) -> np.ndarray:
        """θ as flat float32 (line 8: what a finished worker sends)."""
        return flatten(self._actor_named)

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        """Line 29: replace θ with received parameters θ̄."""
        self._replace(self._actor_named, flat, "actor parameter")

    # The whole actor-critic (θ and μ), for the schemes that average models.

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of every network parameter, in flat order."""
        return layout(self._model_named())

    def model_parameters(self) -> np.ndarray:
        """Every network parameter as flat float32."""
        return flatten(self._model_named())

    def set_model_parameters(self, flat: np.ndarray) -> None:
        """Replace every network parameter (the Adam states are kept)."""
        self._replace(self._model_named(), flat, "model parameter")

    def _model_named(self) -> Named:
        return self._actor_named + self.net.head_parameters("value")

    def _replace(self, named: Named, flat: np.ndarray, what: str) -> None:
        chunks = split(flat, named, what)
        self._score_new_transitions()
        with torch.no_grad():
            for (_, p), value in zip(named, chunks, strict=True):
                p.copy_(value)
        self._policy.refresh(self.net)

    # ---- resumable state (fleetrl.agent.state) and model files (fleetrl.agent.checkpoint) ---------------

    def optimisers(self) -> dict[str, torch.optim.Optimizer]:
        """The Adam optimisers by name: ``actor`` and ``critic``, or the one ``shared`` optimiser."""
        if self.actor_optimizer is self.critic_optimizer:
            return {"shared": self.actor_optimizer}
        return {"actor": self.actor_optimizer, "critic": self.critic_optimizer}

    def optimiser_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the optimisers' state as one flat vector."""
        return optimisers.optimiser_layout(self.optimisers())

    def optimiser_parameters(self) -> np.ndarray:
        """The optimisers' state, flat float32."""
        return optimisers.optimiser_flat(self.optimisers())

    def set_optimiser_parameters(self, flat: np.ndarray) -> None:
        """Replace the optimisers' state (a fleet's, from the chief)."""
        optimisers.load_optimiser_flat(self.optimisers(), flat)

    def rng_states(self) -> dict[str, Any]:
        """Unit 0's bit-generator states of action sampling and window starts (JSON-ready)."""
        return {
            "act": self._act_rngs[0].bit_generator.state,
            "window": self._window_rngs[0].bit_generator.state,
        }

    def load_rng_states(self, states: dict[str, Any]) -> None:
        """Continue unit 0's action sampling and window starts from :meth:`rng_states`."""
        self._act_rngs[0].bit_generator.state = states["act"]
        self._window_rngs[0].bit_generator.state = states["window"]

    def refresh_policy(self) -> None:
        """Copy the network into the acting policy after its weights were changed in place."""
        self._policy.refresh(self.net)

    def architecture(self) -> dict[str, Any]:
        """What a model file must match to be loaded into this agent."""
        return architecture(self)

    def save(self, path: str | Path) -> None:
        """Write the model file: the network weights with config, architecture and seed."""
        save_agent(self, path)

    @classmethod
    def load(
        cls,
        path: str | Path,
        obs_dim: int | None = None,
        n_actions: int | None = None,
        action_space: ActionSpace | None = None,
    ) -> PPOAgent:
        """An agent rebuilt from a model file (:func:`.checkpoint.load_agent`)."""
        return load_agent(cls, path, obs_dim, n_actions, action_space)

    def load_weights(self, tensors: dict[str, np.ndarray], source: str) -> None:
        """Replace the network's weights with a model file's ``tensors``."""
        check_tensors_fit(tensors, {k: tuple(t.shape) for k, t in self.net.state_dict().items()}, source)
        self._score_new_transitions()
        state = {k: torch.from_numpy(np.asarray(v, dtype=np.float32)) for k, v in tensors.items()}
        self.net.load_state_dict(state)
        self._policy.refresh(self.net)
