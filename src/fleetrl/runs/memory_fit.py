"""Whether a run fits this machine's memory: measured costs per process, worker, unit host and unit
(``lab/benchmarks/run_memory.py``) against ``MemAvailable``, keeping :data:`HEADROOM` free."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

from fleetrl.runs.host_settings import units_per_core, usable_cores
from fleetrl.runs.processes import fork_available

MB = 2**20

COMMAND_MB = 320.0
"""the ``fleetrl train`` process itself: torch and fleetrl imported, the chief, the run's recorder"""
FORKED_WORKER_MB = 145.0
"""a worker process forked from the command, carrying one unit"""
SPAWNED_WORKER_MB = 275.0
"""a worker process started afresh: it imports torch and fleetrl itself"""
THREAD_UNIT_MB = 6.5
"""a unit run as its own worker thread of the command (``--transport local``)"""
HOST_MB = 5.0
"""a unit host's own cost: its agent, optimiser and worker"""
HOSTED_UNIT_MB = 2.0
"""each unit a host carries: its env, trajectory memory and criterion"""
HEADROOM = 0.2
"""the share of the available memory a run leaves free"""
MEMINFO = Path("/proc/meminfo")


def available_mb(meminfo: Path = MEMINFO) -> float | None:
    """``MemAvailable`` in MB, or None where the kernel does not say (the check is skipped)."""
    try:
        lines = meminfo.read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) * 1024 / MB
    return None


@dataclass(frozen=True)
class RunLayout:
    """Where a run's units live: worker processes (forked or spawned) or threads of the command, each carrying
    one unit or a unit host's ``per_host``."""

    units: int
    processes: bool
    per_host: int = 1
    forked: bool = True

    @classmethod
    def of(cls, units: int, mode: str, transport: str, per_host: int, forked: bool) -> RunLayout:
        processes = mode == "individual" or transport == "mqtt"
        return cls(units, processes, per_host, forked)

    @property
    def hosts(self) -> int:
        return 0 if self.per_host == 1 else math.ceil(self.units / self.per_host)

    @property
    def process_mb(self) -> float:
        return FORKED_WORKER_MB if self.forked else SPAWNED_WORKER_MB

    def estimate_mb(self) -> float:
        """The memory the run is expected to hold at its peak (MB)."""
        if self.hosts:
            each = HOST_MB + (self.process_mb if self.processes else 0.0)
            return COMMAND_MB + self.hosts * each + self.units * HOSTED_UNIT_MB
        if self.processes:
            return COMMAND_MB + self.units * self.process_mb
        return COMMAND_MB + self.units * THREAD_UNIT_MB

    def described(self) -> str:
        if self.hosts:
            where = " (processes)" if self.processes else ""
            return f"{self.hosts} unit hosts of {self.per_host} units{where}"
        if self.processes:
            return f"{self.units} worker processes of ~{self.process_mb:.0f} MB"
        return f"{self.units} worker threads of ~{THREAD_UNIT_MB:.0f} MB"

    def most_units(self, budget_mb: float) -> int:
        """The most units this layout holds within ``budget_mb`` (0: not even one)."""
        low, high = 0, max(self.units, 1)
        while replace(self, units=high).estimate_mb() <= budget_mb:
            low, high = high, high * 2
        while high - low > 1:  # estimate_mb grows with the units: bisect
            middle = (low + high) // 2
            fits = replace(self, units=middle).estimate_mb() <= budget_mb
            low, high = (middle, high) if fits else (low, middle)
        return low


def memory_problem(
    layout: RunLayout,
    available: float | None,
    *,
    threads_possible: bool,
    hosts_possible: bool,
    cores: int,
) -> str | None:
    """Why ``layout`` does not fit ``available`` MB (what it needs, what fits, what to type instead), or None
    when it fits or nothing is known of the memory."""
    if available is None:
        return None
    budget = available * (1 - HEADROOM)
    need = layout.estimate_mb()
    if need <= budget:
        return None
    hosted = replace(layout, per_host=units_per_core(layout.units, cores))
    threads = replace(layout, processes=False, per_host=1)
    if hosts_possible and hosted.hosts and hosted.estimate_mb() <= budget:
        instead = f"--units-per-host {hosted.per_host} (about {_gb(hosted.estimate_mb())})"
    elif threads_possible and layout.processes and threads.estimate_mb() <= budget:
        instead = f"--transport local (worker threads, about {_gb(threads.estimate_mb())})"
    else:
        best = hosted if hosts_possible else threads if threads_possible else layout
        most = best.most_units(budget)
        per_host = units_per_core(most, cores)  # hosts of about one per core for the units that fit
        how = f" --units-per-host {per_host}" if best.hosts and per_host > 1 else ""
        instead = f"--units {most}{how}" if most else "a machine with more memory"
    return (
        f"--units {layout.units}: {layout.described()} need about {_gb(need)} but this machine has "
        f"{_gb(available)} available (a run leaves {HEADROOM:.0%} of it free): at most "
        f"{layout.most_units(budget)} units fit this way; type {instead} instead"
    )


def _gb(mb: float) -> str:
    return f"{mb / 1024:.1f} GB"


def run_memory_problem(
    units: int, mode: str, transport: str, per_host: int, *, hosts_possible: bool
) -> str | None:
    """:func:`memory_problem` of a run of these settings on this machine."""
    try:
        forked = fork_available()
    except ValueError:  # a bad FLEETRL_WORKER_START: the run refuses it when it starts its workers
        forked = False
    layout = RunLayout.of(units, mode, transport, per_host, forked)
    federated = mode == "federated"
    return memory_problem(
        layout,
        available_mb(),
        threads_possible=federated,
        hosts_possible=federated and hosts_possible,
        cores=usable_cores(),
    )
