"""The Actor-Critic PPO agent of one worker (Eqs. 2-7; Algorithm 2, lines 3, 5, 8, 11-25, 29, 31)."""

from __future__ import annotations

from collections.abc import Generator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fleetrl.agent.action_space import ActionSpace, as_action_space
from fleetrl.agent.checkpoint import (
    check_tensors_fit,
)
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.flat import Named, flatten, flatten_tensors, layout, split
from fleetrl.agent.memory import TrajectoryMemory
from fleetrl.agent.model_file import architecture, load_agent, save_agent
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.optimiser_flat import load_optimiser_flat, optimiser_flat, optimiser_layout
from fleetrl.agent.policy_numpy import NumpyPolicy
from fleetrl.agent.update import (
    ACTOR,
    CRITIC,
    ExtraLoss,
    Gradient,
    Model,
    StepExchange,
    UpdateStats,
    choose_variants,
    hand_back,
    ppo_update,
)

__all__ = ["PPOAgent", "UpdateStats"]


def checked_weights(weights: Sequence[float] | None, units: int) -> np.ndarray | None:
    """``weights`` as float64, one positive finite number per unit (None stays None); else a ValueError."""
    if weights is None:
        return None
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (units,) or not np.isfinite(w).all() or not (w > 0).all():
        raise ValueError(f"unit weights must be {units} positive finite numbers, got {list(weights)}")
    return w


class PPOAgent:
    """Actor-Critic PPO with a shared trunk; θ = trunk + policy head, μ = value head (+ trunk if shared).

    The actor head follows the action space: a softmax over ``n`` discrete actions, or for a box a
    Gaussian (mean from the trunk, state-independent log-std) whose samples the env receives clipped to
    the bounds (:meth:`env_action`); the memory keeps the unclipped sample, whose density is log π.

    :param obs_dim: length of an observation
    :param actions: the action space; an int is that many discrete actions
    :param config: hyper-parameters (a preset from :func:`fleetrl.agent.config.get_preset`, or a variant)
    :param seed: fixes the initial weights (torch generator), action sampling and window starts (numpy)
    """

    def __init__(self, obs_dim: int, actions: int | ActionSpace, config: PPOConfig, seed: int) -> None:
        config.validate()
        self.action_space = as_action_space(actions)
        self.obs_dim = obs_dim
        self.n_actions = self.action_space.n
        """number of discrete actions (0 for a box)"""
        self.config = config
        self.seed = seed
        generator = torch.Generator().manual_seed(seed)
        act_seed, window_seed = np.random.SeedSequence(seed).spawn(2)
        self._act_rng = np.random.default_rng(act_seed)
        self._window_rng = np.random.default_rng(window_seed)
        self.net = ActorCritic.from_config(obs_dim, self.action_space, config, generator)
        trunk = self.net.trunk_parameters()
        # θ: the actor model — the shared trunk and the actor head (softmax, or Gaussian mean and log-std);
        # this is what the federation shares.
        self._actor_named = trunk + self.net.head_parameters("policy")
        # μ: the critic model — the value head, plus the trunk when both optimisers step it ("shared").
        value_head = self.net.head_parameters("value")
        self._critic_named = (trunk if config.trunk_split == "shared" else []) + value_head
        if config.optimisers == "per_model":
            self.actor_optimizer = torch.optim.Adam([p for _, p in self._actor_named], lr=config.actor_lr)
            self.critic_optimizer = torch.optim.Adam([p for _, p in self._critic_named], lr=config.critic_lr)
        else:  # one Adam over the whole network: each step moves only the parameters given a gradient
            shared = torch.optim.Adam([p for _, p in self._model_named()], lr=config.actor_lr)
            self.actor_optimizer = self.critic_optimizer = shared
        self.memory = TrajectoryMemory(
            config.memory_size,
            obs_dim,
            grows=config.trajectory_memory == "per_round",
            action_dim=self.action_space.dim,
        )
        self._policy = NumpyPolicy(self.net)
        self._discrete = self.action_space.is_discrete
        self._model = Model(
            self.net,
            [p for _, p in self._actor_named],
            [p for _, p in self._critic_named],
            [p for _, p in trunk + value_head],  # L^V is differentiated w.r.t. both in either split
            len(trunk),
            self.actor_optimizer,
            self.critic_optimizer,
            config,
            choose_variants(config),  # the preset's variants, chosen once
        )
        self._parts = self._model.variants.parts
        self._last_actor_gradient: Gradient | None = None
        """line 25's gradient: the last actor gradient the update applied (as applied, i.e. clipped)"""
        self._exchange: StepExchange | None = None
        self._unit_weights: np.ndarray | None = None
        """the units' weights of the update :meth:`begin_update` starts (None: the same; read as it starts)"""

    @property
    def units(self) -> int:
        """The units this agent acts for: one (a unit host's agent: U)."""
        return 1

    # ---- acting (Algorithm 2, lines 3 and 5) ------------------------------------------------------------

    def act(self, obs: np.ndarray) -> Any:
        """Sample a_t ~ π_θ(·|s_t) (line 3) on the numba copy of the actor: an action index, or for a box a
        float32 vector as sampled (not clipped; send the env :meth:`env_action` of it, remember it as is)."""
        if self._discrete:
            return self._policy.act(obs, float(self._act_rng.random()))
        return self._policy.act_continuous(obs, self._act_rng.standard_normal(self.action_space.dim))

    def act_greedy(self, obs: np.ndarray) -> Any:
        """The most probable action under π_θ (evaluation): the arg-max index, or the Gaussian's mean
        clipped to the box."""
        if self._discrete:
            return self._policy.act_greedy(obs)
        return self._policy.act_continuous(obs, None)

    def env_action(self, action: Any) -> Any:
        """What the env is sent for an action of :meth:`act`: the index itself, or the vector clipped to
        the box (the clip belongs to the env's side: log π stays the Gaussian density of the sample)."""
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
        """Store ⟨s_t, a_t, r_{t+1}, s_{t+1}⟩ in the trajectory memory (line 5)."""
        self.memory.add(obs, action, reward, next_obs, terminated, truncated)

    # ---- learning (Algorithm 2, lines 11-25) ----------------------------------------------------------

    def needs_more_episodes(self) -> bool:
        """Whether the round goes on with another episode before its update: never for a ``ring`` memory (a
        round is one episode); for ``per_round`` until the memory holds ``memory_size`` transitions."""
        return self.config.trajectory_memory == "per_round" and not self.memory.filled()

    def set_extra_loss(self, fn: ExtraLoss | None) -> None:
        """Add ``fn(model)``, a scalar tensor of the network, to each minibatch's loss (FedProx's proximal
        term μ/2·‖θ − θ_global‖², say): every step's gradient gains ∇fn over the parameters the step moves.
        None (the default) adds nothing, and every number is as without the hook."""
        self._model.extra_loss = fn

    def update(self) -> UpdateStats:
        """K optimisations on contiguous windows of U transitions (lines 11-24), every step applying its own
        gradient (:func:`~fleetrl.agent.update.hand_back`); keeps line 25's gradient."""
        return hand_back(self.update_steps())

    def update_steps(self) -> Generator[Gradient, Gradient, UpdateStats]:
        """The update as a generator (:func:`~fleetrl.agent.update.ppo_update`): it yields each step's
        gradient and applies the gradient sent back; then the acting copy follows θ, a ``per_round`` memory
        is emptied, and it returns the statistics.

        :raises RuntimeError: (at the first step) the trajectory memory is empty
        """
        if len(self.memory) == 0:
            raise RuntimeError("update() needs at least one transition in the trajectory memory")
        self._score_new_transitions()
        finished = yield from ppo_update(self._model, self.memory.transitions(), self._window_rng)
        self._last_actor_gradient = finished.actor_gradient
        self._policy.refresh(self.net)
        if self.config.trajectory_memory == "per_round":
            self.memory.clear()
        return finished.stats

    # ---- the update as flat vectors, step by step (a scheme that combines the fleet's step gradients) ----

    def update_step_count(self) -> int:
        """How many steps an update takes: K, or 2K with ``optimisers='one_sequential'``."""
        return self.config.n_optimisations * len(self._parts)

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of step ``k``'s flat gradient: ``critic:<name>`` over the critic optimiser's
        parameters, then ``actor:<name>`` over θ, for the parts the step moves (both with ``per_model``;
        the critic's at even, the actor's at odd steps with ``one_sequential``); needs no update under way."""
        return [
            (f"{part}:{name}", shape) for part, named in self._step_named(k) for name, shape in layout(named)
        ]

    def begin_update(self, unit_weights: Sequence[float] | None = None) -> int:
        """Start :meth:`update_steps` (line 11 and step 0's gradient); the number of steps it takes.

        :param unit_weights: what each unit's minibatch gradient weighs in the update's gradient (one per
            unit; None: the same). One unit's gradient is its own whatever its weight (the weight counts
            at the chief, in the fleet's mean); a unit host weighs its units' gradients by them.
        :raises RuntimeError: the trajectory memory is empty, or an update is already under way
        :raises ValueError: ``unit_weights`` is not one positive finite number per unit
        """
        if self._exchange is not None:
            raise RuntimeError("an update is already under way: finish it with end_update()")
        self._unit_weights = checked_weights(unit_weights, self.units)
        try:  # the update reads the weights as it starts (StepExchange computes step 0 at once)
            self._exchange = StepExchange(self.update_steps())
        finally:
            self._unit_weights = None
        return self.update_step_count()

    def step_gradients(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient as flat float32 in :meth:`step_layout` order, nothing stepped. Steps go in
        order, each applied (:meth:`apply_step`) before the next is asked for.

        :raises RuntimeError: no update under way, ``k`` is not the next step, or the last gradient was
            not applied yet
        """
        exchange = self._exchange_under_way()
        if exchange.taken:
            raise RuntimeError(f"step {exchange.step}'s gradient is not applied yet: call apply_step()")
        if exchange.gradient is None or k != exchange.step:
            n = self.update_step_count()
            raise RuntimeError(f"step {k} requested, but step {exchange.step} of {n} is next")
        exchange.taken = True
        return flatten_tensors(exchange.gradient)

    def apply_step(self, flat_grad: np.ndarray) -> None:
        """Lines 21 and 23: step the optimiser(s) with a gradient for the step last asked for (its own, or
        a combination of several workers' in the same layout); then the next step's gradient is taken.

        :raises RuntimeError: no step's gradient is waiting to be applied
        :raises ValueError: the vector does not fit :meth:`step_layout` or is not finite
        """
        exchange = self._exchange_under_way()
        if not exchange.taken:
            raise RuntimeError("no step gradient to apply: call step_gradients(k) first")
        named = [item for _, part in self._step_named(exchange.step) for item in part]
        exchange.send(split(flat_grad, named, "step gradient"))

    def apply_fleet_step(self, k: int, flat_grad: np.ndarray) -> None:
        """Step the optimiser(s) with the fleet's gradient of step ``k`` of an update this agent took no part
        in (a straggler catching up): the same optimiser steps :meth:`apply_step` takes, no update under way.

        :raises RuntimeError: an update is under way
        :raises ValueError: the vector does not fit :meth:`step_layout` ``(k)`` or is not finite
        """
        if self._exchange is not None:
            raise RuntimeError("an update is under way: its steps are applied with apply_step()")
        parts = self._step_named(k)
        chunks = split(flat_grad, [item for _, named in parts for item in named], "step gradient")
        self._score_new_transitions()
        start = 0
        for part, named in parts:
            self._model.step(part, chunks[start : start + len(named)])
            start += len(named)
        self._policy.refresh(self.net)

    def end_update(self) -> UpdateStats:
        """The update's statistics (the acting copy follows θ, a ``per_round`` memory is emptied).

        :raises RuntimeError: no update under way, or not every step was applied
        """
        exchange = self._exchange_under_way()
        if exchange.stats is None:
            raise RuntimeError(f"end_update() after {exchange.step} of {self.update_step_count()} steps")
        self._exchange = None
        return exchange.stats

    def abandon_update(self) -> None:
        """Drop the round's update, under way or not begun (the fleet went on past this agent: it takes the
        fleet's model next). The steps applied stay; the acting copy follows θ; the round's transitions are
        dropped where a round's memory is its own (``per_round``)."""
        if self._exchange is not None:
            self._exchange.abandon()
        self._exchange = None
        self._policy.refresh(self.net)
        if self.config.trajectory_memory == "per_round":
            self._clear_round_memory()

    def _clear_round_memory(self) -> None:
        self.memory.clear()

    def _exchange_under_way(self) -> StepExchange:
        if self._exchange is None:
            raise RuntimeError("no update under way: call begin_update() first")
        return self._exchange

    def _step_named(self, k: int) -> list[tuple[str, Named]]:
        named = {CRITIC: self._critic_named, ACTOR: self._actor_named}
        return [(part, named[part]) for part in self._parts[k % len(self._parts)]]

    def _score_new_transitions(self) -> None:
        """Record log π(a|s) of the acting policy for transitions stored since θ last changed."""
        slots = self.memory.unscored()
        if slots.size == 0:
            return
        obs, actions = self.memory.slots(slots)
        with torch.no_grad():
            log_probs = self.net.log_probs(torch.from_numpy(obs), torch.from_numpy(actions))
        self.memory.score(slots, log_probs.numpy())

    # ---- what the federation exchanges (lines 8, 25, 29, 31) -------------------------------------------

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of θ, in the order of every flat actor vector (gradient or parameters)."""
        return layout(self._actor_named)

    def actor_gradient(self) -> np.ndarray:
        """The actor's last gradient of the round (line 25) as flat float32, in :meth:`actor_layout` order."""
        if self._last_actor_gradient is None:
            raise RuntimeError("no actor gradient yet: call update() first")
        return flatten_tensors(self._last_actor_gradient)

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        """Line 31: update π_θ with a received (average) gradient ḡ through the actor's Adam."""
        chunks = split(flat, self._actor_named, "actor gradient")
        self._score_new_transitions()
        params = [p for _, p in self._actor_named]
        for p, g in zip(params, chunks, strict=True):
            p.grad = g
        self.actor_optimizer.step()
        for p in params:
            p.grad = None
        self._policy.refresh(self.net)

    def actor_parameters(self) -> np.ndarray:
        """θ as flat float32 in :meth:`actor_layout` order (line 8: what a finished worker sends)."""
        return flatten(self._actor_named)

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        """Line 29: replace θ with received parameters θ̄ (the critic head and Adam state are kept)."""
        self._replace(self._actor_named, flat, "actor parameter")

    # The whole actor-critic (θ and μ: trunk, policy head and value head), for the ``fedavg`` scheme, which
    # averages models rather than actor gradients (docs/algorithm.md, "Federation schemes").

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of every network parameter, in the order of every flat model vector."""
        return layout(self._model_named())

    def model_parameters(self) -> np.ndarray:
        """Every network parameter as flat float32 in :meth:`model_layout` order."""
        return flatten(self._model_named())

    def set_model_parameters(self, flat: np.ndarray) -> None:
        """Replace every network parameter (both Adam states are kept: each worker's own optimiser)."""
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

    # ---- resumable state (fleetrl.agent.state) --------------------------------------------------------

    def optimisers(self) -> dict[str, torch.optim.Optimizer]:
        """The Adam optimisers by name: ``actor`` and ``critic``, or the one ``shared`` optimiser."""
        if self.actor_optimizer is self.critic_optimizer:
            return {"shared": self.actor_optimizer}
        return {"actor": self.actor_optimizer, "critic": self.critic_optimizer}

    def optimiser_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the optimisers' state as one flat vector (:mod:`.optimiser_flat`)."""
        return optimiser_layout(self.optimisers())

    def optimiser_parameters(self) -> np.ndarray:
        """The optimisers' state, flat float32 in :meth:`optimiser_layout` order."""
        return optimiser_flat(self.optimisers())

    def set_optimiser_parameters(self, flat: np.ndarray) -> None:
        """Replace the optimisers' state (a fleet's, from the chief)."""
        load_optimiser_flat(self.optimisers(), flat)

    def rng_states(self) -> dict[str, Any]:
        """The bit-generator states of action sampling and window starts (JSON-ready)."""
        return {"act": self._act_rng.bit_generator.state, "window": self._window_rng.bit_generator.state}

    def load_rng_states(self, states: dict[str, Any]) -> None:
        """Continue action sampling and window starts from :meth:`rng_states`."""
        self._act_rng.bit_generator.state = states["act"]
        self._window_rng.bit_generator.state = states["window"]

    def refresh_policy(self) -> None:
        """Copy the network into the acting policy after its weights were changed in place."""
        self._policy.refresh(self.net)

    # ---- model files (fleetrl.agent.model_file) ---------------------------------------------------------

    def architecture(self) -> dict[str, Any]:
        """What a model file must match to be loaded into this agent (:func:`.model_file.architecture`)."""
        return architecture(self)

    def save(self, path: str | Path) -> None:
        """Write the network weights (safetensors) with config, architecture and seed as JSON metadata."""
        save_agent(self, path)

    @classmethod
    def load(
        cls,
        path: str | Path,
        obs_dim: int | None = None,
        n_actions: int | None = None,
        action_space: ActionSpace | None = None,
    ) -> PPOAgent:
        """An agent rebuilt from a model file (:func:`.model_file.load_agent`).

        :raises FileNotFoundError: no file at ``path``
        :raises CheckpointError: corrupt file, not a fleetrl model, or a model for another architecture
        """
        return load_agent(cls, path, obs_dim, n_actions, action_space)

    def load_weights(self, tensors: dict[str, np.ndarray], source: str) -> None:
        """Replace the network's weights with a model file's ``tensors`` (``source``: for errors)."""
        check_tensors_fit(tensors, {k: tuple(t.shape) for k, t in self.net.state_dict().items()}, source)
        self._score_new_transitions()
        self.net.load_state_dict(
            {k: torch.from_numpy(np.asarray(v, dtype=np.float32)) for k, v in tensors.items()}
        )
        self._policy.refresh(self.net)
