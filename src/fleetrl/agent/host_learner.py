"""A unit host's learning loop without the federation: U envs stepped together, one agent acting for all of
them, each unit with its own completion criterion, round by round.

The host plays a round as its units would alone, side by side: every unit plays its round's episodes (one,
or with ``trajectory_memory='per_round'`` whole episodes until its memory is filled) on its own env, from its
own seed. At each time step the units still playing act in one call of the agent
(:meth:`~fleetrl.agent.host_agent.HostAgent.act_units`), step together where their envs allow
(:class:`~fleetrl.envs.host_envs.HostEnvs`: in-process CartPoles in one compiled call, in-process QUBEs in
another, every other unit through its own env) and are remembered in one call
(:meth:`~fleetrl.agent.host_agent.HostAgent.remember_units`). Each unit's criterion sees its own scores; the
round ends with at most one update of the host's one network. The host's round result summarises its units
(the mean score, the summed steps); :attr:`HostLearner.unit_rounds` keeps each unit's own.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.host_agent import HostAgent
from fleetrl.agent.ppo import UpdateStats
from fleetrl.agent.round_result import Episodes, RoundResult
from fleetrl.envs.host_envs import HostEnvs

__all__ = ["HostLearner", "HostPlayed"]


@dataclass(frozen=True)
class HostPlayed:
    """The first half of a host's round: each unit's episodes, and whether an update follows."""

    units: tuple[Episodes, ...]
    updates: bool
    started: float
    """``time.perf_counter()`` as the round began"""


class HostLearner:
    """Plays rounds of U units on one :class:`~fleetrl.agent.host_agent.HostAgent`.

    :param envs: one Gymnasium env per unit (flat Box observations)
    :param agent: the host's agent, with one seed per env
    :param criteria: one completion criterion per unit
    :param keep_learning: update every round, also once every unit's criterion holds (per-step schemes,
        whose mature units stay); else update while some unit's does not hold
    """

    def __init__(
        self,
        envs: Sequence[gymnasium.Env[Any, Any]],
        agent: HostAgent,
        criteria: Sequence[CompletionCriterion],
        keep_learning: bool = False,
    ) -> None:
        if not len(envs) == len(criteria) == agent.units:
            raise ValueError(
                f"a unit host needs one env, criterion and seed per unit: got {len(envs)} envs, "
                f"{len(criteria)} criteria, {agent.units} seeds"
            )
        self.envs = list(envs)
        self._envs = HostEnvs(self.envs)
        self.agent = agent
        self.criteria = list(criteria)
        self.keep_learning = keep_learning
        self.rounds = 0
        self.episodes = [0] * agent.units
        """learning episodes each unit played in all rounds"""
        self.completed_once = [False] * agent.units
        """whether each unit's criterion has held at some round (a unit completes once, as a worker does)"""
        self.unit_rounds: tuple[RoundResult, ...] = ()
        """each unit's result of the latest round"""
        self.last_round: RoundResult | None = None
        """the host's result of the latest round (its units' summary)"""

    @property
    def completed(self) -> bool:
        """Every unit has completed: its criterion held at some round, not necessarily this one (as
        :attr:`Learner.completed <fleetrl.agent.learner.Learner.completed>` for one unit). Units that stay
        and learn with the fleet move around their target; waiting until all of a host's hold in the same
        round kept a 1,000-unit run going for 69 rounds after its last unit had completed."""
        return all(self.completed_once)

    def unit_progress(self) -> list[float]:
        """Each unit's progress towards its criterion (:attr:`CompletionCriterion.progress`), unit 0's
        first."""
        return [criterion.progress for criterion in self.criteria]

    def units_completed(self) -> list[bool]:
        """Whether each unit has completed (its criterion held at some round), unit 0's first."""
        return list(self.completed_once)

    def play_episodes(self) -> tuple[Episodes, ...]:
        """Every unit's episodes of the round (Algorithm 2, lines 2-6), the units stepped together."""
        agent, envs = self.agent, self._envs
        to_env = None if agent.action_space.is_discrete else agent.env_action
        obs = np.stack([self._reset(u) for u in range(agent.units)])
        score = np.zeros(agent.units)
        steps = np.zeros(agent.units, dtype=np.int64)
        played: list[list[tuple[float, int]]] = [[] for _ in range(agent.units)]
        playing = np.ones(agent.units, dtype=bool)
        units = np.arange(agent.units)
        while units.size:
            before = obs[units]
            actions = agent.act_units(before, units)  # line 3, for every unit still playing
            sent = actions if to_env is None else [to_env(a) for a in actions]
            step = envs.step(units, sent)  # line 4
            agent.remember_units(
                units, before, actions, step.rewards, step.obs, step.terminated, step.truncated
            )
            score[units] += step.rewards
            steps[units] += 1
            ended = step.terminated | step.truncated
            obs[units[~ended]] = step.obs[~ended]
            for u in units[ended].tolist():
                played[u].append((float(score[u]), int(steps[u])))
                self.episodes[u] += 1
                score[u], steps[u] = 0.0, 0
                if agent.unit_needs_more_episodes(u):
                    obs[u] = self._reset(u)
                else:
                    playing[u] = False
            if ended.any():
                units = np.flatnonzero(playing)
        agent.store_pending()
        self.rounds += 1
        episodes = []
        for u, (criterion, unit_played) in enumerate(zip(self.criteria, played, strict=True)):
            scores, lengths = zip(*unit_played, strict=True)
            episodes.append(Episodes(scores, lengths))
            criterion.add(episodes[-1].score)
            self.completed_once[u] = self.completed_once[u] or criterion.done
        return tuple(episodes)

    def _reset(self, unit: int) -> np.ndarray:
        seed = self.agent.seeds[unit] if self.episodes[unit] == 0 else None
        return self._envs.reset(unit, seed)

    def wants_update(self) -> bool:
        """Line 7 for the host: update unless every unit's criterion holds; always if keep_learning."""
        return self.keep_learning or not all(c.done for c in self.criteria)

    def begin_round(self) -> HostPlayed:
        """:meth:`play_episodes` and line 7's decision; the caller updates the agent, or not, and hands its
        statistics to :meth:`end_round`."""
        started = time.perf_counter()
        units = self.play_episodes()
        return HostPlayed(units, self.wants_update(), started)

    def play_round(self) -> RoundResult:
        """A whole round alone: :meth:`begin_round`, the host's update if it makes one, :meth:`end_round`."""
        played = self.begin_round()
        return self.end_round(played, self.agent.update() if played.updates else None)

    def end_round(self, played: HostPlayed, stats: UpdateStats | None) -> RoundResult:
        """Each unit's result (:attr:`unit_rounds`) and the host's (returned): each unit's own episodes,
        criterion and losses on its windows; the host's are their means (steps and episodes: sums)."""
        seconds = time.perf_counter() - played.started
        per_unit = self.agent.unit_stats if stats is not None else None
        self.unit_rounds = tuple(
            _result(self.rounds, episodes, criterion, None if per_unit is None else per_unit[u], seconds)
            for u, (episodes, criterion) in enumerate(zip(played.units, self.criteria, strict=True))
        )
        host = _result(self.rounds, Episodes((), ()), None, stats, seconds)
        units = self.unit_rounds
        self.last_round = dataclasses.replace(
            host,
            score=float(np.mean([r.score for r in units])),
            steps=sum(r.steps for r in units),
            episodes=sum(r.episodes for r in units),
            wma=float(np.mean([r.wma for r in units])),
            completed=self.completed,
        )
        return self.last_round


def _result(
    round_: int,
    episodes: Episodes,
    criterion: CompletionCriterion | None,
    stats: UpdateStats | None,
    seconds: float,
) -> RoundResult:
    nan = math.nan
    losses = (nan,) * 5 if stats is None else dataclasses.astuple(stats)
    actor_loss, critic_loss, entropy, approx_kl, clip_fraction = losses
    return RoundResult(
        round_,
        episodes.score if episodes.scores else nan,
        sum(episodes.steps),
        len(episodes.scores),
        nan if criterion is None else criterion.wma,
        False if criterion is None else criterion.done,
        actor_loss,
        critic_loss,
        entropy,
        seconds,
        approx_kl,
        clip_fraction,
    )
