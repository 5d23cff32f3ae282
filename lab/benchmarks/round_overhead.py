"""Federation round overhead: from the last gradient of a round published to the average received by every
worker, for N workers with the QUBE agent's real actor size, over mosquitto, amqtt and the in-process bus.

    python lab/benchmarks/round_overhead.py [--quick] [--workers 3,8,64] [--rounds N] [--transports ...]

The chief, workers, encoding and transports are real; each worker's round returns at once with a fixed
gradient, so a round is all communication. Modes: ``all at once`` (every worker publishes together) and
``last alone`` (the chief accepted the other N−1 before the last one publishes).
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import re
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib.metadata import version

import numpy as np

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent
from fleetrl.federation.chief.machine import Chief, ChiefEvent
from fleetrl.federation.plan import ChiefPlan, WorkerPlan
from fleetrl.federation.runner import run_chief
from fleetrl.federation.wire.messages import Layout, layout_size
from fleetrl.federation.wire.topics import worker_of_topic
from fleetrl.federation.worker.runner import FederatedWorker
from fleetrl.transport.base import Transport
from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

MODES = ("all at once", "last alone")
WARMUP = 3  # rounds played before the measured ones
TIMEOUT = 120.0  # seconds a configuration may take before it is reported as failed


@dataclass
class RoundClock:
    """Publish and receive times of every round, shared by all workers of one configuration."""

    sent: dict[int, list[float]] = field(default_factory=dict)
    got: dict[int, list[float]] = field(default_factory=dict)
    closed: dict[int, list[float]] = field(default_factory=dict)  # run_chief's ``averaged`` events
    lock: threading.Lock = field(default_factory=threading.Lock)

    def mark(self, table: dict[int, list[float]], rnd: int) -> None:
        now = time.perf_counter()
        with self.lock:
            table.setdefault(rnd, []).append(now)

    def overheads_ms(self, n_workers: int, first: int) -> tuple[list[float], list[float]]:
        """Per complete round from ``first`` on (ms): the overhead, and its part until the average went."""
        total, chief = [], []
        for rnd in sorted(self.sent):
            if rnd >= first and len(self.sent[rnd]) == n_workers and len(self.got.get(rnd, [])) == n_workers:
                last_sent = max(self.sent[rnd])
                total.append(1e3 * (max(self.got[rnd]) - last_sent))
                chief.append(1e3 * (self.closed[rnd][0] - last_sent))
        return total, chief


class _Result:
    """The few fields FederatedWorker reads from a round (a learner's RoundResult)."""

    score = wma = actor_loss = critic_loss = entropy = 0.0
    steps = 0
    completed = False


class StaticAgent:
    """An actor that always sends the same gradient and timestamps every average it is given."""

    def __init__(self, layout: Layout, seed: int, clock: RoundClock) -> None:
        self.layout = list(layout)
        gradient = np.random.default_rng(seed).normal(0.0, 1e-3, layout_size(layout))
        self.gradient: np.ndarray = gradient.astype(np.float32)
        self.clock = clock
        self.round = 0

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return list(self.layout)

    def actor_gradient(self) -> np.ndarray:
        return self.gradient

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        self.clock.mark(self.clock.got, self.round)

    def actor_parameters(self) -> np.ndarray:
        return self.gradient

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        raise AssertionError("no transfers in this benchmark")


class InstantLearner:
    """A round with no episode: all workers leave ``barrier`` together; ``hold`` (the last worker in ``last
    alone`` mode) waits until the chief accepted the others."""

    def __init__(
        self, agent: StaticAgent, barrier: threading.Barrier, hold: Callable[[int], None] | None
    ) -> None:
        self.agent = agent
        self.barrier = barrier
        self.hold = hold

    def play_round(self) -> _Result:
        self.barrier.wait()
        self.agent.round += 1
        if self.hold is not None:
            self.hold(self.agent.round)
        return _Result()


class TimedTransport:
    """A Transport that timestamps, just before sending, every message published on a worker topic."""

    def __init__(self, inner: Transport, run_id: str, agent: StaticAgent, clock: RoundClock) -> None:
        self.inner = inner
        self.run_id = run_id
        self.agent = agent
        self.clock = clock

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        if worker_of_topic(self.run_id, topic) is not None:
            self.clock.mark(self.clock.sent, self.agent.round)
        self.inner.publish(topic, payload, qos=qos, retain=retain)


class AcceptedCounter:
    """Counts the chief's ``accepted`` events per round and timestamps its ``averaged`` events."""

    def __init__(self, needed: int, clock: RoundClock) -> None:
        self.needed = needed
        self.clock = clock
        self.counts: dict[int, int] = {}
        self.cond = threading.Condition()

    def on_event(self, event: ChiefEvent) -> None:
        if event.kind == "averaged":  # run_chief reports events after publishing the step's messages
            self.clock.mark(self.clock.closed, event.round)
        elif event.kind == "accepted":
            with self.cond:
                self.counts[event.round] = self.counts.get(event.round, 0) + 1
                self.cond.notify_all()

    def wait(self, rnd: int) -> None:
        with self.cond:
            if not self.cond.wait_for(lambda: self.counts.get(rnd, 0) >= self.needed, TIMEOUT):
                raise TimeoutError(
                    f"the chief accepted only {self.counts.get(rnd, 0)} gradients of round {rnd}"
                )


def run_configuration(
    make_transport: Callable[[], Transport], layout: Layout, n_workers: int, rounds: int, mode: str, tag: str
) -> tuple[list[float], list[float]]:
    """One federated run of ``WARMUP + rounds`` rounds; see :meth:`RoundClock.overheads_ms`."""
    run_id = f"bench-{tag}-{n_workers}-{mode.replace(' ', '-')}"
    total = WARMUP + rounds
    clock = RoundClock()
    counter = AcceptedCounter(n_workers - 1, clock)
    workers = [str(i) for i in range(1, n_workers + 1)]
    chief = Chief(ChiefPlan(run_id=run_id, workers=workers, layout=layout, max_rounds=total, scheme="paper"))
    barrier = threading.Barrier(n_workers, timeout=TIMEOUT)
    errors: list[BaseException] = []

    def guarded(fn: Callable[[], object]) -> Callable[[], None]:
        def body() -> None:
            try:
                fn()
            except BaseException as exc:
                errors.append(exc)
                barrier.abort()

        return body

    threads = [
        threading.Thread(
            target=guarded(lambda: run_chief(chief, make_transport(), on_event=counter.on_event,
                                             idle_timeout=TIMEOUT)),
            name="chief", daemon=True,
        )
    ]  # fmt: skip
    for i in range(1, n_workers + 1):
        agent = StaticAgent(layout, seed=i, clock=clock)
        last = mode == "last alone" and i == n_workers and n_workers > 1
        learner = InstantLearner(agent, barrier, counter.wait if last else None)
        plan = WorkerPlan(
            run_id=run_id,
            worker_id=str(i),
            scheme="paper",
            layout=layout,
            max_rounds=total,
            reply_timeout=TIMEOUT,
        )
        worker = FederatedWorker(learner, TimedTransport(make_transport(), run_id, agent, clock), plan)
        threads.append(threading.Thread(target=guarded(worker.run), name=f"worker-{i}", daemon=True))
    deadline = time.monotonic() + TIMEOUT
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(max(0.0, deadline - time.monotonic()))
    if errors:
        first = next((e for e in errors if not isinstance(e, threading.BrokenBarrierError)), errors[0])
        raise RuntimeError(f"{type(first).__name__}: {first}")
    if any(t.is_alive() for t in threads):
        raise RuntimeError(f"not finished within {TIMEOUT:g} s")
    return clock.overheads_ms(n_workers, WARMUP + 1)


@contextmanager
def transport_factory(kind: str) -> Iterator[Callable[[], Transport]]:
    """Fresh unconnected transports of ``kind`` (``local``, ``mosquitto`` or ``amqtt``) for one benchmark."""
    if kind == "local":
        bus = LocalBus()
        yield bus.client
        return
    with EmbeddedBroker(prefer="mosquitto" if kind == "mosquitto" else "amqtt") as broker:
        yield lambda: MqttTransport(broker.url)


class LogTally(logging.Handler):
    """Counts the warnings and errors logged during a configuration (amqtt's, asyncio's, the transport's)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.counts: dict[str, int] = {}

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage().splitlines()[0][:60]
        if record.exc_info and record.exc_info[1] is not None:
            text = f"{text} ({type(record.exc_info[1]).__name__}: {record.exc_info[1]})"
        key = f"{record.name} {record.levelname}: {re.sub(r'fd=[0-9]+|[0-9]+', 'N', text)}"
        self.counts[key] = self.counts.get(key, 0) + 1

    def take(self) -> dict[str, int]:
        counts, self.counts = self.counts, {}
        return counts


def ms(value: float) -> str:
    return f"{value:.{2 if value < 10 else 1 if value < 100 else 0}f}"


def cells(total: list[float], chief: list[float]) -> list[str]:
    """``p50 / p99`` of the overhead, and the p50 of its part until the chief published the average."""
    if not total:
        return ["–", "–"]
    p50, p99 = np.percentile(total, [50, 99])
    return [f"{ms(p50)} / {ms(p99)}", ms(float(np.percentile(chief, 50)))]


def environment_line() -> str:
    mosquitto = "not installed"
    binary = find_mosquitto()
    if binary:
        probe = subprocess.run([binary, "-h"], capture_output=True, text=True, check=False)
        mosquitto = (probe.stdout.splitlines() or ["?"])[0].removeprefix("mosquitto version ")
    return (
        f"Python {platform.python_version()}, paho-mqtt {version('paho-mqtt')}, amqtt {version('amqtt')}, "
        f"mosquitto {mosquitto}, {os.cpu_count()} CPUs"
    )


def load_line() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    """Measure every (transport, workers) configuration in both modes and print a markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 and 8 workers, 5 rounds: a smoke run")
    parser.add_argument("--workers", default=None, help="comma-separated worker counts (default 3,8,64)")
    parser.add_argument("--rounds", type=int, default=None, help="measured rounds per configuration (100)")
    kinds_help = "which of local,mosquitto,amqtt"
    parser.add_argument("--transports", default="local,mosquitto,amqtt", help=kinds_help)
    args = parser.parse_args()
    workers = [int(w) for w in (args.workers or ("3,8" if args.quick else "3,8,64")).split(",")]
    rounds = args.rounds or (5 if args.quick else 100)
    kinds = [k.strip() for k in args.transports.split(",")]
    unknown = set(kinds) - {"local", "mosquitto", "amqtt"}
    if unknown or min(workers) < 1 or rounds < 1:
        parser.error(f"bad --transports {sorted(unknown)} / --workers / --rounds")
    tally = LogTally()
    logging.basicConfig(level=logging.WARNING, handlers=[tally])

    layout = PPOAgent(4, 3, get_preset("paper"), seed=0).actor_layout()  # the QUBE agent's actor
    size = layout_size(layout)
    print(f"actor of the QUBE agent (paper preset): {size} float32 = {4 * size / 1024:.0f} KiB per message")
    print(environment_line())
    print(f"load average (1/5/15 min) at start: {load_line()}")
    rows = []
    started = time.monotonic()
    for kind in kinds:
        with transport_factory(kind) as make_transport:
            for n in workers:
                row: list[str] = []
                for mode in MODES:
                    t0 = time.monotonic()
                    try:
                        row += cells(*run_configuration(make_transport, layout, n, rounds, mode, kind))
                    except RuntimeError as exc:
                        row += [f"failed: {exc}", "–"]
                    print(f"  {kind} {n} workers, {mode}: {row[-2]} ms, chief sent at {row[-1]} ms "
                          f"({time.monotonic() - t0:.1f} s)", flush=True)  # fmt: skip
                    for what, count in sorted(tally.take().items()):
                        print(f"    logged {count}x {what}")
                mb = 2 * n * 4 * size / 1e6
                rows.append(f"| {kind} | {n} | {rounds} | {mb:.1f} | {' | '.join(row)} |")
    print(f"load average (1/5/15 min) at end: {load_line()}; total {time.monotonic() - started:.0f} s")
    print()
    print("| transport | workers | rounds | MB via broker per round | all at once: p50 / p99 (ms) | "
          "chief sent (p50) | last alone: p50 / p99 (ms) | chief sent (p50) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
