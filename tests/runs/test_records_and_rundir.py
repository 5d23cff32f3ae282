"""The run directory's files: metrics rows, summary, plot, and refusing to overwrite a run."""

import csv
import json
import math

import pytest

from fleetrl.runs.records import CSV_COLUMNS, RoundRecord
from fleetrl.runs.rundir import RunRecorder


def make_record(worker: int, round_: int, score: float, event: str = "") -> RoundRecord:
    return RoundRecord(round_, worker, score, score / 2, 0.1, 0.2, 1.0, int(score), 0.5 * round_, event)


def test_record_json_round_trip_keeps_nan_as_nan() -> None:
    record = RoundRecord(3, 1, 12.0, 11.5, math.nan, 0.25, 1.05, 12, 0.75, "gradient")
    parsed = RoundRecord.from_json(record.to_json())
    assert parsed.round == 3 and parsed.event == "gradient" and parsed.critic_loss == 0.25
    assert math.isnan(parsed.actor_loss)


@pytest.mark.parametrize("line", ["[1, 2]", '{"round": 1}', "not json"])
def test_record_rejects_lines_that_are_not_records(line: str) -> None:
    with pytest.raises(ValueError):
        RoundRecord.from_json(line)


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
    assert json.loads((out / "config.json").read_text())["env"] == "cartpole"
    assert (out / "scores.png").stat().st_size > 10_000
    assert any((out / "tensorboard").iterdir())


def test_recorder_refuses_to_overwrite_a_run(tmp_path) -> None:
    RunRecorder(tmp_path, {"mode": "individual"}, [0]).finish()
    with pytest.raises(FileExistsError, match="already holds a run"):
        RunRecorder(tmp_path, {"mode": "individual"}, [0])
