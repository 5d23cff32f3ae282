"""The live view: a progress line where stderr is not a terminal, nothing (and no ``rich``) when disabled."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fleetrl.runs.live import LiveView
from fleetrl.runs.rundir import WorkerProgress


def test_an_enabled_view_off_a_terminal_prints_one_plain_progress_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    progress = {0: WorkerProgress(round=3, score=12.0, wma=10.5, state="learning")}
    with LiveView("run", 100.0) as view:
        view.update(progress, 2.0, force=True)
        view.update(progress, 2.5)  # within the interval: not printed again
    err = capsys.readouterr().err
    assert err.count("w0 r3 wma 10.5 learning") == 1


def test_a_disabled_view_prints_nothing_and_does_not_import_rich() -> None:
    code = (
        "import sys\n"
        "from fleetrl.runs.live import LiveView\n"
        "from fleetrl.runs.rundir import WorkerProgress\n"
        "with LiveView('run', 100.0, enabled=False) as view:\n"
        "    view.update({0: WorkerProgress(round=1)}, 1.0, force=True)\n"
        "print('rich' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False" and done.stderr == ""
