"""The chief's work and bytes per exchange as its members grow: the real
:class:`~fleetrl.federation.chief.machine.Chief` of the default scheme (``pergrad``) fed the encoded step
gradients of N emulated members, no transport and no learner.

    python lab/benchmarks/chief_scale.py [--members 10 100 1000] [--env qube] [--exchanges 20]

Per N: the chief's CPU time (one thread) for one exchange, median over ``--exchanges``, and per member; the
bytes in (N payloads) and out (one answer, which the broker fans out N times).
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.messages import Message, encode
from fleetrl.portable import host_cpu
from fleetrl.runs.launch import chief_plan
from fleetrl.runs.settings import LearningSettings, RoundRules, fleet_shape, resolve_learning

RUN = "scale"
Layout = list[tuple[str, tuple[int, ...]]]


def layout_size(layout: Layout) -> int:
    return sum(int(np.prod(shape)) for _, shape in layout)


def exchange_payloads(layout: Layout, members: int, rnd: int, step: int) -> list[bytes]:
    """Each member's encoded step gradient for (rnd, step): small random values, one unit each."""
    rng = np.random.default_rng(rnd * 1000 + step)
    flat = (rng.standard_normal(layout_size(layout)) * 1e-3).astype(np.float32)
    return [
        encode(Message("step_gradient", RUN, str(m), rnd, flat=flat, step=step, samples=500), layout=layout)
        for m in range(members)
    ]


def learning_of(env: str) -> LearningSettings:
    return resolve_learning(LearningSettings(env=env, preset="standard", scheme="pergrad", max_rounds=1000))


def kept_model(learning: LearningSettings, run_id: str = RUN) -> Any:
    """The fleet's model the chief of ``learning`` (run ``run_id``) keeps."""
    return chief_plan(learning, RoundRules(quorum=1.0), run_id=run_id, workers=("0",))[1]["fleet_model"]


def plan(shape: Any, members: int, **more: Any) -> ChiefPlan:
    """The plan of a ``pergrad`` chief (or aggregator) of ``members`` members, quorum 1."""
    return ChiefPlan(
        run_id=RUN,
        workers=[str(m) for m in range(members)],
        layout=shape.layout,
        max_rounds=1000,
        scheme="pergrad",
        steps_per_round=shape.exchanges_per_round,
        quorum=1.0,
        **more,
    )


def chief_exchanges(
    chief: Chief, layout: Layout, exchanges: int, payloads_of: Callable[[int, int], list[bytes]]
) -> tuple[float, int, int]:
    """The chief's CPU seconds per exchange (median, after a warm-up) fed ``payloads_of(round, step)``, and
    the bytes in and out of one exchange."""
    times, bytes_in, bytes_out = [], 0, 0
    now = 0.0
    for _ in range(exchanges + 1):  # the first exchange is a warm-up
        payloads = payloads_of(chief.round, chief.state.step)
        start = time.process_time()
        out: list[Message] = []
        for m, payload in enumerate(payloads):
            now += 1e-4
            out += chief.receive_bytes(payload, topic_worker=str(m), now=now).outgoing
        (answer,) = [message for message in out if message.type == "average"]
        sent = encode(answer, layout=layout)
        times.append(time.process_time() - start)
        bytes_in, bytes_out = sum(len(p) for p in payloads), len(sent)
    return statistics.median(times[1:]), bytes_in, bytes_out


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--members", type=int, nargs="+", default=[10, 100, 1000])
    parser.add_argument("--env", default="qube", help="whose agent sets the message size (qube or cartpole)")
    parser.add_argument(
        "--exchanges", type=int, default=20, help="measured exchanges per N (after one warm-up)"
    )
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)  # the chief's process: one thread, as the roles run
    print(f"host: {host_cpu()}")
    print(f"load average at the start: {os.getloadavg()[0]:.1f}; env {args.env}, scheme pergrad (quorum 1)")
    print("| members | chief CPU per exchange | per member | bytes in | bytes out (once; fanned out N×) |")
    print("|---|---|---|---|---|")
    for members in args.members:
        learning = learning_of(args.env)
        shape = fleet_shape(learning)
        chief = Chief(plan(shape, members), fleet_model=kept_model(learning))
        payloads = functools.partial(exchange_payloads, shape.layout, members)
        seconds, bytes_in, bytes_out = chief_exchanges(chief, shape.layout, args.exchanges, payloads)
        print(
            f"| {members} | {seconds * 1e3:.1f} ms | {seconds / members * 1e6:.0f} µs "
            f"| {bytes_in / 1e6:.2f} MB | {bytes_out / 1e3:.0f} kB |",
            flush=True,
        )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
