"""One policy at every exchange of a per-step scheme (``pergrad``): what each worker holds (the scheme's
``start_parameters``) once it has applied every answer before an exchange, compared between workers — a unit
that caught up against one that was never behind. Used by tests and by fault_soak.py and netns_tree.py; as a
script it runs a ``fleetrl`` command with the recorder installed (one JSON line per applied answer):

    python lab/benchmarks/one_policy.py --digests w0.jsonl [--mutate skip] -- worker --worker-id 0 ...

A mutation breaks this process's catch-up on purpose, to show the check fails: ``skip`` drops the first
missed answer, ``swap`` applies the first two in reverse order, ``perturb`` scales every missed answer's
largest element by 1 + 2⁻¹⁰.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import sys
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

Exchange = tuple[int, int]
"""(round, step) of the fleet's next exchange: every answer before it is applied"""
MUTATIONS = ("skip", "swap", "perturb")
LIVE, CAUGHT_UP = "live", "catch-up"
ApplyFleetStep = Callable[[int, np.ndarray], None]


def digest(flat: np.ndarray) -> str:
    """A short hash of ``flat``'s bytes (equal digests: the same numbers, bit for bit)."""
    return hashlib.sha256(np.ascontiguousarray(flat).tobytes()).hexdigest()[:16]


def perturbed(flat: np.ndarray) -> np.ndarray:
    """``flat`` with its largest element scaled by 1 + 2⁻¹⁰ (one term of the step differs)."""
    out = np.array(flat, copy=True)
    i = int(np.argmax(np.abs(out)))
    out[i] = out[i] * out.dtype.type(1.0 + 2.0**-10)
    return out


class BrokenCatchUp:
    """A catch-up broken on purpose (see the module's docstring): called as ``broken(apply, k, flat)`` for
    each missed answer in the order they come, where ``apply(k, flat)`` is the real catch-up step."""

    def __init__(self, mutation: str) -> None:
        if mutation not in MUTATIONS:
            raise ValueError(f"unknown mutation {mutation!r} (choose {', '.join(MUTATIONS)})")
        self.mutation, self.calls = mutation, 0
        self._held: tuple[int, np.ndarray] | None = None

    def __call__(self, apply: ApplyFleetStep, k: int, flat: np.ndarray) -> None:
        self.calls += 1
        if self.mutation == "skip" and self.calls == 1:
            return
        if self.mutation == "swap" and self.calls == 1:
            self._held = (k, flat)
            return
        apply(k, perturbed(flat) if self.mutation == "perturb" else flat)
        if self._held is not None:
            held, self._held = self._held, None
            apply(*held)


@dataclass(frozen=True)
class Held:
    """What ``worker`` held at ``exchange``, and whether it got there by a catch-up or a live answer."""

    worker: str
    exchange: Exchange
    digest: str
    how: str


class Recorder:
    """Thread-safe list of :class:`Held`, appended to a JSON-lines file too if ``path`` is given."""

    def __init__(self, path: Path | None = None) -> None:
        self.path, self.held = path, list[Held]()
        self._lock = threading.Lock()

    def record(self, held: Held) -> None:
        with self._lock:
            self.held.append(held)
            if self.path is not None:
                with self.path.open("a") as out:
                    out.write(json.dumps(asdict(held)) + "\n")


def load(paths: Iterable[Path]) -> list[Held]:
    """The records of :class:`Recorder` files (missing files hold none)."""
    out = []
    for path in paths:
        for line in path.read_text().splitlines() if path.exists() else ():
            raw = json.loads(line)
            rnd, step = raw["exchange"]
            out.append(Held(raw["worker"], (int(rnd), int(step)), raw["digest"], raw["how"]))
    return out


@contextlib.contextmanager
def recording(recorder: Recorder, broken: Mapping[str, BrokenCatchUp] | None = None) -> Iterator[None]:
    """While open, every ``FederatedWorker`` of this process records what it holds after each answer it
    applies; a worker named in ``broken`` catches up through its :class:`BrokenCatchUp`."""
    from fleetrl.federation.worker import actions
    from fleetrl.federation.worker.runner import FederatedWorker

    original = FederatedWorker._execute
    mutated: Mapping[str, BrokenCatchUp] = broken if broken is not None else {}

    def execute(self: Any, output: Any) -> None:
        catch_up = isinstance(output, actions.ApplyFleetStep)
        if catch_up and self.worker_id in mutated:
            agent = self.learner.agent
            apply: ApplyFleetStep = lambda k, flat: self.scheme.catch_up_step(agent, k, flat)  # noqa: E731
            mutated[self.worker_id](apply, output.step, output.flat)
        else:
            original(self, output)
        if catch_up or isinstance(output, actions.ApplyStep):
            shared = self.scheme.start_parameters(self.learner.agent)
            how = CAUGHT_UP if catch_up else LIVE
            recorder.record(Held(self.worker_id, tuple(self.machine.fleet_at), digest(shared), how))

    FederatedWorker._execute = execute  # type: ignore[method-assign]
    try:
        yield
    finally:
        FederatedWorker._execute = original  # type: ignore[method-assign]


@dataclass
class OnePolicy:
    """The comparison of :func:`compare`."""

    compared: int = 0
    """exchanges where at least two workers' holdings were compared"""
    after_catch_up: int = 0
    """(worker, exchange) holdings of a worker at or after its first catch-up, compared with a worker never
    behind up to that exchange"""
    caught_up: dict[str, int] = field(default_factory=dict)
    """per worker: the answers it applied by catching up"""
    mismatches: list[str] = field(default_factory=list)

    @property
    def holds(self) -> bool:
        """No mismatch, and the check was not vacuous: some unit that caught up was compared."""
        return not self.mismatches and self.after_catch_up > 0

    def summary(self) -> str:
        """One line."""
        first = f"; first: {self.mismatches[0]}" if self.mismatches else ""
        return (
            f"{self.compared} exchanges compared, {self.after_catch_up} holdings after a catch-up against a "
            f"unit never behind, catch-ups {dict(sorted(self.caught_up.items()))}, "
            f"{len(self.mismatches)} mismatches{first}"
        )


def compare(held: Iterable[Held]) -> OnePolicy:
    """At every exchange, every worker that reached it must hold the same numbers; count the holdings of a
    unit after its first catch-up compared with a unit never behind up to that exchange."""
    by_exchange: dict[Exchange, dict[str, set[str]]] = {}
    first_catch_up: dict[str, Exchange] = {}
    report = OnePolicy()
    for h in held:
        by_exchange.setdefault(h.exchange, {}).setdefault(h.worker, set()).add(h.digest)
        if h.how == CAUGHT_UP:
            report.caught_up[h.worker] = report.caught_up.get(h.worker, 0) + 1
            first_catch_up[h.worker] = min(first_catch_up.get(h.worker, h.exchange), h.exchange)
    for exchange, workers in sorted(by_exchange.items()):
        if len(workers) < 2:
            continue
        report.compared += 1
        behind = {w for w in workers if w in first_catch_up and first_catch_up[w] <= exchange}
        if len(behind) < len(workers):
            report.after_catch_up += len(behind)
        if len({d for digests in workers.values() for d in digests}) > 1:
            held_by = ", ".join(
                f"{w}{' (caught up)' if w in behind else ''}: {'/'.join(sorted(d))}"
                for w, d in sorted(workers.items())
            )
            report.mismatches.append(f"before round {exchange[0]} step {exchange[1]}: {held_by}")
    return report


def main() -> int:
    """Run ``fleetrl`` with the arguments after ``--``, recording (and maybe mutating) its catch-ups."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--digests", type=Path, required=True, help="JSON-lines file to append to")
    parser.add_argument("--mutate", choices=MUTATIONS, default=None, help="break this process's catch-up")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- and the fleetrl command line")
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    from fleetrl.cli.main import main as fleetrl

    broken = _EveryWorker(args.mutate) if args.mutate else None
    with recording(Recorder(args.digests), broken):
        return fleetrl(command)


class _EveryWorker(dict[str, BrokenCatchUp]):
    """Every worker id maps to its own :class:`BrokenCatchUp` (a process runs one worker, or a host's)."""

    def __init__(self, mutation: str) -> None:
        super().__init__()
        self.mutation = mutation

    def __missing__(self, worker: str) -> BrokenCatchUp:
        self[worker] = BrokenCatchUp(self.mutation)
        return self[worker]

    def __contains__(self, worker: object) -> bool:
        return True


if __name__ == "__main__":
    sys.exit(main())
