"""The chief's work and bytes per exchange as its members grow (issue 24, "the path to 100k"): the real
:class:`~fleetrl.federation.chief.machine.Chief` state machine of the default scheme (``pergrad``) fed the
encoded step gradients of N emulated members, no transport and no learner.

    python lab/benchmarks/chief_scale.py [--members 10 100 1000] [--env qube] [--exchanges 20]

Per N: the chief's CPU time for one exchange — N payloads decoded and validated (envelope, layout, finite
values), admitted, the weighted mean taken, the fleet model stepped (the chief keeps it: Adam on the
actor-critic), the answer built and encoded once — as a median over ``--exchanges`` exchanges, and per
member; the bytes in (N payloads) and out (one answer; a broker delivers it to each of the N members, so its
fan-out is N × that, carried by the broker, not the chief's process). A member may be one unit, a unit host or
an edge aggregator carrying thousands: the chief's cost depends on N, not on the units behind them (each
message says how many units it carries and the mean weighs by it).

CPU time of this process (``time.process_time``), one thread: the machine's other jobs show less in it than in
wall time, but cache and frequency effects of a busy machine still do; say how loaded it was (printed).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

import numpy as np

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.wire.messages import Message, encode
from fleetrl.portable import host_cpu
from fleetrl.runs.launch import chief_plan
from fleetrl.runs.settings import LearningSettings, RoundRules, fleet_shape, resolve_learning

RUN = "scale"


def exchange_payloads(
    layout: list[tuple[str, tuple[int, ...]]], members: int, rnd: int, step: int
) -> list[bytes]:
    """Each member's encoded step gradient for (rnd, step): small random values, one unit each."""
    size = sum(int(np.prod(shape)) for _, shape in layout)
    rng = np.random.default_rng(rnd * 1000 + step)
    flat = (rng.standard_normal(size) * 1e-3).astype(np.float32)
    return [
        encode(Message("step_gradient", RUN, str(m), rnd, flat=flat, step=step, samples=500), layout=layout)
        for m in range(members)
    ]


def kept_model(learning: LearningSettings, run_id: str = RUN) -> Any:
    """The fleet's model the chief of ``learning`` (run ``run_id``) keeps."""
    return chief_plan(learning, RoundRules(quorum=1.0), run_id=run_id, workers=("0",))[1]["fleet_model"]


def measure(env: str, members: int, exchanges: int) -> dict[str, float]:
    """The chief's CPU seconds per exchange (median) and the bytes in and out of one exchange."""
    learning = resolve_learning(
        LearningSettings(env=env, preset="standard", scheme="pergrad", max_rounds=1000)
    )
    shape = fleet_shape(learning)
    chief = Chief(
        ChiefPlan(
            run_id=RUN,
            workers=[str(m) for m in range(members)],
            layout=shape.layout,
            max_rounds=1000,
            scheme="pergrad",
            steps_per_round=shape.exchanges_per_round,
            quorum=1.0,
        ),
        fleet_model=kept_model(learning),
    )
    times, bytes_in, bytes_out = [], 0, 0
    now = 0.0
    for _ in range(exchanges + 1):  # the first exchange is a warm-up
        rnd, step = chief.round, chief.state.step
        payloads = exchange_payloads(shape.layout, members, rnd, step)
        start = time.process_time()
        out: list[Message] = []
        for m, payload in enumerate(payloads):
            now += 1e-4
            out += chief.receive_bytes(payload, topic_worker=str(m), now=now).outgoing
        (answer,) = [message for message in out if message.type == "average"]
        sent = encode(answer, layout=shape.layout)
        times.append(time.process_time() - start)
        bytes_in, bytes_out = sum(len(p) for p in payloads), len(sent)
    per_exchange = statistics.median(times[1:])
    return {
        "members": members,
        "ms_per_exchange": per_exchange * 1e3,
        "us_per_member": per_exchange / members * 1e6,
        "bytes_in": bytes_in,
        "bytes_out": bytes_out,
    }


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
        row = measure(args.env, members, args.exchanges)
        print(
            f"| {members} | {row['ms_per_exchange']:.1f} ms | {row['us_per_member']:.0f} µs "
            f"| {row['bytes_in'] / 1e6:.2f} MB | {row['bytes_out'] / 1e3:.0f} kB |",
            flush=True,
        )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
