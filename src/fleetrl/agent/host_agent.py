"""The agent of a unit host: one PPO agent (one network, one optimiser state) acting and learning for U units.

Each unit keeps what makes it a unit: its own trajectory memory and its own random streams for actions and
window starts, drawn from its own seed exactly as :class:`~fleetrl.agent.ppo.PPOAgent` draws them. So a host
of one unit acts and learns as the agent of that unit alone. Acting takes one call for every unit's
observation (:meth:`HostAgent.act_units`: each unit's draw from its own stream in one compiled loop,
:mod:`~fleetrl.agent.unit_draws`; the actions by matrix products, each the per-row kernel's,
:mod:`~fleetrl.agent.row_acting`), and remembering one call for every unit's transition
(:meth:`HostAgent.remember_units`, :mod:`~fleetrl.agent.pending`). The update is
:func:`~fleetrl.agent.host_update.host_update` (one forward and one backward pass over the units' minibatches
per step). The flat-vector API a per-step scheme drives (``begin_update`` … ``end_update``,
``apply_fleet_step``, the model and optimiser vectors) is the :class:`PPOAgent`'s, on the host's one network.
"""

from __future__ import annotations

from collections.abc import Generator, Sequence

import numpy as np
import torch

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import PPOConfig, host_config_problem
from fleetrl.agent.host_update import host_update
from fleetrl.agent.memory import TrajectoryMemory
from fleetrl.agent.pending import PendingTransitions
from fleetrl.agent.ppo import PPOAgent
from fleetrl.agent.row_acting import RowActing
from fleetrl.agent.unit_draws import UniformDraws
from fleetrl.agent.update import Gradient, UpdateStats

__all__ = ["HostAgent"]


class HostAgent(PPOAgent):
    """One policy for U units (see the module's docstring).

    :param obs_dim: length of an observation
    :param actions: the action space; an int is that many discrete actions
    :param config: hyper-parameters (``gae_scope='memory'`` and ``optimisers='per_model'``)
    :param seeds: one per unit: its action draws and window starts (unit 0's also draws the initial weights,
        as a unit's own agent would)
    :raises ValueError: no seed, or a config a host cannot update (one line saying which setting)
    """

    def __init__(
        self, obs_dim: int, actions: int | ActionSpace, config: PPOConfig, seeds: Sequence[int]
    ) -> None:
        if not seeds:
            raise ValueError("a unit host needs at least one unit (one seed)")
        problem = host_config_problem(config)
        if problem is not None:
            raise ValueError(problem)
        super().__init__(obs_dim, actions, config, seed=seeds[0])
        self.seeds = tuple(seeds)
        streams = [np.random.SeedSequence(seed).spawn(2) for seed in seeds[1:]]
        self._act_rngs = [self._act_rng, *(np.random.default_rng(act) for act, _ in streams)]
        self._window_rngs = [self._window_rng, *(np.random.default_rng(window) for _, window in streams)]
        self._memories = [self.memory] + [
            TrajectoryMemory(
                config.memory_size,
                obs_dim,
                grows=config.trajectory_memory == "per_round",
                action_dim=self.action_space.dim,
            )
            for _ in seeds[1:]
        ]
        self._pending = PendingTransitions(len(seeds), obs_dim, self.action_space.dim)
        self._draws = UniformDraws(self._act_rngs)
        self._rows = RowActing(self._policy) if self._discrete else None
        self.unit_stats: tuple[UpdateStats, ...] | None = None
        """each unit's statistics of the last update (None before the first)"""

    @property
    def units(self) -> int:
        """U, the units this agent acts for."""
        return len(self.seeds)

    @property
    def memories(self) -> list[TrajectoryMemory]:
        """Each unit's trajectory memory (unit u's is ``memories[u]``), its pending transitions moved in."""
        self.store_pending()
        return self._memories

    def store_pending(self) -> None:
        """Move the transitions :meth:`remember_units` holds into each unit's memory (``memory``, unit 0's,
        included); everything that reads the memories does it first."""
        self._pending.drain(self._memories)

    # ---- acting ----

    def act_units(self, obs: np.ndarray, units: np.ndarray) -> np.ndarray:
        """Sample a_t ~ π_θ(·|s_t) for the distinct units ``units`` at their observations ``obs`` (one row
        each), each with its own draw: the action each unit's own agent would take (as :meth:`PPOAgent.act`):
        for a discrete space the indices (int64, one per unit), in one pass over every row; for a box the
        sampled vectors (float32, one row per unit), one Gaussian draw per unit."""
        if self._rows is not None:
            return self._rows.act(obs, self._draws.draw(units))
        dim = self.action_space.dim
        return np.array(
            [
                self._policy.act_continuous(row, self._act_rngs[u].standard_normal(dim))
                for row, u in zip(obs, units.tolist(), strict=True)
            ],
            dtype=np.float32,
        ).reshape(len(units), dim)

    def remember_units(
        self,
        units: np.ndarray,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
    ) -> None:
        """:meth:`remember_unit` for each of the distinct units ``units`` (row j of each array is
        ``units[j]``'s transition), in one call."""
        self._pending.add(units, obs, actions, rewards, next_obs, terminated, truncated, self._memories)

    def remember_unit(
        self,
        unit: int,
        obs: np.ndarray,
        action: int | np.ndarray,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        truncated: bool,
    ) -> None:
        """Store ⟨s_t, a_t, r_{t+1}, s_{t+1}⟩ in unit ``unit``'s trajectory memory (line 5)."""
        self.memories[unit].add(obs, action, reward, next_obs, terminated, truncated)

    def unit_needs_more_episodes(self, unit: int) -> bool:
        """:meth:`PPOAgent.needs_more_episodes` for unit ``unit``'s memory (its pending transitions
        counted)."""
        memory = self._memories[unit]
        stored = len(memory) + int(self._pending.counts[unit])
        return self.config.trajectory_memory == "per_round" and stored < memory.capacity

    # ---- learning ----

    def _clear_round_memory(self) -> None:
        for memory in self.memories:
            memory.clear()

    def update_steps(self) -> Generator[Gradient, Gradient, UpdateStats]:
        """The host's update (:func:`~fleetrl.agent.host_update.host_update`) as a generator, like
        :meth:`PPOAgent.update_steps`; keeps each unit's statistics in :attr:`unit_stats`.

        :raises RuntimeError: (at the first step) some unit's trajectory memory is empty
        """
        empty = [u for u, memory in enumerate(self.memories) if len(memory) == 0]
        if empty:
            raise RuntimeError(f"update() needs a transition in every unit's memory; units {empty} have none")
        self._score_new_transitions()
        data = [memory.transitions() for memory in self.memories]
        finished = yield from host_update(self._model, data, self._window_rngs, self._unit_weights)
        self._last_actor_gradient = finished.actor_gradient
        self.unit_stats = finished.unit_stats
        self._policy.refresh(self.net)
        if self.config.trajectory_memory == "per_round":
            for memory in self.memories:
                memory.clear()
        return finished.stats

    def _score_new_transitions(self) -> None:
        """Record log π(a|s) of the acting policy for every unit's transitions stored since θ last changed,
        in one forward pass."""
        slots = [memory.unscored() for memory in self.memories]
        if not any(s.size for s in slots):
            return
        stored = [memory.slots(s) for memory, s in zip(self.memories, slots, strict=True)]
        obs = np.concatenate([o for o, _ in stored])
        actions = np.concatenate([a for _, a in stored])
        with torch.no_grad():
            log_probs = self.net.log_probs(torch.from_numpy(obs), torch.from_numpy(actions)).numpy()
        at = 0
        for memory, s in zip(self.memories, slots, strict=True):
            memory.score(s, log_probs[at : at + s.size])
            at += s.size
