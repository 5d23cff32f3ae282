"""What a fleet of each size cost this machine, from its records: wall seconds per round and unit-steps per
wall second, whole runs averaged."""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from fleetrl_lab.records import RunRecord


@dataclass(frozen=True)
class RunThroughput:
    """One run's rounds, wall seconds per round and unit-steps per wall second."""

    units: int
    rounds: int
    seconds_per_round: float
    unit_steps_per_second: float


def run_throughput(record: RunRecord) -> RunThroughput | None:
    """One run's figures (None for a run without rounds, wall time or the steps it played)."""
    workers = record.data["workers"].values()
    rounds = max((len(w["score"]) for w in workers), default=0)
    wall = record.wall_seconds
    if rounds == 0 or wall <= 0 or any("steps" not in w for w in workers):
        return None
    steps = sum(sum(w["steps"]) for w in workers)
    return RunThroughput(len(record.data["workers"]), rounds, wall / rounds, steps / wall)


def throughput_lines(arms: Sequence[tuple[str, Sequence[RunRecord]]]) -> list[str]:
    """The report's table of each arm's cost on the machine (medians over its runs), with a note; none if no
    arm has a run."""
    rows = []
    for label, records in arms:
        runs = [t for t in map(run_throughput, records) if t is not None]
        if not runs:
            continue
        hosts = sorted({r.host.split(",")[0] for r in records})
        rows.append(
            f"| {label} | {runs[0].units} | {statistics.median(t.rounds for t in runs):g} | "
            f"{statistics.median(t.seconds_per_round for t in runs):.2f} | "
            f"{statistics.median(t.unit_steps_per_second for t in runs):,.0f} | {len(runs)} | "
            f"{'; '.join(hosts)} |"
        )
    if not rows:
        return []
    header = (
        "| arm | units | rounds played (median) | wall s per round (median) | unit-steps per wall s (median) "
        "| runs | CPU |\n|---|---|---|---|---|---|---|"
    )
    note = (
        "What each fleet cost this machine (2 cores), from the records: the run's wall time over its rounds, "
        "and the steps its units played over its wall time — whole runs, start-up and short early episodes "
        "included (`fleetrl_lab.throughput`). A round of 1,000 full-length episodes, and peak "
        'memory: docs/benchmarks.md, "Unit hosts".'
    )
    return ["", note, "", header, *rows]
