"""An arm of an experiment: one training configuration repeated over seeds, and what its runs measured."""

import json
import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleetrl.experiments.stats import Completion, read_completion
from fleetrl.experiments.sweep import Run
from fleetrl.runs.records import read_metrics


@dataclass(frozen=True)
class Arm:
    """One configuration of ``fleetrl train``, run once per seed."""

    key: str
    """directory name (no spaces)"""
    label: str
    """how the report names it"""
    args: tuple[str, ...]
    """``fleetrl train`` arguments other than ``--seed`` and ``--out``"""

    def run(self, root: Path, seed: int) -> Run:
        """The run of this arm for ``seed`` under ``root``."""
        return Run(
            root / self.key / f"seed-{seed}",
            [*self.args, "--seed", str(seed)],
            {"arm": self.key, "seed": seed},
        )

    def runs(self, root: Path, seeds: list[int]) -> list[Run]:
        """One run per seed."""
        return [self.run(root, seed) for seed in seeds]

    def command(self, root: Path) -> str:
        """The command that regenerates the arm's runs (one per seed)."""
        out = shlex.quote(str(root / self.key))
        return f"for s in SEEDS; do fleetrl train {shlex.join(self.args)} --seed $s --out {out}/seed-$s; done"


def completions(runs: list[Run]) -> list[Completion]:
    """Rounds to completion of each run."""
    return [read_completion(run.out) for run in runs]


def mean_score_curve(runs: list[Run], max_rounds: int) -> np.ndarray:
    """Mean score per round over every worker of every run (a finished worker holds its last WMA)."""
    totals = np.zeros(max_rounds)
    count = 0
    for run in runs:
        per_worker: dict[int, list[float]] = {}
        for record in read_metrics(run.out / "metrics.csv"):
            per_worker.setdefault(record.worker, []).append(record.score)
        for scores in per_worker.values():
            padded = np.full(max_rounds, scores[-1] if scores else 0.0)
            padded[: len(scores)] = scores[:max_rounds]
            totals += padded
            count += 1
    return totals / max(count, 1)


def wall_seconds(runs: list[Run]) -> list[float]:
    """Wall time of each run."""
    return [float(json.loads((run.out / "summary.json").read_text())["wall_seconds"]) for run in runs]


def same_scores(a: Path, b: Path) -> bool:
    """Whether two run directories hold exactly the same (worker, round, score) rows."""

    def rows(path: Path) -> list[tuple[int, int, float]]:
        return sorted((r.worker, r.round, r.score) for r in read_metrics(path / "metrics.csv"))

    return rows(a) == rows(b)
