"""Figure-5-style plots: per worker, its score, WMA and actor loss per round (or episode) with its transfers;
for a large fleet, one panel of the median WMA in a 10-90 % band and the units completed."""

import itertools
import math
from collections import defaultdict
from pathlib import Path
from typing import Literal

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fleetrl.runs.fleet_summary import fleet_rounds
from fleetrl.runs.records import MetricsRow

XAxis = Literal["rounds", "episodes"]
X_LABELS: dict[str, str] = {
    "rounds": "round (one update: one episode, or with paper-code the episodes filling the memory)",
    "episodes": "episodes played",
}
SCORE_LABEL = "score (episode return)"
LOSS_LABEL = r"actor loss $-L^{\mathrm{CLIP}}$ (dotted)"
FLEET_WMA_LABEL = "WMA of the last 10 scores\n(fleet median, 10-90 % band)"
COMPLETED_LABEL = "units completed (of {units})"


def by_worker(records: list[MetricsRow]) -> dict[int, list[MetricsRow]]:
    """Records grouped per worker, each group in round order."""
    groups: dict[int, list[MetricsRow]] = defaultdict(list)
    for record in records:
        groups[record.worker].append(record)
    return {w: sorted(rs, key=lambda r: r.round) for w, rs in sorted(groups.items())}


def x_values(rows: list[MetricsRow], x_axis: XAxis = "rounds") -> list[int]:
    """Where each of one worker's rounds sits on the x-axis: its number, or the episodes played by then."""
    if x_axis == "rounds":
        return [r.round for r in rows]
    return list(itertools.accumulate(r.episodes for r in rows))


def draw_worker(ax: Axes, rows: list[MetricsRow], label: str, x_axis: XAxis = "rounds") -> None:
    """One worker's panel: score, WMA, actor loss (right axis, where a row carries one), transfers and
    completion."""
    rounds = x_values(rows, x_axis)
    ax.plot(rounds, [r.score for r in rows], color="tab:blue", lw=0.8, label="score")
    ax.plot(rounds, [r.wma for r in rows], color="tab:red", lw=1.5, label="WMA (last 10)")
    if any(math.isfinite(r.actor_loss) for r in rows):
        loss_ax = ax.twinx()
        loss_ax.plot(rounds, [r.actor_loss for r in rows], "g:", lw=0.8, label="actor loss")
        loss_ax.tick_params(axis="y", labelsize=7, colors="tab:green")
        loss_ax.set_ylabel(LOSS_LABEL, fontsize=8, color="tab:green")
    completed_at = None  # the first round the criterion held (under fedavg it may hold again later)
    for x, r in zip(rounds, rows, strict=True):
        events = r.event.split("+")
        if r.event.startswith("transfer_in"):
            ax.axvline(x, color="tab:purple", ls="--", lw=1)
            ax.text(
                x,
                0.95,
                f" from {r.event.split(':', 1)[-1]}",
                transform=ax.get_xaxis_transform(),
                fontsize=7,
                va="top",
                color="tab:purple",
            )
        if completed_at is None and any(e.startswith("completed") for e in events):
            completed_at = x
            ax.axvline(x, color="black", lw=0.8)
    ax.set_ylabel(f"{label}\n{SCORE_LABEL}")
    ax.grid(alpha=0.3)


def scores_figure(records: list[MetricsRow], title: str = "", x_axis: XAxis = "rounds") -> Figure:
    """One panel per worker against rounds or episodes (``x_axis``); the caller saves and closes it."""
    groups = by_worker(records) or {0: []}
    fig, axes = plt.subplots(len(groups), 1, figsize=(9, 2.6 * len(groups)), sharex=True, squeeze=False)
    for ax, (worker, rows) in zip(axes[:, 0], groups.items(), strict=True):
        draw_worker(ax, rows, f"worker {worker}", x_axis)
    axes[0, 0].legend(loc="upper left", fontsize=8)
    axes[-1, 0].set_xlabel(X_LABELS[x_axis])
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def fleet_figure(records: list[MetricsRow], title: str = "", target: float | None = None) -> Figure:
    """One panel for the whole fleet against rounds (:func:`fleetrl.runs.fleet_summary.fleet_rounds`), the
    ``target`` dashed; the caller saves and closes it."""
    fleet = fleet_rounds(records)
    fig, ax = plt.subplots(figsize=(9, 4.2))
    p10, median, p90 = fleet.wma
    ax.fill_between(fleet.rounds, p10, p90, color="tab:red", alpha=0.2, lw=0, label="WMA p10-p90")
    ax.plot(fleet.rounds, median, color="tab:red", lw=1.5, label="WMA median")
    if target is not None:
        ax.axhline(target, color="tab:red", ls="--", lw=0.8, label=f"target {target:g}")
    ax.set_ylabel(FLEET_WMA_LABEL)
    ax.set_xlabel(X_LABELS["rounds"])
    ax.grid(alpha=0.3)
    done_ax = ax.twinx()
    done_ax.step(fleet.rounds, fleet.completed, where="post", color="black", lw=1.2, label="completed")
    done_ax.set_ylim(0, max(fleet.units, 1) * 1.05)
    done_ax.set_ylabel(COMPLETED_LABEL.format(units=fleet.units))
    lines = ax.get_legend_handles_labels()[0] + done_ax.get_legend_handles_labels()[0]
    ax.legend(lines, [str(line.get_label()) for line in lines], loc="upper left", fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_run(
    records: list[MetricsRow],
    path: Path,
    title: str = "",
    x_axis: XAxis = "rounds",
    *,
    summarise: bool = False,
    target: float | None = None,
) -> None:
    """Save a PNG at ``path`` of :func:`scores_figure`, or with ``summarise`` of :func:`fleet_figure`."""
    fig = fleet_figure(records, title, target) if summarise else scores_figure(records, title, x_axis)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def unlabelled_axes(fig: Figure) -> list[str]:
    """Every shown axis of ``fig`` (visible, with tick labels) that has no label, as "panel N x|y"."""
    fig.canvas.draw()
    missing = []
    for i, ax in enumerate(fig.axes):
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            ticks = [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            if axis.get_visible() and ticks and not axis.get_label_text().strip():
                missing.append(f"panel {i} {name}")
    return missing
