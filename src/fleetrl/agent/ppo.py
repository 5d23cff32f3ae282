"""The Actor-Critic PPO agent of one worker (Eqs. 2-7; Algorithm 2, lines 3, 5, 8, 11-25, 29, 31)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from fleetrl.agent.checkpoint import CheckpointError, read_checkpoint, write_checkpoint
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.losses import clipped_surrogate, critic_loss, gae, td_targets
from fleetrl.agent.memory import TrajectoryMemory, sample_window
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.policy_numpy import NumpyPolicy


@dataclass(frozen=True)
class UpdateStats:
    """What one round's update did, averaged over its K optimisations."""

    actor_loss: float
    """−L^CLIP (Eq. 6), the quantity the actor minimises (entropy bonus not included)"""
    critic_loss: float
    """L^V (Eq. 3)"""
    entropy: float
    """mean entropy of π_θ over the sampled windows (nats)"""
    approx_kl: float
    """mean of (R − 1) − log R, an estimate of KL(π_θold ‖ π_θ) (diagnostic)"""
    clip_fraction: float
    """share of samples whose ratio R_t lay outside [1 − ε, 1 + ε] (diagnostic)"""


class PPOAgent:
    """Actor-Critic PPO with a shared trunk; θ = trunk + policy head, μ = value head (+ trunk if shared).

    :param obs_dim: length of an observation
    :param n_actions: number of discrete actions
    :param config: hyper-parameters (a preset from :func:`fleetrl.agent.config.get_preset`, or a variant)
    :param seed: fixes the initial weights (torch generator), action sampling and window starts (numpy)
    """

    def __init__(self, obs_dim: int, n_actions: int, config: PPOConfig, seed: int) -> None:
        config.validate()
        self.obs_dim = obs_dim
        self.n_actions = n_actions
        self.config = config
        self.seed = seed
        generator = torch.Generator().manual_seed(seed)
        act_seed, window_seed = np.random.SeedSequence(seed).spawn(2)
        self._act_rng = np.random.default_rng(act_seed)
        self._window_rng = np.random.default_rng(window_seed)
        self.net = ActorCritic.from_config(obs_dim, n_actions, config, generator)
        trunk = self.net.trunk_parameters()
        # θ: the actor model — the shared trunk and the softmax head; this is what the federation shares.
        self._actor_named = trunk + self.net.head_parameters("policy")
        # μ: the critic model — the value head, plus the trunk when both optimisers step it ("shared").
        value_head = self.net.head_parameters("value")
        self._critic_named = (trunk if config.trunk_split == "shared" else []) + value_head
        # The critic loss is differentiated w.r.t. trunk and value head in both splits (see _step).
        self._critic_grad_params = [p for _, p in trunk + value_head]
        self._n_trunk = len(trunk)
        self.actor_optimizer = torch.optim.Adam([p for _, p in self._actor_named], lr=config.actor_lr)
        self.critic_optimizer = torch.optim.Adam([p for _, p in self._critic_named], lr=config.critic_lr)
        self.memory = TrajectoryMemory(config.memory_size, obs_dim)
        self._policy = NumpyPolicy(self.net)
        self._last_actor_gradient: np.ndarray | None = None

    # ---- acting (Algorithm 2, lines 3 and 5) ------------------------------------------------------------

    def act(self, obs: np.ndarray) -> int:
        """Sample a_t ~ π_θ(·|s_t) (line 3) on the numba copy of the actor."""
        return self._policy.act(obs, float(self._act_rng.random()))

    def act_greedy(self, obs: np.ndarray) -> int:
        """The most probable action under π_θ (evaluation)."""
        return self._policy.act_greedy(obs)

    def remember(
        self,
        obs: np.ndarray,
        action: int,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        truncated: bool,
    ) -> None:
        """Store ⟨s_t, a_t, r_{t+1}, s_{t+1}⟩ in the trajectory memory (line 5)."""
        self.memory.add(obs, action, reward, next_obs, terminated, truncated)

    # ---- learning (Algorithm 2, lines 11-25) ----------------------------------------------------------

    def update(self) -> UpdateStats:
        """K optimisations on contiguous windows of U transitions (lines 11-24); keeps line 25's gradient."""
        cfg = self.config
        if len(self.memory) == 0:
            raise RuntimeError("update() needs at least one transition in the trajectory memory")
        self._score_new_transitions()
        data = self.memory.transitions()
        obs = torch.from_numpy(data.obs)
        actions = torch.from_numpy(data.actions)
        rewards = torch.from_numpy(data.rewards)
        next_obs = torch.from_numpy(data.next_obs)
        terminated = torch.from_numpy(data.terminated)
        episode_end = torch.from_numpy(data.episode_end)

        # Line 11: π_θold ← π_θ — the log-probabilities of the stored actions under the policy as it is now.
        with torch.no_grad():
            logits, values = self.net(obs)
            old_log_probs = functional.log_softmax(logits, dim=-1).gather(1, actions[:, None]).squeeze(1)
            if cfg.old_policy == "behaviour":
                old_log_probs = torch.from_numpy(data.behaviour_log_probs)
            if cfg.gae_scope == "memory":  # Eq. 2 once over the whole memory, critic frozen at line 11
                next_values = self.net.value_of(next_obs)
                memory_adv = gae(
                    rewards, values, next_values, terminated, episode_end, cfg.gamma, cfg.gae_lambda
                )

        totals = np.zeros(5)
        for _ in range(cfg.n_optimisations):  # line 12
            start, stop = sample_window(len(data), cfg.batch_size, self._window_rng)  # line 13: mini-batch B
            w = slice(start, stop)
            logits, v = self.net(obs[w])  # lines 14-16: π_θ(·|s_t) and V_μ(s_t)
            with torch.no_grad():
                v_next = self.net.value_of(next_obs[w])
            if cfg.gae_scope == "window":  # line 15, Eq. 2: the sum runs to the end of the window
                adv = gae(
                    rewards[w], v.detach(), v_next, terminated[w], episode_end[w], cfg.gamma, cfg.gae_lambda
                )
            else:
                adv = memory_adv[w]
            if cfg.critic_target == "td":  # line 16, Eq. 3: V^target = r + γV(s'), bootstrapped at truncation
                targets = td_targets(rewards[w], v_next, terminated[w], cfg.gamma)
            else:  # the λ-return Â + V(s)
                targets = adv + v.detach()
            if cfg.normalise_advantages and adv.numel() > 1:
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            l_v = critic_loss(v, targets, cfg.critic_loss)  # line 17, Eq. 3
            log_probs_all = functional.log_softmax(logits, dim=-1)
            log_probs = log_probs_all.gather(1, actions[w][:, None]).squeeze(1)
            entropy = -(log_probs_all.exp() * log_probs_all).sum(-1).mean()
            l_clip = clipped_surrogate(log_probs, old_log_probs[w], adv, cfg.clip_eps)  # line 18, Eq. 6
            actor_objective = -l_clip - cfg.entropy_coef * entropy  # Eq. 7 descends on −L^CLIP
            self._step(actor_objective, l_v)  # lines 20-23

            with torch.no_grad():
                log_ratio = log_probs - old_log_probs[w]
                ratio = log_ratio.exp()
                kl = ((ratio - 1.0) - log_ratio).mean()
                clipped = ((ratio - 1.0).abs() > cfg.clip_eps).float().mean()
            totals += [-l_clip.item(), l_v.item(), entropy.item(), kl.item(), clipped.item()]

        self._policy.refresh(self.net)
        means = totals / cfg.n_optimisations
        return UpdateStats(*(float(m) for m in means))

    def _score_new_transitions(self) -> None:
        """Record log π(a|s) of the acting policy for transitions stored since θ last changed."""
        slots = self.memory.unscored()
        if slots.size == 0:
            return
        obs, actions = self.memory.slots(slots)
        with torch.no_grad():
            logits, _ = self.net(torch.from_numpy(obs))
            log_probs = functional.log_softmax(logits, dim=-1).gather(1, torch.from_numpy(actions)[:, None])
        self.memory.score(slots, log_probs.squeeze(1).numpy())

    def _step(self, actor_objective: torch.Tensor, l_v: torch.Tensor) -> None:
        """Lines 20-23: g_μ = ∇L^V, step the critic; g_θ = ∇(−L^CLIP), step the actor (both Adam).

        Both gradients are taken at the same parameters before either step. With ``trunk_split ==
        'actor'`` the critic loss's trunk gradient, times ``critic_trunk_coef``, joins g_θ, so the actor
        optimiser alone moves the trunk and the shared gradient carries the critic's say in it.
        """
        cfg = self.config
        actor_params = [p for _, p in self._actor_named]
        g_theta = list(torch.autograd.grad(actor_objective, actor_params, retain_graph=True))
        g_v = list(torch.autograd.grad(l_v, self._critic_grad_params))
        trunk_grads, head_grads = g_v[: self._n_trunk], g_v[self._n_trunk :]
        if cfg.trunk_split == "shared":
            g_mu = trunk_grads + head_grads
        else:
            g_mu = head_grads
            for i, g in enumerate(trunk_grads):
                g_theta[i] = g_theta[i] + cfg.critic_trunk_coef * g
        self._apply(self.critic_optimizer, [p for _, p in self._critic_named], g_mu)  # line 21
        self._apply(self.actor_optimizer, actor_params, g_theta)  # line 23
        # Line 25 sends the last of these; keep it (as applied, i.e. after clipping).
        self._last_actor_gradient = np.concatenate([g.detach().numpy().ravel() for g in g_theta]).astype(
            np.float32
        )

    def _apply(
        self, optimizer: torch.optim.Optimizer, params: list[nn.Parameter], grads: list[torch.Tensor]
    ) -> None:
        for p, g in zip(params, grads, strict=True):
            p.grad = g
        if self.config.max_grad_norm > 0.0:
            nn.utils.clip_grad_norm_(params, self.config.max_grad_norm)  # in place: ``grads`` see it too
        optimizer.step()
        for p in params:
            p.grad = None

    # ---- what the federation exchanges (lines 8, 25, 29, 31) -------------------------------------------

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of θ, in the order of every flat actor vector (gradient or parameters)."""
        return _layout(self._actor_named)

    def actor_size(self) -> int:
        """Length of a flat actor vector."""
        return sum(p.numel() for _, p in self._actor_named)

    def actor_gradient(self) -> np.ndarray:
        """The actor's last gradient of the round (line 25) as flat float32, in :meth:`actor_layout` order."""
        if self._last_actor_gradient is None:
            raise RuntimeError("no actor gradient yet: call update() first")
        return self._last_actor_gradient.copy()

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        """Line 31: update π_θ with a received (average) gradient ḡ through the actor's Adam."""
        chunks = _split(flat, self._actor_named, "actor gradient")
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
        return _flatten(self._actor_named)

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        """Line 29: replace θ with received parameters θ̄ (the critic head and Adam state are kept)."""
        self._replace(self._actor_named, flat, "actor parameter")

    # The whole actor-critic (θ and μ: trunk, policy head and value head), for the ``fedavg`` scheme, which
    # averages models rather than actor gradients (docs/algorithm.md, "Federation schemes").

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of every network parameter, in the order of every flat model vector."""
        return _layout(self._model_named())

    def model_parameters(self) -> np.ndarray:
        """Every network parameter as flat float32 in :meth:`model_layout` order."""
        return _flatten(self._model_named())

    def set_model_parameters(self, flat: np.ndarray) -> None:
        """Replace every network parameter (both Adam states are kept: each worker's own optimiser)."""
        self._replace(self._model_named(), flat, "model parameter")

    def _model_named(self) -> list[tuple[str, nn.Parameter]]:
        return self._actor_named + self.net.head_parameters("value")

    def _replace(self, named: list[tuple[str, nn.Parameter]], flat: np.ndarray, what: str) -> None:
        chunks = _split(flat, named, what)
        self._score_new_transitions()
        with torch.no_grad():
            for (_, p), value in zip(named, chunks, strict=True):
                p.copy_(value)
        self._policy.refresh(self.net)

    # ---- resumable state (fleetrl.agent.state) --------------------------------------------------------

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

    # ---- checkpoints ------------------------------------------------------------------------------------

    def architecture(self) -> dict[str, Any]:
        """What a model file must match to be loaded into this agent."""
        return {
            "obs_dim": self.obs_dim,
            "n_actions": self.n_actions,
            "hidden": list(self.config.hidden),
            "activation": self.config.activation,
        }

    def save(self, path: str | Path) -> None:
        """Write the network weights (safetensors) with config, architecture and seed as JSON metadata."""
        tensors = {name: t.detach().numpy().copy() for name, t in self.net.state_dict().items()}
        metadata = {"architecture": self.architecture(), "config": self.config.to_dict(), "seed": self.seed}
        write_checkpoint(path, tensors, metadata)

    @classmethod
    def load(cls, path: str | Path, obs_dim: int | None = None, n_actions: int | None = None) -> PPOAgent:
        """An agent rebuilt from a model file; ``obs_dim``/``n_actions``, if given, must match it.

        :raises FileNotFoundError: no file at ``path``
        :raises CheckpointError: corrupt file, not a fleetrl model, or a model for another architecture
        """
        tensors, metadata = read_checkpoint(path)
        try:
            arch = metadata["architecture"]
            config = PPOConfig.from_dict(metadata["config"])
            agent = cls(int(arch["obs_dim"]), int(arch["n_actions"]), config, int(metadata.get("seed", 0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{path}: fleetrl metadata is incomplete or invalid ({exc})") from exc
        expected = {"obs_dim": obs_dim, "n_actions": n_actions}
        for key, want in expected.items():
            if want is not None and want != agent.architecture()[key]:
                raise CheckpointError(
                    f"{path} is a model for {key}={agent.architecture()[key]}, but {want} is needed here "
                    "(a model trained for another environment or architecture)"
                )
        agent._load_tensors(tensors, str(path))
        return agent

    def load_weights(self, path: str | Path) -> None:
        """Replace this agent's weights with a model file of the same architecture."""
        tensors, metadata = read_checkpoint(path)
        if metadata.get("architecture") != self.architecture():
            raise CheckpointError(
                f"{path} is a model for architecture {metadata.get('architecture')}, "
                f"this agent is {self.architecture()}"
            )
        self._load_tensors(tensors, str(path))

    def _load_tensors(self, tensors: dict[str, np.ndarray], source: str) -> None:
        state = self.net.state_dict()
        problems = [f"missing {k}" for k in state if k not in tensors]
        problems += [f"unexpected {k}" for k in tensors if k not in state]
        problems += [
            f"{k} has shape {tuple(tensors[k].shape)}, expected {tuple(state[k].shape)}"
            for k in state
            if k in tensors and tuple(tensors[k].shape) != tuple(state[k].shape)
        ]
        if problems:
            raise CheckpointError(f"{source} does not fit this architecture: " + "; ".join(problems))
        self._score_new_transitions()
        self.net.load_state_dict(
            {k: torch.from_numpy(np.asarray(v, dtype=np.float32)) for k, v in tensors.items()}
        )
        self._policy.refresh(self.net)


def _layout(named: list[tuple[str, nn.Parameter]]) -> list[tuple[str, tuple[int, ...]]]:
    return [(name, tuple(p.shape)) for name, p in named]


def _flatten(named: list[tuple[str, nn.Parameter]]) -> np.ndarray:
    return np.concatenate([p.detach().numpy().ravel() for _, p in named]).astype(np.float32)


def _split(flat: np.ndarray, named: list[tuple[str, nn.Parameter]], what: str) -> list[torch.Tensor]:
    """``flat`` cut into tensors shaped like ``named``; ValueError if it does not fit or is not finite."""
    array = np.asarray(flat)
    size = sum(p.numel() for _, p in named)
    if array.ndim != 1 or array.shape[0] != size:
        raise ValueError(f"{what} vector must be flat with {size} values, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} vector has non-finite values")
    tensor = torch.from_numpy(array.astype(np.float32))
    chunks, offset = [], 0
    for _, p in named:
        chunks.append(tensor[offset : offset + p.numel()].view_as(p).clone())
        offset += p.numel()
    return chunks
