"""Every axis of the run's plot (scores.png) names its quantity: rendered, then inspected axis by axis."""

import math

import matplotlib.pyplot as plt
import pytest

from fleetrl.runs.plots import LOSS_LABEL, SCORE_LABEL, X_LABELS, XAxis, scores_figure, unlabelled_axes
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
