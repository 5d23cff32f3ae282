"""What the chief remembers: :class:`ChiefState` with its :class:`AnswerBook`, an asynchronous scheme's
:class:`Contributions`, a per-step scheme's :class:`FleetModel`, and the state as data. Times and the open
exchange's answers are not kept (docs/protocol.md, "Checkpoints and resume")."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from fleetrl.federation.chief.stragglers import FleetPace
from fleetrl.federation.events import ChiefEvent
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import FleetStart, StepScheme
from fleetrl.federation.wire.messages import Layout, Message, Reason
from fleetrl.federation.wire.topics import CHIEF_ID, sorted_workers

STATE_VERSION = 2
"""Version of the state's fields; :func:`~.checkpoint.chief_from_state` refuses any other."""
SCHEME_TENSOR = "scheme."
"""Prefix of the scheme's own state tensors (a server optimiser's moments) in the tensor file."""


class AnswerBook:
    """The answers the chief broadcast, kept to answer re-sends: every exchange's of the open round and the
    round before, and the last one (followed by ``done`` once the run ended). A re-sent message gets the
    answer of its (round, step), or the last one if that is no longer kept (docs/protocol.md, "Broker loss and
    idempotent resends").

    :param holdoff: least seconds between two re-sends of one answer to one worker (from its broadcast too).
    :param last: the last answer of a restored chief.
    """

    def __init__(self, holdoff: float, last: tuple[Message, ...] = ()) -> None:
        self.holdoff = holdoff
        self.last = last
        self._kept: dict[tuple[int, int], tuple[Message, ...]] = {}  # (round, step) → its answer
        self._sent: dict[tuple[str, int, int], float] = {}  # (worker, round, step) → last sent

    def broadcast(self, reply: Message, workers: Iterable[str], now: float) -> None:
        """Keep ``reply``, broadcast to ``workers`` at ``now``; forget answers of rounds before the last."""
        rnd, step = reply.round, reply.step
        self.last = (reply,)
        self._kept = {at: answer for at, answer in self._kept.items() if at[0] >= rnd - 1}
        self._kept[rnd, step] = self.last
        self._sent = {key: t for key, t in self._sent.items() if key[1] >= rnd - 1}
        self._sent.update(((worker, rnd, step), now) for worker in workers)

    def end(self, done: Message) -> None:
        """The run ended: ``done`` follows the last answer whenever it is sent again."""
        if self.last:
            self._kept[self.last[0].round, self.last[0].step] = (*self.last, done)
        self.last = (*self.last, done)

    def resend(self, worker: str, at: tuple[int, int], now: float) -> tuple[Message, ...]:
        """The answer to send again for ``worker``'s stale message of (round, step) ``at``; nothing if there
        is none yet or within the hold-off."""
        answer = self._kept.get(at, self.last)
        if not answer:
            return ()
        key = (worker, answer[0].round, answer[0].step)
        if now < self._sent.get(key, -math.inf) + self.holdoff:
            return ()
        self._sent[key] = now
        return answer


@dataclass
class Contributions:
    """One worker's contributions to an asynchronous run (a re-sent one is answered again, never applied)."""

    applied: int = 0
    left_out: int = 0  # staler than the run's max_staleness
    last_round: int = 0  # the worker's last round taken: a contribution of this round or before is a re-send
    staleness_total: int = 0
    staleness_max: int = 0

    def take(self, rnd: int, staleness: int, *, applied: bool) -> None:
        """Count the worker's contribution of round ``rnd`` and staleness ``staleness``."""
        self.last_round = rnd
        self.staleness_total += staleness
        self.staleness_max = max(self.staleness_max, staleness)
        if applied:
            self.applied += 1
        else:
            self.left_out += 1

    def to_dict(self) -> dict[str, Any]:
        """The counts, and the mean staleness (chief.json)."""
        taken = self.applied + self.left_out
        mean = round(self.staleness_total / taken, 3) if taken else 0.0
        return {**asdict(self), "staleness_mean": mean}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Contributions:
        """The record :meth:`to_dict` wrote."""
        return cls(**{key: int(data[key]) for key in cls.__dataclass_fields__})


class FleetModel:
    """A per-step scheme's one policy, kept by its chief: its copy of ``agent`` (set to the fleet's start)
    steps with every answer as each worker's does, so a joining worker's welcome and the checkpoint carry it.
    """

    def __init__(self, scheme: StepScheme, agent: FederatedAgent) -> None:
        self.scheme = scheme
        self.agent = agent
        self.layout: Layout = list(scheme.welcome_layout(agent))

    def apply(self, answer: Message) -> None:
        """Apply one of the chief's step answers (every one, in order, as the workers do)."""
        if answer.flat is None:
            raise ValueError(f"a {answer.type} without tensors cannot move the fleet's model")
        self.scheme.catch_up_step(self.agent, answer.step, answer.flat)

    def snapshot(self) -> np.ndarray:
        """The model a joining worker takes: network and optimiser state, flat in :attr:`layout` order."""
        return np.asarray(self.scheme.start_parameters(self.agent), dtype=np.float32)

    def start(self) -> FleetStart:
        """The fleet's start a welcome carries until the fleet's first answer: the model as it is."""
        return FleetStart(self.layout, self.snapshot())

    def welcome(self, run_id: str, rnd: int, step: int) -> Message:
        """The welcome a worker joining at exchange (``rnd``, ``step``) takes: the model as it now is."""
        return Message("welcome", run_id, CHIEF_ID, rnd, step=step, origin=CHIEF_ID, flat=self.snapshot())

    def load(self, flat: np.ndarray) -> None:
        """Make the copy ``flat`` (a checkpoint's :meth:`snapshot`)."""
        self.scheme.take_parameters(self.agent, flat)


@dataclass
class ChiefState:
    """Everything the chief remembers across inputs that a checkpoint keeps."""

    members: set[str]  # W: the workers still learning
    answers: AnswerBook
    round: int = 1  # the open round (after the end: the last round played)
    step: int = 0  # the open exchange of the round
    config: dict[str, float | str] = field(default_factory=dict)  # the scheme's asks for the open round
    left: set[str] = field(default_factory=set)  # workers that sent parameters and left W for good
    end_reason: str | None = None
    suspects: dict[str, float] = field(default_factory=dict)  # offline → leaves W at this time
    incarnations: dict[str, int] = field(default_factory=dict)  # the newest seen of each worker
    model: Message | None = None
    """what a (re)joining worker starts from: the last transfer's θ* (fedavg: the last average) or the
    fleet's start"""
    rejections: Counter[Reason] = field(default_factory=Counter)
    completed: dict[str, int] = field(default_factory=dict)  # worker → the first round its criterion held
    transfers: list[tuple[int, str, tuple[str, ...]]] = field(default_factory=list)  # (round, origin, to)
    dropouts: list[tuple[int, str, str]] = field(default_factory=list)  # (round, worker, reason)
    rejoins: list[tuple[int, str]] = field(default_factory=list)  # (round, worker)
    pace: FleetPace = field(default_factory=FleetPace)  # a per-step scheme's stragglers
    contributions: dict[str, Contributions] = field(default_factory=dict)  # an asynchronous scheme's
    epoch: int = 0  # 0, or one more than the newest the chief knew of when it took over (:mod:`.lease`)

    def drop(self, workers: Iterable[str], reason: str) -> tuple[ChiefEvent, ...]:
        """``workers`` leave W (they may come back) for ``reason``; their events."""
        events = []
        for worker in workers:
            self.members.discard(worker)
            self.dropouts.append((self.round, worker, reason))
            remaining = tuple(sorted_workers(self.members))
            events.append(
                ChiefEvent("dropped", self.round, sender=worker, detail=reason, remaining=remaining)
            )
        return tuple(events)

    def rejoin(self, worker: str, why: str) -> tuple[ChiefEvent, ...]:
        """``worker`` is heard from (``why``): no longer suspected, and back in W if it was dropped."""
        self.suspects.pop(worker, None)
        if worker in self.members or worker in self.left:
            return ()
        self.members.add(worker)
        self.rejoins.append((self.round, worker))
        remaining = tuple(sorted_workers(self.members))
        return (ChiefEvent("rejoined", self.round, sender=worker, detail=why, remaining=remaining),)

    def admit(self, worker: str) -> tuple[ChiefEvent, ...]:
        """``worker``, new to the run, is in W from now on."""
        self.members.add(worker)
        remaining = tuple(sorted_workers(self.members))
        return (
            ChiefEvent("admitted", self.round, sender=worker, detail="new to the fleet", remaining=remaining),
        )

    def fields(self) -> dict[str, Any]:
        """The JSON part (cheap: the runner compares it after every input)."""
        model = self.model
        return {
            "round": self.round,
            "step": self.step,
            "round_config": dict(self.config),
            "members": sorted_workers(self.members),
            "left": sorted(self.left),
            "end_reason": self.end_reason,
            "suspects": sorted(self.suspects),
            "incarnations": dict(sorted(self.incarnations.items())),
            "last_answer": [_message_fields(m, f"answer.{i}") for i, m in enumerate(self.answers.last)],
            "model": None if model is None else _message_fields(model, "model"),
            "rejections": {reason.value: n for reason, n in sorted(self.rejections.items())},
            "transfers": [[r, origin, list(to)] for r, origin, to in self.transfers],
            "completed": dict(sorted(self.completed.items())),
            "dropouts": [list(d) for d in self.dropouts],
            "rejoins": [list(r) for r in self.rejoins],
            "pace": self.pace.fields(),
            "epoch": self.epoch,
            **({"contributions": self.contribution_counts()} if self.contributions else {}),
        }

    def contribution_counts(self) -> dict[str, dict[str, Any]]:
        """Worker → its contributions' counts (an asynchronous scheme's; empty for the others)."""
        return {w: self.contributions[w].to_dict() for w in sorted_workers(self.contributions)}

    def tensors(self) -> dict[str, np.ndarray]:
        """The tensors: the last answer's and the fleet model's flat vectors."""
        tensors = {f"answer.{i}": m.flat for i, m in enumerate(self.answers.last) if m.flat is not None}
        if self.model is not None and self.model.flat is not None:
            tensors["model"] = self.model.flat
        return {name: np.asarray(flat, dtype=np.float32) for name, flat in tensors.items()}

    @classmethod
    def from_data(
        cls, fields: dict[str, Any], tensors: dict[str, np.ndarray], *, run_id: str, holdoff: float,
        grace: float, now: float,
    ) -> ChiefState:  # fmt: skip
        """The state :meth:`fields` and :meth:`tensors` describe, its suspects' grace re-armed at ``now``."""
        # only the last answer: each worker's first re-send gets it at once
        last = tuple(_message(run_id, m, tensors) for m in fields["last_answer"])
        return cls(
            members=set(fields["members"]),
            answers=AnswerBook(holdoff, last),
            round=int(fields["round"]),
            step=int(fields["step"]),
            config=dict(fields["round_config"]),
            left=set(fields["left"]),
            end_reason=fields["end_reason"],
            suspects={w: now + grace for w in fields["suspects"]},
            incarnations={w: int(i) for w, i in fields["incarnations"].items()},
            model=None if fields["model"] is None else _message(run_id, fields["model"], tensors),
            rejections=Counter({Reason(r): int(n) for r, n in fields["rejections"].items()}),
            completed={str(w): int(r) for w, r in fields["completed"].items()},
            transfers=[(int(r), str(o), tuple(to)) for r, o, to in fields["transfers"]],
            dropouts=[(int(r), str(w), str(why)) for r, w, why in fields["dropouts"]],
            rejoins=[(int(r), str(w)) for r, w in fields["rejoins"]],
            pace=FleetPace.from_fields(fields.get("pace")),
            contributions={
                str(w): Contributions.from_dict(c) for w, c in fields.get("contributions", {}).items()
            },
            epoch=int(fields.get("epoch", 0)),  # a state written before epochs: the run's first chief
        )


def _message_fields(message: Message, tensor: str) -> dict[str, Any]:
    return {
        "type": message.type,
        "round": message.round,
        "step": message.step,
        "origin": message.origin,
        "finished": list(message.finished),
        "contributors": list(message.contributors),
        "metrics": dict(message.metrics),
        "samples": message.samples,
        "units": message.units,
        "config": dict(message.config),
        "tensor": None if message.flat is None else tensor,
    }


def _message(run_id: str, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> Message:
    name = fields["tensor"]
    if name is not None and name not in tensors:
        raise ValueError(f"chief state names tensor {name!r}, which is not in its tensor file")
    return Message(
        fields["type"], run_id, CHIEF_ID, int(fields["round"]),
        flat=None if name is None else np.asarray(tensors[name], dtype=np.float32),
        metrics={str(k): float(v) for k, v in fields["metrics"].items()}, origin=fields["origin"],
        finished=tuple(fields["finished"]), contributors=tuple(fields["contributors"]),
        step=int(fields["step"]), samples=int(fields["samples"]), units=int(fields["units"]),
        config=dict(fields["config"]),
    )  # fmt: skip
