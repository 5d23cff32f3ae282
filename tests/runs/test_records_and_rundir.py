"""The run directory's files: metrics rows, summary, plot, and refusing to overwrite a run."""

import csv
import dataclasses
import json
import math

import pytest

from fleetrl.agent.criterion import interrupted_round
from fleetrl.agent.learner import RoundResult
from fleetrl.runs.records import CSV_COLUMNS, FIGURES, MetricsRow
from fleetrl.runs.rundir import RunRecorder


def make_record(worker: int, round_: int, score: float, event: str = "") -> MetricsRow:
    return MetricsRow(round_, worker, score, score / 2, 0.1, 0.2, 1.0, int(score), 0.5 * round_, event)


def test_record_json_round_trip_keeps_nan_as_nan() -> None:
    record = MetricsRow(3, 1, 12.0, 11.5, math.nan, 0.25, 1.05, 12, 0.75, "gradient")
    parsed = MetricsRow.from_json(record.to_json())
    assert parsed.round == 3 and parsed.event == "gradient" and parsed.critic_loss == 0.25
    assert math.isnan(parsed.actor_loss)


def test_the_row_is_the_learner_s_result_flattened_in_the_file_s_column_order() -> None:
    assert CSV_COLUMNS == (
        "round", "worker", "score", "wma", "actor_loss", "critic_loss", "entropy", "steps", "wall_time",
        "event", "episodes", "approx_kl", "clip_fraction",
    )  # fmt: skip
    assert {f.name for f in dataclasses.fields(RoundResult)} >= FIGURES
    result = RoundResult(2, 25.5, 204, 8, 20.0, False, 0.1, 0.2, 0.6, 3.0, 0.01, 0.25)
    row = MetricsRow.of(0, 5, result, 1.5, "gradient")  # the federation's round 5 (a resumed worker)
    assert row == MetricsRow(5, 0, 25.5, 20.0, 0.1, 0.2, 0.6, 204, 1.5, "gradient", 8, 0.01, 0.25)
    assert all(getattr(row, name) == getattr(result, name) for name in FIGURES)


@pytest.mark.parametrize("line", ["[1, 2]", '{"round": 1}', "not json"])
def test_record_rejects_lines_that_are_not_records(line: str) -> None:
    with pytest.raises(ValueError):
        MetricsRow.from_json(line)


def test_recorder_writes_metrics_summary_and_plot(tmp_path) -> None:
    out = tmp_path / "run"
    recorder = RunRecorder(
        out, {"mode": "individual", "env": "cartpole", "preset": "standard", "seed": 4}, [0, 1]
    )
    recorder.add(make_record(0, 1, 10.0))
    recorder.add(make_record(1, 1, 20.0))
    recorder.add(make_record(0, 2, 500.0, "completed"))
    recorder.add(make_record(1, 2, 30.0, "transfer_in:0"))
    summary = recorder.finish()

    rows = list(csv.reader((out / "metrics.csv").open()))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert len(rows) == 5 and rows[3][CSV_COLUMNS.index("event")] == "completed"
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk == json.loads(json.dumps(summary))
    assert on_disk["seed"] == 4 and on_disk["rounds"] == 2
    assert on_disk["workers"]["0"]["completed_at_round"] == 2
    assert on_disk["workers"]["1"]["completed_at_round"] is None
    assert on_disk["workers"]["1"]["final_wma"] == 15.0
    # each unit alone on CartPole rigs (20 ms a step): unit 0 played 10 + 500 steps, unit 1 20 + 30
    rig = {
        "period": 0.02,
        "rule": "nobody waits",
        "fleet": 10.2,
        "per_unit": {"0": 10.2, "1": 1.0},
        "controlled": {"50": 10.2, "90": None, "100": None},  # 1 of 2 units completed, unit 1 never did
        "complete": False,
        "parts": {
            "0": {"played": 10.2, "reset": 0.0, "absent": 0.0, "waited": 0.0},
            "1": {"played": 1.0, "reset": 0.0, "absent": 0.0, "waited": 0.0},
        },
    }
    assert on_disk["rig_seconds"] == rig
    assert json.loads((out / "config.json").read_text())["env"] == "cartpole"
    assert (out / "scores.png").stat().st_size > 10_000
    assert any((out / "tensorboard").iterdir())


def test_recorder_refuses_to_overwrite_a_run(tmp_path) -> None:
    RunRecorder(tmp_path, {"mode": "individual"}, [0]).finish()
    with pytest.raises(FileExistsError, match="already holds a run"):
        RunRecorder(tmp_path, {"mode": "individual"}, [0])


def test_records_carry_the_episodes_of_a_round_and_read_back_the_same() -> None:
    record = MetricsRow(2, 0, 25.5, 20.0, 0.1, 0.2, 0.6, 204, 1.5, "", episodes=8, approx_kl=0.01,
                         clip_fraction=0.25)  # fmt: skip
    assert MetricsRow.from_json(record.to_json()) == record
    row = dict(zip(CSV_COLUMNS, (str(v) for v in record.csv_row()), strict=True))
    assert MetricsRow.from_csv_row(row) == record
    no_update = dataclasses.replace(record, approx_kl=math.nan, clip_fraction=math.nan)
    back = MetricsRow.from_json(no_update.to_json())
    assert math.isnan(back.approx_kl) and math.isnan(back.clip_fraction)
    with pytest.raises(KeyError):
        MetricsRow.from_csv_row({k: v for k, v in row.items() if k != "episodes"})


def test_the_x_axis_counts_rounds_or_episodes_and_says_which() -> None:
    from fleetrl.runs.plots import X_LABELS, x_values

    rows = [make_record(0, r, 10.0) for r in (1, 2, 3)]
    rows = [dataclasses.replace(r, episodes=n) for r, n in zip(rows, (9, 4, 1), strict=True)]
    assert x_values(rows, "rounds") == [1, 2, 3]
    assert x_values(rows, "episodes") == [9, 13, 14]
    assert X_LABELS["rounds"].startswith("round") and "episode" in X_LABELS["episodes"]


def test_summary_counts_episodes_to_completion(tmp_path) -> None:
    recorder = RunRecorder(tmp_path / "run", {"mode": "individual"}, [0])
    for rnd, episodes in ((1, 10), (2, 7)):
        recorder.add(dataclasses.replace(make_record(0, rnd, 30.0), episodes=episodes))
    recorder.add(dataclasses.replace(make_record(0, 3, 300.0, "completed"), episodes=1))
    summary = recorder.finish()
    worker = summary["workers"]["0"]
    assert worker["completed_at_round"] == 3 and worker["completed_at_episode"] == 18
    assert worker["episodes"] == 18
    assert (tmp_path / "run" / "scores-by-episode.png").is_file()


def test_an_interrupted_round_is_a_row_without_figures_and_the_progress_keeps_the_last_ones(tmp_path) -> None:
    recorder = RunRecorder(tmp_path / "run", {"mode": "federated", "scheme": "pergrad"}, [0])
    recorder.add(make_record(0, 1, 40.0))
    lost = MetricsRow.of(0, 2, interrupted_round(2), 0.0, "interrupted")
    recorder.add(lost)
    progress = recorder.progress[0]
    assert (progress.round, progress.score, progress.wma) == (2, 40.0, 20.0)
    recorder.add(make_record(0, 5, 60.0))
    assert (progress.round, progress.score) == (5, 60.0)
    recorder.finish()
    rows = list(csv.DictReader((tmp_path / "run" / "metrics.csv").open()))
    assert [(r["round"], r["event"], r["steps"]) for r in rows] == [
        ("1", "", "40"), ("2", "interrupted", "0"), ("5", "", "60")
    ]  # fmt: skip
    assert rows[1]["score"] in ("", "nan")


def board_tags(out) -> dict[str, list[tuple[int, float]]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(out / "tensorboard"))
    events.Reload()
    return {tag: [(e.step, e.value) for e in events.Scalars(tag)] for tag in events.Tags()["scalars"]}


def test_a_summarised_recorder_writes_the_fleet_s_scalars_and_one_row_per_unit(tmp_path) -> None:
    out = tmp_path / "run"
    config = {"mode": "federated", "env": "cartpole", "completion_threshold": 40.0}
    recorder = RunRecorder(out, config, list(range(20)), summarise=True)
    for round_ in (1, 2):
        for unit in range(20):
            done = "completed" if round_ == 2 and unit < 5 else "gradient"
            recorder.add(make_record(unit, round_, 10.0 * round_ + unit, done))
    recorder.finish()
    assert len(list(csv.reader((out / "metrics.csv").open()))) == 1 + 2 * 20
    tags = board_tags(out)
    assert sorted(tags) == ["fleet/completed", "fleet/wma_median", "fleet/wma_p10", "fleet/wma_p90"]
    assert tags["fleet/completed"] == [(1, 0.0), (2, 5.0)]
    # WMA = score / 2: round 1 units at 5 … 14.5, round 2 at 10 … 19.5
    assert tags["fleet/wma_median"] == [(1, pytest.approx(9.75)), (2, pytest.approx(14.75))]
    assert (out / "scores.png").stat().st_size > 10_000


def test_a_recorder_of_a_small_fleet_keeps_one_series_per_worker(tmp_path) -> None:
    recorder = RunRecorder(tmp_path / "run", {"mode": "individual"}, [0, 1])
    recorder.add(make_record(0, 1, 10.0))
    recorder.add(make_record(1, 1, 20.0))
    recorder.finish()
    tags = board_tags(tmp_path / "run")
    assert "rollout/wma/worker_0" in tags and "rollout/wma/worker_1" in tags
    assert not any(tag.startswith("fleet/") for tag in tags)


def test_the_summary_names_the_run_s_completion_criterion(tmp_path) -> None:
    argmax = {"mode": "individual", "ppo": {"criterion": "argmax"}, "completion_threshold": 2450.0}
    assert RunRecorder(tmp_path / "a", argmax, [0]).finish()["criterion"] == {
        "kind": "argmax",
        "target": 2450.0,
    }
    sampled = {"mode": "individual", "ppo": {"criterion": "sampled"}, "completion_threshold": 475.0}
    assert RunRecorder(tmp_path / "s", sampled, [0]).finish()["criterion"] == {
        "kind": "sampled",
        "target": 475.0,
    }
