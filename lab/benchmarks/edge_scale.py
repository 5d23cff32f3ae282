"""An edge aggregator's work and bytes per exchange as its members grow, and the root chief's with M
aggregators: the real state machines of the default scheme (``pergrad``) fed encoded messages of emulated
members, no transport and no learner (as lab/benchmarks/chief_scale.py does for a flat chief).

    python lab/benchmarks/edge_scale.py [--members 10 100 1000] [--sites 10 100] [--units 1000] [--env qube]

CPU time of this process for one exchange (one thread) and the bytes in, up, from the root and down; the
root's rows at 10 and ``--units`` units behind each aggregator. The load average is printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from chief_scale import chief_exchanges, exchange_payloads, kept_model, layout_size, learning_of, plan

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.edge.aggregator import EdgeAggregator
from fleetrl.federation.wire.messages import Message, encode
from fleetrl.portable import host_cpu
from fleetrl.runs.settings import fleet_shape

RUN, ROOT = "scale", "root"


def aggregator_exchange(env: str, members: int, exchanges: int) -> dict[str, float]:
    """The aggregator's CPU seconds per exchange (median) and its bytes in and out of one exchange."""
    learning = learning_of(env)
    shape, model = fleet_shape(learning), kept_model(learning, ROOT)
    assert model is not None
    edge = EdgeAggregator(
        plan(shape, members, welcome_layout=model.layout), site_id="0", root_run=ROOT, fleet_model=model
    )
    edge.start(now=0.0)
    edge.from_root(Message("welcome", ROOT, "chief", 1, flat=model.snapshot(), origin="chief"), now=0.0)
    times, now = [], 0.0
    sizes = {}
    for _ in range(exchanges + 1):  # the first exchange is a warm-up
        rnd, step = edge.site.round, edge.site.state.step
        payloads = exchange_payloads(shape.layout, members, rnd, step)
        flat = np.zeros(layout_size(shape.layout), np.float32)
        from_root = encode(Message("average", ROOT, "chief", rnd, step=step, flat=flat), layout=shape.layout)
        start = time.process_time()
        up: list[Message] = []
        for m, payload in enumerate(payloads):
            now += 1e-4
            up += edge.receive_bytes(payload, topic_worker=str(m), now=now).up
        (sum_message,) = up
        to_root = encode(sum_message, layout=shape.layout)
        (down,) = edge.root_bytes(from_root, now=now).down
        to_members = encode(down, layout=shape.layout)
        times.append(time.process_time() - start)
        sizes = {"in": sum(map(len, payloads)), "up": len(to_root), "root": len(from_root)}
        sizes["down"] = len(to_members)
    return {"members": members, "ms": statistics.median(times[1:]) * 1e3, **sizes}


def root_exchange(env: str, sites: int, units: int, exchanges: int) -> tuple[float, int, int]:
    """The root's CPU seconds per exchange (median) with ``sites`` aggregators of ``units`` units each, and
    its bytes in and out of one exchange."""
    learning = learning_of(env)
    shape = fleet_shape(learning)
    root = Chief(plan(shape, sites), fleet_model=kept_model(learning, ROOT))
    rng = np.random.default_rng(0)

    def payloads(rnd: int, step: int) -> list[bytes]:
        total = rng.standard_normal(layout_size(shape.layout)) * 1e-3 * units  # a site's Σ of its units'
        return [
            encode(
                Message("step_gradient", RUN, str(m), rnd, flat=total, step=step, units=units, summed=True),
                layout=shape.layout,
            )
            for m in range(sites)
        ]

    return chief_exchanges(root, shape.layout, exchanges, payloads)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--members", type=int, nargs="+", default=[10, 100, 1000])
    parser.add_argument("--sites", type=int, nargs="+", default=[10, 100])
    parser.add_argument("--units", type=int, default=1000, help="units behind each site at the root (and 10)")
    parser.add_argument("--env", default="qube", help="whose agent sets the message size (qube or cartpole)")
    parser.add_argument(
        "--exchanges", type=int, default=10, help="measured exchanges per row (after a warm-up)"
    )
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)
    print(f"host: {host_cpu()}")
    print(f"load average at the start: {os.getloadavg()[0]:.1f}; env {args.env}, scheme pergrad (quorum 1)")
    print("\nAn edge aggregator, per exchange:\n")
    print("| members | CPU | per member | bytes in | up (float64 sum) | root's answer | down (once) |")
    print("|---|---|---|---|---|---|---|")
    for members in args.members:
        row = aggregator_exchange(args.env, members, args.exchanges)
        print(
            f"| {members} | {row['ms']:.1f} ms | {row['ms'] / members * 1e3:.0f} µs "
            f"| {row['in'] / 1e6:.2f} MB | {row['up'] / 1e3:.0f} kB | {row['root'] / 1e3:.0f} kB "
            f"| {row['down'] / 1e3:.0f} kB |",
            flush=True,
        )
    print("\nThe root chief with M aggregators, per exchange:\n")
    print("| aggregators | units behind each | CPU | per aggregator | bytes in | bytes out (once) |")
    print("|---|---|---|---|---|---|")
    for sites in args.sites:
        for units in (10, args.units):
            seconds, bytes_in, bytes_out = root_exchange(args.env, sites, units, args.exchanges)
            ms = seconds * 1e3
            print(
                f"| {sites} | {units} | {ms:.1f} ms | {ms / sites * 1e3:.0f} µs "
                f"| {bytes_in / 1e6:.2f} MB | {bytes_out / 1e3:.0f} kB |",
                flush=True,
            )
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
