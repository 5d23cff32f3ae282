"""The scheme seam, as a Flower ``Strategy``: what every scheme says (:class:`Scheme`), and its kind — once
per round (:class:`RoundScheme`), per optimisation step (:class:`StepScheme`) or without a barrier
(:class:`AsyncScheme`) — which brings the worker's side, the chief's rules and who the chief waits for."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from fleetrl.federation.aggregation import Aggregator, mean_of_parts
from fleetrl.federation.chief.stragglers import RoundWaits, StepWaits
from fleetrl.federation.schemes.agent import ExtraLoss, FederatedAgent
from fleetrl.federation.wire.messages import Layout, Message, RoundConfig

COMPLETED = "parameters"
"""The message type a worker sends in a round in which its completion criterion holds."""


@dataclass(frozen=True)
class FleetStart:
    """The parameters every worker of a one-policy fleet starts from (flat float32, in ``layout``: the
    scheme's :meth:`~Scheme.welcome_layout`), handed out in the chief's welcome."""

    layout: Layout
    flat: np.ndarray


@dataclass(frozen=True)
class RoundContext:
    """What the chief knows when a round closes, for :meth:`Scheme.combine`."""

    aggregate: Aggregator
    """the run's aggregation rule over flat float32 vectors"""
    members: tuple[str, ...]
    """W when the round closes (sorted), stragglers included"""
    completed: Mapping[str, int]
    """worker → the first round its criterion held, this round's included"""
    step: int = 0
    """the exchange being closed within the round"""
    last_step: bool = True
    """it is the round's last exchange: completions are counted and the run may end"""


@dataclass(frozen=True)
class RoundAnswer:
    """How a scheme answers a closed round; the chief makes it one ``average`` or ``transfer`` message."""

    kind: Literal["average", "transfer"]
    """``average``: ``flat`` combines ``contributors``' vectors; ``transfer``: it is ``origin``'s"""
    flat: np.ndarray
    contributors: tuple[str, ...] = ()
    origin: str | None = None
    finished: tuple[str, ...] = ()
    """workers that stop with this answer"""
    leave_w: tuple[str, ...] = ()
    """workers that leave W for good with this answer"""
    fleet_model: bool = False
    """``flat`` is what a worker (re)joining the run starts from (sent in the ``welcome``)"""
    ends_run: bool = False
    """the run is complete after this answer (the chief then sends ``done``)"""


class Scheme(ABC):
    """What every scheme says, and the chief's side of it; its kind brings the worker's side. An instance
    may hold state across rounds (a server optimiser's momentum), saved with the chief (:meth:`state`)."""

    name: ClassVar[str]
    """the registry name (``--scheme NAME``)"""
    summary: ClassVar[str]
    """one line for logs and ``--help``"""
    round_message: ClassVar[str]
    """the message type a still-learning worker sends (lower-case letters, digits and ``_``)"""
    stays_after_completion: ClassVar[bool]
    """a worker whose criterion holds keeps learning in W (True) or transfers and leaves (False)"""
    default_quorum: ClassVar[float] = 1.0
    """the chief's quorum when the run names none"""
    shared_start: ClassVar[bool] = False
    """the fleet is one policy: the chief's ``welcome`` hands every joining worker the fleet's start"""
    round_barrier: ClassVar[bool] = True
    """a round closes when its contributors are ready (False: each worker plays at its own pace)"""
    leaves_late_units: ClassVar[bool] = False
    """a unit late for a round is left behind after the quorum's time and a grace (True), else waited for"""
    one_policy_per_step: ClassVar[bool] = False
    """every optimisation step of the fleet is one step of one shared policy (a unit host may sum its units'
    steps into one message)"""

    def params(self) -> dict[str, Any]:
        """The scheme's parameters (JSON values), for the welcome's shared settings and checkpoints."""
        return {}

    @abstractmethod
    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError naming the first of a chief's rules this scheme's kind cannot run with."""

    @abstractmethod
    def waits(self, quorum: float, round_timeout: float | None, max_staleness: int | None) -> RoundWaits:
        """The chief's waiting rule for this scheme's kind (:mod:`fleetrl.federation.chief.stragglers`)."""

    def accepts(self, message_type: str) -> bool:
        """Whether the chief takes a worker message of this type in a round."""
        return message_type in (self.round_message, COMPLETED)

    @abstractmethod
    def layout(self, agent: FederatedAgent) -> Layout:
        """Names and shapes of the tensors a worker sends and the chief answers with, for ``agent``."""

    def welcome_layout(self, agent: FederatedAgent) -> Layout:
        """Names and shapes of the parameters a ``welcome`` hands a joining worker (the fleet's model or
        start)."""
        return self.layout(agent)

    def start_parameters(self, agent: FederatedAgent) -> np.ndarray:
        """``agent``'s parameters in :meth:`welcome_layout` order: the fleet's start (``shared_start``)."""
        return agent.model_parameters()

    @abstractmethod
    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Replace the worker's shared parameters with ``flat`` (a transfer's, or a welcome's)."""

    def exchanges_per_round(self, agent: FederatedAgent) -> int:
        """How many messages a worker sends per round (the chief's ``steps_per_round``)."""
        del agent
        return 1

    def configure(self, round: int, members: tuple[str, ...]) -> RoundConfig:
        """What the chief asks of every worker for ``round`` (Flower's ``configure_fit``), W being
        ``members``: names to numbers or short texts, handed to :meth:`RoundScheme.local_loss`."""
        del round, members
        return {}

    @abstractmethod
    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """The chief's answer to a closed round (or step); ``answers``: sender → message, in sorted worker-id
        order, each carrying ``flat`` of :meth:`layout`."""

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(JSON fields, named float32 tensors) of state kept across rounds on the chief."""
        return {}, {}

    def restore(self, fields: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> None:
        """Take back what :meth:`state` returned (a resumed chief)."""
        del fields, tensors


class RoundScheme(Scheme):
    """A scheme whose worker sends once per round, after its local training (the round's K optimisations)."""

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError unless one exchange a round, and a timeout for a quorum below 1."""
        del aggregation
        if quorum < 1.0 and round_timeout is None:
            raise ValueError(
                f"scheme {self.name!r}: a quorum below 1 needs a round timeout (--round-timeout)"
            )
        if steps_per_round != 1:
            raise ValueError(
                f"steps_per_round = {steps_per_round}: scheme {self.name!r} sends once per round (1)"
            )

    def waits(self, quorum: float, round_timeout: float | None, max_staleness: int | None) -> RoundWaits:
        """Who the chief waits for in a round."""
        del max_staleness
        return RoundWaits(quorum, round_timeout)

    @abstractmethod
    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        """(type, flat vector) a worker sends after a round; type :data:`COMPLETED` if its criterion holds."""

    @abstractmethod
    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        """Act on the chief's ``average``; ``completed``: this worker's criterion held in that round;
        ``contributed``: its message is among those averaged."""

    def local_loss(self, agent: FederatedAgent, config: RoundConfig) -> ExtraLoss | None:
        """What the worker adds to its local training's loss this round, given the chief's
        :meth:`~Scheme.configure` for it; None: nothing."""
        del agent, config
        return None


class StepScheme(Scheme):
    """A scheme whose worker exchanges every optimisation step of its update with the chief: it sends the
    step's gradient and applies the chief's combination before the next step."""

    default_quorum: ClassVar[float] = 0.6
    """DD-PPO's share of workers after which the rest are not waited for (habitat-lab's ``sync_frac``)"""
    leaves_late_units: ClassVar[bool] = True

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError unless at least one exchange a round."""
        del quorum, round_timeout, aggregation
        if steps_per_round < 1:
            raise ValueError(
                f"steps_per_round = {steps_per_round}: scheme {self.name!r} sends per step (at least 1)"
            )

    def waits(self, quorum: float, round_timeout: float | None, max_staleness: int | None) -> RoundWaits:
        """Who the chief waits for at each exchange, and for how long (a grace after a quorum)."""
        return StepWaits(quorum, round_timeout, max_staleness)

    @abstractmethod
    def exchanges_per_round(self, agent: FederatedAgent) -> int:
        """The steps of one update; a ValueError if the agent's settings do not fit the scheme."""

    @abstractmethod
    def apply_step_answer(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Apply the chief's combination of the workers' gradients of the step."""

    def catch_up_step(self, agent: FederatedAgent, step: int, flat: np.ndarray) -> None:
        """Apply the fleet's step ``step`` that this worker took no part in (it was behind), outside an
        update."""
        agent.apply_fleet_step(step, flat)


class AsyncScheme(RoundScheme):
    """A scheme without a round barrier (docs/protocol.md, "Asynchronous schemes"): each worker plays a
    :class:`RoundScheme`'s rounds at its own pace, from the newest fleet model. The chief holds that model
    and its version, and applies every contribution on arrival through :meth:`combine`, given alone with its
    ``staleness``; the answer is the fleet model after it."""

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError unless no round barrier and one model mixed in at a time."""
        if quorum < 1.0 or round_timeout is not None:
            raise ValueError(
                f"scheme {self.name!r} has no round barrier: quorum and round_timeout do not apply (leave "
                "them unset; max_staleness bounds the staleness of a contribution applied)"
            )
        if aggregation != "mean":
            raise ValueError(
                f"scheme {self.name!r} mixes one model at a time into the fleet's: aggregation "
                f"{aggregation!r} does not apply (leave it unset)"
            )
        super().check_rules(quorum, round_timeout, steps_per_round, aggregation)

    shared_start: ClassVar[bool] = True
    stays_after_completion: ClassVar[bool] = True
    round_barrier: ClassVar[bool] = False

    @property
    @abstractmethod
    def version(self) -> int:
        """How many contributions the fleet model has taken (0: the fleet's start)."""

    @property
    @abstractmethod
    def model(self) -> np.ndarray | None:
        """The fleet model, flat in :meth:`~Scheme.welcome_layout` order (None before :meth:`begin`)."""

    @abstractmethod
    def begin(self, start: np.ndarray) -> None:
        """Hold ``start`` (the fleet's start) as the fleet model, version 0."""


def flats(answers: Mapping[str, Message]) -> list[np.ndarray]:
    """The answers' vectors in the mapping's (sorted worker-id) order."""
    out = []
    for sender, message in answers.items():
        if message.flat is None:  # decode guarantees tensors for every round message
            raise AssertionError(f"{message.type} from {sender} has no tensors")
        out.append(message.flat)
    return out


def aggregate(
    answers: Mapping[str, Message], context: RoundContext, by: Literal["units", "samples"] = "units"
) -> np.ndarray:
    """The answers' vectors combined with the run's rule, each weighted by its units or its transitions
    (``by``). An edge aggregator's weighted sum (``summed``) is one term of the mean."""
    weights = [float(m.units) if by == "units" else float(m.samples) for m in answers.values()]
    summed = [m.summed for m in answers.values()]
    if any(summed):  # an edge aggregator's sum: the chief takes one only if its rule is the mean
        return mean_of_parts(flats(answers), weights, summed)
    return context.aggregate(flats(answers), weights=weights)


def average_until_all_completed(
    answers: Mapping[str, Message],
    context: RoundContext,
    *,
    fleet_model: bool,
    flat: np.ndarray | None = None,
) -> RoundAnswer:
    """An ``average`` of ``flat`` (default: the answers aggregated with the run's rule); at the last exchange
    of the round in which the last member of W has completed, every member is ``finished``: the run ends."""
    members = set(context.members)
    ends = context.last_step and bool(members) and members.issubset(context.completed)
    return RoundAnswer(
        "average",
        aggregate(answers, context) if flat is None else flat,
        contributors=tuple(answers),
        finished=context.members if ends else (),
        fleet_model=fleet_model,
        ends_run=ends,
    )
