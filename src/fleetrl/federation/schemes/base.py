"""The :class:`Scheme` interface: one federation scheme, read by the chief's and the worker's state machines.

Like a Flower ``Strategy``, a scheme says everything that differs between ways of federating, and the chief,
the worker, the learner factory and the launcher only call it:

* what a worker shares (:meth:`Scheme.layout`: the actor, or the whole actor-critic) and what it sends after a
  round (:meth:`Scheme.outgoing`), and how often (:attr:`Scheme.granularity`);
* how the chief combines the answers of a round (:meth:`Scheme.combine`, with the run's aggregation rule);
* what a worker does with the chief's answer (:meth:`Scheme.apply_average`, :meth:`Scheme.take_parameters`);
* what a worker whose criterion holds does (:attr:`Scheme.stays_after_completion`) and when the run is
  finished (:attr:`RoundAnswer.ends_run`).

The protocol around it is the same for every scheme (docs/protocol.md): a ``parameters`` message says "my
criterion holds"; the chief answers a round with one ``average`` or one ``transfer``; workers named in the
answer's ``finished`` leave W.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, ClassVar, Literal, Protocol

import numpy as np

from fleetrl.federation.aggregation import Aggregator
from fleetrl.federation.messages import Layout, Message

COMPLETED = "parameters"
"""The message type a worker sends in a round in which its completion criterion holds (every scheme)."""


class WrongGranularity(TypeError):
    """A per-round method was called on a per-step scheme, or the reverse: a bug in the caller (the runner
    calls each scheme only through the methods of its :class:`Granularity`), never a user's setting."""


class Granularity(StrEnum):
    """How often a worker sends: once per round, or once per optimisation step of the round."""

    ROUND = "round"
    """one message per round, after the round's K optimisations (``paper``, ``fedavg``)"""
    STEP = "step"
    """one message per optimisation step, keyed (sender, round, step) — for schemes that average every step"""


class FederatedAgent(Protocol):
    """What schemes need from the agent (``fleetrl.agent.ppo.PPOAgent`` provides it)."""

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the actor's parameters, in flat order."""
        ...

    def actor_gradient(self) -> np.ndarray:
        """The actor's last gradient of the round, flat float32."""
        ...

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        """Update the actor with ``flat`` through its optimiser."""
        ...

    def actor_parameters(self) -> np.ndarray:
        """The actor's parameters, flat float32."""
        ...

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        """Replace the actor's parameters."""
        ...

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the whole actor-critic's parameters, in flat order."""
        ...

    def model_parameters(self) -> np.ndarray:
        """The whole actor-critic's parameters, flat float32."""
        ...

    def set_model_parameters(self, flat: np.ndarray) -> None:
        """Replace the whole actor-critic's parameters."""
        ...

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of optimisation step ``k``'s flat gradient."""
        ...

    def update_step_count(self) -> int:
        """How many optimisation steps each update takes."""
        ...

    def begin_update(self) -> int:
        """Start the round's update; the number of optimisation steps it takes."""
        ...

    def step_gradients(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient, flat float32 in :meth:`step_layout` order, nothing stepped."""
        ...

    def apply_step(self, flat_grad: np.ndarray) -> None:
        """Step the optimiser(s) with a gradient for the step last computed."""
        ...

    def end_update(self) -> Any:
        """Finish the update (every step applied); its statistics."""
        ...


@dataclass(frozen=True)
class RoundContext:
    """What the chief knows when a round closes, for :meth:`Scheme.combine`."""

    aggregate: Aggregator
    """the run's aggregation rule (:mod:`fleetrl.federation.aggregation`) over flat float32 vectors"""
    members: tuple[str, ...]
    """W when the round closes (sorted), including members that did not answer (stragglers)"""
    completed: Mapping[str, int]
    """worker → the first round its criterion held, this round's completions included"""
    step: int = 0
    """the exchange being closed within the round (0 for a scheme that sends once per round)"""
    last_step: bool = True
    """it is the round's last exchange: completions are counted and the run may end"""


@dataclass(frozen=True)
class RoundAnswer:
    """How a scheme answers a closed round; the chief makes it one ``average`` or ``transfer`` message."""

    kind: Literal["average", "transfer"]
    """``average``: ``flat`` is the combination of the answers; ``transfer``: one worker's parameters"""
    flat: np.ndarray
    """the answer's tensors (the scheme's layout)"""
    contributors: tuple[str, ...] = ()
    """whose vectors ``flat`` combines (``average``)"""
    origin: str | None = None
    """whose parameters ``flat`` is (``transfer``)"""
    finished: tuple[str, ...] = ()
    """workers that stop with this answer"""
    leave_w: tuple[str, ...] = ()
    """workers that leave W for good with this answer (they are then rejected as ``not in W``)"""
    fleet_model: bool = False
    """``flat`` is what a worker (re)joining the run starts from (sent in the ``welcome``)"""
    ends_run: bool = False
    """the run is complete after this answer (the chief then sends ``done``)"""


class Scheme(ABC):
    """One federation scheme. Subclasses live one per module in :mod:`fleetrl.federation.schemes` and are
    registered there by name; an instance may hold state across rounds (a server optimiser's momentum), saved
    with the chief through :meth:`state` and :meth:`restore`.
    """

    name: ClassVar[str]
    """the registry name (``--scheme NAME``)"""
    summary: ClassVar[str]
    """one line for logs and ``--help``"""
    round_message: ClassVar[str]
    """the message type a still-learning worker sends (a key of ``MESSAGE_TYPES``)"""
    stays_after_completion: ClassVar[bool]
    """a worker whose criterion holds keeps learning in W (True) or transfers and leaves (False); the learner
    factory sets ``Learner.keep_learning`` from it"""
    granularity: ClassVar[Granularity] = Granularity.ROUND
    """how often a worker sends: once per round, or once per optimisation step (the chief is then built with
    the round's number of steps, and the worker exchanges every step, sending the step's gradient and
    applying the answer with :meth:`apply_step_answer`)"""
    shared_start: ClassVar[bool] = False
    """every worker starts from the same parameters (those drawn from the run's seed, not its own): a scheme
    that averages gradients into identical models needs it"""

    def params(self) -> dict[str, Any]:
        """The scheme's parameters (JSON values), for the welcome's shared settings and checkpoints."""
        return {}

    def accepts(self, message_type: str) -> bool:
        """Whether the chief takes a worker message of this type in a round."""
        return message_type in (self.round_message, COMPLETED)

    # -- worker side ---------------------------------------------------------------------------------------

    @abstractmethod
    def layout(self, agent: FederatedAgent) -> Layout:
        """Names and shapes of the tensors this scheme puts on the wire for ``agent``."""

    @abstractmethod
    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        """(type, flat vector) a worker sends after a round; type :data:`COMPLETED` if its criterion holds."""

    @abstractmethod
    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Replace the worker's shared parameters with ``flat`` (a ``transfer``, or the welcome's θ*)."""

    @abstractmethod
    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        """Act on the chief's ``average``.

        :param completed: this worker's criterion held in the round it answers.
        :param contributed: this worker's message is among those averaged (False: the round closed without it,
            or the worker is catching up with rounds it missed).
        """

    def exchanges_per_round(self, agent: FederatedAgent) -> int:
        """How many messages a worker sends per round (the chief's ``steps_per_round``): 1, or for a per-step
        scheme the steps of one update; a ValueError if the agent's settings do not fit the scheme."""
        del agent
        return 1

    def apply_step_answer(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """A per-step scheme: apply the chief's combination of the workers' gradients of the step."""
        raise WrongGranularity(f"scheme {self.name!r} sends once per round: it has no step answers")

    # -- chief side ----------------------------------------------------------------------------------------

    @abstractmethod
    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """The chief's answer to a closed round.

        :param answers: sender → message, in sorted worker-id order (never arrival order), every one carrying
            ``flat`` of :meth:`layout`.
        :param context: the aggregation rule, W and who has completed.
        """

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(JSON fields, named float32 tensors) of state kept across rounds on the chief; none by default."""
        return {}, {}

    def restore(self, fields: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> None:
        """Take back what :meth:`state` returned (a resumed chief); nothing to do by default."""
        del fields, tensors


def flats(answers: Mapping[str, Message]) -> list[np.ndarray]:
    """The answers' vectors in the mapping's (sorted worker-id) order."""
    out = []
    for sender, message in answers.items():
        if message.flat is None:  # decode guarantees tensors for every round message
            raise AssertionError(f"{message.type} from {sender} has no tensors")
        out.append(message.flat)
    return out


def average_until_all_completed(
    answers: Mapping[str, Message], context: RoundContext, *, fleet_model: bool
) -> RoundAnswer:
    """The answers aggregated with the run's rule; at the last exchange of the round in which the last member
    of W has completed, every member is listed in ``finished`` and the run ends (the end rule of the schemes
    whose mature workers stay)."""
    members = set(context.members)
    ends = context.last_step and bool(members) and members.issubset(context.completed)
    return RoundAnswer(
        "average",
        context.aggregate(flats(answers)),
        contributors=tuple(answers),
        finished=context.members if ends else (),
        fleet_model=fleet_model,
        ends_run=ends,
    )
