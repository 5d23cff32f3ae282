"""A sweep reuses finished runs only: a run interrupted by Ctrl-C (valid but partial) is run again."""

import json
from pathlib import Path

import pytest

from fleetrl.experiments.sweep import Run


@pytest.mark.parametrize(
    ("summary", "done"),
    [(None, False), ({"interrupted": False}, True), ({"interrupted": True}, False), ("{not json", False)],
)
def test_only_an_uninterrupted_summary_marks_a_run_done(tmp_path: Path, summary: object, done: bool) -> None:
    run = Run(tmp_path / "seed-0", ["--seed", "0"])
    if summary is not None:
        run.out.mkdir()
        text = summary if isinstance(summary, str) else json.dumps(summary)
        (run.out / "summary.json").write_text(text)
    assert run.done is done
