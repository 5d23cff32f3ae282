"""A fleet of more than 16 units end to end: its plot, TensorBoard and closing lines summarise the fleet,
metrics.csv keeps one row per unit per round; ``--per-unit-detail`` is a setting like any other."""

import csv
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.runs.setting_values import build
from fleetrl.runs.settings import RunSettings

UNITS = 20


@pytest.mark.slow
def test_a_large_fleet_run_summarises_its_plot_board_and_closing_lines(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = tmp_path / "run"
    argv = ["train", "--env", "cartpole", "--units", str(UNITS), "--units-per-host", "10", "--mode",
            "federated", "--transport", "local", "--scheme", "pergrad", "--max-rounds", "2", "--no-live",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    rows = list(csv.DictReader((out / "metrics.csv").open()))
    assert sorted((int(r["worker"]), int(r["round"])) for r in rows) == [
        (u, r) for u in range(UNITS) for r in (1, 2)
    ]
    events = EventAccumulator(str(out / "tensorboard"))
    events.Reload()
    tags = events.Tags()["scalars"]
    assert "fleet/wma_median" in tags and not any("worker_" in tag for tag in tags)
    assert [e.step for e in events.Scalars("fleet/completed")] == [1, 2]
    assert (out / "scores.png").stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert f"of {UNITS} completed" in printed and "worker 19:" not in printed
    assert "per_unit_detail = false" in (out / "config.toml").read_text()


def test_per_unit_detail_is_a_checked_setting_that_changes_no_result(tmp_path: Path) -> None:
    values = {"env": "cartpole", "units": 40, "out": str(tmp_path / "run")}
    plain = build(RunSettings, values, {}, resolve=False).learning_resolved()
    detailed = build(RunSettings, values, {"per_unit_detail": True}, resolve=False).learning_resolved()
    assert detailed.per_unit_detail and not plain.per_unit_detail
    assert detailed.result_settings() == plain.result_settings()
    assert "per_unit_detail = true" in detailed.to_toml()
    with pytest.raises(ValueError, match="per-unit-detail = 'yes': expected true or false"):
        build(RunSettings, {**values, "per_unit_detail": "yes"}, {}, resolve=False)
