"""``pergrad`` with a straggler and a late unit (docs/protocol.md, "Stragglers"): real CartPole learners over
the in-process bus, and the chief keeping the fleet's model. One policy is checked during the run, at every
exchange, between the unit that caught up and the units never behind (lab/benchmarks/one_policy.py), and that
check is shown to fail on a catch-up broken on purpose in the test."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import fleet_model

from fleetrl.agent.learner import Learner
from fleetrl.federation.chief.machine import Chief
from fleetrl.runs.factory import make_learner
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.base import Transport
from fleetrl.transport.local import LocalBus

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "lab" / "benchmarks"))  # one_policy

from one_policy import MUTATIONS, BrokenCatchUp, OnePolicy, Recorder, compare, recording

ROUNDS = 7
JOIN = 3


class SlowLearner:
    """A learner whose rounds take ``pause`` seconds more to play (a slow unit)."""

    def __init__(self, learner: Learner, pause: float) -> None:
        self.inner, self.pause = learner, pause

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def begin_round(self) -> Any:
        time.sleep(self.pause)
        return self.inner.begin_round()


class LateTransport:
    """A worker's transport that connects only once the chief has reached round ``at`` (a unit added to a
    fleet that is already learning)."""

    def __init__(self, inner: Transport, chiefs: list[Chief], at: int) -> None:
        self.inner, self.chiefs, self.at = inner, chiefs, at

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def connect(self, *args: Any, **kwargs: Any) -> None:
        while not self.chiefs or self.chiefs[0].round < self.at:
            time.sleep(0.05)
        self.inner.connect(*args, **kwargs)


def straggler_run(
    fleet_runner: Callable[..., Any], broken: BrokenCatchUp | None = None
) -> tuple[Any, Chief, dict[str, Any], Any, OnePolicy]:
    """Workers 0 and 1 are even; 2 plays its rounds a second slower (its catch-up through ``broken``, if
    given); 3, a unit the chief was not started with, joins at round JOIN. The run's result, its chief, the
    learners, the chief's fleet model, and what every worker held at every exchange, compared."""
    learning = resolve_learning(
        LearningSettings(env="cartpole", preset="standard", scheme="pergrad", max_rounds=ROUNDS)
    )
    learners: dict[str, Any] = {
        w: make_learner(WorkerSpec(worker=int(w), unit=int(w), learning=learning, out="/nonexistent"))
        for w in ("0", "1", "2", "3")
    }
    plain = dict(learners)
    learners["2"] = SlowLearner(learners["2"], pause=1.0)
    model = fleet_model(learning)
    assert model is not None
    chief_kwargs = {
        "scheme": "pergrad", "steps_per_round": fleet_shape(learning).exchanges_per_round,
        "fleet_model": model, "quorum": 0.6, "workers": ["0", "1", "2"],  # 3 is new to the fleet
    }  # fmt: skip
    chiefs: list[Chief] = []
    bus = LocalBus()

    def transport(role: str) -> Transport:
        return LateTransport(bus.client(), chiefs, JOIN) if role == "3" else bus.client()

    recorder = Recorder()
    with recording(recorder, None if broken is None else {"2": broken}):
        result = fleet_runner(
            bus.client, learners, max_rounds=ROUNDS, chief_kwargs=chief_kwargs, role_transport=transport,
            worker_kwargs={"scheme": "pergrad"}, timeout=120, on_chief=chiefs.append,
        )  # fmt: skip
    (chief,) = chiefs
    return result, chief, plain, model, compare(recorder.held)


def end_models_are_the_chief_s(plain: dict[str, Any], model: Any) -> bool:
    """The old end-of-run check: every worker's final network and Adam state are the chief's fleet model's
    (which a ``done`` that ends a worker's run hands it first: a broken catch-up shows only in a worker that
    ended otherwise, on reaching M say)."""
    kept = model.agent
    return all(
        np.array_equal(learner.agent.model_parameters(), kept.model_parameters())
        and np.array_equal(learner.agent.optimiser_parameters(), kept.optimiser_parameters())
        for learner in plain.values()
    )


@pytest.mark.slow  # a 4-worker CartPole run with a slow unit and a late one
def test_a_slow_unit_and_a_late_one_leave_the_fleet_one_policy_the_chief_s(
    fleet_runner: Callable[..., Any],
) -> None:
    """The fleet does not wait for 2 round after round; 2 applies every answer it missed and contributes
    what it played, stale; 3 starts from the fleet's model the chief hands it. At every exchange, the
    straggler (after a catch-up) and the late unit hold what the units never behind hold — network and
    optimisers' state — checked as they apply each answer, before any final hand-over; and every worker
    ends with the chief's model."""
    result, chief, plain, model, one_policy = straggler_run(fleet_runner)
    assert chief.end_reason == f"reached M={ROUNDS} rounds" and not chief.dropouts
    assert len(result.records["0"]) == len(result.records["1"]) == ROUNDS
    slow_rounds = [r.round for r in result.records["2"]]
    assert 1 <= len(slow_rounds) < ROUNDS, slow_rounds  # it took part in some rounds, stale, not in all
    assert chief.state.pace.late["2"] >= 1 and not chief.state.pace.late["0"]
    late_rounds = [r.round for r in result.records["3"]]
    assert late_rounds and min(late_rounds) >= JOIN, late_rounds
    assert chief.all_workers == ("0", "1", "2", "3")
    assert not one_policy.mismatches, one_policy.summary()
    assert one_policy.caught_up.get("2", 0) >= 1 and one_policy.after_catch_up >= 1, one_policy.summary()
    assert end_models_are_the_chief_s(plain, model)


@pytest.mark.slow  # the same run, the straggler's catch-up broken
@pytest.mark.parametrize("mutation", MUTATIONS)
def test_the_one_policy_check_fails_on_a_broken_catch_up(
    fleet_runner: Callable[..., Any], mutation: str
) -> None:
    """Skip one missed answer; apply two out of order; a catch-up step with one gradient term changed: the
    check during the run finds the straggler off the fleet's policy. (The end-of-run check passes or not
    by timing: a worker that ends on the chief's ``done`` takes the chief's model first.)"""
    _, _, plain, model, one_policy = straggler_run(fleet_runner, BrokenCatchUp(mutation))
    end = "held" if end_models_are_the_chief_s(plain, model) else "failed"
    print(f"{mutation}: {one_policy.summary()}; the end-of-run check {end}")
    assert one_policy.mismatches and "2 (caught up)" in one_policy.mismatches[0], one_policy.summary()


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)
