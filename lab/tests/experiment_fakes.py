"""Fake run directories and records, so the sweep's reuse rule and the report are tested without training."""

import csv
import json
from pathlib import Path
from typing import Any

from fleetrl.runs.records import CSV_COLUMNS
from fleetrl_lab.records import FORMAT
from fleetrl_lab.sweep import Run


def write_run_dir(
    run: Run, scores: dict[int, list[float]], completed: dict[int, int | None], episodes: bool = False
) -> None:
    """A finished run directory of ``run`` (metrics.csv, summary.json, config.json), as ``fleetrl train``
    leaves one; ``episodes``: two episodes a round, as the paper-code preset's rounds."""
    run.out.mkdir(parents=True)
    with (run.out / "metrics.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(CSV_COLUMNS)
        for worker, worker_scores in scores.items():
            for i, score in enumerate(worker_scores, start=1):
                event = "completed" if completed.get(worker) == i else "gradient"
                row = [i, worker, score, score, 0.1, 0.2, 0.3, 50, 1.0, event, 2 if episodes else 1, 0.0, 0.0]
                writer.writerow(row)
    workers = {str(w): {"completed_at_round": c, "state": "finished"} for w, c in completed.items()}
    summary = {"interrupted": False, "wall_seconds": 12.345, "workers": workers}
    (run.out / "summary.json").write_text(json.dumps(summary))
    (run.out / "config.json").write_text(json.dumps({"result_settings": run.expected}))


def record(
    run: Run, fleet: int, units: int = 3, wall: float = 10.0, unseen: list[float] | None = None
) -> Any:
    """A record of ``run`` whose last unit completes at round ``fleet`` (worker k at fleet - k)."""
    completed = {str(k): fleet - k for k in range(units)}
    workers = {
        k: {
            "score": [float(r) for r in range(1, c + 1)],
            "wma": [float(r) for r in range(1, c + 1)],
            "steps": list(range(1, c + 1)),
            "events": {},
        }
        | {"completed_at_round": c}
        for k, c in completed.items()
    }
    generalisation = {"units": [10, 11], "cap": 500, "scores": {"0": unseen or [500, 120]}}
    return {
        "format": FORMAT,
        "command": run.command(),
        "result_settings": run.expected,
        "host": "test host",
        "wall_seconds": wall,
        "max_rounds": int(run.settings["max_rounds"]),
        "workers": workers,
        "generalisation": generalisation,
    }


def write_record_of(run: Run, data: Any) -> Path:
    """Write ``data`` as ``run``'s record."""
    from fleetrl_lab.records import write_record

    write_record(run.record, data)
    return run.record
