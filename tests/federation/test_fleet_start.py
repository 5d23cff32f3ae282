"""Under a scheme whose fleet is one policy (``pergrad``), workers started with different ``--seed`` values
end with identical models: the chief's welcome hands every joining worker the fleet's start."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import fleet_model
from safetensors.numpy import load_file

from fleetrl.federation.schemes.base import FleetStart
from fleetrl.runs.factory import make_learner
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.local import LocalBus


def fleet_start(learning: LearningSettings) -> FleetStart | None:
    """The fleet's start the chief hands out before the fleet has learnt anything: its fleet model's first
    snapshot (None for a scheme whose fleet is not one policy)."""
    model = fleet_model(learning)
    return None if model is None else FleetStart(model.layout, model.snapshot())


FleetRunner = Callable[..., Any]

SEEDS = {"0": 40, "1": 41, "2": 42}
"""worker id → the --seed it was started with"""


def pergrad(seed: int = 0) -> LearningSettings:
    """CartPole under pergrad, preset standard, 3 rounds, learning seed ``seed`` (resolved)."""
    learning = LearningSettings(env="cartpole", preset="standard", scheme="pergrad", seed=seed, max_rounds=3)
    return resolve_learning(learning)


def final_models(fleet_runner: FleetRunner, start: FleetStart | None) -> dict[str, np.ndarray]:
    """Three pergrad workers on CartPole units 0-2, each built as ``fleetrl worker --seed S`` builds it, and a
    chief handing out ``start``, 3 rounds over the in-process bus."""
    settings = pergrad()
    specs = {
        w: WorkerSpec(worker=int(w), unit=int(w), learning=pergrad(seed), out="/nonexistent")
        for w, seed in SEEDS.items()
    }
    learners = {w: make_learner(spec) for w, spec in specs.items()}
    bus = LocalBus()
    steps = fleet_shape(settings).exchanges_per_round
    chief_kwargs = {"scheme": "pergrad", "steps_per_round": steps, "start": start}
    result = fleet_runner(
        bus.client, learners, max_rounds=3, chief_kwargs=chief_kwargs, worker_kwargs={"scheme": "pergrad"}
    )
    assert all(len(r) == 3 for r in result.records.values()), result.records
    return {w: learner.agent.model_parameters() for w, learner in learners.items()}


@pytest.mark.slow  # two 3-worker CartPole runs
def test_workers_of_different_seeds_end_with_one_model_from_the_chief_s_start(
    fleet_runner: FleetRunner,
) -> None:
    start = fleet_start(pergrad(seed=7))  # the run's learning seed
    assert start is not None
    models = final_models(fleet_runner, start)
    assert all(np.array_equal(models["0"], m) for m in models.values())
    # without the chief's start each worker starts from its own seed's network and the fleet splits
    apart = final_models(fleet_runner, None)
    assert max(float(np.abs(apart["0"] - m).max()) for m in apart.values()) > 1e-3


def test_only_a_one_policy_scheme_has_a_fleet_start() -> None:
    fedavg = resolve_learning(LearningSettings(env="cartpole", preset="standard", scheme="fedavg"))
    assert fleet_start(fedavg) is None
    first, again = fleet_start(pergrad()), fleet_start(pergrad())
    assert first is not None and again is not None
    assert first.flat.tobytes() == again.flat.tobytes()  # drawn from the seed: the same on every machine


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_standalone_workers_of_seeds_40_41_42_end_as_one_model_over_mosquitto(tmp_path: Path) -> None:
    """``fleetrl chief`` and three ``fleetrl worker --seed 40/41/42`` processes on one mosquitto broker."""
    run = ["--run-id", "seeds", "--env", "cartpole", "--preset", "standard", "--max-rounds", "3"]
    base = [sys.executable, "-m", "fleetrl.cli.main"]
    with EmbeddedBroker("mosquitto") as broker:
        url = ["--broker", broker.url]
        roles = [[*base, "chief", *url, *run, "--workers", "3", "--out", str(tmp_path / "chief")]]
        roles += [
            [
                *base,
                "worker",
                *url,
                *run,
                "--worker-id",
                w,
                "--seed",
                str(s),
                "--out",
                str(tmp_path / f"w{w}"),
            ]
            for w, s in SEEDS.items()
        ]
        procs = [subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for argv in roles]
        codes = [p.wait(timeout=600) for p in procs]
    assert codes == [0, 0, 0, 0], [p.stderr.read()[-500:] if p.stderr else b"" for p in procs]
    models = [load_file(str(tmp_path / f"w{w}" / "models" / f"worker-{w}.safetensors")) for w in SEEDS]
    assert all(set(m) == set(models[0]) for m in models)
    assert all(np.array_equal(models[0][name], m[name]) for m in models for name in models[0])
