"""A two-level federated CartPole fleet across Linux network namespaces, on two real mosquitto brokers.

Run as root: ``.venv/bin/python lab/benchmarks/netns_tree.py`` (``--workers 3 --rounds 10``;
``--centre-delay-ms 20 --site-delay-ms 2 …`` add netem; ``--uneven "--slow w1=4"`` gives every worker more
flags; ``--mutate skip`` breaks every catch-up, so the one-policy check must fail; ``--keep`` keeps the logs).
Topology ``chief ─ centre broker ─ aggregator ─ site broker ─ workers``, built with netns_fleet.py's helpers.
Prints the checks (exit 1 if any fails), the round overhead with its root and site shares, and the bytes per
exchange at the root; docs/benchmarks.md explains each.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import shlex
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from fault_soak import ONE_POLICY, holds_fleet_model
from netns_fleet import (
    FLEETRL,
    PORT,
    STAMP,
    Fleet,
    add_netem,
    check_machine,
    overheads,
    run_and_clean,
    run_args,
    sh,
    spread,
    start_broker,
    timestamp,
    wait_all,
    wait_for_broker,
)
from one_policy import MUTATIONS, compare, load

ROOT_RUN, SITE_RUN, SITE_ID = "tree", "tree-site", "0"
EDGE = r" INFO fleetrl\.federation\.edge\.runner: site \S+: round (\d+): "
FORWARDED = re.compile(STAMP + EDGE + r".* to the root \(step (\d+), (\d+) units")
ANSWERED = re.compile(STAMP + EDGE + r".*\(the root's answer\)")


@dataclass(frozen=True)
class Tree:
    """Where each role finds its broker(s), and the aggregator's end of its uplink."""

    centre_for_chief: str
    centre_for_aggregator: str
    site_for_aggregator: str
    site_for_worker: dict[str, str]
    uplink: str


def build(fleet: Fleet, args: argparse.Namespace) -> tuple[Tree, list[str]]:
    """The namespaces and veths, netem where asked; returns the addresses and what netem did."""
    centre, site = fleet.namespace("centre"), fleet.namespace("site")
    workers = [f"w{k}" for k in range(args.workers)]
    _, chief_ip, _, _ = fleet.link(0, centre, fleet.namespace("chief"))
    near, centre_ip, uplink, _ = fleet.link(1, centre, fleet.namespace("agg"))
    _, site_ip, _, _ = fleet.link(2, site, fleet.namespace("agg"))
    notes = [impair(((centre, near), (fleet.namespace("agg"), uplink)), "centre", args)]
    site_ips, worker_ends = {}, []
    for k, node in enumerate(workers):
        near_k, site_ips[node], far_k, _ = fleet.link(3 + k, site, fleet.namespace(node))
        worker_ends += [(site, near_k), (fleet.namespace(node), far_k)]
    notes.append(impair(worker_ends, "site", args))
    return Tree(chief_ip, centre_ip, site_ip, site_ips, uplink), notes


def impair(ends: Iterable[tuple[str, str]], where: str, args: argparse.Namespace) -> str:
    """netem with the ``--{where}-*`` flags on every (namespace, ifname) of ``ends``; what was done."""
    delay, jitter, loss = (getattr(args, f"{where}_{name}") for name in ("delay_ms", "jitter_ms", "loss"))
    if not (delay or jitter or loss):
        return f"{where} links: no netem"
    if why := add_netem(ends, delay, jitter, loss):
        return f"{where} links: netem not available in this kernel ({why}); running without it"
    return f"{where} links: delay {delay} ms ± {jitter} ms, loss {loss} % on both ends"


def start_roles(
    fleet: Fleet, tree: Tree, args: argparse.Namespace, work: Path
) -> dict[str, subprocess.Popen[bytes]]:
    """The chief, the aggregator and the workers, each in its namespace; role → process."""
    rounds, timeout = args.rounds, str(args.timeout)
    roles = {
        "chief": fleet.start(
            fleet.namespace("chief"),
            [*FLEETRL, "chief", "--broker", f"mqtt://{tree.centre_for_chief}:{PORT}",
             *run_args(ROOT_RUN, rounds), "--workers", "1", "--out", str(work / "chief"),
             "--idle-timeout", timeout],
            work / "chief.log",
        ),
        "agg": fleet.start(
            fleet.namespace("agg"),
            [*FLEETRL, "aggregator", "--broker", f"mqtt://{tree.centre_for_aggregator}:{PORT}",
             *run_args(ROOT_RUN, rounds), "--site-id", SITE_ID, "--site-run", SITE_RUN,
             "--members", str(args.workers), "--site-broker", f"mqtt://{tree.site_for_aggregator}:{PORT}",
             "--resend-interval", "2", "--idle-timeout", timeout],
            work / "agg.log",
        ),
    }  # fmt: skip
    mutate = ["--mutate", args.mutate] if args.mutate else []
    options = FLEETRL[FLEETRL.index("fleetrl.cli.main") + 1 :]  # fleetrl's own (-v), before the command
    for node, host in tree.site_for_worker.items():
        digests = str(work / f"{node}.digests.jsonl")
        recorded = [sys.executable, str(ONE_POLICY), "--digests", digests, *mutate, "--", *options]
        roles[node] = fleet.start(
            fleet.namespace(node),
            [*recorded, "worker", "--broker", f"mqtt://{host}:{PORT}",
             *run_args(SITE_RUN, rounds), "--worker-id", node[1:], "--out", str(work / node),
             "--resend-interval", "2", "--reply-timeout", timeout, *shlex.split(args.uneven)],
            work / f"{node}.log",
        )  # fmt: skip
    return roles


def root_times(agg_log: Path) -> tuple[dict[tuple[int, int], float], Counter[int]]:
    """(round, step) → ms from the aggregator's sum sent up to the root's answer in; and how many of its
    sums carried how many units (fewer than N: a straggler left out by the quorum rule)."""
    times: dict[tuple[int, int], float] = {}
    units: Counter[int] = Counter()
    sent: tuple[int, int, float] | None = None
    for line in agg_log.read_text(errors="replace").splitlines():
        if m := FORWARDED.match(line):
            sent = (int(m.group(2)), int(m.group(3)), timestamp(m.group(1)))
            units[int(m.group(4))] += 1
        elif (m := ANSWERED.match(line)) and sent is not None and sent[0] == int(m.group(2)):
            times[sent[:2]] = 1000.0 * (timestamp(m.group(1)) - sent[2])
            sent = None
    return times, units


def uplink_bytes(fleet: Fleet, ifname: str) -> tuple[int, int]:
    """(tx, rx) bytes of the aggregator's end of its uplink."""
    stats = json.loads(
        sh("ip", "-n", fleet.namespace("agg"), "-j", "-s", "link", "show", "dev", ifname).stdout
    )
    return stats[0]["stats64"]["tx"]["bytes"], stats[0]["stats64"]["rx"]["bytes"]


def checks(work: Path, args: argparse.Namespace, codes: dict[str, int | None]) -> dict[str, bool]:
    """Each check's name → whether it held."""
    from fleetrl.runs.checkpoints import ChiefCheckpoint, chief_checkpoint_dir

    workers = {node[1:]: work / node for node in codes if node.startswith("w")}
    result = {"every role exited 0": all(code == 0 for code in codes.values())}
    chief_json = work / "chief" / "chief.json"
    n = json.loads(chief_json.read_text())["rounds"] if chief_json.exists() else 0
    result[f"the chief ran {n} of {args.rounds} rounds"] = n >= 1
    if args.uneven:  # a straggler plays fewer rounds than the fleet
        result[f"every worker's metrics.csv: rounds of 1 … {n} once each, in order"] = n >= 1 and all(
            len(rs) > 0 and rs == sorted(set(rs)) and rs[-1] <= n
            for rs in (metrics_rounds(out / "metrics.csv") for out in workers.values())
        )
    else:
        result[f"every worker's metrics.csv: rounds 1 … {n} once each"] = n >= 1 and all(
            metrics_rounds(out / "metrics.csv") == list(range(1, n + 1)) for out in workers.values()
        )
    checkpoint = ChiefCheckpoint(chief_checkpoint_dir(work / "chief"))
    if checkpoint.exists():
        fields, _ = checkpoint.store.load()
        answer = next((m for m in fields["last_answer"] if m["type"] == "average"), {})
        result["every worker's final model is the chief's, bit for bit"] = holds_fleet_model(
            work / "chief", workers
        )
        held = compare(load(work / f"w{w}.digests.jsonl" for w in workers))
        label = f"every worker held one policy at every exchange ({held.summary()})"
        result[label] = not held.mismatches and (held.after_catch_up > 0 or not (args.uneven or args.mutate))
        units = f"1 … {args.workers}" if args.uneven else str(args.workers)  # a straggler may be left out
        result[f"the chief's one member is the site, its answer for {units} units"] = (
            fields["members"] == [SITE_ID]
            and answer.get("contributors") == [SITE_ID]
            and (
                1 <= answer.get("units", 0) <= args.workers
                if args.uneven
                else answer.get("units") == args.workers
            )
        )
    else:
        result["the chief's checkpoint exists"] = False
    summaries = [line for line in (work / "agg.log").read_text().splitlines() if line.startswith("{")]
    ended = json.loads(summaries[-1]).get("end_reason") if summaries else None
    result["the aggregator ended with the root's run"] = ended == "the root ended the run"
    return result


def metrics_rounds(path: Path) -> list[int]:
    """The rounds of a worker's metrics.csv, in file order ([] if there is none)."""
    if not path.exists():
        return []
    with path.open() as rows:
        return [int(row["round"]) for row in csv.DictReader(rows)]


def measure(fleet: Fleet, tree: Tree, work: Path, workers: int) -> None:
    """Print the round overhead and its root and site shares, and the bytes per exchange at the root."""
    units_view = overheads([work / f"w{k}.log" for k in range(workers)])
    root, units = root_times(work / "agg.log")
    print(f"the site's sums sent up, units carried → how many: {dict(sorted(units.items()))}")
    last_step = max((step for _, step in root), default=0)
    rounds = [r for r in sorted(units_view) if r > 1 and (r, last_step) in root]
    if rounds:
        root_share = [root[(r, last_step)] for r in rounds]
        print(f"round overhead, rounds {rounds[0]}-{rounds[-1]} (last send → last record, at the units): "
              f"{spread([units_view[r] for r in rounds])}")  # fmt: skip
        print(f"  its root share (the site's sum up → the root's answer in): {spread(root_share)}")
        print(
            f"  its site share (the rest): {spread([units_view[r] - root[(r, last_step)] for r in rounds])}"
        )
    later = [ms for (r, _), ms in root.items() if r > 1]
    if later:
        print(f"root time per exchange, {len(later)} exchanges of rounds 2+: {spread(later)}")
    if root:
        tx, rx = uplink_bytes(fleet, tree.uplink)
        print(
            f"bytes per exchange at the root ({len(root)} exchanges, framing and the join/welcome included): "
            f"up {tx / len(root) / 1000:.1f} kB, down {rx / len(root) / 1000:.1f} kB"
        )


def run(args: argparse.Namespace, fleet: Fleet, work: Path) -> int:
    """Build the tree, run the fleet, check and measure; returns the exit code."""
    deadline = time.monotonic() + args.timeout
    tree, notes = build(fleet, args)
    print("netem: " + "; ".join(notes))
    start_broker(fleet, fleet.namespace("centre"), work, "centre-broker")
    start_broker(fleet, fleet.namespace("site"), work, "site-broker")
    wait_for_broker(fleet, fleet.namespace("chief"), tree.centre_for_chief, deadline)
    wait_for_broker(fleet, fleet.namespace("w0"), tree.site_for_worker["w0"], deadline)
    started = time.monotonic()
    codes = wait_all(start_roles(fleet, tree, args, work), deadline)
    print(f"roles' exit codes: {codes}; wall time {time.monotonic() - started:.1f} s (start-up included)")
    measure(fleet, tree, work, args.workers)
    fleet.stop()  # roles the timeout cut short must not compete with the checks for the CPU
    result = checks(work, args, codes)
    for name, held in result.items():
        print(f"{'ok ' if held else 'FAILED'} {name}")
    passed = all(result.values())
    print(f"passed: {'yes' if passed else 'NO'} ({args.workers} workers behind one aggregator, "
          f"{args.rounds} rounds)")  # fmt: skip
    if not passed or args.keep:
        print(f"logs and run directories kept in {work}")
    return 0 if passed else 1


def main() -> int:
    """Parse the options, check the machine, run, and always clean up."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=3, help="the site's workers, N")
    parser.add_argument("--rounds", type=int, default=10, help="M")
    for where in ("centre", "site"):
        parser.add_argument(f"--{where}-delay-ms", type=float, default=0.0, help="netem delay per qdisc (ms)")
        parser.add_argument(f"--{where}-jitter-ms", type=float, default=0.0, help="netem jitter (ms)")
        parser.add_argument(f"--{where}-loss", type=float, default=0.0, help="netem loss per qdisc (%%)")
    parser.add_argument("--timeout", type=float, default=240.0, help="bound on the fleet's run (s)")
    parser.add_argument("--uneven", default="", help="more flags for every worker, quoted")
    parser.add_argument(
        "--mutate", choices=MUTATIONS, default=None, help="break every worker's catch-up: the check must fail"
    )
    parser.add_argument("--keep", action="store_true", help="keep the run directories and logs")
    args = parser.parse_args()
    check_machine(parser)
    if not 1 <= args.workers <= 60:
        parser.error("--workers must be 1 … 60 (one /30 of 10.77.0.0/24 each, after the three of the tree)")
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    return run_and_clean(args, "ft", run)


if __name__ == "__main__":
    sys.exit(main())
