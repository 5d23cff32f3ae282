"""What a worker does with its learner, per scheme kind: a round played whole and its share sent (per round,
asynchronous: :class:`RoundPlay`), or its update exchanged step by step (per step: :class:`StepPlay`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

from fleetrl.federation.schemes import RoundScheme, Scheme, StepScheme
from fleetrl.federation.schemes.agent import LocalTraining
from fleetrl.federation.wire.messages import RoundConfig
from fleetrl.federation.worker.actions import (
    NOTHING,
    AbandonUpdate,
    ApplyAverage,
    ApplyFleetStep,
    ApplyStep,
    BeginUpdate,
    ComputeStep,
    EndUpdate,
    RoundPlayer,
    WorkerOutput,
    WorkerStep,
)
from fleetrl.federation.worker.machine import WorkerMachine
from fleetrl.federation.worker.per_step import StepWorkerMachine


class Play(ABC):
    """The learner's side of a worker's rounds under one scheme kind: the rounds the machine asks for, and
    the actions only this kind's machine asks for."""

    def __init__(
        self, scheme: Scheme, learner: RoundPlayer, machine: WorkerMachine, clock: Callable[[], float]
    ) -> None:
        """Play ``learner``'s rounds under ``scheme``, reporting to ``machine`` at ``clock``'s times."""
        self.scheme, self.learner, self.machine, self.clock = scheme, learner, machine, clock

    @abstractmethod
    def play(self, config: RoundConfig) -> WorkerStep:
        """Play the round the machine asked for with the chief's ``config``, and report it."""

    @abstractmethod
    def execute(self, output: WorkerOutput) -> WorkerStep | None:
        """Do one of this kind's actions and report it (None: not one of this kind's)."""


class RoundPlay(Play):
    """A round played whole (its K optimisations inside), then what the scheme shares sent once."""

    scheme: RoundScheme

    def play(self, config: RoundConfig) -> WorkerStep:
        """The scheme's local loss for the round installed, the round played, its share sent (lines 8, 25)."""
        agent = self.learner.agent
        extra = self.scheme.local_loss(agent, config)
        if isinstance(agent, LocalTraining):
            agent.set_extra_loss(extra)
        elif extra is not None:
            raise TypeError(
                f"scheme {self.scheme.name!r} adds a term to local training, which this agent "
                f"({type(agent).__name__}) cannot take: it has no set_extra_loss(fn)"
            )
        result = self.learner.play_round()
        share = self.scheme.outgoing(agent, completed=bool(result.completed))
        return self.machine.round_played(result, now=self.clock(), share=share)

    def execute(self, output: WorkerOutput) -> WorkerStep | None:
        """The fleet's average applied (line 31, or fedavg's model taken)."""
        if not isinstance(output, ApplyAverage):
            return None
        agent = self.learner.agent
        self.scheme.apply_average(
            agent, output.flat, completed=output.completed, contributed=output.contributed
        )
        return NOTHING


class StepPlay(Play):
    """A round's episodes played, then its update's K steps exchanged with the fleet one by one."""

    scheme: StepScheme
    machine: StepWorkerMachine
    _played: Any = None
    """the round under way: what ``learner.begin_round`` returned"""

    def play(self, config: RoundConfig) -> WorkerStep:
        """The round's episodes (no update yet): the machine then joins the fleet's exchange."""
        del config
        self._played = self.learner.begin_round()
        return self.machine.round_collected(completed=bool(self.learner.completed), now=self.clock())

    def execute(self, output: WorkerOutput) -> WorkerStep | None:
        """Begin the update (line 11), compute a step's gradient, apply the fleet's step, end the round."""
        agent = self.learner.agent
        match output:
            case BeginUpdate():
                steps = agent.begin_update() if self._played.updates else 0
                return self.machine.update_begun(steps, now=self.clock())
            case ApplyFleetStep(k, flat):  # behind the fleet: its step, taken outside an update
                self.scheme.catch_up_step(agent, k, flat)
            case ComputeStep(k):
                return self.machine.step_computed(k, agent.step_gradients(k), now=self.clock())
            case ApplyStep(flat):  # the chief's combination: the agent steps and takes the next gradient
                self.scheme.apply_step_answer(agent, flat)
            case EndUpdate():
                return self._end_round(abandoned=False)
            case AbandonUpdate():
                return self._end_round(abandoned=True)
            case _:
                return None
        return NOTHING

    def _end_round(self, *, abandoned: bool) -> WorkerStep:
        """Every step was applied (or the fleet went on past this worker's step: ``abandoned``): finish the
        update and report the round."""
        played, self._played = self._played, None
        agent = self.learner.agent
        stats = None
        if abandoned:
            agent.abandon_update()
        elif played.updates:
            stats = agent.end_update()
        return self.machine.round_played(self.learner.end_round(played, stats), now=self.clock())
