"""What a run's parts cost in memory: a worker process, a unit in-process, a unit host; the figures behind
:mod:`fleetrl.runs.memory_fit` (Linux: it reads /proc).

    python lab/benchmarks/run_memory.py [--rounds 4] [--parts process,spawned,thread,host]

Each figure is the difference of the peak summed PSS of two ``fleetrl train`` process trees of different
sizes, divided by the difference in workers, units or hosts.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SAMPLE_EVERY = 0.2


def children(pid: int) -> list[int]:
    """``pid`` and every process under it (read from /proc/*/stat's parent ids)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    tree, frontier = [pid], [pid]
    while frontier:
        frontier = [p for p, parent in parents.items() if parent in frontier]
        tree += frontier
    return tree


def pss_bytes(pid: int) -> int:
    """The proportional set size of ``pid`` (0 once it has ended)."""
    try:
        for line in (Path("/proc") / str(pid) / "smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def peak_pss(command: subprocess.Popen, every: float) -> int:
    """The peak of the summed PSS of ``command``'s process tree, sampled every ``every`` s until it ends."""
    peak = 0
    while command.poll() is None:
        peak = max(peak, sum(pss_bytes(p) for p in children(command.pid)))
        time.sleep(every)
    return peak


def peak_tree_pss(argv: list[str], environment: dict[str, str]) -> float:
    """Run ``argv`` (with ``environment`` added) and return the peak of its process tree's summed PSS, in
    MB."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), **environment}
    with tempfile.TemporaryFile("w+") as errors:  # a file, not a pipe: a full pipe would stop the run
        command = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=errors, text=True, env=env)
        peak = peak_pss(command, SAMPLE_EVERY)
        if command.returncode != 0:
            errors.seek(0)
            raise SystemExit(f"{' '.join(argv)} exited {command.returncode}: {errors.read()[-2000:]}")
    return peak / 2**20


def train_peak(units: int, rounds: int, *extra: str, spawn: bool = False) -> float:
    """Peak PSS (MB) of one ``fleetrl train`` of ``units`` CartPole units (``spawn``: worker processes
    spawned, not forked)."""
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "fleetrl.cli.main", "train", "--env", "cartpole", "--mode", "federated",
                "--preset", "standard", "--scheme", "pergrad", "--max-rounds", str(rounds), "--no-live",
                "--units", str(units), "--out", str(Path(tmp) / "run"), *extra]  # fmt: skip
        peak = peak_tree_pss(argv, {"FLEETRL_WORKER_START": "spawn"} if spawn else {})
    shown = " ".join(extra) + (" (spawned)" if spawn else "")
    print(f"  N={units:3d} {shown:40s} peak tree PSS {peak:7.0f} MB  [load "
          f"{os.getloadavg()[0]:.1f}]", flush=True)  # fmt: skip
    return peak


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--parts", default="process,thread,host")
    args = parser.parse_args()
    parts = args.parts.split(",")
    print(f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    if "process" in parts:
        few, many = (train_peak(n, args.rounds, "--transport", "mqtt") for n in (2, 6))
        print(f"worker process (forked): {(many - few) / 4:.0f} MB each")
    if "spawned" in parts:
        few, many = (train_peak(n, args.rounds, "--transport", "mqtt", spawn=True) for n in (2, 6))
        print(f"worker process (spawned): {(many - few) / 4:.0f} MB each")
    if "thread" in parts:
        few, many = (train_peak(n, args.rounds, "--transport", "local") for n in (20, 60))
        unit = (many - few) / 40
        print(f"unit as a worker thread: {unit:.1f} MB each; the command itself: {few - 20 * unit:.0f} MB")
    if "host" in parts:
        two = train_peak(32, args.rounds, "--transport", "local", "--units-per-host", "16")
        four = train_peak(32, args.rounds, "--transport", "local", "--units-per-host", "8")
        more = train_peak(64, args.rounds, "--transport", "local", "--units-per-host", "16")
        print(f"unit host: {(four - two) / 2:.1f} MB each; hosted unit: {(more - four) / 32:.2f} MB each")


if __name__ == "__main__":
    main()
