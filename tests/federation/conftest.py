"""Shared helpers for federation tests: a small deterministic fake learner and a threaded federated run."""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from fleetrl.federation.chief.machine import Chief, ChiefEvent
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.runner import ChiefSummary, run_chief
from fleetrl.federation.schemes import resolve_scheme
from fleetrl.federation.worker.runner import FederatedRound, FederatedWorker, WorkerSummary
from fleetrl.runs.launch import chief_plan
from fleetrl.runs.settings import RoundRules
from fleetrl.transport.base import Transport

FAKE_LAYOUT: list[tuple[str, tuple[int, ...]]] = [("trunk.weight", (4, 3)), ("head.bias", (3,))]


PLAN_FIELDS = frozenset(f.name for f in dataclasses.fields(ChiefPlan))
WORKER_PLAN_FIELDS = frozenset(f.name for f in dataclasses.fields(WorkerPlan))


def chief_of(make: Callable[..., Any] = Chief, **options: Any) -> Any:
    """``make(plan, **others)`` (a chief class, ``new_chief`` or ``EdgeAggregator``) from keyword options:
    the :class:`ChiefPlan`'s fields (``members``: its ``workers``) and the others."""
    if "members" in options:
        options["workers"] = options.pop("members")
    plan = ChiefPlan(**{k: v for k, v in options.items() if k in PLAN_FIELDS})
    return make(plan, **{k: v for k, v in options.items() if k not in PLAN_FIELDS})


def worker_of(learner: Any, transport: Transport, **options: Any) -> FederatedWorker:
    """A :class:`FederatedWorker` from keyword options: the :class:`WorkerPlan`'s fields (its layouts and
    K from ``learner.agent``) and the worker's others."""
    fields, others = plan_split(options)
    return FederatedWorker(learner, transport, WorkerPlan.for_agent(learner.agent, **fields), **others)


def machine_of(make: Callable[..., Any], **options: Any) -> Any:
    """``make(plan, **others)`` (a worker machine class or ``new_worker_machine``) from keyword options: the
    :class:`WorkerPlan`'s fields and the others."""
    fields, others = plan_split(options)
    return make(WorkerPlan(**fields), **others)


def plan_split(options: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``options`` as (the :class:`WorkerPlan`'s fields, the others)."""
    fields = {k: v for k, v in options.items() if k in WORKER_PLAN_FIELDS}
    return fields, {k: v for k, v in options.items() if k not in WORKER_PLAN_FIELDS}


@dataclass(frozen=True)
class FakeResult:
    """Same fields as fleetrl.agent.learner.RoundResult that the worker reads."""

    score: float
    steps: int
    wma: float
    completed: bool
    actor_loss: float
    critic_loss: float
    entropy: float


class FakeAgent:
    """A 'policy' of 15 floats pulled towards a per-worker target; SGD with lr 0.1 on received gradients."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.params = rng.normal(size=15).astype(np.float32)
        self.target = rng.normal(size=15).astype(np.float32)
        self.noise = rng
        self.last_gradient = np.zeros(15, np.float32)

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return list(FAKE_LAYOUT)

    def actor_gradient(self) -> np.ndarray:
        return self.last_gradient.copy()

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        self.params = (self.params - np.float32(0.1) * flat).astype(np.float32)

    def actor_parameters(self) -> np.ndarray:
        return self.params.copy()

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        self.params = np.array(flat, dtype=np.float32)


class FakeLearner:
    """Plays 'rounds': the score depends on the parameters, so averages and transfers show in the scores.

    :param complete_at: the round at which the completion criterion holds (None: never).
    :param pause: seconds each round takes (to give concurrent tests time to interfere).
    """

    def __init__(self, seed: int, complete_at: int | None = None, pause: float = 0.0) -> None:
        self.agent = FakeAgent(seed)
        self.pause = pause
        self.complete_at = complete_at
        self.rounds = 0
        self.scores: list[float] = []

    def play_round(self) -> FakeResult:
        time.sleep(self.pause)
        self.rounds += 1
        distance = float(np.linalg.norm(self.agent.params - self.agent.target))
        score = round(1000.0 / (1.0 + distance), 6)
        self.scores.append(score)
        completed = self.complete_at is not None and self.rounds >= self.complete_at
        if not completed:
            step = self.agent.params - self.agent.target + 0.01 * self.agent.noise.normal(size=15)
            self.agent.last_gradient = step.astype(np.float32)
        wma = float(np.mean(self.scores[-10:]))
        return FakeResult(score, self.rounds, wma, completed, distance, 0.5 * distance, 1.0)


@dataclass
class FleetResult:
    """What a threaded federated run produced."""

    records: dict[str, list[FederatedRound]]
    workers: dict[str, WorkerSummary]
    chief: ChiefSummary
    events: list[ChiefEvent]
    state: Chief

    def scores(self) -> dict[str, list[float]]:
        return {w: [r.result.score for r in rs] for w, rs in self.records.items()}


FleetRunner = Callable[..., FleetResult]


def run_fleet(
    make_transport: Callable[[], Transport],
    learners: dict[str, FakeLearner] | dict[str, object],
    *,
    run_id: str = "test-run",
    max_rounds: int = 10,
    timeout: float = 60.0,
    role_transport: Callable[[str], Transport] | None = None,
    chief_kwargs: dict[str, Any] | None = None,
    worker_kwargs: dict[str, Any] | None = None,
    on_chief: Callable[[Chief], None] | None = None,
) -> FleetResult:
    """Chief and workers as threads, each with its own transport from ``make_transport`` (or from
    ``role_transport(role)``, role ``chief`` or the worker id); extra keyword arguments for the Chief and
    FederatedWorker; ``on_chief`` sees the chief's state machine before it starts."""
    agent = learners[next(iter(learners))].agent  # type: ignore[attr-defined]
    chief_kwargs = {"scheme": "paper", **(chief_kwargs or {})}
    worker_kwargs = {"scheme": "paper", **(worker_kwargs or {})}
    layout = resolve_scheme(chief_kwargs["scheme"]).layout(agent)
    chief_kwargs = {"workers": list(learners), **chief_kwargs}  # a chief may know fewer: new units join
    chief = chief_of(Chief, run_id=run_id, layout=layout, max_rounds=max_rounds, **chief_kwargs)
    if on_chief is not None:
        on_chief(chief)

    def transport(role: str) -> Transport:
        return role_transport(role) if role_transport is not None else make_transport()

    events: list[ChiefEvent] = []
    records: dict[str, list[FederatedRound]] = {w: [] for w in learners}
    summaries: dict[str, WorkerSummary] = {}
    outcome: dict[str, ChiefSummary] = {}
    errors: list[BaseException] = []

    def guard(fn: Callable[[], None]) -> Callable[[], None]:
        def body() -> None:
            try:
                fn()
            except BaseException as exc:
                errors.append(exc)

        return body

    def chief_main() -> None:
        outcome["chief"] = run_chief(chief, transport("chief"), on_event=events.append, idle_timeout=timeout)

    def worker_main(worker_id: str) -> Callable[[], None]:
        def main() -> None:
            worker = worker_of(
                learners[worker_id],
                transport(worker_id),
                run_id=run_id,
                worker_id=worker_id,
                max_rounds=max_rounds,
                on_record=records[worker_id].append,
                reply_timeout=timeout,
                **(worker_kwargs or {}),
            )
            summaries[worker_id] = worker.run()

        return main

    threads = [threading.Thread(target=guard(chief_main), name="chief")]
    threads += [threading.Thread(target=guard(worker_main(w)), name=f"worker-{w}") for w in learners]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout + 5)
    assert not errors, errors
    assert not any(t.is_alive() for t in threads), "a role hung"
    return FleetResult(records, summaries, outcome["chief"], events, chief)


def make_fake_fleet(pause: float = 0.0) -> dict[str, FakeLearner]:
    """Three workers: 2 completes at round 4 (transfer to 1 and 3), 1 at round 7 (transfer to 3), 3 never."""
    return {"1": FakeLearner(11, 7, pause), "2": FakeLearner(12, 4, pause), "3": FakeLearner(13, None, pause)}


@pytest.fixture
def fleet_runner() -> FleetRunner:
    """The threaded federated-run helper: ``fleet_runner(make_transport, learners, max_rounds=...)``."""
    return run_fleet


@pytest.fixture
def fake_fleet() -> Callable[..., dict[str, FakeLearner]]:
    """Factory of the three-worker fake fleet (fresh learners each call)."""
    return make_fake_fleet


@pytest.fixture
def fake_learner() -> type[FakeLearner]:
    """The fake learner class."""
    return FakeLearner


class StepAgent:
    """Just enough of an agent for a site's fleet model: a 2-value network and a 1-value optimiser state;
    a fleet step subtracts the gradient's first two values and counts the step."""

    def __init__(self) -> None:
        self.model, self.optimiser = np.zeros(2, np.float32), np.zeros(1, np.float32)

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("m", (2,))]

    def optimiser_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("o", (1,))]

    def model_parameters(self) -> np.ndarray:
        return self.model.copy()

    def optimiser_parameters(self) -> np.ndarray:
        return self.optimiser.copy()

    def set_model_parameters(self, flat: np.ndarray) -> None:
        self.model = np.array(flat, np.float32)

    def set_optimiser_parameters(self, flat: np.ndarray) -> None:
        self.optimiser = np.array(flat, np.float32)

    def apply_fleet_step(self, k: int, flat: np.ndarray) -> None:
        self.model, self.optimiser = self.model - flat[:2], self.optimiser + 1


def fleet_model(learning: Any) -> Any:
    """The fleet's model a chief of resolved ``learning`` keeps (its plan's)."""
    return chief_plan(learning, RoundRules(quorum=1.0), run_id="r", workers=("0",))[1].get("fleet_model")
