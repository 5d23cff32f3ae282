"""Figure-5-style plots: per worker, the score per round (blue), its WMA (red), the actor loss (green
dotted, right axis), and model transfers as vertical lines."""

from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes

from fleetrl.runs.records import RoundRecord


def by_worker(records: list[RoundRecord]) -> dict[int, list[RoundRecord]]:
    """Records grouped per worker, each group in round order."""
    groups: dict[int, list[RoundRecord]] = defaultdict(list)
    for record in records:
        groups[record.worker].append(record)
    return {w: sorted(rs, key=lambda r: r.round) for w, rs in sorted(groups.items())}


def draw_worker(ax: Axes, rows: list[RoundRecord], label: str) -> None:
    """One worker's panel: score, WMA, actor loss (right axis), transfers and completion."""
    rounds = [r.round for r in rows]
    ax.plot(rounds, [r.score for r in rows], color="tab:blue", lw=0.8, label="score")
    ax.plot(rounds, [r.wma for r in rows], color="tab:red", lw=1.5, label="WMA (last 10)")
    loss_ax = ax.twinx()
    loss_ax.plot(rounds, [r.actor_loss for r in rows], "g:", lw=0.8, label="actor loss")
    loss_ax.tick_params(axis="y", labelsize=7, colors="tab:green")
    completed_at = None  # the first round the criterion held (under fedavg it may hold again later)
    for r in rows:
        events = r.event.split("+")
        if r.event.startswith("transfer_in"):
            ax.axvline(r.round, color="tab:purple", ls="--", lw=1)
            ax.text(
                r.round,
                0.95,
                f" from {r.event.split(':', 1)[-1]}",
                transform=ax.get_xaxis_transform(),
                fontsize=7,
                va="top",
                color="tab:purple",
            )
        if completed_at is None and any(e.startswith("completed") for e in events):
            completed_at = r.round
            ax.axvline(r.round, color="black", lw=0.8)
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)


def plot_run(records: list[RoundRecord], path: Path, title: str = "") -> None:
    """Draw one panel per worker and save a PNG at ``path``."""
    groups = by_worker(records) or {0: []}
    fig, axes = plt.subplots(len(groups), 1, figsize=(9, 2.6 * len(groups)), sharex=True, squeeze=False)
    for ax, (worker, rows) in zip(axes[:, 0], groups.items(), strict=True):
        draw_worker(ax, rows, f"worker {worker}\nscore")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    axes[-1, 0].set_xlabel("round (episode)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
