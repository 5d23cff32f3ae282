"""Every axis of the run's plot (scores.png) names its quantity: rendered, then inspected axis by axis."""

import math

import matplotlib.pyplot as plt
import pytest

from fleetrl.runs.plots import (
    COMPLETED_LABEL,
    FLEET_WMA_LABEL,
    LOSS_LABEL,
    SCORE_LABEL,
    X_LABELS,
    XAxis,
    fleet_figure,
    plot_run,
    scores_figure,
    unlabelled_axes,
)
from fleetrl.runs.records import MetricsRow


def rows(workers: int, rounds: int, actor_loss: float = 0.1) -> list[MetricsRow]:
    return [
        MetricsRow(r, w, 10.0 * r, 5.0 * r, actor_loss * r, 0.2, 1.0, 50, 0.5 * r, "", episodes=2)
        for w in range(workers)
        for r in range(1, rounds + 1)
    ]


@pytest.mark.parametrize("x_axis", ["rounds", "episodes"])
def test_every_axis_of_the_scores_plot_has_a_label(x_axis: XAxis) -> None:
    fig = scores_figure(rows(3, 12), "qube · federated", x_axis)
    try:
        assert unlabelled_axes(fig) == []
        panels = [ax for ax in fig.axes if ax.get_ylabel().endswith(SCORE_LABEL)]
        losses = [ax for ax in fig.axes if ax.get_ylabel() == LOSS_LABEL]
        assert len(panels) == 3 and len(losses) == 3  # the dotted actor loss's right axis, per worker
        assert panels[-1].get_xlabel() == X_LABELS[x_axis]
        assert [ax.get_ylabel().split("\n")[0] for ax in panels] == ["worker 0", "worker 1", "worker 2"]
    finally:
        plt.close(fig)


def test_a_plot_without_losses_draws_no_empty_loss_axis() -> None:
    fig = scores_figure(rows(2, 5, actor_loss=math.nan))
    try:
        assert unlabelled_axes(fig) == []
        assert len(fig.axes) == 2 and not any(ax.get_ylabel() == LOSS_LABEL for ax in fig.axes)
    finally:
        plt.close(fig)


def test_the_check_finds_an_unlabelled_axis() -> None:
    fig, ax = plt.subplots()
    try:
        ax.plot([1, 2], [3, 4])
        ax.set_xlabel("round")
        assert unlabelled_axes(fig) == ["panel 0 y"]
        ax.twinx().plot([1, 2], [0.1, 0.2])
        assert unlabelled_axes(fig) == ["panel 0 y", "panel 1 y"]  # a twin's hidden x-axis needs none
    finally:
        plt.close(fig)


def synthetic_fleet(units: int, rounds: int) -> list[MetricsRow]:
    """A fleet whose unit u climbs to 500 by round 20 + u % 300, completing there."""
    fleet = []
    for u in range(units):
        done = 20 + u % 300
        for r in range(1, rounds + 1):
            wma = min(500.0, 500.0 * r / done)
            fleet.append(MetricsRow(r, u, wma, wma, event="completed" if r == done else "gradient"))
    return fleet


def test_the_fleet_plot_labels_both_axes_and_counts_completions_of_all_units() -> None:
    fig = fleet_figure(synthetic_fleet(1000, 200), "cartpole · 1000 units", target=475.0)
    try:
        assert unlabelled_axes(fig) == []
        wma_ax, done_ax = fig.axes  # one panel and its right axis, however many units
        assert wma_ax.get_ylabel() == FLEET_WMA_LABEL and wma_ax.get_xlabel() == X_LABELS["rounds"]
        assert done_ax.get_ylabel() == COMPLETED_LABEL.format(units=1000)
        (steps,) = done_ax.get_lines()
        assert steps.get_ydata()[-1] == 3 * 181 + 100  # by round 200: units with u % 300 ≤ 180
    finally:
        plt.close(fig)


def test_a_summarised_run_plot_is_one_fleet_panel(tmp_path) -> None:
    path = tmp_path / "scores.png"
    plot_run(synthetic_fleet(40, 30), path, "fleet", summarise=True)
    assert path.stat().st_size > 10_000
