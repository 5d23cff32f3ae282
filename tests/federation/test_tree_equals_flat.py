"""THE flat-vs-tree equality: the same 4 CartPole units (real learners, preset standard, pergrad) run flat
(a chief and 4 workers) and as a tree (a root chief, 2 edge aggregators × 2 workers) on the in-process bus
give identical per-round scores and final models."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fleetrl.federation.chief import Chief
from fleetrl.federation.edge import EdgeAggregator
from fleetrl.federation.edge_runner import EdgeSummary, run_edge
from fleetrl.federation.runner import ChiefSummary, run_chief
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.worker import FederatedRound, FederatedWorker
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import fleet_model
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.local import LocalBus

ROUNDS = 3
UNITS = ("0", "1", "2", "3")
SITES = {"site-a": ("0", "1"), "site-b": ("2", "3")}
TIMEOUT = 300.0
FleetRunner = Callable[..., Any]


def learning(seed: int = 0) -> LearningSettings:
    return resolve_learning(
        LearningSettings(env="cartpole", preset="standard", scheme="pergrad", seed=seed, max_rounds=ROUNDS)
    )


def learners() -> dict[str, Any]:
    """The 4 units, each built as ``fleetrl worker --worker-id W --seed 100+W`` builds it."""
    return {
        w: make_learner(
            WorkerSpec(worker=int(w), unit=int(w), learning=learning(100 + int(w)), out="/nonexistent")
        )
        for w in UNITS
    }


def chief_options() -> dict[str, Any]:
    settings = learning()
    model = fleet_model(settings)
    assert model is not None
    start = FleetStart(model.layout, model.snapshot())
    shape = fleet_shape(settings)
    return {"scheme": "pergrad", "steps_per_round": shape.exchanges_per_round, "start": start, "quorum": 1.0}


def flat_run(fleet_runner: FleetRunner, units: dict[str, Any]) -> dict[str, list[float]]:
    result = fleet_runner(
        LocalBus().client, units, run_id="flat", max_rounds=ROUNDS, chief_kwargs=chief_options(),
        worker_kwargs={"scheme": "pergrad"}, timeout=TIMEOUT,
    )  # fmt: skip
    return {w: [r.result.score for r in rs] for w, rs in result.records.items()}


def tree_run(units: dict[str, Any]) -> tuple[dict[str, list[float]], ChiefSummary, list[EdgeSummary]]:
    """A root chief of the two sites, each site an edge aggregator of two workers under its own run id, all
    on one bus."""
    options = chief_options()
    agent = units["0"].agent
    layout = options["start"].layout
    step_layout = list(agent.step_layout(0))
    bus = LocalBus()
    root = Chief(run_id="tree", workers=tuple(SITES), layout=step_layout, max_rounds=ROUNDS, **options)
    records: dict[str, list[FederatedRound]] = {w: [] for w in UNITS}
    outcome: dict[str, Any] = {}
    errors: list[BaseException] = []

    def guarded(name: str, fn: Callable[[], Any]) -> threading.Thread:
        def body() -> None:
            try:
                outcome[name] = fn()
            except BaseException as exc:
                errors.append(exc)

        return threading.Thread(target=body, name=name)

    threads = [guarded("root", lambda: run_chief(root, bus.client(), idle_timeout=TIMEOUT))]
    for site, members in SITES.items():
        edge = EdgeAggregator(
            site_id=site, root_run="tree", run_id=f"tree-{site}", members=members, layout=step_layout,
            welcome_layout=layout, scheme="pergrad", max_rounds=ROUNDS,
            steps_per_round=options["steps_per_round"], quorum=1.0,
        )  # fmt: skip
        threads.append(
            guarded(
                site,
                lambda e=edge: run_edge(
                    e, upstream=bus.client(), downstream=bus.client(), idle_timeout=TIMEOUT
                ),
            )
        )
        for w in members:
            worker = FederatedWorker(
                units[w], bus.client(), run_id=f"tree-{site}", worker_id=w, max_rounds=ROUNDS,
                on_record=records[w].append, reply_timeout=TIMEOUT, scheme="pergrad",
            )  # fmt: skip
            threads.append(guarded(f"worker-{w}", worker.run))
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(TIMEOUT + 10)
    assert not errors, errors
    assert not any(t.is_alive() for t in threads), "a role hung"
    scores = {w: [r.result.score for r in rs] for w, rs in records.items()}
    return scores, outcome["root"], [outcome[s] for s in SITES]


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.mark.slow  # two 4-unit CartPole runs of 3 rounds
def test_a_tree_of_two_sites_gives_the_flat_fleet_s_scores_and_models(fleet_runner: FleetRunner) -> None:
    flat_units, tree_units = learners(), learners()
    flat = flat_run(fleet_runner, flat_units)
    tree, root, sites = tree_run(tree_units)
    assert all(len(s) == ROUNDS for s in flat.values()), flat
    assert tree == flat
    for w in UNITS:
        assert (
            flat_units[w].agent.model_parameters().tobytes()
            == tree_units[w].agent.model_parameters().tobytes()
        )
    # the root saw two members, each standing for two units
    assert root.rounds == ROUNDS and {s.end_reason for s in sites} == {"the root ended the run"}
    models = {u.agent.model_parameters().tobytes() for u in tree_units.values()}
    assert len(models) == 1  # one policy across both sites, and it learnt: not the fleet's start
    final = np.frombuffer(models.pop(), np.float32)
    assert not np.array_equal(final, chief_options()["start"].flat[: final.size])
