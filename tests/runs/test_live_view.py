"""The live view: a progress line where stderr is not a terminal, nothing (and no ``rich``) when disabled."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fleetrl.runs.live import LiveView
from fleetrl.runs.records import WorkerProgress


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
        "from fleetrl.runs.records import WorkerProgress\n"
        "with LiveView('run', 100.0, enabled=False) as view:\n"
        "    view.update({0: WorkerProgress(round=1)}, 1.0, force=True)\n"
        "print('rich' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False" and done.stderr == ""


def test_a_summarised_view_prints_the_fleet_in_one_line_not_a_row_per_unit(
    capsys: pytest.CaptureFixture[str],
) -> None:
    progress = {u: WorkerProgress(round=4, score=100.0 + u, wma=100.0 + u) for u in range(40)}
    progress[7] = WorkerProgress(round=4, score=500.0, wma=480.0, completed_at_round=4, state="completed")
    progress[3] = WorkerProgress(round=2, score=1.0, wma=1.5, state="stopped")
    members = [list(range(h, h + 10)) for h in range(0, 40, 10)]
    with LiveView("run", 475.0, summarise=True, members=members) as view:
        view.update(progress, 2.0, force=True, ended={3})
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    line = lines[0]
    assert "completed 1/40" in line and "(→ 475)" in line and "members online 4/4" in line
    # not completed, lowest WMA first; five of them
    assert "slowest: u3 r2 wma 1.5, u0 r4 wma 100.0, u1 r4 wma 101.0, u2 r4 wma 102.0, u4 r4" in line
    assert "u39" not in line and "w39" not in line


def test_the_terminal_summary_of_a_thousand_units_fits_one_screen() -> None:
    import io

    from rich.console import Console

    from fleetrl.runs.fleet_summary import SLOWEST_SHOWN, snapshot

    progress = {u: WorkerProgress(round=9, score=float(u), wma=float(u)) for u in range(1000)}
    view = LiveView("run", 475.0, enabled=False, summarise=True)
    console = Console(width=120, record=True, file=io.StringIO())
    console.print(view.fleet_tables(snapshot(progress), 3.0))
    text = console.export_text()
    assert "0 of 1000" in text and "1000 of 1000" in text  # completed; members online
    assert len(text.splitlines()) <= 2 * SLOWEST_SHOWN + 10
