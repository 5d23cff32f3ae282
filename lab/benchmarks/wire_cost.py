"""What per-step sharing costs on the wire: a round's communication time over mosquitto, 3 and 8 workers.

    python lab/benchmarks/wire_cost.py [--rounds 20] [--workers 3 8]

Real chief and workers over a real mosquitto, with no learning (a fixed gradient of the standard preset's
QUBE layout), set against a QUBE episode's real-time length (15 s at the cap, 0.3 s early).
"""

from __future__ import annotations

import argparse
import threading
import time
from typing import Any

import numpy as np

from fleetrl.agent.config import get_preset
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.runner import run_chief
from fleetrl.federation.worker.runner import FederatedWorker
from fleetrl.portable import describe_host
from fleetrl.runs.factory import probe_agent
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.mqtt import MqttTransport

EPISODE_AT_CAP = 2500 * 0.006
EARLY_EPISODE = 50 * 0.006


class WireAgent:
    """The agent's federated surface with no learning: a fixed gradient and model of the real layout."""

    def __init__(self, layout: list[tuple[str, tuple[int, ...]]], steps: int) -> None:
        size = sum(int(np.prod(shape)) for _, shape in layout)
        self.layout, self.steps = layout, steps
        self.flat = np.random.default_rng(0).standard_normal(size).astype(np.float32)

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        return self.layout

    model_layout = actor_layout = lambda self: self.layout

    def update_step_count(self) -> int:
        return self.steps

    begin_update = update_step_count

    def step_gradients(self, k: int) -> np.ndarray:
        return self.flat

    def apply_step(self, flat_grad: np.ndarray) -> None:
        pass

    def end_update(self) -> Any:
        return None

    def model_parameters(self) -> np.ndarray:
        return self.flat

    set_model_parameters = apply_step


class Outcome:
    score = wma = actor_loss = critic_loss = entropy = approx_kl = clip_fraction = 0.0
    steps = 1
    completed = False


class WireLearner:
    """Plays nothing; every round updates (the worker drives a per-step scheme's exchanges)."""

    completed = False
    updates = True

    def __init__(self, agent: WireAgent) -> None:
        self.agent = agent

    def play_round(self) -> Outcome:
        return Outcome()

    def begin_round(self) -> WireLearner:
        return self

    def end_round(self, played: Any, stats: Any) -> Outcome:
        return Outcome()


def round_seconds(url: str, scheme: str, workers: int, rounds: int) -> tuple[float, int]:
    """Median wall seconds of one round (all its exchanges), measured on worker 0, and its exchanges."""
    agent0 = probe_agent("qube", get_preset("standard"))
    layout = agent0.step_layout(0) if scheme == "pergrad" else agent0.model_layout()
    steps = agent0.update_step_count() if scheme == "pergrad" else 1
    run_id = f"wire-{scheme}-{workers}"
    ids = [str(k) for k in range(workers)]
    plan = ChiefPlan(
        run_id=run_id, workers=ids, layout=layout, max_rounds=rounds, scheme=scheme, steps_per_round=steps
    )
    chief = Chief(plan)
    threading.Thread(target=run_chief, args=(chief, MqttTransport(url)), daemon=True).start()
    stamps: list[float] = []

    def worker(k: int) -> None:
        learner = WireLearner(WireAgent(layout, steps))
        on_record = (lambda record: stamps.append(time.perf_counter())) if k == 0 else None
        plan = WorkerPlan(
            run_id=run_id,
            worker_id=str(k),
            scheme=scheme,
            layout=layout,
            max_rounds=rounds,
            steps_per_round=steps,
        )
        FederatedWorker(learner, MqttTransport(url), plan, on_record=on_record).run()

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(workers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(600)
    return float(np.median(np.diff(stamps))), steps


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--workers", type=int, nargs="+", default=[3, 8])
    args = parser.parse_args()
    print(describe_host())
    size = sum(int(np.prod(s)) for _, s in probe_agent("qube", get_preset("standard")).model_layout())
    print(f"message: {size} float32 ({4 * size / 1024:.0f} KiB); mosquitto; {args.rounds} rounds per figure")
    print("scheme   workers  exchanges  round s   share of a 15 s episode   share of a 0.3 s episode")
    with EmbeddedBroker("mosquitto") as broker:
        for scheme in ("fedavg", "pergrad"):
            for n in args.workers:
                seconds, exchanges = round_seconds(broker.url, scheme, n, args.rounds)
                print(
                    f"{scheme:8} {n:7d}  {exchanges:9d}  {seconds:7.3f}"
                    f"   {100 * seconds / EPISODE_AT_CAP:22.2f} %   {100 * seconds / EARLY_EPISODE:21.1f} %"
                )


if __name__ == "__main__":
    main()
