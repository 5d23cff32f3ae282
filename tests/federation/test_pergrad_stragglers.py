"""``pergrad`` with a straggler and a late unit (docs/protocol.md, "Stragglers"): real CartPole learners over
the in-process bus, and the chief keeping the fleet's model."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fleetrl.agent.learner import Learner
from fleetrl.federation.chief import Chief
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import fleet_model
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.base import Transport
from fleetrl.transport.local import LocalBus

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


@pytest.mark.slow  # a 4-worker CartPole run with a slow unit and a late one
def test_a_slow_unit_and_a_late_one_leave_the_fleet_one_policy_the_chief_s(
    fleet_runner: Callable[..., Any],
) -> None:
    """Workers 0 and 1 are even; 2 plays its rounds a second slower; 3, a unit the chief was not started
    with, joins at round JOIN. The fleet does not
    wait for 2 round after round; 2 applies every answer it missed and contributes what it played, stale; 3
    starts from the fleet's model the chief hands it. Every worker ends with the chief's model — network and
    optimisers' state."""
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

    result = fleet_runner(
        bus.client, learners, max_rounds=ROUNDS, chief_kwargs=chief_kwargs, role_transport=transport,
        worker_kwargs={"scheme": "pergrad"}, timeout=120, on_chief=chiefs.append,
    )  # fmt: skip
    (chief,) = chiefs
    assert chief.end_reason == f"reached M={ROUNDS} rounds" and not chief.dropouts
    assert len(result.records["0"]) == len(result.records["1"]) == ROUNDS
    slow_rounds = [r.round for r in result.records["2"]]
    assert 1 <= len(slow_rounds) < ROUNDS, slow_rounds  # it took part in some rounds, stale, not in all
    assert chief.state.pace.late["2"] >= 1 and not chief.state.pace.late["0"]
    late_rounds = [r.round for r in result.records["3"]]
    assert late_rounds and min(late_rounds) >= JOIN, late_rounds
    assert chief.all_workers == ("0", "1", "2", "3")
    kept = model.agent
    for w, learner in plain.items():  # every answer applied, in order, to the fleet's model
        assert np.array_equal(learner.agent.model_parameters(), kept.model_parameters()), w
        assert np.array_equal(learner.agent.optimiser_parameters(), kept.optimiser_parameters()), w


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)
