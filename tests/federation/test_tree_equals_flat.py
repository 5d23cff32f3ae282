"""THE flat-vs-tree equality: the same 4 CartPole units (real learners, preset standard) run flat (a chief
and 4 workers) and as a tree (a root chief, 2 edge aggregators × 2 workers) on the in-process bus give
identical per-round scores, events and final models: under ``pergrad`` (the default, to round M; also with
its units weighed by need, each message carrying its own weight) and under ``fedavg`` with a low target, so
that the run ends by every unit completing and the root's ``finished`` reaches every member through its
site."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import pytest
from conftest import chief_of, fleet_model, worker_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.edge.aggregator import EdgeAggregator
from fleetrl.federation.edge.runner import EdgeSummary, run_edge
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.runner import ChiefSummary, run_chief
from fleetrl.federation.schemes.base import FleetStart
from fleetrl.federation.worker.runner import FederatedRound
from fleetrl.runs.factory import make_learner
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.local import LocalBus

ROUNDS = 3
UNITS = ("0", "1", "2", "3")
SITES = {"site-a": ("0", "1"), "site-b": ("2", "3")}
TIMEOUT = 300.0
FleetRunner = Callable[..., Any]


ARMS = {"pergrad": (ROUNDS, None), "fedavg": (12, 25.0)}
"""arm → (M, target score: None for CartPole's own)"""


Outcome = dict[str, list[tuple[float, str]]]


def learning(scheme: str, seed: int = 0) -> LearningSettings:
    rounds, target = ARMS[scheme]
    return resolve_learning(
        LearningSettings(
            env="cartpole",
            preset="standard",
            scheme=scheme,
            seed=seed,
            max_rounds=rounds,
            target_score=target,
        )
    )


def learners(scheme: str) -> dict[str, Any]:
    """The 4 units, each built as ``fleetrl worker --worker-id W --seed 100+W`` builds it."""
    return {
        w: make_learner(
            WorkerSpec(
                worker=int(w), unit=int(w), learning=learning(scheme, 100 + int(w)), out="/nonexistent"
            )
        )
        for w in UNITS
    }


def chief_options(scheme: str) -> dict[str, Any]:
    settings = learning(scheme)
    model = fleet_model(settings)
    start = None if model is None else FleetStart(model.layout, model.snapshot())
    shape = fleet_shape(settings)
    steps = shape.exchanges_per_round
    return {"scheme": scheme, "steps_per_round": steps, "start": start, "quorum": 1.0}


def outcome(records: dict[str, list[FederatedRound]]) -> Outcome:
    return {w: [(r.result.score, r.event) for r in rs] for w, rs in records.items()}


def flat_run(fleet_runner: FleetRunner, scheme: str, units: dict[str, Any]) -> tuple[Outcome, ChiefSummary]:
    result = fleet_runner(
        LocalBus().client, units, run_id="flat", max_rounds=ARMS[scheme][0],
        chief_kwargs=chief_options(scheme), worker_kwargs={"scheme": scheme}, timeout=TIMEOUT,
    )  # fmt: skip
    return outcome(result.records), result.chief


def tree_run(
    scheme: str, units: dict[str, Any], regional: bool = False, sites: dict[str, tuple[str, ...]] = SITES
) -> tuple[Outcome, ChiefSummary, list[EdgeSummary]]:
    """A root chief of the sites, each site an edge aggregator of its workers under its own run id, all on
    one bus; ``regional``: the sites are members of a regional aggregator, the root's only member."""
    options = chief_options(scheme)
    rounds = ARMS[scheme][0]
    agent = units["0"].agent
    layout = None if options["start"] is None else options["start"].layout
    step_layout = list(units["0"].agent.step_layout(0)) if scheme != "fedavg" else list(agent.model_layout())
    bus = LocalBus()
    top = ("region",) if regional else tuple(sites)
    root = chief_of(Chief, run_id="tree", workers=top, layout=step_layout, max_rounds=rounds, **options)
    records: dict[str, list[FederatedRound]] = {w: [] for w in UNITS}
    results: dict[str, Any] = {}
    errors: list[BaseException] = []

    def guarded(name: str, fn: Callable[[], Any]) -> threading.Thread:
        def body() -> None:
            try:
                results[name] = fn()
            except BaseException as exc:
                errors.append(exc)

        return threading.Thread(target=body, name=name)

    threads = [guarded("root", lambda: run_chief(root, bus.client(), idle_timeout=TIMEOUT))]

    def aggregator(site: str, upstream_run: str, members: tuple[str, ...]) -> threading.Thread:
        edge = EdgeAggregator(
            ChiefPlan(
                run_id=f"tree-{site}",
                workers=members,
                layout=step_layout,
                welcome_layout=layout,
                scheme=scheme,
                max_rounds=rounds,
                steps_per_round=options["steps_per_round"],
                quorum=1.0,
            ),
            site_id=site,
            root_run=upstream_run,
        )
        return guarded(
            site, lambda: run_edge(edge, upstream=bus.client(), downstream=bus.client(), idle_timeout=TIMEOUT)
        )

    if regional:
        threads.append(aggregator("region", "tree", tuple(sites)))
    for site, members in sites.items():
        threads.append(aggregator(site, "tree-region" if regional else "tree", members))
        for w in members:
            worker = worker_of(
                units[w], bus.client(), run_id=f"tree-{site}", worker_id=w, max_rounds=rounds,
                on_record=records[w].append, reply_timeout=TIMEOUT, scheme=scheme,
            )  # fmt: skip
            threads.append(guarded(f"worker-{w}", worker.run))
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(TIMEOUT + 10)
    assert not errors, errors
    assert not any(t.is_alive() for t in threads), "a role hung"
    return outcome(records), results["root"], [results[s] for s in sites]


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.mark.slow  # two 4-unit CartPole runs per scheme
@pytest.mark.parametrize("scheme", list(ARMS))
def test_a_tree_of_two_sites_gives_the_flat_fleet_s_scores_and_models(
    fleet_runner: FleetRunner, scheme: str
) -> None:
    flat_units, tree_units = learners(scheme), learners(scheme)
    flat, flat_chief = flat_run(fleet_runner, scheme, flat_units)
    tree, root, sites = tree_run(scheme, tree_units)
    assert all(len(rows) >= 3 for rows in flat.values()), flat
    assert tree == flat
    for w in UNITS:
        assert (
            flat_units[w].agent.model_parameters().tobytes()
            == tree_units[w].agent.model_parameters().tobytes()
        )
    assert (root.rounds, root.end_reason) == (flat_chief.rounds, flat_chief.end_reason)
    assert {s.end_reason for s in sites} == {"the root ended the run"}
    models = {u.agent.model_parameters().tobytes() for u in tree_units.values()}
    assert len(models) == 1  # one policy across both sites
    if scheme == "fedavg":  # ended by completion: the root's finished reached every member through its site
        assert root.end_reason == "every unit completed" and root.rounds < ARMS[scheme][0]
        assert all(rows[-1][1] == "completed" for rows in tree.values()), tree


@pytest.mark.slow  # two 4-unit CartPole runs
def test_a_regional_tier_of_aggregators_gives_the_flat_fleet_s_scores_and_models(
    fleet_runner: FleetRunner,
) -> None:
    """Three tiers: the root's one member is a regional aggregator whose members are two sites' aggregators
    of 3 units and 1 (the 100k arithmetic's shape, docs/deploy.md): each tier weighs by the units behind
    each member, so the fleet's step is the flat fleet's."""
    flat_units, tree_units = learners("pergrad"), learners("pergrad")
    flat, flat_chief = flat_run(fleet_runner, "pergrad", flat_units)
    uneven_sites = {"site-a": ("0", "1", "2"), "site-b": ("3",)}
    tree, root, _ = tree_run("pergrad", tree_units, regional=True, sites=uneven_sites)
    assert tree == flat
    assert {u.agent.model_parameters().tobytes() for u in tree_units.values()} == {
        flat_units["0"].agent.model_parameters().tobytes()
    }
    assert (root.rounds, root.end_reason) == (flat_chief.rounds, flat_chief.end_reason)
