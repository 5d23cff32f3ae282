"""Figure-5-style plots: per worker, the score per round (blue), its WMA (red), the actor loss (green
dotted, right axis), and model transfers as vertical lines."""

from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from fleetrl.runs.records import RoundRecord


def plot_run(records: list[RoundRecord], path: Path, title: str = "") -> None:
    """Draw one panel per worker and save a PNG at ``path``."""
    by_worker: dict[int, list[RoundRecord]] = defaultdict(list)
    for record in records:
        by_worker[record.worker].append(record)
    workers = sorted(by_worker) or [0]
    fig, axes = plt.subplots(len(workers), 1, figsize=(9, 2.6 * len(workers)), sharex=True, squeeze=False)
    for ax, worker in zip(axes[:, 0], workers, strict=True):
        rows = sorted(by_worker.get(worker, []), key=lambda r: r.round)
        rounds = [r.round for r in rows]
        ax.plot(rounds, [r.score for r in rows], color="tab:blue", lw=0.8, label="score")
        ax.plot(rounds, [r.wma for r in rows], color="tab:red", lw=1.5, label="WMA (last 10)")
        loss_ax = ax.twinx()
        loss_ax.plot(rounds, [r.actor_loss for r in rows], "g:", lw=0.8, label="actor loss")
        loss_ax.set_ylabel("actor loss", color="tab:green", fontsize=8)
        for r in rows:
            if r.event.startswith("transfer_in"):
                ax.axvline(r.round, color="tab:purple", ls="--", lw=1)
                ax.annotate(
                    f"from {r.event.split(':', 1)[-1]}", (r.round, ax.get_ylim()[1]), fontsize=7, va="top"
                )
            if "completed" in r.event.split("+"):
                ax.axvline(r.round, color="black", ls="-", lw=0.8)
        ax.set_ylabel(f"worker {worker}\nscore")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper left", fontsize=8)
    axes[-1, 0].set_xlabel("round (episode)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
