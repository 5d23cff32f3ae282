"""A report section's figures: each arm's mean score per round, two arms' per-worker curves side by side."""

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from fleetrl.runs.plots import X_LABELS, by_worker, draw_worker
from fleetrl_lab.records import RunRecord


def mean_score_curve(records: list[RunRecord], max_rounds: int) -> np.ndarray:
    """Mean score per round over every worker of every run (a finished worker holds its last score)."""
    totals = np.zeros(max_rounds)
    count = 0
    for record in records:
        for scores in record.scores().values():
            values = [np.nan if s is None else s for s in scores]
            padded = np.full(max_rounds, values[-1] if values else 0.0)
            padded[: len(values)] = values[:max_rounds]
            totals += padded
            count += 1
    return totals / max(count, 1)


def plot_curves(arms: list[tuple[str, list[RunRecord]]], max_rounds: int, title: str, path: Path) -> None:
    """The mean score per round over every worker of every run, one line per arm that has runs."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for label, records in arms:
        if records:
            ax.plot(mean_score_curve(records, max_rounds), label=label, lw=1.2)
    ax.set_xlabel(X_LABELS["rounds"])
    ax.set_ylabel("mean score (all workers, all seeds)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_side_by_side(columns: list[tuple[str, RunRecord]], path: Path) -> None:
    """Each arm's run as a column of per-worker panels (score, WMA, transfers)."""
    workers = [by_worker(record.round_records()) for _, record in columns]
    n_rows = max(len(w) for w in workers)
    fig, axes = plt.subplots(n_rows, 2, figsize=(12, 2.4 * n_rows), sharex=True, sharey=True, squeeze=False)
    for col, ((label, _), groups) in enumerate(zip(columns, workers, strict=True)):
        axes[0, col].set_title(label, fontsize=10)
        for row, (worker, rows) in enumerate(groups.items()):
            draw_worker(axes[row, col], rows, f"worker {worker}")
        axes[-1, col].set_xlabel(X_LABELS["rounds"], fontsize=8)
    axes[0, 0].legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
