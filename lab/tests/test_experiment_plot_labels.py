"""Every axis of an experiment's plots (mean_score.png, workers.png) names its quantity: the plots are drawn
from fake records, caught as they are saved, and inspected axis by axis."""

from pathlib import Path
from typing import Any

import pytest
from experiment_fakes import record, write_record_of
from matplotlib.figure import Figure

from fleetrl.runs.plots import unlabelled_axes
from fleetrl_lab.arms import Places, arm
from fleetrl_lab.plan import Plan, run_plan
from fleetrl_lab.runner import seeds_line

SEEDS = [100, 101]
ALONE = arm("cartpole", 3, "individual", "standard", 100, "each unit alone")
PERGRAD = arm("cartpole", 3, "federated", "standard", 100, "pergrad", "pergrad")
PLAN = Plan("labels", "Labels", [ALONE, PERGRAD], 100, [], side_by_side=(ALONE, PERGRAD))


def test_every_axis_of_an_experiments_plots_has_a_label(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    places = Places(tmp_path / "runs", tmp_path / "committed")
    for seed in SEEDS:
        for one, fleet in ((ALONE, 30), (PERGRAD, 12)):
            write_record_of(one.run(places, seed), record(one.run(places, seed), fleet))
    saved: dict[str, list[str]] = {}
    save = Figure.savefig

    def inspect_then_save(fig: Figure, path: Any, *args: Any, **kwargs: Any) -> None:
        saved[Path(path).name] = unlabelled_axes(fig)
        save(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", inspect_then_save)
    run_plan(PLAN, tmp_path / "out", places, SEEDS, [seeds_line(SEEDS, 0), ""])
    assert saved == {"mean_score.png": [], "workers.png": []}
