"""The scheme seam, as a Flower ``Strategy``: what every scheme says (:class:`Scheme`: what a worker shares,
how the chief configures a round and combines its answers, where the fleet starts), and its kind — once per
round (:class:`RoundScheme`), per optimisation step (:class:`StepScheme`) or without a barrier
(:class:`AsyncScheme`) — which brings the worker's side, the chief's rules and who the chief waits for.
"""

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
"""The message type a worker sends in a round in which its completion criterion holds (every scheme)."""


@dataclass(frozen=True)
class FleetStart:
    """The parameters every worker of a one-policy fleet starts from, handed out in the chief's welcome."""

    layout: Layout
    """their names and shapes (:meth:`Scheme.welcome_layout`)"""
    flat: np.ndarray
    """the parameters, flat float32 in that order"""


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
    """What every scheme says, and the chief's side of it. A scheme is a :class:`RoundScheme` or a
    :class:`StepScheme` (the worker's side); the built-ins live one per module in
    :mod:`fleetrl.federation.schemes` (found there by name), a user's anywhere (``--scheme module:Class``).
    An instance may hold state across rounds (a server optimiser's momentum), saved with the chief through
    :meth:`state` and :meth:`restore`.
    """

    name: ClassVar[str]
    """the registry name (``--scheme NAME``)"""
    summary: ClassVar[str]
    """one line for logs and ``--help``"""
    round_message: ClassVar[str]
    """the message type a still-learning worker sends: the scheme's own name for it (lower-case letters,
    digits and ``_``), declared here only"""
    stays_after_completion: ClassVar[bool]
    """a worker whose criterion holds keeps learning in W (True) or transfers and leaves (False); the learner
    factory sets ``Learner.keep_learning`` from it"""
    default_quorum: ClassVar[float] = 1.0
    """the chief's quorum when the run names none (:class:`StepScheme`: 0.6, docs/protocol.md "Stragglers")"""
    shared_start: ClassVar[bool] = False
    """the fleet is one policy: every worker starts from the same parameters, the fleet's start, which the
    chief's ``welcome`` hands to every joining worker (whatever its own seed)"""
    round_barrier: ClassVar[bool] = True
    """a round closes when its contributors are ready, and they start their next round then (False: each
    worker plays at its own pace; :class:`AsyncScheme` sets it, no other scheme does)"""
    leaves_late_units: ClassVar[bool] = False
    """a unit late for a round is left behind after the quorum's time and a grace (True), else waited for"""
    one_policy_per_step: ClassVar[bool] = False
    """every optimisation step of the fleet is one step of one shared policy (what a unit host needs: its
    units' steps summed into one message)"""

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
        """Names and shapes of the parameters a ``welcome`` hands a joining worker (the fleet's model or its
        start; :meth:`take_parameters` takes them): :meth:`layout` unless the scheme shares no parameters."""
        return self.layout(agent)

    def start_parameters(self, agent: FederatedAgent) -> np.ndarray:
        """``agent``'s parameters in :meth:`welcome_layout` order: the fleet's start, drawn by the chief's
        role (a ``shared_start`` scheme); the whole actor-critic unless a scheme shares less."""
        return agent.model_parameters()

    @abstractmethod
    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Replace the worker's shared parameters with the fleet's ``flat`` (in :meth:`welcome_layout`): a
        ``transfer``, or a ``welcome``'s model or start."""

    def exchanges_per_round(self, agent: FederatedAgent) -> int:
        """How many messages a worker sends per round (the chief's ``steps_per_round``): 1 for a
        :class:`RoundScheme`."""
        del agent
        return 1

    def configure(self, round: int, members: tuple[str, ...]) -> RoundConfig:
        """What the chief asks of every worker for ``round`` (Flower's ``configure_fit``): a small map of
        names to numbers or short texts, carried by the message that opens the round and handed to the
        worker's side (:meth:`RoundScheme.local_loss`); nothing by default.

        :param members: W as the round opens.
        """
        del round, members
        return {}

    @abstractmethod
    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """The chief's answer to a closed round (or, for a :class:`StepScheme`, a closed step).

        :param answers: sender → message, in sorted worker-id order (never arrival order), every one carrying
            ``flat`` of :meth:`layout` and saying what it stands for (``samples``, ``units``).
        :param context: the aggregation rule, W and who has completed.
        """

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(JSON fields, named float32 tensors) of state kept across rounds on the chief; none by default."""
        return {}, {}

    def restore(self, fields: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> None:
        """Take back what :meth:`state` returned (a resumed chief); nothing to do by default."""
        del fields, tensors


class RoundScheme(Scheme):
    """A scheme whose worker sends once per round, after its local training (the round's K optimisations)."""

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError if a chief of this scheme cannot run with these rules: one exchange a round, and a
        quorum below 1 closes a round only at its deadline."""
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
        """Who the chief waits for in a round (:mod:`fleetrl.federation.chief.stragglers`)."""
        del max_staleness
        return RoundWaits(quorum, round_timeout)

    @abstractmethod
    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        """(type, flat vector) a worker sends after a round; type :data:`COMPLETED` if its criterion holds."""

    @abstractmethod
    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        """Act on the chief's ``average``.

        :param completed: this worker's criterion held in the round it answers.
        :param contributed: this worker's message is among those averaged (False: the round closed without it,
            or the worker is catching up with rounds it missed).
        """

    def local_loss(self, agent: FederatedAgent, config: RoundConfig) -> ExtraLoss | None:
        """What the worker adds to its local training's loss this round (called before the round is
        played, with the chief's :meth:`~Scheme.configure` for it); None: nothing (the default)."""
        del agent, config
        return None


class StepScheme(Scheme):
    """A scheme whose worker exchanges every optimisation step of its update with the chief, keyed (sender,
    round, step): it sends the step's gradient and applies the chief's combination before the next step."""

    default_quorum: ClassVar[float] = 0.6
    """DD-PPO's share of workers after which the rest are not waited for (habitat-lab's ``sync_frac``)"""
    leaves_late_units: ClassVar[bool] = True

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError if a chief of this scheme cannot run with these rules: at least one exchange a round."""
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
        """How many messages a worker sends per round (the chief's ``steps_per_round``): the steps of one
        update; a ValueError if the agent's settings do not fit the scheme."""

    @abstractmethod
    def apply_step_answer(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Apply the chief's combination of the workers' gradients of the step."""

    def catch_up_step(self, agent: FederatedAgent, step: int, flat: np.ndarray) -> None:
        """Apply the chief's answer of the fleet's step ``step`` that this worker took no part in (it was
        behind, docs/protocol.md "Stragglers"): the same change :meth:`apply_step_answer` makes, outside an
        update (``agent.apply_fleet_step``)."""
        agent.apply_fleet_step(step, flat)


class AsyncScheme(RoundScheme):
    """A scheme without a round barrier (docs/protocol.md, "Asynchronous schemes"). A worker's side is a
    :class:`RoundScheme`'s — play a round, send what :meth:`~RoundScheme.outgoing` shares — but each worker
    plays at its own pace, its rounds counted by itself, and takes the newest fleet model before each round.
    The chief holds the fleet model and its version (the contributions applied so far, :meth:`state`); it
    applies every contribution on arrival through :meth:`combine`, given alone, its ``staleness`` set to the
    versions applied since the one the worker started from; the answer is the fleet model after it.
    """

    def check_rules(
        self, quorum: float, round_timeout: float | None, steps_per_round: int, aggregation: str
    ) -> None:
        """ValueError if a chief of this scheme cannot run with these rules: no round barrier to wait at, one
        model mixed in at a time."""
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
    """The answers' vectors combined with the run's rule, each weighted by what it stands for (``by``: its
    weight — the units its message says it carries, or the weight it gives itself, ``Message.mean_weight`` —
    or the transitions; a rule that cannot weigh counts members). Equal weights give exactly the unweighted
    rule. An edge aggregator's answer is its members' weighted sum (``summed``, weighted by their total
    weight): added as one term of the mean (:func:`.aggregation.mean_of_parts`)."""
    weights = [float(m.units) if by == "units" else float(m.samples) for m in answers.values()]
    summed = [m.summed for m in answers.values()]
    if any(summed):  # an edge aggregator's sum: the chief takes one only if its rule is the mean
        return mean_of_parts(flats(answers), weights, summed)
    return context.aggregate(flats(answers), weights=weights)


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
        aggregate(answers, context),
        contributors=tuple(answers),
        finished=context.members if ends else (),
        fleet_model=fleet_model,
        ends_run=ends,
    )
